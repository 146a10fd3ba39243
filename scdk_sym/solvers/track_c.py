"""Direct kinematics along a trajectory with the generated C tracker, in one call into C.

:func:`track_c` compiles (once, cached on disk) the standalone tracker of
:mod:`scdk_sym.codegen`, runs the whole sequence of readings in one ``ctypes`` call, and then
verifies every returned sample in Python with the CasADi kernels (independently of the C
code): a sample that fails its residual check, or a failure status of the C tracker, raises
a :class:`TrackError` naming the sample.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

from ..errors import InputError, SolveError
from ..model.chart import rot_log
from ..model.model import Model
from ..results import Configuration, Crossing, TrackResult
from .sc import validate_start


class TrackError(SolveError):
    """The C tracker failed at a sample, or a sample failed its verification.

    Attributes:
        index: index of the failing sample in ``thetas``.
        status: the C status code (see :data:`scdk_sym.codegen.library.STATUS`), or 0 when the
            C tracker succeeded but the Python verification failed.
        residual: the sample's residual (NaN if none was computed).
    """

    def __init__(self, message: str, index: int, status: int, residual: float = float("nan")):
        self.index = index
        self.status = status
        self.residual = residual
        super().__init__(message)


def track_c(
    model: Model,
    thetas: Sequence[Sequence[float]],
    start: Configuration | None = None,
    *,
    options=None,
) -> TrackResult:
    """Track a sequence of actuated readings with the generated C tracker.

    Each reading is reached from the previous configuration along the singularity-consistent
    solution curve; where several solutions are met (near a fold of the direct kinematics)
    the one continuing the motion is kept: the nearest to the extrapolation of the last
    samples, and among those nearer to each other than the extrapolation is accurate, the
    one farthest along the predicted motion. The start is not a sample: the first reading is
    reached from it on the convergent branch, and the motion is extrapolated from the samples
    on.

    Args:
        model: the model.
        thetas: (N, k) actuated readings [rad or model length unit], in order.
        start: assembled configuration before the first reading (default ``model.home``).
        options: :class:`scdk_sym.codegen.library.Options` of the tracker (default: the
            generated defaults; the tolerance is the model's).

    Returns:
        A verified :class:`~scdk_sym.results.TrackResult` (``backend="c"``): ``y`` canonical,
        ``x`` the workspace coordinates, ``residual`` max |closure row| per sample,
        ``crossings`` the singular-manifold crossings located between samples (each with
        ``index``: the sample after which it occurs, -1 before the first sample; ``s``: the
        fraction of the way to the next sample).

    Raises:
        InputError: ``thetas`` has the wrong shape or non-finite values.
        NotAssembledError: ``start`` violates the closures.
        TrackError: the C tracker failed at a sample, or a sample failed verification.
        BuildError: no C compiler (the library is compiled on first use).
    """
    from ..codegen.library import STATUS, tracker_library

    th = _readings(thetas, model.k)
    start = validate_start(model, start)
    lib = tracker_library(model)
    y0, c0 = model.chart.to_local(start.y)
    out = lib.track(y0, c0, start.theta, th, options)
    if out.status < 0:
        i = max(out.failed, 0)
        why = STATUS.get(out.status, f"status {out.status}")
        raise TrackError(
            f"C tracker failed at sample {i} (theta={th[i].tolist() if len(th) else []}): "
            f"{why} (status {out.status})",
            i,
            out.status,
        )
    N = th.shape[0]
    y_can = _canonical(model, out.y, out.c)
    residual = _residuals(model, y_can, th)
    bad = np.flatnonzero(~(residual <= model.tolerance))
    if bad.size:
        i = int(bad[0])
        raise TrackError(
            f"sample {i} failed verification: residual {residual[i]:.3g} > "
            f"{model.tolerance:.1e} (theta={th[i].tolist()})",
            i,
            0,
            float(residual[i]),
        )
    crossings = _crossings(model, start, y_can, th, out.det)
    return TrackResult(
        x=out.x.reshape(N, len(model.workspace)),
        y=y_can,
        theta=th,
        residual=residual,
        crossings=crossings,
        status="converged",
        backend="c",
    )


def _readings(thetas, k: int) -> np.ndarray:
    try:
        th = np.array(thetas, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"thetas must be an (N, {k}) array of numbers, got {thetas!r}") from exc
    if th.ndim == 1 and th.size == k:
        th = th[None, :]
    if th.ndim != 2 or th.shape[1] != k:
        raise InputError(f"thetas must have shape (N, {k}), got {th.shape}")
    finite = np.all(np.isfinite(th), axis=1)
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise InputError(f"thetas[{i}] must be finite, got {th[i].tolist()}")
    return th


# ---------------------------------------------------------------------------- charts, batched


def _skew(v: np.ndarray) -> np.ndarray:
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    S[..., 1, 0], S[..., 2, 0], S[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return S


def _cayley(rho: np.ndarray) -> np.ndarray:
    W = _skew(rho)
    return np.eye(3) + 2 * (W + W @ W) / (1 + np.sum(rho * rho, axis=-1))[..., None, None]


def _rot_log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors of (N, 3, 3) rotations (angle in [0, pi])."""
    cosang = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1) / 2, -1.0, 1.0)
    angle = np.arccos(cosang)
    w = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], -1)
    small = angle < 1e-9
    near_pi = np.pi - angle < 1e-6
    factor = np.where(small, 0.5, angle / (2 * np.sin(np.where(small | near_pi, 1.0, angle))))
    out = factor[:, None] * w
    for i in np.flatnonzero(near_pi):
        out[i] = rot_log(R[i])
    return out


