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

import contextlib
import hashlib
import multiprocessing
import os
import sys
import time
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import AtlasError, InputError, Interrupted
from ..interrupts import check, on_stop, stop_for, stop_on_signals
from ..optional import require
from .chunk import STATUS, ModelSource, keep_model, model_source, solve_chunk, worker_model
from .grid import Grid, make_grid
from .lock import store_lock
from .store import FORMAT, Layout, create_or_check, remove_partial_writes, write_chunk

if TYPE_CHECKING:
    from ..results import Configuration
    from ..robot import Model

_pkg = "scdk_sym"
#: Points per chunk (one task; also the Zarr chunk length) unless told.
DEFAULT_CHUNK = 4096
#: Tasks in flight per worker.
IN_FLIGHT = 3
#: Seconds the client and the local cluster get to close (an interrupt must end in ~2 s).
CLOSE_TIMEOUT = 1.0
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


def _task(
    source: ModelSource,
    start: tuple[list[float], list[float]],
    out: str,
    layout: Layout,
    index: int,
    grid: Grid | None,
    thetas: np.ndarray | None,
    modes: bool,
    solve: bool = True,
) -> tuple[int, float, float, int]:
    """Solve and write chunk ``index``; returns (index, wall seconds, CPU seconds of this
    thread, points swept)."""
    t0, c0 = time.perf_counter(), time.thread_time()
    model = worker_model(source)
    cfg = model.configuration(np.array(start[0]), np.array(start[1]))
    a, b = layout.bounds(index)
    th = grid.thetas(a, b) if grid is not None else thetas
    assert th is not None  # _points gives a grid or the thetas
    if grid is not None:
        res = solve_chunk(model, cfg, th, modes, offset=a, shape=grid.shape, solve=solve)
    else:
        res = solve_chunk(model, cfg, th, modes, solve=solve)
    write_chunk(out, layout, index, th, res)
    return index, time.perf_counter() - t0, time.thread_time() - c0, res.swept


def atlas(
    model: Model,
    grid_or_thetas: str | Mapping[str, tuple[float, float, int]] | Grid | ArrayLike,
    out: str | Path,
    *,
    workers: int | None = None,
    scheduler: Any = None,
    modes: bool = False,
    solve: bool = True,
    start: Configuration | None = None,
    chunk: int = DEFAULT_CHUNK,
    progress: bool = True,
    on_chunk: Callable[[int, int], None] | None = None,
    wait: bool = False,
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
        workers: number of local worker processes (a Dask ``LocalCluster``, one thread
            each); ``None`` or 0 solves in this process, without Dask.
        scheduler: address of a running Dask scheduler (``"tcp://host:8786"``) or a
            ``distributed.Client``; its workers must see ``out`` and share the kernel cache
            directory or be able to compile (``$SCDK_CACHE_DIR``).
        modes: also store ``n_modes``, the number of real assembly modes at each point
            (:func:`scdk_sym.assembly_modes`, each point's set from its grid neighbour's).
        solve: the convergent solve at every point; False (with ``modes``): a mode map
            alone, every point's status 5 ("not solved"), ``x`` and ``det_jp`` NaN.
        start: the assembled start Configuration (default: ``model.home``).
        chunk: points per chunk (task and Zarr chunk); memory per task is O(chunk).
        progress: a tqdm progress bar on stderr.
        on_chunk: called on the client after each chunk as ``on_chunk(points_done, total)``.
        wait: when another run is writing ``out``, wait for it to end (then solve what it
            left) instead of refusing.

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
    start = _check_call(model, start, chunk, workers, scheduler)
    if not solve and not modes:
        raise InputError("atlas: solve=False leaves nothing to compute; pass modes=True")
    grid, thetas, what = _points(model, grid_or_thetas, start)
    assert grid is not None or thetas is not None  # _points gives one of them
    points = grid.size if grid is not None else len(thetas)  # type: ignore[arg-type]
    layout = Layout(points, model.k, len(model.workspace), int(min(chunk, max(points, 1))), modes)
    meta = _metadata(model, what, points, layout, start, modes, solve)
    out = Path(out)
    with stop_on_signals(), store_lock(out, wait=wait):
        try:
            plan = _Plan(model, out, layout, grid, thetas, start, modes, solve, progress,
                         on_chunk)  # fmt: skip
            return _run(plan, meta, workers, scheduler, t0)
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


def _check_call(model, start, chunk, workers, scheduler) -> Any:
    """The start of an :func:`atlas` call, validated with its other options (see there)."""
    from ..solvers.sc import singular_start, validate_start

    start = validate_start(model, start)
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
    modes: bool
    solve: bool
    progress: bool
    on_chunk: Callable[[int, int], None] | None


def _run(plan: _Plan, meta: dict, workers, scheduler, t0: float) -> AtlasRun:
    """The run of :func:`atlas` on its checked inputs, under the store's lock."""
    model, out, layout, grid, thetas, start = (
        plan.model, plan.out, plan.layout, plan.grid, plan.thetas, plan.start
    )  # fmt: skip
    modes, progress, on_chunk, points = plan.modes, plan.progress, plan.on_chunk, layout.points
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
        return (source, st, str(out), layout, i, grid, rows, modes, plan.solve)

    try:
        if scheduler is None and not workers:
            keep_model(model)  # this process: the caller's model
            for i in todo:
                check()
                finished(*_task(*args(i)))
        else:
            _distributed(todo, args, finished, workers, scheduler)
    finally:
        if bar is not None:
            bar.close()
    remove_partial_writes(out)  # a worker killed while writing left its temporary file
    counts = _counts(out, len(STATUS))
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


def _distributed(todo, args, finished, workers, scheduler) -> None:
    require(
        "distributed",
        needed_for="an atlas with workers or a scheduler",
        install="pip install 'dask[distributed]'",
        error=AtlasError,
    )
    from distributed import Client, LocalCluster, as_completed

    cluster = client = None
    hidden = contextlib.ExitStack()
    try:
        if scheduler is None:
            hidden.enter_context(_main_not_reimported())
            hidden.enter_context(on_stop(_silence_distributed))
            cluster = LocalCluster(
                n_workers=int(workers), threads_per_worker=1, processes=True, dashboard_address=":0"
            )
            client = Client(cluster)
        elif isinstance(scheduler, str):
            client = Client(scheduler)
        else:
            client = scheduler
        slots = IN_FLIGHT * max(1, len(client.scheduler_info().get("workers", {})))
        queue = iter(todo)
        run = uuid.uuid4().hex[:12]  # task keys unique to this call
        pending = as_completed()
        for i in queue:
            pending.add(client.submit(_task, *args(i), key=f"scdk-atlas-{run}-{i}", pure=False))
            if pending.count() >= slots:
                break
        for fut in pending:
            try:
                done_task = fut.result()
            except Exception as exc:
                from ..errors import ScdkError

                if isinstance(exc, ScdkError):
                    raise
                raise AtlasError(
                    f"atlas: a task failed ({type(exc).__name__}: {exc}); re-run the same "
                    "command to resume from the chunks already written"
                ) from exc
            finished(*done_task)
            nxt = next(queue, None)
            if nxt is not None:
                pending.add(
                    client.submit(_task, *args(nxt), key=f"scdk-atlas-{run}-{nxt}", pure=False)
                )
    except BaseException as exc:
        if cluster is not None:  # an interrupt or a failure: end the chunks in flight now
            if isinstance(exc, KeyboardInterrupt) or stop_for(exc) is not None:
                _silence_distributed()  # the closing loop's callbacks outlive this call
            else:
                hidden.enter_context(_quiet_distributed())
            _kill_workers(cluster)
        raise
    finally:
        with contextlib.suppress(Exception):
            if client is not None and client is not scheduler:
                client.close(timeout=CLOSE_TIMEOUT)
            if cluster is not None:
                cluster.close(timeout=CLOSE_TIMEOUT)
        if cluster is not None:
            # closed as far as it closes in CLOSE_TIMEOUT (after an interrupt its killed
            # workers may not answer): Dask's exit hook must not wait 10 s more for it
            cluster.shutdown_on_close = False
        hidden.close()


#: The loggers of Dask and of the event loop under it.
_DASK_LOGGERS = ("distributed", "tornado", "asyncio")


def _silence_distributed() -> None:
    """After a stop: Dask's loggers say nothing below CRITICAL for the rest of the process.

    Run in the signal handler (before the main thread's raise lets Dask cancel its futures
    on the event loop, which logs a traceback), and again on the way out of an interrupt. The
    levels are not restored: the closing cluster's callbacks run after the call has returned,
    and the process is stopping.
    """
    import logging

    for name in _DASK_LOGGERS:
        logging.getLogger(name).setLevel(logging.CRITICAL)


@contextlib.contextmanager
def _quiet_distributed():
    """While a killed cluster closes, Dask's loggers (and those of the event loop under it)
    say nothing below CRITICAL.

    Closing the connections of killed workers makes ``distributed`` log the closed comms
    with their tracebacks (at INFO); the failure is reported on its own.
    """
    import logging

    loggers = [logging.getLogger(name) for name in _DASK_LOGGERS]
    levels = [logger.level for logger in loggers]
    _silence_distributed()
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels, strict=True):
            logger.setLevel(level)


