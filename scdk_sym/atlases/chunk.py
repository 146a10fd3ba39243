"""One chunk of an atlas: the convergent solves of a block of ``theta`` rows, on a worker.

The model travels to workers as its text (:class:`ModelSource`); each worker process builds
it once (:func:`worker_model`) and loads the compiled sweep from the disk cache.
:func:`solve_chunk` runs the sweep over the whole chunk and hands every point it cannot vouch
for to :func:`scdk_sym.solve` itself (see :mod:`scdk_sym.atlases.sweep`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, PathError, ScdkError, SolveError, VerificationError
from ..interrupts import check
from ..products import ATLAS_SWEEPS

#: Status codes of an atlas point (stored in the store's attributes as well).
STATUS = {
    0: "solved",
    1: "PathError: the convergent path never reached theta (no solution on the start's side)",
    2: "VerificationError: the solution failed its residual check",
    3: "SolveError: another solver failure",
    4: "singular: solved, theta on the singular surface (J_p singular)",
}
SOLVED, PATH, VERIFICATION, SOLVE, SINGULAR = 0, 1, 2, 3, 4
#: A sweep end is accepted if its smallest singular value of J_p exceeds this (relative);
#: sc.solve calls a solution singular below 1e-6.
COND_MARGIN = 1e-5
#: Largest accepted Newton correction of a sweep step, relative to the step's motion.
CORRECTION_TOL = 1e-3


@dataclass(frozen=True)
class ModelSource:
    """What a worker needs to rebuild a model: its files' text, frame and content hash."""

    urdf: str
    yaml: str
    frame: str | None
    content_hash: str


@dataclass(frozen=True)
class ChunkResult:
    """Solutions of one chunk of N points.

    Attributes:
        x: (N, n) workspace coordinates (NaN where not solved).
        det_jp: (N,) det J_p at the solution, in the chart centred on it (NaN if not solved).
        status: (N,) int8 codes of :data:`STATUS`.
        n_modes: (N,) int16 number of real assembly modes found (-1 if not computed/failed).
        swept: how many points the compiled sweep settled (the rest went to sc.solve).
    """

    x: np.ndarray
    det_jp: np.ndarray
    status: np.ndarray
    n_modes: np.ndarray
    swept: int


def model_source(model) -> ModelSource:
    """The transportable description of a model."""
    return ModelSource(model.urdf_text, model.spec.to_yaml(), model.frame, model.content_hash)


_MODELS: dict[str, object] = {}


def keep_model(model) -> None:
    """Let :func:`worker_model` in this process return ``model`` itself for its source (the
    caller's model, when chunks are solved in the calling process)."""
    _MODELS.setdefault(model.content_hash, model)


def worker_model(source: ModelSource):
    """The model of ``source``, built once per process."""
    model = _MODELS.get(source.content_hash)
    if model is None:
        from ..model.spec import parse_spec
        from ..model.urdf import parse_urdf
        from ..robot import Model

        tree = parse_urdf(source.urdf, "robot.urdf")
        spec = parse_spec(source.yaml, "robot.yaml")
        model = Model(tree, spec, None, source.frame, source.urdf)
        if model.content_hash != source.content_hash:
            raise InputError(
                f"model rebuilt on a worker has hash {model.content_hash[:12]}, expected "
                f"{source.content_hash[:12]}: use the same scdk_sym version on every worker"
            )
        _MODELS[source.content_hash] = model
    return model


def _sweeps(model):
    from .sweep import load_sweeps

    return model.products.get(ATLAS_SWEEPS, lambda: load_sweeps(model))


def _det_local(model, y: np.ndarray, theta: np.ndarray) -> float:
    y_loc, c = model.chart.to_local(y)
    return float(np.linalg.det(np.array(model.kernels.jac(y_loc, theta, c)[0])))


def solve_chunk(model, start, thetas: np.ndarray, modes: bool = False) -> ChunkResult:
    """Convergent solves of every row of ``thetas`` from ``start``.

    Args:
        model: the model.
        start: the assembled start Configuration (non-singular).
        thetas: (N, k) actuated values.
        modes: also count the real assembly modes at each point (:func:`scdk_sym.assembly_modes`).

    Returns:
        The :class:`ChunkResult`; each solved point equals
        ``sc.solve(model, theta, start=start, branch="convergent")`` to rounding.
    """
    from ..solvers.sc import solve

    thetas = np.ascontiguousarray(thetas, dtype=float)
    N, m, n = len(thetas), model.m, len(model.workspace)
    x = np.full((N, n), np.nan)
    det = np.full(N, np.nan)
    status = np.full(N, SOLVE, dtype=np.int8)
    todo = np.flatnonzero(np.all(np.isfinite(thetas), axis=1))
    y1, c = model.chart.to_local(start.y)
    swept = 0
    for sweep in _sweeps(model):
        if not todo.size:
            break
        cnt = todo.size
        out = sweep.map(cnt)(
            np.repeat(y1[:, None], cnt, 1),
            np.repeat(np.asarray(start.theta, float)[:, None], cnt, 1),
            thetas[todo].T,
            np.repeat(c[:, None], cnt, 1),
        )
        y0, ratio, corr, res, J, x0 = (np.array(o) for o in out)
        Js = J.T.reshape(cnt, m, m).transpose(0, 2, 1)  # column-major vec -> (cnt, m, m)
        with np.errstate(invalid="ignore"):
            sv = np.linalg.svd(np.nan_to_num(Js), compute_uv=False)
            ok = (
                np.all(np.isfinite(y0), axis=0)
                & (ratio.ravel() > 0)
                & (corr.ravel() <= CORRECTION_TOL)
                & (res.ravel() <= model.tolerance)
                & (sv[:, -1] > COND_MARGIN * sv[:, 0])
            )
        idx = todo[ok]
        x[idx] = x0[:, ok].T
        status[idx] = SOLVED
        det[idx] = np.linalg.det(Js[ok])
        swept += idx.size
        todo = todo[~ok]
    for i in todo:
        check()  # a stop between points: the chunk is not written, a rerun redoes it
        try:
            r = solve(
                model,
                thetas[i],
                start=start,
                branch="convergent",
                backend="compiled",
                record_path=False,
            )
        except PathError:
            status[i] = PATH
        except VerificationError:
            status[i] = VERIFICATION
        except (SolveError, InputError):
            status[i] = SOLVE
        else:
            x[i] = r.x
            det[i] = _det_local(model, r.y, r.theta)
            status[i] = SINGULAR if r.status == "singular" else SOLVED
    check()  # an interrupt some library reported as a failed solve is not a failed point
    n_modes = np.full(N, -1, dtype=np.int16)
    if modes:
        from ..solvers.modes import assembly_modes

        for row in range(N):
            check()
            try:
                sols = assembly_modes(model, thetas[row], backend="compiled")
                n_modes[row] = len(sols) if sols.certified else -1
            except ScdkError:
                n_modes[row] = -1
        check()
    return ChunkResult(x, det, status, n_modes, swept)
