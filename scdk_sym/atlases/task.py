"""One task of an atlas: a chunk of points solved and written into the store.

A worker process runs it by reference (Dask pickles the function by name), so it lives in a
module of its own that the client's run loop and the distributed scheduling both import.
"""

from __future__ import annotations

import time

import numpy as np

from .chunk import ModelSource, solve_chunk, worker_model
from .grid import Grid
from .store import Layout, write_chunk


def solve_and_write(
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
