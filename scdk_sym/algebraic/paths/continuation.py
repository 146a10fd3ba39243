"""Batched predictor-corrector path tracker for holomorphic homotopies H(z, t) = 0.

Every path advances in a real path variable ``tau`` mapped to a complex homotopy time
``t = tmap(tau)`` (a straight segment for the main track, a circle about ``t = 1`` for the
endgame). One iteration of :func:`track` moves every active path by its own step ``h``:

- predictor: one classical Runge-Kutta (RK4) step of ``dz/dtau = -H_z^{-1} H_tau``;
- corrector: exactly two Newton iterations at the new time, norms ``nu1, nu2`` of the
  updates (relative to ``1 + |z|``, max norm); the step is accepted when ``nu1 <= trust``
  (no jump to another path), the updates contract (``nu2 <= theta nu1`` up to a noise floor)
  and ``nu2 <= tol``, or when both updates are below ``noise`` (the rounding level); the
  second iteration's factorisation also gives the velocity at the new point, the next step's
  first RK4 stage (five evaluations per step in all);
- step control: accepted, ``h *= clip((eta / nu1)^(1/5), 0.25, 2)`` (``nu1`` is the
  predictor's local error, fifth order: the steps settle where it is ``eta``), the factor at
  most 1 right after a rejected step (no step straight back to the size just rejected);
  rejected, ``h /= 2``.

A path stops as ``DONE`` at ``tau1``, ``DIVERGED`` when ``|z|`` exceeds ``max_norm``,
``UNDERFLOW`` when its step falls below ``h_min``, ``STEP_LIMIT`` after ``max_steps`` tries.
Every loop is bounded. The inner loop is plain array code (evaluate, batched solve,
elementwise updates) so that it ports to C unchanged: its C twin is
:mod:`scdk_sym.algebraic.paths.continuation_c` (``continuation.c``), this tracker the reference.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Status codes of :func:`track`.
RUNNING, DONE, DIVERGED, UNDERFLOW, STEP_LIMIT = 0, 1, 2, 3, 4

#: homotopy(z (M, n), t (M,) complex, idx (M,) int) -> H (M, n), H_z (M, n, n), H_t (M, n).
Homotopy = Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
#: tmap(tau (M,) real, idx (M,) int) -> t (M,) complex, dt/dtau (M,) complex.
TimeMap = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class TrackerOptions:
    """Step control of :func:`track` (norms relative to ``1 + max|z|``).

    Attributes:
        h0: initial step in ``tau``.
        h_min: smallest step before a path is declared ``UNDERFLOW``.
        h_max: largest step.
        eta: target size of the first Newton correction (the predictor error).
        trust: largest first Newton correction accepted (guards against path jumping).
        theta: required contraction factor of successive Newton updates.
        tol: largest last Newton update accepted.
        floor: noise level of the updates (the contraction checks allow it).
        noise: a step whose two updates are both below this is accepted (Newton stagnates at
            the rounding level, ``eps cond(H_z)``, which is large near a path's escape).
        third: a step whose first two updates contract (``nu1 <= trust``, ``nu2 <= theta
            nu1 + floor``) but whose second is above ``tol`` makes a third Newton iteration,
            accepted when ``nu3 <= theta nu2 + floor`` and ``nu3 <= tol`` (False: two
            iterations only). Near a nearly singular endpoint the second update is what
            limits the step: the third lets the predictor's error target ``eta`` be larger.
        max_steps: step attempts per path before ``STEP_LIMIT``.
        max_norm: ``|z|`` beyond which a path is ``DIVERGED``.
    """

    h0: float = 0.05
    h_min: float = 1e-13
    h_max: float = 0.25
    eta: float = 1e-4
    trust: float = 1e-2
    theta: float = 0.25
    tol: float = 1e-7
    floor: float = 1e-11
    noise: float = 1e-7
    max_steps: int = 2000
    max_norm: float = 1e8
    third: bool = True


@dataclass(frozen=True)
class TrackOutcome:
    """Where each path of :func:`track` stopped.

    Attributes:
        z: (M, n) complex, the last accepted point of each path.
        tau: (M,) the path variable reached.
        status: (M,) int, one of ``DONE``, ``DIVERGED``, ``UNDERFLOW``, ``STEP_LIMIT``.
        steps: (M,) int, step attempts (accepted and rejected).
        accepted: (M,) int, accepted steps.
        h: (M,) the step size in use when the path stopped.
    """

    z: np.ndarray
    tau: np.ndarray
    status: np.ndarray
    steps: np.ndarray
    accepted: np.ndarray
    h: np.ndarray


def solve_batched(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve A x = b for a batch, (M, n, n) and (M, n) [or (M, n, k)] -> like b; NaN if singular."""
    try:
        if b.ndim == 3:
            return np.linalg.solve(A, b)
        return np.linalg.solve(A, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        out = np.full(b.shape, np.nan, dtype=complex)
        for k in range(len(A)):
            with contextlib.suppress(np.linalg.LinAlgError):
                out[k] = np.linalg.solve(A[k], b[k])
        return out


def rel_norm(dz: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(M, n), (M, n) -> (M,): ``max|dz| / (1 + max|z|)`` (NaN becomes inf)."""
    v = np.abs(dz).max(axis=1) / (1.0 + np.abs(z).max(axis=1))
    return np.where(np.isfinite(v), v, np.inf)


def newton(
    homotopy: Homotopy, z: np.ndarray, t: np.ndarray, idx: np.ndarray, iterations: int
) -> tuple[np.ndarray, np.ndarray]:
    """``iterations`` Newton steps on H(., t) = 0 for a batch; returns z and the update norms.

    Args:
        homotopy: the homotopy.
        z: (M, n) complex start points.
        t: (M,) complex times.
        idx: (M,) path indices.
        iterations: number of steps (fixed: no data-dependent loop).

    Returns:
        z (M, n) after the steps and nu (M, iterations), the relative norm of each update.
    """
    nu = np.empty((len(z), iterations))
    for k in range(iterations):
        H, Hz, _ = homotopy(z, t, idx)
        dz = solve_batched(Hz, H)
        nu[:, k] = rel_norm(dz, z)
        z = z - np.where(np.isfinite(dz), dz, 0.0)
    return z, nu


def _third(homotopy, zc, v, t, dt, idx, nu1, nu2, converged, o: TrackerOptions):
    """The third Newton iteration of the steps that ask for it (``TrackerOptions.third``):
    the corrected points, velocities and acceptances after it (the others unchanged)."""
    more = ~converged & (nu1 <= o.trust) & (nu2 <= o.theta * nu1 + o.floor)
    more &= np.isfinite(zc).all(axis=1)
    if not more.any():
        return zc, v, converged
    z2 = zc[more]
    H, Hz, Ht = homotopy(z2, t[more], idx[more])
    X = solve_batched(Hz, np.stack([H, Ht * dt[more][:, None]], axis=2))
    nu3 = rel_norm(X[..., 0], z2)
    zc, v, converged = zc.copy(), v.copy(), converged.copy()
    zc[more], v[more] = z2 - X[..., 0], -X[..., 1]
    converged[more] = (nu3 <= o.theta * nu2[more] + o.floor) & (nu3 <= o.tol)
    return zc, v, converged


def _velocity(homotopy, tmap, z, tau, idx):
    t, dt = tmap(tau, idx)
    _, Hz, Ht = homotopy(z, t, idx)
    return -solve_batched(Hz, Ht * dt[:, None])


def track(
    homotopy: Homotopy,
    tmap: TimeMap,
    z0: np.ndarray,
    idx: np.ndarray,
    tau0: np.ndarray,
    tau1: np.ndarray,
    options: TrackerOptions | None = None,
    h0: np.ndarray | None = None,
) -> TrackOutcome:
    """Track every path from ``tau0`` to ``tau1`` (all paths at once, per-path steps).

    Args:
        homotopy: H, H_z, H_t of a batch (see :data:`Homotopy`).
        tmap: the time map of a batch (see :data:`TimeMap`).
        z0: (M, n) complex points on H(z, tmap(tau0)) = 0.
        idx: (M,) int, each path's index into the homotopy's per-path data.
        tau0: (M,) start of each path's range.
        tau1: (M,) end of each path's range (``tau1 > tau0``).
        options: step control; defaults to :class:`TrackerOptions`.
        h0: (M,) initial steps (default ``options.h0``).

    Returns:
        A :class:`TrackOutcome`.
    """
    o = options or TrackerOptions()
    z = np.array(z0, dtype=complex)
    M = len(z)
    tau = np.array(tau0, dtype=float).copy()
    tau1 = np.broadcast_to(np.asarray(tau1, dtype=float), (M,))
    idx = np.asarray(idx)
    h = np.full(M, o.h0) if h0 is None else np.array(h0, dtype=float)
    status = np.full(M, RUNNING)
    status[tau >= tau1] = DONE
    steps = np.zeros(M, dtype=int)
    accepted = np.zeros(M, dtype=int)
    rejected = np.zeros(M, dtype=bool)  # the last step was rejected
    v = _velocity(homotopy, tmap, z, tau, idx) if M else z.copy()
    for _ in range(o.max_steps):
        act = np.flatnonzero(status == RUNNING)
        if act.size == 0:
            break
        za, ta, ia = z[act], tau[act], idx[act]
        remaining = tau1[act] - ta
        hh = np.minimum(h[act], remaining)
        hh = np.where(remaining - hh < 1e-3 * hh, remaining, hh)  # no sliver before the end
        # RK4 predictor (k1 is the velocity kept from the previous corrector)
        k1 = v[act]
        k2 = _velocity(homotopy, tmap, za + 0.5 * hh[:, None] * k1, ta + 0.5 * hh, ia)
        k3 = _velocity(homotopy, tmap, za + 0.5 * hh[:, None] * k2, ta + 0.5 * hh, ia)
        k4 = _velocity(homotopy, tmap, za + hh[:, None] * k3, ta + hh, ia)
        zp = za + (hh / 6.0)[:, None] * (k1 + 2 * k2 + 2 * k3 + k4)
        zp = np.where(np.isfinite(zp), zp, za)
        # Newton corrector: two iterations; the second solve also gives the new velocity
        t_new, dt_new = tmap(ta + hh, ia)
        H, Hz, _ = homotopy(zp, t_new, ia)
        d1 = solve_batched(Hz, H)
        z1 = zp - np.where(np.isfinite(d1), d1, 0.0)
        H, Hz, Ht = homotopy(z1, t_new, ia)
        X = solve_batched(Hz, np.stack([H, Ht * dt_new[:, None]], axis=2))
        zc, v_new = z1 - X[..., 0], -X[..., 1]
        nu1, nu2 = rel_norm(d1, zp), rel_norm(X[..., 0], z1)
        converged = (nu1 <= o.trust) & (nu2 <= o.theta * nu1 + o.floor) & (nu2 <= o.tol)
        if o.third:
            zc, v_new, converged = _third(homotopy, zc, v_new, t_new, dt_new, ia, nu1, nu2,
                                          converged, o)  # fmt: skip
        at_noise = np.maximum(nu1, nu2) <= o.noise
        ok = np.isfinite(zc).all(axis=1) & np.isfinite(v_new).all(axis=1) & (converged | at_noise)
        steps[act] += 1
        accepted[act] += ok
        factor = np.clip((o.eta / np.maximum(nu1, 1e-300)) ** 0.2, 0.25, 2.0)
        factor = np.where(rejected[act], np.minimum(factor, 1.0), factor)
        rejected[act] = ~ok
        h_new = np.where(ok, np.minimum(hh * factor, o.h_max), 0.5 * hh)
        h[act] = h_new
        z[act] = np.where(ok[:, None], zc, za)
        v[act] = np.where(ok[:, None], v_new, k1)
        tau[act] = np.where(ok, ta + hh, ta)
        reached = ok & (ta + hh >= tau1[act])
        big = np.abs(z[act]).max(axis=1) > o.max_norm
        new_status = np.where(reached, DONE, RUNNING)
        new_status = np.where(~reached & big, DIVERGED, new_status)
        new_status = np.where((new_status == RUNNING) & (h[act] < o.h_min), UNDERFLOW, new_status)
        status[act] = new_status
    status[status == RUNNING] = STEP_LIMIT
    return TrackOutcome(z=z, tau=tau, status=status, steps=steps, accepted=accepted, h=h)
