"""The singular-manifold crossings of a finished track (the same for every backend).

Wherever ``det J_p`` has opposite signs at consecutive samples (the start and the first
sample included), :func:`locate` bisects the sign change along the motion between them.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..kernels.fastcall import model_calls
from ..model.rotations import gibbs, rot_exp
from ..results import Configuration, Crossing
from ..robot import Model
from .query import start_det

#: A full turn [rad].
TWO_PI = 2.0 * math.pi


def crossings(
    model: Model, start: Configuration, y: np.ndarray, thetas: np.ndarray, dets: np.ndarray
) -> tuple[Crossing, ...]:
    """Singular-manifold crossings of a finished track (the same for every backend).

    Args:
        model: the model.
        start: the configuration the track started from.
        y: (N, m) canonical unknowns of the samples.
        thetas: (N, k) readings.
        dets: (N,) ``det J_p`` at the samples (any chart: only the sign is used).

    Returns:
        One "fold" :class:`~scdk_sym.results.Crossing` wherever ``det J_p`` has opposite signs
        at consecutive samples (the start and the first sample included): ``index`` the
        sample before it (-1: between the start and sample 0), ``s`` the fraction of the way
        to the next sample, located by :func:`locate`.
    """
    dets = np.asarray(dets, dtype=float)
    if dets.size == 0:
        return ()
    det0 = start_det(model, start)
    if (det0 > 0 and (dets > 0).all()) or (det0 < 0 and (dets < 0).all()):
        return ()  # one sign throughout: no change
    dd = np.concatenate([[det0], dets])
    changes = np.flatnonzero(np.sign(dd[:-1]) * np.sign(dd[1:]) < 0)
    if changes.size == 0:
        return ()
    ys = np.vstack([start.y, y])
    ths = np.vstack([start.theta, thetas])
    out = []
    for j in changes:
        out.append(locate(model, ys[j], ys[j + 1], ths[j], ths[j + 1], float(dd[j]), j - 1))
    return tuple(out)


#: Workspace coordinates that are angles (interpolated the short way round).
ANGLES = ("phi", "roll", "pitch", "yaw")


def locate(model: Model, ya, yb, tha, thb, da: float, index: int) -> Crossing:
    """The crossing between two samples: where ``det J_p`` vanishes between them.

    With as many workspace coordinates as actuators, the motion between the samples is
    interpolated linearly in the workspace coordinates ``x`` (angles the short way round)
    and each interpolated pose solved by inverse-kinematics Newton over ``(y, theta)`` (regular
    at direct-kinematic singularities) from the chord between the samples; otherwise the
    chord in ``(y, theta)`` is projected onto the closure manifold ``g = 0`` (minimum-norm
    Gauss-Newton over ``(y, theta)``). The sign change of ``det J_p`` along that path is
    bisected; ``s`` is the fraction of the way from the first sample.

    Args:
        model: the model.
        ya: (m,) canonical unknowns of the first sample.
        yb: (m,) those of the second.
        tha: (k,) the first reading.
        thb: (k,) the second.
        da: ``det J_p`` at the first sample (its sign).
        index: the first sample's index, kept in the record.
    """
    m = model.m
    kern = model.kernels
    calls = model_calls(model)  # the same values as kern's plain calls, without conversions
    ya_loc, c = model.chart.to_local(ya)
    yb_loc = np.array(yb, dtype=float)
    for i, rot in enumerate(model.chart.rotations):
        idx = list(rot)
        R_ref = c[9 * i : 9 * i + 9].reshape(3, 3, order="F")
        yb_loc[idx] = gibbs(R_ref.T @ rot_exp(np.asarray(yb)[idx]))
    za = np.concatenate([ya_loc, tha])
    zb = np.concatenate([yb_loc, thb])
    tol = 1e-3 * model.tolerance

    def det_at(z) -> float:
        return float(np.linalg.det(calls.jac(z[:m], z[m:], c)[0]))

    def chord(alpha):
        z = za + alpha * (zb - za)
        for _ in range(30):
            g = calls.g(z[:m], z[m:], c).ravel()
            if np.max(np.abs(g)) <= tol:
                return z
            Jp, Js = calls.jac(z[:m], z[m:], c)
            G = np.hstack([Jp, -Js])
            z = z - G.T @ np.linalg.solve(G @ G.T, g)
        return z

    path = chord
    if len(model.workspace) == model.k:
        xa = calls.pose(ya_loc, tha, c)[1].ravel()
        dx = calls.pose(yb_loc, thb, c)[1].ravel() - xa
        for i, name in enumerate(model.workspace):
            if name in ANGLES:
                dx[i] = (dx[i] + math.pi) % TWO_PI - math.pi

        def motion(alpha):
            T = model.target_pose(xa + alpha * dx)
            z = za + alpha * (zb - za)
            for _ in range(30):
                zn, res = kern.ik_step(z, T, c)
                z = np.array(zn).ravel()
                if not np.all(np.isfinite(z)):
                    break
                if float(res) <= tol:
                    return z
            raise np.linalg.LinAlgError("inverse kinematics did not converge")

        path = motion
    sign_lo = float(np.sign(da))
    ends = (sign_lo * det_at(za), sign_lo * det_at(zb))
    for attempt in (path, chord):
        try:
            with np.errstate(all="ignore"):
                lo, hi, z = _sign_change(attempt, lambda z: sign_lo * det_at(z), za, *ends)
        except np.linalg.LinAlgError:
            continue
        if np.all(np.isfinite(z)):
            break
    else:  # fall back on the chord (accurate to the sample spacing)
        lo = hi = 0.5
        z = za + 0.5 * (zb - za)
    cfg = model.configuration(z[:m], z[m:], c)
    return Crossing(0.5 * (lo + hi), cfg.x, cfg.y, cfg.theta, index, "fold")


def _sign_change(
    point: Callable[[float], np.ndarray],
    value: Callable[[np.ndarray], float],
    z0: np.ndarray,
    f_lo: float,
    f_hi: float,
    xtol: float = 1e-13,
    iterations: int = 60,
) -> tuple[float, float, np.ndarray]:
    """Where ``value(point(a))`` turns from positive to not positive for ``a`` in [0, 1]:
    false position with the Illinois rule (the bracket kept, superlinear), bisection where a
    value is not usable.

    Args:
        point: the path's point at the fraction ``a`` of the way.
        value: the function of a point (positive at ``point(0)``).
        z0: ``point(0)``.
        f_lo: its value at ``a = 0``.
        f_hi: its value at ``a = 1``.
        xtol: bracket width to reach.
        iterations: at most that many evaluations.

    Returns:
        ``(lo, hi, z)``: the final bracket and the point of the last evaluation.
    """
    lo, hi, side, z = 0.0, 1.0, 0, z0
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if f_lo > 0.0 and f_hi <= 0.0 and math.isfinite(f_lo) and math.isfinite(f_hi):
            cut = lo + (hi - lo) * f_lo / (f_lo - f_hi)
            if lo < cut < hi:
                mid = cut
        z = point(mid)
        f = value(z)
        if f > 0.0:
            lo, f_lo = mid, f
            f_hi = 0.5 * f_hi if side == 1 else f_hi
            side = 1
        else:
            hi, f_hi = mid, f
            f_lo = 0.5 * f_lo if side == -1 else f_lo
            side = -1
        if hi - lo < xtol:
            break
    return lo, hi, z
