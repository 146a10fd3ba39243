"""``sc.atlas``: the convergent direct kinematics over a joint grid, chunk by chunk, on Dask.

Each chunk of points is one task: a worker rebuilds the model once per process
(:func:`~scdk_sym.atlases.chunk.worker_model`), loads its compiled kernels from the disk cache
(built here, on the client, before any task starts), solves the chunk
(:func:`~scdk_sym.atlases.chunk.solve_chunk`) and writes it into the Zarr store, its
done-marker last. Re-running with the same ``out`` solves only the chunks without a marker, so
an interrupted run (Ctrl-C, a killed worker) resumes and ends byte-identical to an
uninterrupted one. At most a few tasks per worker are in flight, so the client's memory does
not grow with the grid.
"""

from __future__ import annotations

import hashlib
import multiprocessing
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
from numpy.typing import ArrayLike

from ..errors import AtlasError, InputError, Interrupted
from ..interrupts import check, stop_for, stop_on_signals
from .chunk import STATUS, keep_model, model_source
from .grid import Grid, make_grid
from .lock import store_lock
from .store import FORMAT, Layout, create_or_check, remove_partial_writes
from .task import solve_and_write

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from ..results import Configuration
    from ..robot import Model

_pkg = "scdk_sym"
#: Points per chunk (one task; also the Zarr chunk length) unless told.
DEFAULT_CHUNK = 4096
#: What produced n_modes (recorded in the store).
MODES_METHOD = (
    "the number of real solutions of the certified set of scdk_sym.assembly_modes(model, theta, "
    "backend='compiled'), each point's set from its grid neighbour's complete root set by a "
    "parameter homotopy where that set is known (scdk_sym.solvers.homotopy_modes."
    "modes_from_neighbour), else from the start system; certified complete: every path "
    "regular, the root count of distinct roots, every real solution proven by a Krawczyk "
    "test; -1 where it is not certified or the search failed"
)


@dataclass(frozen=True)
class AtlasRun:
    """Summary of one :func:`atlas` call.

    Attributes:
        out: the store path.
        points: points of the grid.
        chunks: chunks of the store.
        computed: chunks solved by this call (the others were already done).
        counts: status code -> number of points with it, over the whole store.
        elapsed: wall time of this call [s].
        busy: time spent in the chunk tasks of this call, summed over workers [s] (model
            loading on a worker's first task included).
        cpu: CPU time of the threads that ran those tasks [s] (what the tasks cost, whatever
            else shares the cores).
        swept: points of this call settled by the C sweep (the others by sc.solve).
    """

    out: Path
    points: int
    chunks: int
    computed: int
    counts: Mapping[int, int]
    elapsed: float
    busy: float
    cpu: float
    swept: int


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(_pkg)
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "unknown"


@dataclass(frozen=True)
class AtlasOptions:
    """The options of an :func:`atlas` run (its keyword arguments; see there).

    Attributes:
        workers: local worker processes (None or 0: this process, without Dask).
        scheduler: a Dask scheduler's address or a ``distributed.Client``.
        modes: also store the number of real assembly modes at each point.
        solve: the convergent solve at every point.
        start: the assembled start Configuration (None: ``model.home``).
        chunk: points per chunk (task and Zarr chunk).
        progress: a tqdm progress bar on stderr.
        on_chunk: called on the client after each chunk as ``on_chunk(points_done, total)``.
        wait: wait for another run writing the store instead of refusing.
    """

    workers: int | None = None
    scheduler: Any = None
    modes: bool = False
    solve: bool = True
    start: Configuration | None = None
    chunk: int = DEFAULT_CHUNK
    progress: bool = True
    on_chunk: Callable[[int, int], None] | None = None
    wait: bool = False


class AtlasKeywords(TypedDict, total=False):
    """The keyword arguments of :func:`atlas`: the fields of :class:`AtlasOptions`."""

    workers: int | None
    scheduler: Any
    modes: bool
    solve: bool
    start: Configuration | None
    chunk: int
    progress: bool
    on_chunk: Callable[[int, int], None] | None
    wait: bool


