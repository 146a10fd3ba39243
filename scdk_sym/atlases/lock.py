"""One writer per atlas store: a lock file beside the store.

``STORE.lock`` holds an exclusive ``flock`` for as long as a run writes ``STORE`` and says
who holds it (process id, host, start time, JSON). The kernel releases the lock when its
process ends, however it ends, so a lock file left by a killed run is stale by construction:
the next run takes it over and says so. A second run while the first is alive refuses in one
line (:class:`~scdk_sym.errors.StoreLockedError`), or waits for it (``wait=True``) and then
finds the chunks already done.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from ..errors import StoreLockedError


def lock_path(store: str | Path) -> Path:
    """The lock file of a store: ``STORE.lock`` beside it."""
    p = Path(store)
    return p.with_name(p.name + ".lock")


def _holder(fd: int) -> dict:
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        return json.loads(os.read(fd, 4096).decode() or "{}")
    except (OSError, ValueError):
        return {}


def _describe(holder: dict) -> str:
    if not holder:
        return "another process"
    since = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(holder.get("started", 0)))
    return f"process {holder.get('pid', '?')} on {holder.get('host', '?')} (since {since})"


@contextlib.contextmanager
def store_lock(store: str | Path, *, wait: bool = False) -> Iterator[dict]:
    """Hold the store's write lock for the duration of the ``with`` block.

    Args:
        store: the store directory.
        wait: block until the lock is free instead of refusing.

    Yields:
        What the lock file said before it was taken (empty when it was free or new): a
        stale holder's ``pid``/``host`` when a killed run left it.

    Raises:
        StoreLockedError: another live run holds the lock (and ``wait`` is False).
    """
    path = lock_path(store)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            if not wait:
                os.close(fd)
                raise StoreLockedError(
                    f"atlas store {str(store)!r} is being written by {_describe(holder)}; "
                    f"wait for it to end (or stop it) and re-run, or pass --wait (wait=True) "
                    f"(lock file {str(path)!r})",
                    str(store),
                    holder,
                ) from None
            print(
                f"scdk atlas: waiting for {_describe(holder)} to finish writing {str(store)!r}",
                file=sys.stderr,
                flush=True,
            )
            fcntl.flock(fd, fcntl.LOCK_EX)
        # the file may have been removed (and a new one made) between our open and flock
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        previous = _holder(fd)
        if previous:
            print(
                f"scdk atlas: taking over a stale lock of {_describe(previous)}, "
                f"which no longer runs",
                file=sys.stderr,
                flush=True,
            )
        me = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.time()}
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        os.write(fd, json.dumps(me).encode())
        os.fsync(fd)
        yield previous
    finally:
        # removed while held: a run that opens it after this sees a new inode and retries
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)
