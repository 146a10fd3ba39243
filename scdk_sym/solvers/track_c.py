"""Direct kinematics along a trajectory with the generated C tracker, in one call into C.

:func:`track_c` compiles (once, cached on disk) the standalone tracker of
:mod:`scdk_sym.codegen` and runs the whole sequence of readings in one ``ctypes`` call, which
also returns the closure residual of every sample (evaluated there by the generated closure
function, the model's ``g``); Python checks each against the model's tolerance: a sample that
fails it, or a failure status of the C tracker, raises a
:class:`~scdk_sym.errors.TrackError` naming the sample (re-exported here). The C tracker
judges every reading by the rule of :mod:`scdk_sym.solvers.track` (the same as
``track(backend="cvodes")``), and the crossings are computed from the finished track by the
same function, :func:`scdk_sym.solvers.crossings.crossings`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..codegen.library import ERR_NO_SOLUTION, ERR_UNDECIDABLE, STATUS, tracker_library
from ..errors import InputError, TrackError
from ..model.rotations import cayley, rot_log
from ..results import Configuration, TrackResult
from ..robot import Model
from .crossings import crossings as track_crossings
from .query import validate_start
from .track_errors import no_solution_error, undecidable_error, verify_samples

__all__ = ["TrackError", "track_c"]


def track_c(
    model: Model,
    thetas: ArrayLike,
    start: Configuration | None = None,
    *,
    options=None,
) -> TrackResult:
    """Track a sequence of actuated readings with the generated C tracker.

    Each reading is judged by the rule of :mod:`scdk_sym.solvers.track`: the cheap
    continuation where nothing hints at a singularity, else the candidate solution (met along
    the singularity-consistent curve, or corrected from the predicted motion) that continues
    the extrapolation of the last samples, provided no other candidate is about as consistent
    with it; otherwise the tracker refuses to guess. The start is not a sample: the first
    reading is reached from it on the convergent branch, and the motion is extrapolated from
    the samples on.

    Args:
        model: the model.
        thetas: (N, k) actuated readings [rad or model length unit], in order.
        start: assembled configuration before the first reading (default ``model.home``).
        options: :class:`scdk_sym.codegen.library.Options` of the tracker (default: the
            generated defaults, the rule's constants; the tolerance is the model's).

    Returns:
        A verified :class:`~scdk_sym.results.TrackResult` (``backend="c"``): ``y`` canonical,
        ``x`` the workspace coordinates, ``residual`` max |closure row| per sample,
        ``crossings`` the singular-manifold crossings located between samples (each with
        ``index``: the sample after which it occurs, -1 before the first sample; ``s``: the
        fraction of the way to the next sample).

    Raises:
        InputError: ``thetas`` has the wrong shape or non-finite values.
        NotAssembledError: ``start`` violates the closures.
        TrackError: the readings are too coarse to decide between two candidates at a sample
            (status -9, ``candidates`` their workspace x), no solution was met (-5), another
            failure of the C tracker, or a sample failed verification (status 0).
        BuildError: no C compiler (the library is compiled on first use).
    """
    th = _readings(thetas, model.k)
    start = validate_start(model, start)
    lib = tracker_library(model)
    y0, c0 = model.chart.to_local(start.y)
    out = lib.track(y0, c0, start.theta, th, options)
    if out.status < 0:
        i = max(out.failed, 0)
        theta_i = th[i] if len(th) else np.zeros(model.k)
        if out.status == ERR_UNDECIDABLE and out.refusal is not None:
            r = out.refusal
            raise undecidable_error(i, theta_i, list(r.x), list(r.miss), r.accuracy, r.step)
        if out.status == ERR_NO_SOLUTION:
            raise no_solution_error(i, theta_i)
        why = STATUS.get(out.status, f"status {out.status}")
        raise TrackError(
            f"C tracker failed at sample {i} (theta={theta_i.tolist()}): {why} "
            f"(status {out.status})",
            i, out.status, theta=theta_i,
        )  # fmt: skip
    N = th.shape[0]
    y_can = _canonical(model, out.y, out.c)
    residual = out.residual
    verify_samples(model, residual, th)
    crossings = track_crossings(model, start, y_can, th, out.det)
    for a in (out.x, y_can, th, residual):  # arrays of this call: read-only, not copied
        a.setflags(write=False)
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
    if not np.isfinite(th).all():
        i = int(np.flatnonzero(~np.isfinite(th).all(axis=1))[0])
        raise InputError(f"thetas[{i}] must be finite, got {th[i].tolist()}")
    return th


# ---------------------------------------------------------------------------- charts, batched


def _canonical(model: Model, y: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Local (y, c) rows -> canonical y rows (rotation vectors)."""
    y = np.array(y, dtype=float)
    for i, rot in enumerate(model.chart.rotations):
        idx = list(rot)
        R = c[:, 9 * i : 9 * i + 9].reshape(-1, 3, 3).transpose(0, 2, 1)  # column-major
        if np.any(y[:, idx]):  # re-centred charts (the tracker's) have rho = 0: cayley = I
            R = R @ cayley(y[:, idx])
        y[:, idx] = rot_log(R)
    return y
