"""What several benchmarks share: a warmed local Dask cluster, an example script as a module."""

from __future__ import annotations

import contextlib
import importlib.util
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def warm_cluster(workers: int, warm: Callable, *args) -> Iterator[tuple[object, float]]:
    """A ``LocalCluster`` of ``workers`` processes (one thread each) and its client, after
    ``warm(*args)`` ran on every worker (the model built, its kernels loaded: costs paid once
    per process, left out of the timings).

    Yields:
        ``(client, seconds)``: the client and the time the cluster took to be ready [s].
    """
    from distributed import Client, LocalCluster

    t = time.perf_counter()
    with (
        LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                     dashboard_address=":0") as cluster,
        Client(cluster) as client,
    ):  # fmt: skip
        client.run(warm, *args)
        yield client, time.perf_counter() - t


def example(name: str) -> ModuleType:
    """``examples/<name>.py`` as a module."""
    path = ROOT / "examples" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
