"""One chunk of an atlas: the convergent solves of a block of ``theta`` rows, on a worker.

The model travels to workers as its text (:class:`ModelSource`); each worker process builds
it once (:func:`worker_model`) and loads the model's C tracker library from the disk cache.
:func:`solve_chunk` runs the library's sweep over the whole chunk in one call (each grid point
continued from its neighbour, one grid step away, and solved from the start where that is not
vouched for: the rule is stated in the generated header, ``<prefix>_sweep``) and hands every
point the sweep leaves (a singular path, a nearly singular solution) to :func:`scdk_sym.solve`
itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, PathError, ScdkError, SolveError, VerificationError
from ..interrupts import check

#: Status codes of an atlas point (stored in the store's attributes as well).
STATUS = {
    0: "solved",
    1: "PathError: the convergent path never reached theta (no solution on the start's side)",
    2: "VerificationError: the solution failed its residual check",
    3: "SolveError: another solver failure",
    4: "singular: solved, theta on the singular surface (J_p singular)",
    5: "not solved: a mode map alone (atlas(..., solve=False))",
}
SOLVED, PATH, VERIFICATION, SOLVE, SINGULAR, UNSOLVED = 0, 1, 2, 3, 4, 5
#: Points per call into the C sweep (interrupts are checked between calls, and each call's
#: first point is solved from the start).
SWEEP_CALL = 1024
#: A swept solution is kept if a lower bound of sigma_min / sigma_max of its J_p exceeds this;
#: sc.solve calls a solution singular below 1e-6.
COND_MARGIN = 1e-5


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
        swept: how many points the C sweep settled (the rest went to sc.solve).
        modes_continued: how many mode sets came from a grid neighbour's root set.
    """

    x: np.ndarray
    det_jp: np.ndarray
    status: np.ndarray
    n_modes: np.ndarray
    swept: int
    modes_continued: int = 0


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


def _tracker(model):
    from ..codegen.library import tracker_library

    return tracker_library(model)


def _det_local(model, y: np.ndarray, theta: np.ndarray) -> float:
    y_loc, c = model.chart.to_local(y)
    return float(np.linalg.det(np.array(model.kernels.jac(y_loc, theta, c)[0])))


def solve_chunk(
    model,
    start,
    thetas: np.ndarray,
    modes: bool = False,
    *,
    offset: int = 0,
    shape: tuple[int, ...] | None = None,
    solve: bool = True,
) -> ChunkResult:
    """Convergent solves of every row of ``thetas`` from ``start``.

    Args:
        model: the model.
        start: the assembled start Configuration (non-singular).
        thetas: (N, k) actuated values: points ``offset`` to ``offset + N - 1`` of a grid.
        modes: also count the real assembly modes at each point (:func:`mode_counts`); a point
            with none, certified, is a PathError without a solve (no path can reach it).
        offset: flat (C-order) index of the first row in the grid.
        shape: the grid's shape (default ``(N,)``: a list of readings, each row continued from
            the row before it).
        solve: the convergent solves; False (with ``modes``): the mode counts alone, every
            finite point's status :data:`UNSOLVED`.

    Returns:
        The :class:`ChunkResult`; each solved point equals
        ``sc.solve(model, theta, start=start, branch="convergent")`` to rounding.
    """
    thetas = np.ascontiguousarray(thetas, dtype=float)
    N, n = len(thetas), len(model.workspace)
    grid_shape = (N,) if shape is None else tuple(shape)
    x = np.full((N, n), np.nan)
    det = np.full(N, np.nan)
    status = np.full(N, SOLVE, dtype=np.int8)
    finite = np.all(np.isfinite(thetas), axis=1)
    if not solve:
        status[finite] = UNSOLVED
        n_modes, continued = np.full(N, -1, dtype=np.int16), 0
        if modes:
            n_modes, continued = mode_counts(model, thetas, offset, grid_shape)
        return ChunkResult(x, det, status, n_modes, 0, continued)
    swept = 0
    ok = np.zeros(N, dtype=bool)
    y1, c = model.chart.to_local(start.y)
    for a in range(0, N, SWEEP_CALL):
        b = min(a + SWEEP_CALL, N)
        out = _tracker(model).sweep(
            y1, c, start.theta, thetas[a:b], offset + a, grid_shape, COND_MARGIN
        )
        ok[a:b] = (out.codes >= 0) & (out.residual <= model.tolerance) & finite[a:b]
        x[a:b][ok[a:b]] = out.x[ok[a:b]]
        det[a:b][ok[a:b]] = out.det[ok[a:b]]
        check()  # a stop between calls into C
    status[ok] = SOLVED
    swept = int(np.sum(ok))
    todo = np.flatnonzero(finite & ~ok)
    n_modes = np.full(N, -1, dtype=np.int16)
    continued = 0
    if modes:
        n_modes, continued = mode_counts(model, thetas, offset, grid_shape)
        # no real solution, certified: no path reaches theta (sc.solve's PathError)
        status[todo[n_modes[todo] == 0]] = PATH
        todo = todo[n_modes[todo] != 0]
    _direct(model, start, thetas, todo, x, det, status)
    check()  # an interrupt some library reported as a failed solve is not a failed point
    return ChunkResult(x, det, status, n_modes, swept, continued)


def _direct(model, start, thetas, todo, x, det, status) -> None:
    """``sc.solve`` at the points ``todo``, written into ``x``, ``det`` and ``status``."""
    from ..solvers.solve import solve

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