def _kill_workers(cluster) -> None:
    """SIGKILL the worker processes of a local cluster (their nannies stay to be closed).

    What a killed worker was writing has no done-marker yet, so a rerun solves it again:
    nothing finished is lost, and closing does not wait for chunks that take seconds.
    """
    import signal

    for nanny in list(getattr(cluster, "workers", {}).values()):
        pid = getattr(getattr(getattr(nanny, "process", None), "process", None), "pid", None)
        if pid:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)


@contextlib.contextmanager
def _main_not_reimported():
    """While local workers live, their processes do not run the caller's ``__main__``.

    A spawned process re-imports the main script (or module) of its parent before it
    unpickles its task, so a script that calls :func:`atlas` with workers outside an ``if
    __name__ == "__main__":`` block would start workers within workers. The workers only
    run this package's tasks, so they are started as from an interactive session: the main
    module's ``__file__`` and ``__spec__`` are hidden from multiprocessing meanwhile.
    """
    main = sys.modules.get("__main__")
    names = ("__file__", "__spec__")
    saved: dict[str, Any] = {k: getattr(main, k) for k in names if hasattr(main, k)}
    try:
        if main is not None:
            if hasattr(main, "__file__"):
                delattr(main, "__file__")
            main.__spec__ = None
        yield
    finally:
        if main is not None:
            for k, v in saved.items():
                setattr(main, k, v)


def _chunks_done(out: Path) -> int:
    """How many chunks of the store at ``out`` are written (0 when it is not created yet)."""
    from .store import done_mask, open_atlas

    try:
        return int(np.count_nonzero(done_mask(out, int(open_atlas(out)["done"].shape[0]))))
    except AtlasError:
        return 0


def _counts(out: Path, size: int) -> dict[int, int]:
    from .store import open_atlas

    status = np.asarray(open_atlas(out)["status"][:])
    codes, n = np.unique(status, return_counts=True)
    return {int(c): int(k) for c, k in zip(codes, n, strict=True)}
