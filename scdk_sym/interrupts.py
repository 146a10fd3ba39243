"""Stopping long runs on SIGINT and SIGTERM, promptly and without losing finished work.

Within :func:`stop_on_signals` (the CLI wraps every command in it; :func:`scdk_sym.atlas`
wraps its run), SIGINT and SIGTERM raise :class:`~scdk_sym.errors.Interrupted` in the main
thread and set a flag. The raise stops Python code where it is; the flag catches the places
where a library turns the raise into its own error (CasADi's integrators report an interrupt
as a ``RuntimeError``): code that catches such errors calls :func:`check` first, so an
interrupt is never taken for a failed point. Where a library turns the raise into some other
error on its way out (CasADi's argument conversion reports a ``NotImplementedError``), the
error leaving :func:`stop_on_signals` after a signal is the stop: :func:`stop_for` names it.
A second signal while the first is being handled is the same stop. CasADi also prints the
interrupt it turns into an error (``rhs failed: KeyboardInterrupt``) on ``sys.stderr``: after a
signal, :class:`_QuietStop` drops those lines, and only those.
"""

from __future__ import annotations

import contextlib
import re
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from types import FrameType

from .errors import Interrupted

#: The signals that stop a run.
SIGNALS = (signal.SIGINT, signal.SIGTERM)

_state: dict[str, object] = {"signal": None, "depth": 0}

#: What runs in the signal handler, before the raise (see :func:`on_stop`).
_hooks: list[Callable[[], None]] = []


def requested() -> str | None:
    """The name of the signal that asked to stop (``None`` when none did)."""
    sig = _state["signal"]
    return None if sig is None else str(sig)


def check() -> None:
    """Raise :class:`~scdk_sym.errors.Interrupted` when a stop was requested.

    Raises:
        Interrupted: SIGINT or SIGTERM arrived within :func:`stop_on_signals`.
    """
    sig = requested()
    if sig is not None:
        raise Interrupted(f"stopped by {sig}", sig)


def stop_for(exc: BaseException) -> Interrupted | None:
    """The stop an exception stands for: itself when it is an :class:`Interrupted`, an
    :class:`Interrupted` (caused by it) when it was raised after a stop was requested, else
    ``None`` (a real error)."""
    if isinstance(exc, Interrupted):
        return exc
    sig = requested()
    if sig is None or not isinstance(exc, Exception):
        return None
    stop = Interrupted(f"stopped by {sig}", sig)
    stop.__cause__ = exc
    return stop


#: What CasADi writes, in pieces, for an evaluation it stopped on an interrupt.
_CASADI_STOP = re.compile(r"\w+ failed: |KeyboardInterrupt|Interrupted|\n")


class _QuietStop:
    """``sys.stderr`` within :func:`stop_on_signals`: everything passes through, except, once a
    signal arrived, the pieces of CasADi's ``NAME failed: KeyboardInterrupt`` lines."""

    def __init__(self, stream):
        self._stream = stream
        self._dropping = False

    def write(self, text: str) -> int:
        if requested() is not None and _CASADI_STOP.fullmatch(text):
            if text.endswith("failed: "):
                self._dropping = True
            if self._dropping:
                if text == "\n":
                    self._dropping = False
                return len(text)
        self._dropping = False
        return self._stream.write(text)

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def _handler(signum: int, frame: FrameType | None) -> None:
    name = signal.Signals(signum).name
    _state["signal"] = name
    for hook in list(_hooks):
        with contextlib.suppress(Exception):
            hook()
    raise Interrupted(f"stopped by {name}", name)


@contextlib.contextmanager
def on_stop(hook: Callable[[], None]) -> Iterator[None]:
    """Within the block, ``hook()`` runs in the signal handler when SIGINT or SIGTERM
    arrives, before :class:`~scdk_sym.errors.Interrupted` is raised: before any other thread
    can react to the raise (Dask's event loop logs the futures it cancels). Its errors are
    ignored."""
    _hooks.append(hook)
    try:
        yield
    finally:
        _hooks.remove(hook)


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """SIGINT and SIGTERM raise :class:`~scdk_sym.errors.Interrupted` inside the block (see
    the module docs); the previous handlers are restored after it. Nested uses share one
    installation; outside the main thread (where Python cannot install handlers) it does
    nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    depth = int(_state["depth"])  # type: ignore[call-overload]
    previous = {}
    stderr = sys.stderr
    if depth == 0:
        _state["signal"] = None
        previous = {s: signal.signal(s, _handler) for s in SIGNALS}
        sys.stderr = _QuietStop(stderr)
    _state["depth"] = depth + 1
    try:
        yield
    except Exception as exc:
        stop = stop_for(exc)
        if stop is None:
            raise
        raise stop from exc
    finally:
        _state["depth"] = depth
        if depth == 0:
            for s, h in previous.items():
                signal.signal(s, h)
            if isinstance(sys.stderr, _QuietStop):
                sys.stderr = stderr
            _state["signal"] = None
