"""On-disk cache of expensive products (compiled kernels), keyed by content hashes."""

from __future__ import annotations

import os
import shutil
from pathlib import Path


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
    """Delete every cached product; returns the number of entries removed."""
    d = cache_dir()
    n = 0
    for entry in d.iterdir():
        if entry.is_dir():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)
        n += 1
    return n
