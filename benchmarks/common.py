"""What several benchmarks share: one BLAS thread, a warmed local Dask cluster, an example
script or a test reference module as a module."""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import os
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


def pin_blas_threads() -> None:
    """One BLAS / OpenMP thread unless the environment says otherwise (oversubscribed threads
    make numpy many times slower on a shared machine); call it before numpy is imported."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def test_references(name: str) -> ModuleType:
    """``tests/<name>.py``, the references the tests use (e.g. ``stewart``), as a module."""
    tests = str(ROOT / "tests")
    if tests not in sys.path:
        sys.path.insert(0, tests)
    return importlib.import_module(name)


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
