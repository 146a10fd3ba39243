"""Assembly without a given ``home``: from the neutral configuration to a closed one.

Gepetto's files give no assembled configuration; their toolbox assembles one by optimisation
from the neutral configuration. Here the closure is relaxed and tightened by continuation:
``r(z) - (1 - lam) r(z0) = 0`` from ``lam = 0`` (where the neutral ``z0`` solves it) to
``lam = 1``, over every joint coordinate ``z`` (unknowns and actuators), each corrector step a
minimum-norm Gauss-Newton step, so the path moves as little as the closures need. The closed
configuration is then moved, along the closure manifold, towards the neutral one (minimum
change). Where the path fails (it meets a singular configuration of the relaxed system),
seeded perturbations of the neutral configuration are tried and the closest result is kept.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..model.rotations import rot_exp, rot_log, skew, vee
from ..model.spec import Closure as ClosureSpec
from ..symbolic.kinematics import closure_residual
from ..symbolic.system import Symbolic

#: Residual and Jacobian of the closure rows at a configuration z (every joint coordinate),
#: relaxed to the level lam in [0, 1] (1: the true closure).
Closure = Callable[[np.ndarray, float], tuple[np.ndarray, np.ndarray]]

#: Relative singular-value cut-off of the minimum-norm steps.
RCOND = 1e-10
#: Number of perturbed seeds tried after the neutral one, and their size [rad or length unit].
SEEDS = 8
SEED_SCALE = 0.2
#: Corrector iterations per continuation step.
CORRECTOR_ITERATIONS = 8


@dataclass(frozen=True)
class Assembly:
    """An assembled configuration found from the neutral one.

    Attributes:
        z: (n,) every joint coordinate (unknowns, then actuators) [rad or length unit].
        residual: max |closure row| at ``z`` [length unit or rad].
        seed: 0 for the neutral configuration itself, ``i`` for the i-th perturbed seed.
        steps: continuation steps taken.
        change: max |z - z0| [rad or length unit].
    """

    z: np.ndarray
    residual: float
    seed: int
    steps: int
    change: float


def closure_rows(
    full: Symbolic, closures: Sequence[ClosureSpec], c: np.ndarray, start: np.ndarray
) -> Closure:
    """The closure rows of an assembly over ``z = (y, theta)``, relaxed about ``start``.

    At level ``lam`` a point closure asks ``d(z) = (1 - lam) d(start)`` and a weld (6d)
    ``R_a^T R_b = exp((1 - lam) w0)`` with ``w0 = log(R_a^T R_b)`` at the start, its rotation
    error the rotation vector ``log(exp((1 - lam) w0)^T R_a^T R_b)`` (as Gepetto's ``log6``):
    smooth along the whole relaxed path, even from a weld left at a half turn (CAD exports
    often leave one), where the skew part of ``R_a^T R_b`` and its gradient vanish.

    Args:
        full: the symbolic system over every unknown candidate.
        closures: the model's closures (frames resolved to links).
        c: chart of ``full`` (reference rotations of its rotation joints).
        start: (n,) the configuration where the relaxation starts (``lam = 0``).
    """
    z = ca.vertcat(full.y, full.theta)
    plain, turns = [], []
    for cl in closures:
        T_a, T_b = full.placements[cl.frame_a], full.placements[cl.frame_b]
        if cl.type == "6d":
            plain.append(T_a[:3, 3] - T_b[:3, 3])
            turns.append(ca.reshape(T_a[:3, :3].T @ T_b[:3, :3], 9, 1))
        else:
            plain.append(closure_residual(cl, T_a, T_b, full.values))
    rows = ca.vertcat(*plain)
    mats = ca.vertcat(*turns) if turns else ca.SX(0, 1)
    outs = [rows, ca.jacobian(rows, z), mats, ca.jacobian(mats, z)]
    f = ca.Function(
        "assembly", [full.y, full.theta], [ca.substitute(e, full.c, ca.DM(c)) for e in outs]
    )
    m = full.m

    def parts(zv: np.ndarray):
        r, Jr, R, JR = (np.array(v) for v in f(zv[:m], zv[m:]))
        n = R.size // 9
        Rs = R.reshape(n, 3, 3).transpose(0, 2, 1)  # column-major blocks
        dR = JR.reshape(n, 3, 3, zv.size).transpose(0, 2, 1, 3)
        return r.ravel(), Jr, Rs, dR

    r0, _, R0, _ = parts(start)
    w0 = rot_log(R0) if len(R0) else np.zeros((0, 3))

    def evaluate(zv: np.ndarray, lam: float) -> tuple[np.ndarray, np.ndarray]:
        r, Jr, Rs, dR = parts(zv)
        res, jac = [r - (1.0 - lam) * r0], [Jr]
        for i in range(len(Rs)):
            omega = 0.5 * vee(np.einsum("ji,jkn->nik", Rs[i], dR[i])).T  # (3, n) body rates
            w = rot_log(rot_exp((1.0 - lam) * w0[i]).T @ Rs[i])
            res.append(w)
            jac.append(_log_jacobian_inverse(w) @ omega)
        return np.concatenate(res), np.vstack(jac)

    return evaluate


def _log_jacobian_inverse(w: np.ndarray) -> np.ndarray:
    """``d log(R) / d(body rotation)`` at ``w = log R`` (inverse right Jacobian of SO(3))."""
    angle = float(np.linalg.norm(w))
    W = skew(w)
    if angle < 1e-6:
        return np.eye(3) + 0.5 * W + W @ W / 12.0
    coef = 1.0 / angle**2 - (1.0 + np.cos(angle)) / (2.0 * angle * np.sin(angle))
    return np.eye(3) + 0.5 * W + coef * (W @ W)


def _step(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The minimum-norm least-squares step ``-J^+ r``."""
    return -np.linalg.lstsq(J, r, rcond=RCOND)[0]


def _correct(closure: Closure, z: np.ndarray, lam: float, tol: float) -> tuple[np.ndarray, bool]:
    """Gauss-Newton on ``|r(z, lam)|^2`` from ``z``; ``(z, converged)``.

    Converged: the residual is below ``tol``, or the least-squares step has become negligible
    (a relaxed closure need not be attainable exactly where closure rows are dependent)."""
    r, J = closure(z, lam)
    cost = float(r @ r)
    for _ in range(CORRECTOR_ITERATIONS):
        if not np.isfinite(cost):
            return z, False
        if np.abs(r).max() < tol:
            return z, True
        dz = _step(J, r)
        zn = z + dz
        rn, Jn = closure(zn, lam)
        if not float(rn @ rn) <= cost:
            return z, False
        z, r, J, cost = zn, rn, Jn, float(rn @ rn)
        if np.abs(dz).max() < 1e-12:
            return z, True
    return z, bool(np.abs(r).max() < tol)


def _continuation(
    closure: Closure, z0: np.ndarray, tol: float, max_steps: int = 400
) -> tuple[np.ndarray, int] | None:
    """Track the relaxed closure from lam = 0 (at ``z0``) to 1; the end and the step count."""
    z, lam, h, steps = z0.copy(), 0.0, 0.25, 0
    while lam < 1.0 and steps < max_steps:
        steps += 1
        trial = min(1.0, lam + h)
        zn, ok = _correct(closure, z, trial, tol)
        if ok and np.abs(zn - z).max() < 1.0:
            z, lam, h = zn, trial, min(0.5, 2 * h)
        else:
            h /= 2
            if h < 1e-6:
                return None
    if lam < 1.0:
        return None
    z, _ = _correct(closure, z, 1.0, tol)
    if np.abs(closure(z, 1.0)[0]).max() > tol:
        return None
    return z, steps


def _closest(closure: Closure, z: np.ndarray, z0: np.ndarray, tol: float) -> np.ndarray:
    """Move a closed ``z`` along the closure manifold towards ``z0`` (tangent steps, each
    followed by a correction back onto the manifold)."""
    for _ in range(20):
        _, J = closure(z, 1.0)
        d = z0 - z
        tangent = d - np.linalg.lstsq(J, J @ d, rcond=RCOND)[0]
        if np.abs(tangent).max() < 1e-10:
            break
        alpha = 1.0
        while alpha > 1e-3:
            zn, ok = _correct(closure, z + alpha * tangent, 1.0, tol)
            if ok and np.linalg.norm(zn - z0) < np.linalg.norm(z - z0):
                z = zn
                break
            alpha /= 2
        else:
            break
    return z


def assemble(
    rows: Callable[[np.ndarray], Closure],
    z0: np.ndarray,
    tol: float,
    start: np.ndarray | None = None,
    seed: int = 0,
) -> Assembly | None:
    """Assemble from the neutral configuration ``z0`` (see the module docstring).

    Args:
        rows: the relaxed closure about a start configuration (:func:`closure_rows`).
        z0: (n,) the neutral configuration [rad or length unit].
        tol: closure tolerance [length unit or rad].
        start: (n,) where the relaxed closure starts (default ``z0``), e.g. a least-squares
            projection of ``z0`` with the actuators held.
        seed: seed of the perturbations tried when the first start fails.

    Returns:
        The closest assembly found, or ``None`` when every seed failed.
    """
    rng = np.random.default_rng(seed)
    found: list[Assembly] = []
    first = z0 if start is None else start
    for i in range(SEEDS + 1):
        begin = first if i == 0 else first + rng.normal(scale=SEED_SCALE, size=z0.size)
        closure = rows(begin)
        out = _continuation(closure, begin, tol)
        if out is None:
            continue
        z = _closest(closure, out[0], z0, tol)
        r, _ = closure(z, 1.0)
        found.append(Assembly(z, float(np.abs(r).max()), i, out[1], float(np.abs(z - z0).max())))
        if i == 0:
            break
    if not found:
        return None
    return min(found, key=lambda a: float(np.linalg.norm(a.z - z0)))


def least_squares(
    rows: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], z: np.ndarray, steps: int = 200
) -> tuple[np.ndarray, float]:
    """Levenberg-Marquardt with minimum-norm steps: ``(z, largest |row|)`` where it stops.

    Every step has no component along the directions the rows do not see (singular values
    below ``1e-10`` of the largest): a step along an idle freedom would be driven by rounding
    alone, and the result would depend on the floating-point library.

    Args:
        rows: ``z -> (r, dr/dz)``.
        z: the start.
        steps: most steps.
    """
    mu = 1e-3
    g, J = rows(z)
    cost = g @ g
    for _ in range(steps):
        if cost < 1e-30:
            break
        u, sv, vt = np.linalg.svd(J, full_matrices=False)
        s_max = float(sv[0]) if sv.size else 0.0
        keep = sv > 1e-10 * s_max
        sv, u, vt = sv[keep], u[:, keep], vt[keep]
        dz = -vt.T @ ((sv / (sv * sv + mu * s_max**2)) * (u.T @ g))
        zn = z + dz
        gn, Jn = rows(zn)
        if gn @ gn < cost:
            z, g, J, cost = zn, gn, Jn, gn @ gn
            mu = max(mu / 3, 1e-16)
            if np.linalg.norm(dz) < 1e-15:
                break
        else:
            mu *= 4
            if mu > 1e12:
                break
    return z, float(np.abs(g).max()) if g.size else 0.0
