"""Complete assembly modes of a 6-6 platform by homotopy: monodromy once, then queries.

On Dietmaier's platform written as a PolynomialSystem (tests/polynomial_systems.py: leg
lengths as parameters, quaternion in a real affine chart) prints

* the start system: ``start_system`` time (monodromy + trace test; loaded from the cache
  on a second run), loops, root count, trace residual;
* per query (all root-count paths, numpy, start system in memory): median wall and CPU time
  over the queries, paths and steps, the real solutions and whether they contain the pose the
  legs were computed from (independent check), and for Dietmaier's legs whether the real set
  equals the random-start LM reference (rotation and translation within 1e-8);
* the baseline, measured in the same run: the LM reference (tests/stewart.py, 4000 starts),
  and the ratio query time / LM time.

    python benchmarks/homotopy_6_6.py [--queries 5] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from scdk_sym.algebraic import solve_homotopy, start_system
from scdk_sym.algebraic.monodromy import cache_path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from polynomial_systems import StewartGough  # noqa: E402
from stewart import (  # noqa: E402  (references shared with the tests)
    DIETMAIER_BASE,
    DIETMAIER_LENGTHS,
    DIETMAIER_PLATFORM,
    rotations,
    stewart_reference,
)


def timed(fn, *args, **kwargs):
    w, c = time.perf_counter(), time.process_time()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - w, time.process_time() - c


def same_poses(system, real_z, reference, tol=1e-8) -> bool:
    poses = system.poses(real_z)
    return len(poses) == len(reference) and all(
        min(max(np.abs(p - q).max(), np.abs(R - S).max()) for q, S in poses) <= tol
        for p, R in reference
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queries", type=int, default=5, help="random poses queried")
    parser.add_argument("--seed", type=int, default=0, help="seed of the start system")
    args = parser.parse_args()
    A, B = DIETMAIER_BASE, DIETMAIER_PLATFORM
    system = StewartGough(A, B)
    cached = cache_path(system, args.seed).exists()
    start, wall, cpu = timed(start_system, system, args.seed)
    print(
        f"start system ({'loaded from the cache' if cached else 'monodromy + trace test'}): "
        f"{start.root_count} roots, {start.loops} loops, trace residual "
        f"{start.trace_residual:.1e} ({'passed' if start.trace_passed else 'FAILED'}), "
        f"{wall:.1f} s wall / {cpu:.1f} s CPU"
    )
    rng = np.random.default_rng(1)
    queries = [("Dietmaier legs", DIETMAIER_LENGTHS, None)]
    for k in range(args.queries):
        p = np.array([0.5, 0.5, 0.8]) + 0.05 * rng.normal(size=3)
        R = rotations(0.2 * rng.normal(size=(1, 3)))[0]
        legs = np.linalg.norm(p + B @ R.T - A, axis=1)
        queries.append((f"pose #{k}", legs, (p, R)))
    walls, cpus = [], []
    for name, legs, pose in queries:
        res, wall, cpu = timed(solve_homotopy, system, start, legs)
        walls.append(wall)
        cpus.append(cpu)
        status = dict(zip(*np.unique(res.status, return_counts=True), strict=True))
        line = (
            f"{name}: {wall * 1e3:.0f} ms wall / {cpu * 1e3:.0f} ms CPU, "
            f"{len(res.endpoints)} paths, steps max {res.steps.max()} mean "
            f"{res.steps.mean():.0f}, attempts {res.attempts}, {status}, complete "
            f"{res.complete}, real {len(res.real_solutions)}"
        )
        if pose is not None:
            hit = any(
                max(np.abs(q - pose[0]).max(), np.abs(S - pose[1]).max()) < 1e-8
                for q, S in system.poses(res.real_solutions)
            )
            line += f", contains the pose: {hit}"
        print(line)
    ref, lm_wall, _ = timed(stewart_reference, A, B, DIETMAIER_LENGTHS, 4000, 0)
    dres = solve_homotopy(system, start, DIETMAIER_LENGTHS)
    print(
        f"Dietmaier: real set equals the LM reference ({len(ref)} poses): "
        f"{same_poses(system, dres.real_solutions, ref)}"
    )
    med = float(np.median(walls))
    print(
        f"median query {med * 1e3:.0f} ms wall / {np.median(cpus) * 1e3:.0f} ms CPU; "
        f"baseline LM 4000 starts {lm_wall * 1e3:.0f} ms; ratio query / LM {med / lm_wall:.2f}"
    )


if __name__ == "__main__":
    main()
