"""The distinct real points among a homotopy's endpoints, each polished by real Newton steps
(in C with the system's C tracker, else in numpy)."""

from __future__ import annotations

import numpy as np

from .distinct import dedup_groups
from .parameter_homotopy import ParameterHomotopy
from .paths.continuation import rel_norm
from .system import PolynomialSystem


def real_endpoints(
    system: PolynomialSystem,
    z: np.ndarray,
    p0: np.ndarray,
    real_tol: float = 1e-8,
    dedup_tol: float = 1e-8,
    polish: bool = True,
    ctrack=None,
) -> np.ndarray:
    """Distinct real points among endpoints, each polished by two real Newton steps.

    Args:
        system: the polynomial system.
        z: (M, n) complex endpoints (NaN rows are skipped).
        p0: (n_params,) the target parameters.
        real_tol: largest ``max|Im z| / (1 + max|z|)`` of a real endpoint.
        dedup_tol: relative distance under which two real points are one.
        polish: run the real Newton steps (not at singular endpoints).
        ctrack: the system's C tracker (:func:`~scdk_sym.algebraic.paths.continuation_c.c_tracker`):
            the Newton steps in C (at real points and parameters they stay real); ``None``:
            in numpy.

    Returns:
        (K, n) float, sorted lexicographically.
    """
    p = np.asarray(p0, dtype=complex)[None]
    return real_endpoints_many(system, [z], p, real_tol, dedup_tol, polish, ctrack)[0]


def real_endpoints_many(
    system: PolynomialSystem,
    zs: list[np.ndarray],
    P0: np.ndarray,
    real_tol: float = 1e-8,
    dedup_tol: float = 1e-8,
    polish: bool = True,
    ctrack=None,
) -> list[np.ndarray]:
    """:func:`real_endpoints` of several targets, the C Newton steps of all in one call.

    Args:
        system: the polynomial system.
        zs: W arrays (M_w, n) of complex endpoints, one per target.
        P0: (W, n_params) the targets' parameters.
        real_tol: as :func:`real_endpoints`.
        dedup_tol: as :func:`real_endpoints`.
        polish: as :func:`real_endpoints`.
        ctrack: as :func:`real_endpoints`.

    Returns:
        W arrays (K_w, n) float, each as :func:`real_endpoints` returns it (each row's Newton
        steps are those of a single call).
    """
    n = system.n
    owner = np.repeat(np.arange(len(zs)), [len(z) for z in zs])
    z = np.concatenate(zs) if zs else np.zeros((0, n), dtype=complex)
    z = z.reshape(len(owner), n)
    keep = np.isfinite(z).all(axis=1)
    keep[keep] = rel_norm(z[keep].imag, z[keep]) <= real_tol
    owner = owner[keep]
    sizes = np.bincount(owner, minlength=len(zs)).tolist()
    xs = np.split(z[keep].real.astype(complex), np.cumsum(sizes)[:-1]) if zs else []
    if sum(sizes) and polish and ctrack is not None:
        P = np.asarray(P0, dtype=complex).reshape(len(zs), system.n_params)
        b = np.zeros((len(zs), system.n), dtype=complex)
        at_p0 = ParameterHomotopy(system, P, P, b, b, np.ones(len(zs)))
        idx = np.repeat(np.arange(len(zs)), sizes)
        x = ctrack.newton(at_p0, np.concatenate(xs), np.zeros(len(idx)), idx, 2, False)[0]
        xs = np.split(x, np.cumsum(sizes)[:-1])
    elif sum(sizes) and polish:
        xs = [_real_newton(system, x, p) for x, p in zip(xs, P0, strict=True)]
    return dedup_groups([x.real for x in xs], dedup_tol)


def _real_newton(system: PolynomialSystem, x: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """Two real Newton steps in numpy at ``p0`` (all stop where one Jacobian is singular)."""
    if not len(x):
        return x
    P = np.broadcast_to(np.asarray(p0, dtype=complex), (len(x), system.n_params))
    for _ in range(2):
        G, Gz, _ = system.evaluate(x, P)
        try:
            dx = np.linalg.solve(Gz.real, G.real[..., None])[..., 0]
        except np.linalg.LinAlgError:
            break
        x = x - np.where(np.isfinite(dx), dx, 0.0)
    return x
