"""Assembly modes of 6-6 Stewart-Gough platforms: count and time against random-start LM.

For each platform (Dietmaier's 40-mode platform and two random 6-6 platforms) prints, with
the compiled kernels warm (the C library built once and cached):

* SC: ``assembly_modes`` -- solutions found and median wall time over ``--repeat`` seeds,
  with the curves followed and the predictor-corrector steps taken (the states computed);
* LM: a baseline written here, random-start Levenberg-Marquardt on the leg equations
  (vectorised numpy: every start iterated at once), at doubling numbers of starts; the
  smallest number of starts that found all the SC solutions in every repeat, its median time
  and the ratio LM time / SC time.

    python benchmarks/modes_6_6.py [--repeat 7]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import scdk_sym as sc
from scdk_sym.solvers.modes import explore

DIETMAIER = (
    np.array(
        [
            [0.0, 0.0, 0.0],
            [1.107915, 0.0, 0.0],
            [0.549094, 0.756063, 0.0],
            [0.735077, -0.223935, 0.525991],
            [0.514188, -0.526063, -0.368418],
            [0.590473, 0.094733, -0.205018],
        ]
    ),
    np.array(
        [
            [0.0, 0.0, 0.0],
            [0.542805, 0.0, 0.0],
            [0.956919, -0.528915, 0.0],
            [0.665885, -0.353482, 1.402538],
            [0.478359, 1.158742, 0.107672],
            [-0.137087, -0.235121, 0.353913],
        ]
    ),
    np.array([1.0, 0.645275, 1.086284, 1.503439, 1.281933, 0.771071]),
)


def rotations(w: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of rotation vectors (N, 3)."""
    angle = np.linalg.norm(w, axis=1)[:, None, None]
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K = K - K.transpose(0, 2, 1)
    safe = np.where(angle < 1e-12, 1.0, angle)
    a = np.where(angle < 1e-12, 1.0, np.sin(safe) / safe)
    b = np.where(angle < 1e-12, 0.5, (1 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * K + b * K @ K


def random_platform(seed: int):
    """A general 6-6 platform (anchors near two parallel planes) and the legs of a pose."""
    rng = np.random.default_rng(seed)
    ab, ap = rng.uniform(0, 2 * np.pi, 6), rng.uniform(0, 2 * np.pi, 6)
    rb, rp = rng.uniform(0.3, 0.6, 6), rng.uniform(0.15, 0.35, 6)
    A = np.c_[rb * np.cos(ab), rb * np.sin(ab), rng.uniform(-0.1, 0.1, 6)]
    B = np.c_[rp * np.cos(ap), rp * np.sin(ap), rng.uniform(-0.1, 0.1, 6)]
    position = np.array([*rng.uniform(-0.1, 0.1, 2), rng.uniform(0.4, 0.7)])
    R = rotations(rng.normal(size=(1, 3)) * 0.3)[0]
    return A, B, np.linalg.norm(position + B @ R.T - A, axis=1)


def lm_baseline(A, B, lengths, starts: int, seed: int) -> list[np.ndarray]:
    """Random-start Levenberg-Marquardt: the distinct converged poses as 4x4 matrices."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(starts, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    R = rotations(2 * np.arccos(np.clip(np.abs(q[:, :1]), 0, 1)) * _axes(q))
    reach = lengths.max() + np.linalg.norm(A, axis=1).max() + np.linalg.norm(B, axis=1).max()
    p = rng.uniform(-reach, reach, size=(starts, 3))

    def residual(p, R):
        d = p[:, None, :] + np.einsum("nij,kj->nki", R, B) - A[None]
        return 0.5 * (np.sum(d * d, axis=2) - lengths**2), d

    def jacobian(R, d):
        return np.concatenate([d, np.cross(np.einsum("nij,kj->nki", R, B), d)], axis=2)

    r, d = residual(p, R)
    cost = np.sum(r * r, axis=1)
    mu = np.full(starts, 1e-2)
    for _ in range(60):
        J = jacobian(R, d)
        JtJ = J.transpose(0, 2, 1) @ J
        damped = JtJ + mu[:, None, None] * (np.eye(6) * (1 + np.einsum("nii->ni", JtJ)[:, :, None]))
        step = -np.linalg.solve(damped, np.einsum("nki,nk->ni", J, r)[..., None])[..., 0]
        p_new, R_new = p + step[:, :3], rotations(step[:, 3:]) @ R
        r_new, d_new = residual(p_new, R_new)
        c_new = np.sum(r_new * r_new, axis=1)
        ok = c_new < cost
        p[ok], R[ok], r[ok], d[ok], cost[ok] = p_new[ok], R_new[ok], r_new[ok], d_new[ok], c_new[ok]
        mu = np.where(ok, mu / 3, mu * 4)
    for _ in range(6):
        J = jacobian(R, d)
        regular = np.abs(np.linalg.det(J)) > 1e-14
        step = np.zeros((starts, 6))
        step[regular] = -np.linalg.solve(J[regular], r[regular][..., None])[..., 0]
        p, R = p + step[:, :3], rotations(step[:, 3:]) @ R
        r, d = residual(p, R)
    good = np.all(np.isfinite(r), axis=1) & (np.abs(r).max(axis=1) < 1e-11)
    poses: list[np.ndarray] = []
    for pi, Ri in zip(p[good], R[good], strict=True):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Ri, pi
        if not any(np.abs(T - S).max() < 1e-6 for S in poses):
            poses.append(T)
    return poses


def _axes(q: np.ndarray) -> np.ndarray:
    v = q[:, 1:] * np.sign(q[:, :1] + (q[:, :1] == 0))
    n = np.linalg.norm(v, axis=1)[:, None]
    return np.where(n > 1e-12, v / np.where(n > 1e-12, n, 1.0), 0.0)


def covered(found: list[np.ndarray], poses: list[np.ndarray]) -> bool:
    return all(any(np.abs(T - S).max() < 1e-6 for S in found) for T in poses)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="seeds per measurement")
    args = parser.parse_args()
    platforms = {
        "Dietmaier 1998": DIETMAIER,
        "random 6-6 #4": random_platform(4),
        "random 6-6 #18": random_platform(18),
    }
    print(f"{'platform':<16} {'method':<6} {'found':>5} {'median [s]':>10}  details")
    for name, (A, B, lengths) in platforms.items():
        model = sc.builders.stewart_gough(A, B)
        explore(model, lengths, backend="compiled")  # build and load the C library (cached)
        runs = [explore(model, lengths, seed=s, backend="compiled") for s in range(args.repeat)]
        sc_time = float(np.median([r.elapsed for r in runs]))
        counts = sorted({len(r.solutions) for r in runs})
        poses = [c.platform_pose for c in runs[0].solutions]
        print(
            f"{name:<16} {'SC':<6} {'/'.join(map(str, counts)):>5} {sc_time:>10.3f}  "
            f"curves {int(np.median([r.curves for r in runs]))}, "
            f"steps (states) {int(np.median([r.steps for r in runs]))} (median)"
        )
        starts = 250
        while True:
            times, complete, found = [], True, []
            for s in range(args.repeat):
                t = time.perf_counter()
                sols = lm_baseline(A, B, lengths, starts, seed=s)
                times.append(time.perf_counter() - t)
                complete &= covered(sols, poses)
                found.append(len(sols))
            lm_time = float(np.median(times))
            print(
                f"{'':<16} {'LM':<6} {int(np.median(found)):>5} {lm_time:>10.3f}  "
                f"{starts} starts, all {len(poses)} found in every repeat: {complete}"
            )
            if complete or starts >= 32000:
                break
            starts *= 2
        print(f"{'':<16} ratio LM / SC time (to find all): {lm_time / sc_time:.2f}")


if __name__ == "__main__":
    main()