def _rot_exp(w: np.ndarray) -> np.ndarray:
    angle = np.linalg.norm(w, axis=-1)
    safe = np.where(angle < 1e-12, 1.0, angle)
    K = _skew(w / safe[:, None])
    s = np.where(angle < 1e-12, 0.0, np.sin(angle))[:, None, None]
    c = np.where(angle < 1e-12, 0.0, 1 - np.cos(angle))[:, None, None]
    R = np.eye(3) + s * K + c * (K @ K)
    tiny = angle < 1e-12
    if tiny.any():
        R[tiny] = np.eye(3) + _skew(w[tiny])
    return R


def _canonical(model: Model, y: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Local (y, c) rows -> canonical y rows (rotation vectors)."""
    y = np.array(y, dtype=float)
    for i, idx in enumerate(model.chart.rotations):
        idx = list(idx)
        R_ref = c[:, 9 * i : 9 * i + 9].reshape(-1, 3, 3).transpose(0, 2, 1)  # column-major
        y[:, idx] = _rot_log(R_ref @ _cayley(y[:, idx]))
    return y


def _to_local(model: Model, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Canonical y rows -> (local y rows with zero rotation parameters, chart rows)."""
    y = np.array(y, dtype=float)
    c = np.zeros((y.shape[0], model.chart.size))
    for i, idx in enumerate(model.chart.rotations):
        idx = list(idx)
        R = _rot_exp(y[:, idx])
        c[:, 9 * i : 9 * i + 9] = R.transpose(0, 2, 1).reshape(-1, 9)
        y[:, idx] = 0.0
    return y, c


def _residuals(model: Model, y_can: np.ndarray, th: np.ndarray) -> np.ndarray:
    """Max |closure row| of each canonical sample (CasADi SX kernels, not the C code)."""
    N = y_can.shape[0]
    if N == 0:
        return np.zeros(0)
    y_loc, c = _to_local(model, y_can)
    maps = model.__dict__.setdefault("_check_maps", {})
    if N not in maps:
        if len(maps) > 8:
            maps.clear()
        maps[N] = model.kernels.check.map(N)
    check = maps[N]
    rows = np.array(check(y_loc.T, th.T, c.T if c.size else ca.DM.zeros(0, N)))
    res = np.max(np.abs(rows), axis=0)
    res[~np.all(np.isfinite(y_can), axis=1)] = np.nan
    return res


# ---------------------------------------------------------------------------- crossings


def _crossings(model, start, y_can, th, det) -> tuple[Crossing, ...]:
    """Singular-manifold crossings: det J_p changes sign between consecutive samples."""
    if det.size == 0:
        return ()
    y_loc0, c0 = model.chart.to_local(start.y)
    det0 = float(np.linalg.det(np.array(model.kernels.jac(y_loc0, start.theta, c0)[0])))
    dets = np.concatenate([[det0], det])
    ys = np.vstack([start.y, y_can])
    ths = np.vstack([start.theta, th])
    out = []
    for j in np.flatnonzero(np.sign(dets[:-1]) * np.sign(dets[1:]) < 0):
        out.append(
            _locate(model, ys[j], ys[j + 1], ths[j], ths[j + 1], dets[j], dets[j + 1], j - 1)
        )
    return tuple(out)


def _locate(model, ya, yb, tha, thb, da, db, index) -> Crossing:
    """The crossing between two samples: where ``det J_p`` vanishes between them.

    The chord between the samples in ``(y, theta)`` is projected onto the closure manifold
    ``g = 0`` (minimum-norm Gauss-Newton over ``(y, theta)``, regular at direct-kinematic
    singularities where ``[J_p, -J_s]`` keeps full rank), and the sign change of ``det J_p``
    along it is bisected. ``s`` is the fraction of the way from the first sample.
    """
    m = model.m
    kern = model.kernels
    ya_loc, c = model.chart.to_local(ya)
    yb_loc = np.array(yb, dtype=float)
    for i, idx in enumerate(model.chart.rotations):
        idx = list(idx)
        R_ref = c[9 * i : 9 * i + 9].reshape(3, 3, order="F")
        M = R_ref.T @ _rot_exp(np.asarray(yb)[idx][None, :])[0]
        yb_loc[idx] = np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]]) / (
            1 + np.trace(M)
        )
    za = np.concatenate([ya_loc, tha])
    zb = np.concatenate([yb_loc, thb])

    def project(alpha):
        z = za + alpha * (zb - za)
        for _ in range(30):
            g = np.array(kern.g(z[:m], z[m:], c)).ravel()
            if np.max(np.abs(g)) <= 1e-3 * model.tolerance:
                break
            Jp, Js = (np.array(a) for a in kern.jac(z[:m], z[m:], c))
            G = np.hstack([Jp, -Js])
            z = z - G.T @ np.linalg.solve(G @ G.T, g)
        return z, float(np.linalg.det(np.array(kern.jac(z[:m], z[m:], c)[0])))

    lo, hi = 0.0, 1.0
    sign_lo = np.sign(da)
    z = za
    try:
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            z, det = project(mid)
            if np.sign(det) == sign_lo:
                lo = mid
            else:
                hi = mid
            if hi - lo < 1e-13:
                break
    except np.linalg.LinAlgError:
        pass
    if not np.all(np.isfinite(z)):  # fall back on the chord (accurate to the sample spacing)
        alpha = da / (da - db)
        z = za + alpha * (zb - za)
    cfg = model.configuration(z[:m], z[m:], c)
    return Crossing(0.5 * (lo + hi), cfg.x, cfg.y, cfg.theta, index)
