"""Cauchy endgame: the endpoint at t = 1 of paths that do not arrive there regularly.

Near ``t = 1`` a path is a Puiseux series ``z(t) = sum_k a_k (1 - t)^(k / c)`` with winding
number ``c``. Tracking around the circle ``t = 1 - r e^(i phi)`` returns to the start after
exactly ``c`` loops, and the mean of ``z`` over ``K`` equally spaced samples per loop (the
trapezoid rule of Cauchy's integral in the variable ``s = (1 - t)^(1/c)``) is ``a_0`` up to
``O((r / R)^K)``, ``R`` the distance to the nearest other branch point. The endgame runs this
at radii ``r0, r0/4, r0/16, ...``: two successive estimates that agree, with the samples'
spread about them shrinking, give a singular endpoint with its winding number; a spread that
grows at two successive radii (a pole of the series, ``a_0`` is then only its constant term)
marks a path to infinity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .paths.continuation import DONE, Homotopy, TrackerOptions, rel_norm, track

#: Endgame verdicts.
EG_SINGULAR, EG_INFINITY, EG_FAILED = 1, 2, 3


@dataclass(frozen=True)
class EndgameOutcome:
    """Verdict of :func:`cauchy_endgame` per path.

    Attributes:
        z: (M, n) complex endpoint estimates (NaN where failed or at infinity).
        verdict: (M,) int, ``EG_SINGULAR``, ``EG_INFINITY`` or ``EG_FAILED``.
        winding: (M,) int winding numbers (0 where unknown).
        radius: (M,) the last radius used.
    """

    z: np.ndarray
    verdict: np.ndarray
    winding: np.ndarray
    radius: np.ndarray


def _circle(r: np.ndarray):
    def tmap(tau, idx):
        e = np.exp(2j * np.pi * tau)
        rr = r[idx]
        return 1.0 - rr * e, -2j * np.pi * rr * e

    return tmap


def _segment(t0: np.ndarray, t1: np.ndarray):
    def tmap(tau, idx):
        return t0[idx] + (t1[idx] - t0[idx]) * tau + 0j, (t1[idx] - t0[idx]) + 0j

    return tmap


def _loops_around(homotopy, z, idx, r, n_data, samples, max_winding, options):
    """Loops of radius ``r`` about ``t = 1`` from the points ``z`` (M, n) until each closes
    (within ``max_winding`` loops): the Cauchy estimates (M, n) (NaN where no loop closed),
    the loops each took to close (0: none, -1: its path failed) and the spread of the
    samples about the estimate."""
    rr = np.zeros(n_data)
    rr[idx] = r
    tmap = _circle(rr)
    start = z.copy()
    cur = start.copy()
    total = np.zeros_like(cur)
    taken = [start]  # the loop's samples, to measure their spread about the estimate
    closed = np.zeros(len(z), dtype=int)
    going = np.ones(len(z), dtype=bool)
    for k in range(samples * max_winding):
        g = np.flatnonzero(going)
        if g.size == 0:
            break
        total[g] += cur[g]
        res = track(
            homotopy,
            tmap,
            cur[g],
            idx[g],
            np.full(g.size, k / samples),
            np.full(g.size, (k + 1) / samples),
            options,
        )
        cur[g] = res.z
        bad = res.status != DONE
        going[g[bad]] = False
        closed[g[bad]] = -1
        taken.append(cur.copy())
        if (k + 1) % samples == 0:
            loops = (k + 1) // samples
            back = (~bad) & (rel_norm(res.z - start[g], start[g]) < 1e-6)
            closed[g[back]] = loops
            going[g[back]] = False
    ok = closed > 0
    est = np.where(ok[:, None], total / np.maximum(closed, 1)[:, None] / samples, np.nan)
    # spread of the samples about the estimate: ~ r^(1/c) at a finite endpoint (shrinks
    # with r), ~ r^(-1/c) on a path to infinity (grows by 4^(1/c) >= 1.18 per level)
    stack = np.stack(taken)  # (S, M, n)
    upto = np.arange(len(stack))[:, None] < closed[None, :] * samples
    dev = np.abs(stack - est[None]).max(axis=2)
    spread = np.where(upto, dev, 0.0).max(axis=0)
    return est, closed, spread


def cauchy_endgame(
    homotopy: Homotopy,
    z: np.ndarray,
    idx: np.ndarray,
    r0: float,
    options: TrackerOptions | None = None,
    samples: int = 16,
    max_winding: int = 8,
    levels: int = 6,
    tol: float = 1e-8,
) -> EndgameOutcome:
    """Endpoints at t = 1 of paths given at the real time t = 1 - r0.

    Args:
        homotopy: the homotopy (holomorphic in complex t).
        z: (M, n) complex points on H(z, 1 - r0) = 0.
        idx: (M,) path indices into the homotopy's data.
        r0: the first radius (0 < r0 < 1).
        options: tracker step control.
        samples: samples per loop ``K``.
        max_winding: loops tried before giving up at a radius.
        levels: radii tried (``r0 4^-k``, k < levels).
        tol: agreement of two successive estimates (relative to ``1 + |z|``).

    Returns:
        An :class:`EndgameOutcome`.
    """
    M = len(z)
    idx = np.asarray(idx)
    n_data = int(idx.max()) + 1 if M else 0
    zc = np.array(z, dtype=complex)
    out = np.full(zc.shape, np.nan + 0j)
    verdict = np.full(M, EG_FAILED)
    winding = np.zeros(M, dtype=int)
    radius = np.full(M, r0)
    prev_est = np.full(zc.shape, np.nan + 0j)
    spread_hist = np.zeros((M, 2))
    alive = np.ones(M, dtype=bool)
    r = r0
    for level in range(levels):
        if level > 0:  # move along the real segment 1 - 4r -> 1 - r
            a = np.flatnonzero(alive)
            t0 = np.zeros(n_data)
            t1 = np.zeros(n_data)
            t0[idx[a]], t1[idx[a]] = 1.0 - 4.0 * r, 1.0 - r
            res = track(
                homotopy,
                _segment(t0, t1),
                zc[a],
                idx[a],
                np.zeros(a.size),
                np.ones(a.size),
                options,
            )
            zc[a] = res.z
            alive[a[res.status != DONE]] = False
        radius[alive] = r
        a = np.flatnonzero(alive)
        if a.size == 0:
            break
        est, closed, spread = _loops_around(
            homotopy, zc[a], idx[a], r, n_data, samples, max_winding, options
        )
        ok = closed > 0
        alive[a[closed <= 0]] = False  # failed, or no closure within max_winding loops
        for j in np.flatnonzero(ok):
            i = a[j]
            s0, s1 = spread_hist[i, 0], spread_hist[i, 1]  # two levels back, one level back
            if s1 > 0 and s0 > 0 and spread[j] > 1.1 * s1 and s1 > 1.1 * s0:
                verdict[i], winding[i] = EG_INFINITY, closed[j]
                alive[i] = False
            elif (
                np.isfinite(prev_est[i]).all()
                and rel_norm((est[j] - prev_est[i])[None], est[j][None])[0] <= tol
                and spread[j] < s1
            ):
                verdict[i], winding[i], out[i] = EG_SINGULAR, closed[j], est[j]
                alive[i] = False
            prev_est[i] = est[j]
            spread_hist[i] = (s1, spread[j])
        r /= 4.0
    return EndgameOutcome(z=out, verdict=verdict, winding=winding, radius=radius)