def continuation_tree(
    offset: int, count: int, shape: tuple[int, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """A shallow spanning forest of a chunk's points: the neighbour each point of a mode map
    is continued from, and its front (depth).

    Two points are neighbours when their grid indices differ by one along one axis (both in
    the chunk). Each connected part of the chunk is searched breadth first from the point
    nearest the centre of its index box (axes in order, the step back before the step
    forward): every point lies as few steps from its part's root as the grid allows, so a
    chunk of ``a x b`` grid lines has about ``(a + b) / 2`` fronts where a walk from a corner
    has ``a + b`` (and the points of a front are solved in one batch).

    Args:
        offset: flat index (C order) of the chunk's first point.
        count: points in the chunk.
        shape: the grid's shape.

    Returns:
        ``(pred, depth)``: (count,) int, each point's neighbour (index within the chunk; -1
        at a root, solved from scratch) and its number of steps from its root.
    """
    pred = np.full(count, -1, dtype=np.int64)
    depth = np.full(count, -1, dtype=np.int64)
    if not count:
        return pred, depth
    idx = np.stack(np.unravel_index(offset + np.arange(count), shape))  # (axes, count)
    strides = np.cumprod((*shape[1:], 1)[::-1])[::-1].tolist()
    while (depth < 0).any():
        part = np.zeros(count, dtype=np.int64) - 1  # the part of the first point left
        _search(int(np.argmax(depth < 0)), idx, strides, shape, part, pred.copy())
        rest = np.flatnonzero(part >= 0)
        centre = (idx[:, rest].min(axis=1) + idx[:, rest].max(axis=1)) / 2
        off = np.abs(idx[:, rest] - centre[:, None])
        _search(int(rest[np.lexsort((off.sum(axis=0), off.max(axis=0)))[0]]), idx, strides,
                shape, depth, pred)  # fmt: skip
    return pred, depth


def _search(root: int, idx: np.ndarray, strides: list[int], shape, depth, pred) -> None:
    """Breadth-first search of the chunk's grid graph from ``root``: ``depth`` (-1 where not
    reached yet) and ``pred`` of the points it reaches set in place (axes in order, the step
    back before the step forward)."""
    count = len(depth)
    depth[root], front, d = 0, np.array([root]), 0
    while front.size:
        d += 1
        grown = []
        for axis, stride in enumerate(strides):
            for step in (-1, 1):
                at = idx[axis, front] + step
                src = front[(at >= 0) & (at < shape[axis])]
                nb = src + step * stride
                ok = (nb >= 0) & (nb < count)
                nb, src = nb[ok], src[ok]
                new = depth[nb] < 0
                nb, src = nb[new], src[new]
                pred[nb], depth[nb] = src, d
                grown.append(nb)
        front = np.concatenate(grown)


#: Most points of a front of a mode map solved in one batch.
FRONT = 64


def _one(model, theta: np.ndarray, near):
    """:func:`~scdk_sym.solvers.homotopy_modes.modes_from_neighbour` at one point, None
    where it fails."""
    from ..solvers.homotopy_modes import modes_from_neighbour

    try:
        return modes_from_neighbour(model, theta, near, backend="compiled")
    except ScdkError:
        return None


def mode_counts(
    model, thetas: np.ndarray, offset: int, shape: tuple[int, ...]
) -> tuple[np.ndarray, int]:
    """Certified real-mode counts of a chunk, each point's set from its grid neighbour's
    complete root set where that is known (the neighbour and the fronts:
    :func:`continuation_tree`)
    (:func:`scdk_sym.solvers.homotopy_modes.modes_from_neighbour`; models of independent
    blocks: :func:`scdk_sym.assembly_modes` at each point).

    Args:
        model: the model.
        thetas: (N, k) points ``offset`` to ``offset + N - 1`` of the grid.
        offset: flat index of the first one.
        shape: the grid's shape (``(N,)`` for a list of readings).

    Returns:
        ``(n_modes, continued)``: (N,) int16 counts (-1 where not certified) and how many
        sets came from a neighbour.
    """
    from ..solvers.block_modes import split
    from ..solvers.homotopy_modes import ModeSeed, modes_from_neighbours
    from ..solvers.modes import assembly_modes

    N = len(thetas)
    n_modes = np.full(N, -1, dtype=np.int16)
    continued = 0
    if split(model) is not None:
        for row in range(N):
            check()
            try:
                sols = assembly_modes(model, thetas[row], backend="compiled")
                n_modes[row] = len(sols) if sols.certified else -1
            except ScdkError:
                pass
        check()
        return n_modes, continued
    if not N:
        return n_modes, continued
    # fronts: a point's front is one more than its neighbour's, so a front's points are solved
    # together from the sets of the front before (kept until then)
    pred, depth = continuation_tree(offset, N, shape)
    followed = np.zeros(N, dtype=bool)
    followed[pred[pred >= 0]] = True
    fronts = np.split(np.argsort(depth, kind="stable"), np.cumsum(np.bincount(depth))[:-1])
    before: dict[int, ModeSeed] = {}
    for front in fronts:
        seeds: dict[int, ModeSeed] = {}
        for rows in np.array_split(front, -(-len(front) // FRONT)):
            check()
            near = [before.get(int(pred[r])) for r in rows]
            try:
                found = modes_from_neighbours(model, thetas[rows], near, backend="compiled")
            except ScdkError:  # which point: each on its own
                found = [_one(model, thetas[r], nb) for r, nb in zip(rows, near, strict=True)]
            for r, item in zip(rows, found, strict=True):
                if item is not None:
                    sols, seed, used = item
                    n_modes[r] = len(sols) if sols.certified else -1
                    continued += used
                    if seed is not None and followed[r]:
                        seeds[int(r)] = seed
        before = seeds
    check()
    return n_modes, continued
