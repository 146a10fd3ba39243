"""The chunk tasks of an atlas on Dask: a local cluster or a running scheduler.

At most a few tasks per worker are in flight, so the client's memory does not grow with the
grid. An interrupt or a failure kills the local workers at once (what a killed worker was
writing has no done-marker, so a rerun solves it again) and keeps Dask's closing logs quiet.
"""

from __future__ import annotations

import contextlib
import os
import sys
import uuid
from typing import Any

from ..errors import AtlasError
from ..interrupts import on_stop, stop_for
from ..optional import require
from .task import solve_and_write

#: Tasks in flight per worker.
IN_FLIGHT = 3
#: Seconds the client and the local cluster get to close (an interrupt must end in ~2 s).
CLOSE_TIMEOUT = 1.0


def run_distributed(todo, args, finished, workers, scheduler) -> None:
    """Run the chunk tasks ``todo`` (``args(i)``: the arguments of chunk ``i``) on a local
    cluster of ``workers`` processes or on ``scheduler``, at most :data:`IN_FLIGHT` per worker
    at a time, calling ``finished(*result)`` as each ends (see :func:`scdk_sym.atlas`)."""
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

        def submit(i: int):
            return client.submit(solve_and_write, *args(i), key=f"scdk-atlas-{run}-{i}", pure=False)

        for i in queue:
            pending.add(submit(i))
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
                pending.add(submit(nxt))
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

    for logger in _dask_loggers():
        logger.setLevel(logging.CRITICAL)


def _dask_loggers() -> list:
    """The loggers of :data:`_DASK_LOGGERS` and every logger below them that exists: Dask's
    configuration gives some their own level (``tornado.application``: ERROR), which a level
    set on the parent does not override."""
    import logging

    names = list(logging.Logger.manager.loggerDict)  # a copy: other threads may add loggers
    below = [n for n in names if n.split(".")[0] in _DASK_LOGGERS and n not in _DASK_LOGGERS]
    return [logging.getLogger(name) for name in (*_DASK_LOGGERS, *below)]


@contextlib.contextmanager
def _quiet_distributed():
    """While a killed cluster closes, Dask's loggers (and those of the event loop under it)
    say nothing below CRITICAL.

    Closing the connections of killed workers makes ``distributed`` log the closed comms
    with their tracebacks (at INFO); the failure is reported on its own.
    """
    loggers = _dask_loggers()
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
