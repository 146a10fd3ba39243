"""``auto`` never makes a user wait on a compiler.

Where ``backend="auto"`` resolves to a compiled backend (``c`` or ``compiled``) whose products
this model has not built yet in this process, :func:`without_waiting` starts building them in a
background thread (the compiled libraries land in the on-disk cache, as a call with that
backend would leave them: the thread makes that call once, at home), says so once per model
on stderr, and hands back ``cvodes`` for this call. Once the thread is done, ``auto`` runs the
compiled backend, whose products the thread stored in ``model.products``. An explicit
``backend="c"`` or ``"compiled"`` still waits (with the ``compiling kernels for ...`` line).

The compiler runs in a child process, outside the interpreter's lock, so the answers in the
meantime cost what ``cvodes`` costs. A build still running when the program ends is finished
before it exits (one line says so; Ctrl-C skips it), so that the next run finds the libraries
in the cache: a one-shot ``scdk solve --backend auto`` prints its answer first.
``SCDK_AUTO_WAITS=1`` restores the waiting behaviour (``auto`` then compiles in the call).
"""

from __future__ import annotations

import atexit
import concurrent.futures.thread  # noqa: F401 - its exit hook first (see the end of this module)
import os
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..backends import Resolved
from ..codegen.library import cached_tracker
from ..products import BACKGROUND_BUILDS, C_TRACKER

#: Backends whose first use compiles.
COMPILED = ("c", "compiled")

_lock = threading.Lock()
#: The builds started in this process (what the exit hook waits for).
_STARTED: list[threading.Thread] = []


@dataclass
class _Builds:
    """One model's background builds (a product of the model: ``BACKGROUND_BUILDS``).

    Attributes:
        jobs: backend -> the thread building it.
        ready: the backends built.
        failed: backend -> why its build failed (``auto`` then keeps answering with cvodes).
        said: the one line on stderr was printed.
    """

    jobs: dict[str, threading.Thread] = field(default_factory=dict)
    ready: set[str] = field(default_factory=set)
    failed: dict[str, str] = field(default_factory=dict)
    said: bool = False


def _builds(model: Any) -> _Builds:
    return model.products.get(BACKGROUND_BUILDS, _Builds)


def without_waiting(model: Any, backend: Resolved, warm: Callable[[Resolved], object]) -> Resolved:
    """The backend to run now: ``backend`` itself unless it is ``auto``'s choice of a compiled
    backend not built yet for ``model``; then ``cvodes``, with ``warm(backend)`` (a call with
    that backend) started in a background thread that builds it.

    Args:
        model: the model.
        backend: the resolved backend of the call.
        warm: makes one call of the function with a given backend (at home), building its
            products.
    """
    if getattr(backend, "asked", None) != "auto" or backend not in COMPILED:
        return backend
    if os.environ.get("SCDK_AUTO_WAITS") == "1":
        return backend
    state = _builds(model)
    name = str(backend)
    if name in state.ready or (name == "c" and _c_tracker_at_hand(model)):
        return backend  # built, or in the cache from an earlier run: loads without compiling
    if name in state.failed:  # no compiler, or it failed: cvodes, as auto would without one
        return Resolved("cvodes", "auto")
    with _lock:
        if name not in state.jobs:
            job = threading.Thread(target=_build, args=(state, name, warm), daemon=True,
                                   name=f"{model.name}-{name}")  # fmt: skip
            state.jobs[name] = job
            _STARTED.append(job)
            job.start()
        if not state.said:
            state.said = True
            print(
                f"note: building the {name} kernels of {model.name} in the background; "
                "backend='auto' answers with cvodes until they are ready",
                file=sys.stderr,
                flush=True,
            )
    return Resolved("cvodes", "auto")


def _c_tracker_at_hand(model: Any) -> bool:
    """The model's C tracker is loaded, or in the on-disk cache (the loaded one is checked
    first: the cache's lookup hashes the package's sources)."""
    return model.products.peek(C_TRACKER) is not None or cached_tracker(model) is not None


def _build(state: _Builds, name: str, warm: Callable[[Resolved], object]) -> None:
    try:
        warm(Resolved(name, name))
    except BaseException as exc:  # noqa: BLE001 - recorded: auto keeps answering with cvodes
        state.failed[name] = f"{type(exc).__name__}: {exc}"
        return
    state.ready.add(name)


def wait(model: Any, timeout: float | None = None) -> bool:
    """Wait for the background builds of ``model`` (every backend); True when none is left
    running. For scripts that want the compiled backend from the next call on."""
    with _lock:
        jobs = list(_builds(model).jobs.values())
    for job in jobs:
        job.join(timeout)
    return not any(job.is_alive() for job in jobs)


def ready(model: Any, backend: str) -> bool:
    """Whether ``auto`` runs ``backend`` for ``model`` now (built in the background)."""
    return str(backend) in _builds(model).ready


def _finish_at_exit() -> None:
    """Let the running builds end before the interpreter does (their libraries then land in
    the cache for the next run)."""
    with _lock:
        alive = [job for job in _STARTED if job.is_alive()]
    if not alive:
        return
    names = ", ".join(job.name for job in alive)
    print(f"note: finishing the background build ({names}) before exiting; Ctrl-C skips it",
          file=sys.stderr, flush=True)  # fmt: skip
    try:
        for job in alive:
            job.join()
    except KeyboardInterrupt:
        pass


# run before the interpreter's threads shut down, and before concurrent.futures stops taking
# work (its hook, registered at its import, runs after this one: they run in reverse order),
# for the compiler's thread pool to finish the build
_register = getattr(threading, "_register_atexit", None)
if _register is not None:
    _register(_finish_at_exit)
else:  # pragma: no cover - an interpreter without the hook: at least try at exit
    atexit.register(_finish_at_exit)
