"""Trace test for families whose solutions escape to infinity: the trace is rational.

Along the offset pencil ``b(lambda) = b* + lambda v`` the sum ``T(lambda)`` of ``f(z_j)`` over
the whole fibre is a symmetric function of the fibre, hence single valued; it is a polynomial
only when no solution goes to infinity in the disk sampled. For a model's algebraic form
(angles as ``(c, s)`` on the circle ``c^2 + s^2 = 1``, which is not compact in C^2) solutions
do escape near the base point: ``T`` is then a rational function with poles there, and the
polynomial test of :func:`scdk_sym.algebraic.monodromy.trace_test` rejects a complete set.

This test fits ``T = P / Q`` with ``deg P, deg Q <= d`` (linearised least squares,
``T Q - P = 0``, on ``K`` samples of a random combination of the traced functions) and
checks the fit at ``K`` other samples of the same circle, for ``d = 1 .. max_degree``. The
sum over a proper subset is not single valued: sampled along rays from the base point it
jumps across the cuts of the branch points inside the circle and no rational function of
low degree follows it, so the validation error stays large. A complete set passes with a
validation error at the tracking accuracy. Like the polynomial test, a failure is possible
for a complete set (poles too many for ``max_degree``): a false negative, never a false
positive beyond the numerical tolerance.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .homotopy import ParameterHomotopy, dedup, track_parameter_homotopy
from .system import PolynomialSystem
from .tracker import TrackerOptions


def _cnormal(rng: np.random.Generator, shape) -> np.ndarray:
    return (rng.normal(size=shape) + 1j * rng.normal(size=shape)) / np.sqrt(2.0)


def _fit_error(lam: np.ndarray, T: np.ndarray, lam_v: np.ndarray, T_v: np.ndarray, d: int):
    """Validation error (max abs) of the degree-(d, d) rational least-squares fit."""
    V = np.vander(lam, d + 1, increasing=True)
    A = np.hstack([T[:, None] * V, -V])
    _, _, vh = np.linalg.svd(A)
    c = vh[-1].conj()
    q, p = c[: d + 1], c[d + 1 :]
    Vv = np.vander(lam_v, d + 1, increasing=True)
    Qv = Vv @ q
    if np.min(np.abs(Qv)) <= 1e-12 * np.max(np.abs(Qv)):
        return np.inf
    return float(np.max(np.abs(T_v - (Vv @ p) / Qv)))


def rational_trace_test(
    system: PolynomialSystem,
    solutions: np.ndarray,
    p: np.ndarray,
    b: np.ndarray,
    rng: np.random.Generator,
    trace_map: Callable[[np.ndarray], np.ndarray],
    *,
    samples: int = 32,
    max_degree: int = 8,
    radius: float = 0.5,
    options: TrackerOptions | None = None,
) -> tuple[float, int]:
    """Relative validation error of the best low-degree rational fit of the trace.

    Args:
        system: the polynomial system (with offset rows).
        solutions: (R, n) complex solutions at ``(p, b)``.
        p: (n_params,) base parameters.
        b: (n,) base offsets.
        rng: random generator (pencil direction, sample phase, combination weights).
        trace_map: ``f``, (N, n) -> (N, m) complex.
        samples: fit samples ``K`` (as many again validate), > 2 (max_degree + 1).
        max_degree: largest degree ``d`` of numerator and denominator tried.
        radius: sample circle radius, relative to ``1 + max|b|``.
        options: tracker step control.

    Returns:
        ``(error, degree)``: the smallest validation error relative to the mean of
        ``sum_j |f(z_j)|`` over the samples, and the degree that reached it; ``(inf, -1)``
        if a path failed or two paths met.
    """
    R, n = solutions.shape
    offs = np.asarray(system.offset_rows, dtype=bool)
    vb = np.where(offs, _cnormal(rng, n), 0.0) * (1.0 + np.abs(b).max())
    K = 2 * samples
    phase = rng.uniform()
    lam = radius * np.exp(2j * np.pi * (np.arange(K) / 2 + phase) / samples)
    hom = ParameterHomotopy(
        system,
        np.repeat(p[None], K, 0),
        np.repeat(p[None], K, 0),
        np.repeat(b[None], K, 0),
        b[None] + lam[:, None] * vb[None],
        np.ones(K),
    )
    z = np.tile(solutions, (K, 1))
    idx = np.repeat(np.arange(K), R)
    ends = track_parameter_homotopy(system, z, hom, idx, options, endgame=False)
    if not (ends.status == "success").all():
        return float("inf"), -1
    zk = ends.z.reshape(K, R, n)
    for k in range(K):
        if len(dedup(zk[k], 1e-8)) != R:
            return float("inf"), -1
    fk = np.asarray(trace_map(ends.z)).reshape(K, R, -1)
    scale = float(np.abs(fk).max(axis=2).sum(axis=1).mean())
    w = _cnormal(rng, fk.shape[2])
    T = fk.sum(axis=1) @ w / np.abs(w).sum()
    fit, val = slice(0, K, 2), slice(1, K, 2)
    x = lam / radius
    best, best_d = float("inf"), -1
    for d in range(1, max_degree + 1):
        err = _fit_error(x[fit], T[fit], x[val], T[val], d) / scale
        if err < best:
            best, best_d = err, d
    return best, best_d
