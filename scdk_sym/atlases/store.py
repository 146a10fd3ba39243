"""The atlas store: a Zarr group of chunked arrays with per-chunk done-markers.

Layout (``N`` points, ``k`` actuated joints, ``n`` workspace coordinates, chunks of ``C``
points along the first axis of every array):

* ``theta`` (N, k) float64, ``x`` (N, n) float64 (NaN where not solved), ``det_jp`` (N,)
  float64, ``status`` (N,) int8 (codes in the ``status_codes`` attribute), ``n_modes`` (N,)
  int16 (with modes only; -1 where the search failed);
* ``done`` (number of chunks,) uint8, one Zarr chunk per entry: 1 once every array of that
  chunk is written (the marker is written last, so a chunk interrupted mid-write is redone);
* attribute ``scdk_atlas``: what the store is for (model hash, grid or the hash of the
  explicit thetas, start, modes, chunk size, package version); a store whose attribute
  differs from the requested run is refused.

Written for zarr 3 (Python >= 3.11) and zarr 2.18 (Python 3.10, where zarr 3 does not
install): the only difference used is how a group's arrays and attributes are created.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import AtlasError, StoreMismatchError
from ..optional import require

#: Format of the store layout.
FORMAT = 1


def _zarr():
    hint = "'zarr>=3'" if sys.version_info >= (3, 11) else "'zarr>=2.18,<3'"
    return require("zarr", needed_for="the atlas", install=f"pip install {hint}", error=AtlasError)


@dataclass(frozen=True)
class Layout:
    """Sizes of a store."""

    points: int
    k: int
    n: int
    chunk: int
    modes: bool

    @property
    def chunks(self) -> int:
        return -(-self.points // self.chunk)

    def bounds(self, index: int) -> tuple[int, int]:
        """(start, stop) points of chunk ``index``."""
        return index * self.chunk, min(self.points, (index + 1) * self.chunk)


_OPEN: dict[tuple[str, Layout], Any] = {}


def create_or_check(path: str | Path, layout: Layout, meta: dict) -> np.ndarray:
    """Create the store, or check that an existing one is for the same run.

    Args:
        path: the store directory (``*.zarr``).
        layout: sizes.
        meta: the ``scdk_atlas`` attribute of this run (JSON-able).

    Returns:
        (chunks,) bool: the chunks already done.

    Raises:
        StoreMismatchError: the store exists and was written for another model, grid, start,
            chunk size, modes setting or package version.
        AtlasError: the path exists and is not an atlas store.
    """
    zarr = _zarr()
    p = Path(path)
    meta = json.loads(json.dumps(meta))  # the form it takes in JSON
    if p.exists() and any(p.iterdir()):
        try:
            group = zarr.open_group(str(p), mode="r")
        except Exception as exc:  # zarr raises several types for a non-store directory
            raise AtlasError(
                f"--out {str(p)!r} exists and is not an atlas store: choose a new path"
            ) from exc
        old = group.attrs.get("scdk_atlas")
        if old is None:
            raise AtlasError(
                f"--out {str(p)!r} is a Zarr store but not an atlas: choose a new path"
            )
        if old != meta:
            diff = sorted(key for key in set(old) | set(meta) if old.get(key) != meta.get(key))
            raise StoreMismatchError(
                f"store {str(p)!r} was written for another run (differs in: {', '.join(diff)}); "
                "use a new --out path or the same model, grid and options"
            )
        remove_partial_writes(p)
        return done_mask(p, layout.chunks, group)
    # built beside its place and renamed into it: a store is complete or absent
    tmp = p.with_name(f".{p.name}.{os.getpid()}.partial")
    if tmp.exists():
        shutil.rmtree(tmp)
    if hasattr(zarr, "create_array"):  # zarr 3
        group = zarr.open_group(str(tmp), mode="w-", attributes={"scdk_atlas": meta})
    else:  # zarr 2 (Python 3.10)
        group = zarr.open_group(str(tmp), mode="w-")
        group.attrs.update({"scdk_atlas": meta})
    N, C = layout.points, layout.chunk
    arrays = [
        ("theta", (N, layout.k), (C, layout.k), "float64", np.nan),
        ("x", (N, layout.n), (C, layout.n), "float64", np.nan),
        ("det_jp", (N,), (C,), "float64", np.nan),
        ("status", (N,), (C,), "int8", -1),
        *([("n_modes", (N,), (C,), "int16", -1)] if layout.modes else []),
        ("done", (layout.chunks,), (1,), "uint8", 0),
    ]
    for name, shape, chunks, dtype, fill in arrays:
        create = getattr(group, "create_array", None) or group.create_dataset
        create(name, shape=shape, chunks=chunks, dtype=dtype, fill_value=fill)
    os.replace(tmp, p)
    return np.zeros(layout.chunks, dtype=bool)


def remove_partial_writes(path: str | Path) -> int:
    """Delete the temporary files of chunk writes that never finished in a local store (Zarr
    writes ``<key>.<hex>.partial`` and renames it into place: a worker killed in between
    leaves it behind). Only under the store's lock, with no worker of this run writing.

    Returns:
        How many were deleted.
    """
    removed = 0
    for folder, _, names in os.walk(path):
        for name in names:
            if name.endswith(".partial"):
                with contextlib.suppress(FileNotFoundError):
                    os.remove(os.path.join(folder, name))
                    removed += 1
    return removed


def done_mask(path: str | Path, chunks: int, group=None) -> np.ndarray:
    """(chunks,) bool: the chunks of the store at ``path`` whose done-marker is written.

    On a local store the markers are read from the directory listing (a marker is stored
    only once written, as 1, and never with the fill value 0): one listing instead of a
    read per chunk, which for 10^4 chunks is milliseconds instead of seconds. Any other
    store is read through Zarr (``group``, opened when not given).
    """
    folder = Path(path) / "done"
    if (folder / "zarr.json").is_file():  # zarr 3, default chunk keys: done/c/<i>
        names = os.listdir(folder / "c") if (folder / "c").is_dir() else []
    elif (folder / ".zarray").is_file():  # zarr 2: done/<i>
        names = [n for n in os.listdir(folder) if not n.startswith(".")]
    else:
        group = group if group is not None else _zarr().open_group(str(path), mode="r")
        return np.asarray(group["done"][:]) == 1
    mask = np.zeros(chunks, dtype=bool)
    index = np.array([int(n) for n in names if n.isdigit()], dtype=np.int64)
    mask[index[index < chunks]] = True
    return mask


def write_chunk(path: str, layout: Layout, index: int, theta, result) -> None:
    """Write one chunk's arrays, then its done-marker."""
    group = _OPEN.get((path, layout))
    if group is None:
        group = _OPEN[(path, layout)] = _zarr().open_group(path, mode="r+")
    a, b = layout.bounds(index)
    group["theta"][a:b] = theta
    group["x"][a:b] = result.x
    group["det_jp"][a:b] = result.det_jp
    group["status"][a:b] = result.status
    if layout.modes:
        group["n_modes"][a:b] = result.n_modes
    group["done"][index] = 1


def open_atlas(path: str | Path):
    """The Zarr group of an atlas store (read-only).

    Raises:
        AtlasError: the path is not an atlas store.
    """
    zarr = _zarr()
    try:
        group = zarr.open_group(str(path), mode="r")
    except Exception as exc:
        raise AtlasError(f"cannot open atlas store {str(path)!r}: {exc}") from exc
    if "scdk_atlas" not in group.attrs:
        raise AtlasError(f"{str(path)!r} is not an atlas store (no scdk_atlas attribute)")
    return group