def atlas(
    model: Model,
    grid_or_thetas: str | Mapping[str, tuple[float, float, int]] | Grid | ArrayLike,
    out: str | Path,
    **options: Unpack[AtlasKeywords],
) -> AtlasRun:
    """Convergent direct kinematics at every point of a joint grid, into a Zarr store.

    Point ``i`` holds ``sc.solve(model, theta_i, start=start, branch="convergent")``.

    Args:
        model: the model.
        grid_or_thetas: a grid ``"NAME=lo:hi:n,..."`` or mapping ``name -> (lo, hi, n)``
            (point ``i`` is the C-order flattening, axes in the order given; actuated joints
            that are not axes stay at the start's value), or explicit (N, k) ``theta`` rows
            in the model's actuated order.
        out: the store directory (``*.zarr``); an existing store of the same run resumes.
        **options: the run's options, by keyword (the fields of :class:`AtlasOptions`):
            ``workers``, the number of local worker processes (a Dask ``LocalCluster``, one
            thread each; ``None`` or 0 solves in this process, without Dask); ``scheduler``,
            the address of a running Dask scheduler (``"tcp://host:8786"``) or a
            ``distributed.Client`` (its workers must see ``out`` and share the kernel cache
            directory or be able to compile, ``$SCDK_CACHE_DIR``); ``modes``, also store
            ``n_modes``, the number of real assembly modes at each point
            (:func:`scdk_sym.assembly_modes`, each point's set from its grid neighbour's);
            ``solve`` (default True), the convergent solve at every point (False, with
            ``modes``: a mode map alone, every point's status 5 "not solved", ``x`` and
            ``det_jp`` NaN); ``start``, the assembled start Configuration (default:
            ``model.home``); ``chunk``, points per chunk (task and Zarr chunk; memory per task
            is O(chunk)); ``progress`` (default True), a tqdm progress bar on stderr;
            ``on_chunk``, called on the client after each chunk as ``on_chunk(points_done,
            total)``; ``wait``, when another run is writing ``out``, wait for it to end (then
            solve what it left) instead of refusing.

    Returns:
        The :class:`AtlasRun` summary; the data is in the store (see
        :mod:`scdk_sym.atlases.store`).

    Raises:
        InputError: bad grid, thetas, chunk or worker count; ``solve=False`` without
            ``modes``.
        UnknownNameError: a grid name is not an actuated joint.
        StoreMismatchError: ``out`` holds an atlas of another model, grid or options.
        StoreLockedError: another run is writing ``out`` (and ``wait`` is False).
        AtlasError: Dask or Zarr missing, workers lost (re-run to resume).
        Interrupted: SIGINT or SIGTERM (within about a second; the chunks written are kept
            and the same call resumes; a ``KeyboardInterrupt``).

    A store has one writer at a time (:mod:`scdk_sym.atlases.lock`). Worker processes do not
    re-import the calling script, so a script needs no ``if __name__ == "__main__":`` guard.
    """
    t0 = time.perf_counter()
    opts = _options(options)
    start = _check_call(model, opts)
    if not opts.solve and not opts.modes:
        raise InputError("atlas: solve=False leaves nothing to compute; pass modes=True")
    grid, thetas, what = _points(model, grid_or_thetas, start)
    assert grid is not None or thetas is not None  # _points gives one of them
    points = grid.size if grid is not None else len(thetas)  # type: ignore[arg-type]
    chunk = int(min(opts.chunk, max(points, 1)))
    layout = Layout(points, model.k, len(model.workspace), chunk, opts.modes)
    meta = _metadata(model, what, points, layout, start, opts.modes, opts.solve)
    out = Path(out)
    with stop_on_signals(), store_lock(out, wait=opts.wait):
        try:
            plan = _Plan(model, out, layout, grid, thetas, start, opts)
            return _run(plan, meta, t0)
        except (Interrupted, Exception) as exc:  # a stop, or the error a library made of one
            stop = stop_for(exc)
            if stop is None:
                raise
            chunks = _chunks_done(out)
            raise Interrupted(
                f"atlas stopped by {stop.signal}: {chunks} of {layout.chunks} chunks are written "
                f"to {str(out)!r}; run the same command again to resume",
                stop.signal,
                resume=f"the same call with out={str(out)!r}",
            ) from None


def _options(options: Mapping[str, Any]) -> AtlasOptions:
    """The keyword arguments of an :func:`atlas` call as its options (a TypeError names an
    unknown one, as for any keyword)."""
    names = {f.name for f in fields(AtlasOptions)}
    unknown = sorted(set(options) - names)
    if unknown:
        raise TypeError(
            f"atlas() got an unexpected keyword argument {unknown[0]!r} "
            f"(valid: {', '.join(sorted(names))})"
        )
    return AtlasOptions(**options)


def _check_call(model, opts: AtlasOptions) -> Any:
    """The start of an :func:`atlas` call, validated with its other options (see there)."""
    from ..solvers.query import singular_start, validate_start

    chunk, workers, scheduler = opts.chunk, opts.workers, opts.scheduler
    start = validate_start(model, opts.start)
    if singular_start(model, start):
        raise InputError("atlas: the start configuration is singular; start from a regular one")
    if not isinstance(chunk, int | np.integer) or chunk < 1:
        raise InputError(f"atlas: chunk must be a positive number of points, got {chunk!r}")
    if workers is not None and (not isinstance(workers, int | np.integer) or workers < 0):
        raise InputError(f"atlas: workers must be a non-negative integer, got {workers!r}")
    if workers and getattr(multiprocessing.current_process(), "_inheriting", False):
        raise AtlasError(
            "atlas: called while a worker process was starting (it re-imported the script "
            "that starts the workers); put the call under 'if __name__ == \"__main__\":'"
        )
    if workers and scheduler is not None:
        raise InputError("atlas: give workers (a local cluster) or scheduler, not both")
    return start


