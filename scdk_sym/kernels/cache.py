"""On-disk cache of expensive products (compiled kernels, start systems), keyed by content
hashes.

Every entry is written atomically and sealed: the artefact is written to a temporary file
beside its place, its SHA-256 is written next to it (``NAME.sha256``), and both are renamed
into place. An entry is used only when its digest matches; a missing digest, a truncated or
foreign file (what a killed compile, a full disk or another program leaves) is rebuilt with
one line on stderr, never a failure (:func:`cached_file`, :func:`read_entry`).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")

#: Suffix of the digest written beside each cache entry.
DIGEST_SUFFIX = ".sha256"


def cache_dir() -> Path:
    """The cache directory: ``$SCDK_CACHE_DIR``, else ``$XDG_CACHE_HOME/scdk_sym``, else
    ``~/.cache/scdk_sym`` (created on demand)."""
    env = os.environ.get("SCDK_CACHE_DIR")
    if env:
        d = Path(env)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        d = Path(base) / "scdk_sym"
    d.mkdir(parents=True, exist_ok=True)
    return d


def clear_cache() -> int:
    """Delete every cached product; returns the number of entries removed (an artefact and
    its digest count as one)."""
    d = cache_dir()
    n = 0
    for entry in d.iterdir():
        if entry.is_dir():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)
        n += not entry.name.endswith(DIGEST_SUFFIX)
    return n


def digest_path(target: Path) -> Path:
    """Where the SHA-256 of the cache entry ``target`` is kept."""
    return target.with_name(target.name + DIGEST_SUFFIX)


def file_digest(path: Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def damage(target: Path) -> str | None:
    """Why the cache entry ``target`` cannot be used (``"missing"`` when it was never
    written), or ``None`` when its bytes match its digest."""
    if not target.exists():
        return "missing"
    seal = digest_path(target)
    try:
        expected = seal.read_text().strip()
    except OSError:
        return "unsealed (no digest: an interrupted write or an older version)"
    try:
        actual = file_digest(target)
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    if actual != expected:
        return f"damaged (SHA-256 {actual[:12]}, sealed as {expected[:12]})"
    return None


def notice(message: str) -> None:
    """One line on stderr about the cache."""
    print(f"scdk_sym cache: {message}", file=sys.stderr, flush=True)


def write_entry(target: Path, write: Callable[[Path], object]) -> Path:
    """Write the cache entry ``target`` atomically: ``write(partial)`` makes the artefact in
    a temporary file beside it, which is sealed with its digest and renamed into place, so a
    reader never sees a partial file as an intact one (a reader that meets the artefact
    before its digest, or two writers' files crossed, rebuilds; it never fails).

    Returns:
        ``target``.
    """
    tag = f".{os.getpid()}-{uuid.uuid4().hex[:8]}.tmp"
    partial = target.with_name(target.name + tag)
    seal = digest_path(target)
    seal_partial = seal.with_name(seal.name + tag)
    try:
        write(partial)
        seal_partial.write_text(file_digest(partial) + "\n")
        os.replace(seal_partial, seal)
        os.replace(partial, target)
    finally:
        partial.unlink(missing_ok=True)
        seal_partial.unlink(missing_ok=True)
    return target


def cached_file(target: Path, build: Callable[[Path], object], what: str) -> Path:
    """The intact cache entry ``target``, built by ``build(path)`` when missing; a damaged,
    unsealed or foreign one is rebuilt with one line on stderr (:func:`notice`).

    Args:
        target: the entry's path (its name carries the content hash of its inputs).
        build: writes the artefact to the path it is given.
        what: what the entry is, for the notice (e.g. ``"kernel library"``).

    Returns:
        ``target``, intact.
    """
    why = damage(target)
    if why is None:
        return target
    if why != "missing":
        notice(f"{what} {target.name} is {why}; rebuilding it")
    return write_entry(target, build)


def read_entry(target: Path, read: Callable[[Path], T], what: str) -> T | None:
    """The cache entry ``target`` read by ``read(path)``, or ``None`` when there is none to
    use: missing (silently), or damaged, unsealed or unreadable (one line on stderr, and the
    entry removed so the caller's rebuild replaces it). ``read`` may return ``None`` to
    refuse an entry it finds stale."""
    why = damage(target)
    if why == "missing":
        return None
    if why is None:
        try:
            return read(target)
        except Exception as exc:  # noqa: BLE001 - any unreadable entry is rebuilt
            first = (str(exc).splitlines() or [""])[0][:80]
            why = f"unreadable ({type(exc).__name__}: {first})"
    notice(f"{what} {target.name} is {why}; rebuilding it")
    target.unlink(missing_ok=True)
    digest_path(target).unlink(missing_ok=True)
    return None