def _metadata(
    model, what: dict, points: int, layout: Layout, start, modes: bool, solve: bool
) -> dict:
    """The store's metadata of a run: what a resumed run must match (see :mod:`.store`)."""
    return {
        "format": FORMAT,
        "package": _pkg,
        "version": _version(),
        "model": {
            "name": model.name,
            "content_hash": model.content_hash,
            "frame": model.frame,
            "actuated": list(model.actuated),
            "workspace": list(model.workspace),
        },
        **what,
        "points": points,
        "chunk": layout.chunk,
        "start": {"theta": np.asarray(start.theta).tolist(), "y": np.asarray(start.y).tolist()},
        "branch": "convergent" if solve else None,
        "status_codes": {str(k): v for k, v in STATUS.items()},
        "modes": modes,
        **({"n_modes_method": MODES_METHOD} if modes else {}),
    }


@dataclass(frozen=True)
class _Plan:
    """The checked inputs of one :func:`atlas` call."""

    model: Any
    out: Path
    layout: Layout
    grid: Grid | None
    thetas: np.ndarray | None
    start: Any
    options: AtlasOptions


def _run(plan: _Plan, meta: dict, t0: float) -> AtlasRun:
    """The run of :func:`atlas` on its checked inputs, under the store's lock."""
    model, out, layout, grid, thetas, start = (
        plan.model, plan.out, plan.layout, plan.grid, plan.thetas, plan.start
    )  # fmt: skip
    opts, points = plan.options, layout.points
    modes, progress, on_chunk = opts.modes, opts.progress, opts.on_chunk
    done = create_or_check(out, layout, meta)
    todo = [i for i in range(layout.chunks) if not done[i]]
    _prebuild(model)
    source = model_source(model)
    st = (np.asarray(start.y).tolist(), np.asarray(start.theta).tolist())
    already = sum(
        layout.bounds(i)[1] - layout.bounds(i)[0] for i in range(layout.chunks) if done[i]
    )
    bar = _bar(progress, points, already)
    count = [already]

    spent: list[float] = [0.0, 0.0, 0]

    def finished(index: int, seconds: float, cpu: float, swept: int) -> None:
        spent[0] += seconds
        spent[1] += cpu
        spent[2] += swept
        a, b = layout.bounds(index)
        count[0] += b - a
        if bar is not None:
            bar.update(b - a)
        if on_chunk is not None:
            on_chunk(count[0], points)

    def args(i: int):
        a, b = layout.bounds(i)
        rows = None if grid is not None else thetas[a:b]  # type: ignore[index]
        return (source, st, str(out), layout, i, grid, rows, modes, opts.solve)

    try:
        if opts.scheduler is None and not opts.workers:
            keep_model(model)  # this process: the caller's model
            for i in todo:
                check()
                finished(*solve_and_write(*args(i)))
        else:
            from .distributed import run_distributed  # Dask, imported when used

            run_distributed(todo, args, finished, opts.workers, opts.scheduler)
    finally:
        if bar is not None:
            bar.close()
    remove_partial_writes(out)  # a worker killed while writing left its temporary file
    counts = _counts(out)
    return AtlasRun(
        out,
        points,
        layout.chunks,
        len(todo),
        counts,
        time.perf_counter() - t0,
        spent[0],
        spent[1],
        int(spent[2]),
    )


def _points(model, grid_or_thetas, start) -> tuple[Grid | None, np.ndarray | None, dict]:
    if isinstance(grid_or_thetas, Grid):
        grid = grid_or_thetas
        if grid.actuated != tuple(model.actuated):
            raise InputError("atlas: the grid was made for another model (actuated names differ)")
    elif isinstance(grid_or_thetas, str | Mapping):
        grid = make_grid(model, grid_or_thetas, np.asarray(start.theta, float))
    else:
        thetas = np.array(grid_or_thetas, dtype=float)
        if thetas.ndim != 2 or thetas.shape[1] != model.k or not len(thetas):
            raise InputError(
                f"atlas: thetas must be (N, {model.k}) rows ({', '.join(model.actuated)}), "
                f"got shape {thetas.shape}"
            )
        digest = hashlib.sha256(np.ascontiguousarray(thetas).tobytes()).hexdigest()
        return None, thetas, {"grid": None, "thetas_sha256": digest}
    return grid, None, {"grid": grid.to_attrs(), "thetas_sha256": None}


def _prebuild(model) -> None:
    """Compile (or find in the disk cache) every kernel the workers load."""
    from ..codegen.library import tracker_library
    from ..follower.cvodes import engine

    tracker_library(model)
    engine(model, "compiled")


def _bar(progress: bool, total: int, initial: int):
    if not progress:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, unit="pt", desc="atlas", smoothing=0.05)


def _chunks_done(out: Path) -> int:
    """How many chunks of the store at ``out`` are written (0 when it is not created yet)."""
    from .store import done_mask, open_atlas

    try:
        return int(np.count_nonzero(done_mask(out, int(open_atlas(out)["done"].shape[0]))))
    except AtlasError:
        return 0


def _counts(out: Path) -> dict[int, int]:
    from .store import open_atlas

    status = np.asarray(open_atlas(out)["status"][:])
    codes, n = np.unique(status, return_counts=True)
    return {int(c): int(k) for c, k in zip(codes, n, strict=True)}
