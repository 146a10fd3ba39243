"""Certified assembly-mode map of the 3-RPR over a 40 x 40 leg grid, against the homotopy
from scratch at every point.

The slice of ``examples/atlas_3rpr_singularity.py`` (leg_1 held, leg_2 x leg_3 in ``--n``
values each). Prints, measured in the same run (BLAS pinned to one thread):

* the baseline: ``sc.assembly_modes(model, theta, backend="compiled")`` (the parameter
  homotopy from the start system, the Krawczyk certificates) at ``--baseline`` seeded points
  of the grid;
* the mode walk alone (``scdk_sym.atlases.chunk.mode_counts`` over the whole grid as one
  chunk: each point's certified set from its grid neighbour's complete root set), its rate
  and the ratio to the baseline, and how many sets came from a neighbour;
* ``sc.atlas(..., modes=True)`` in this process and on ``--workers`` local worker processes
  (points per busy worker-second; the convergent solves included: a point the C sweep
  leaves, past a fold of its straight path or unreachable, costs a full ``sc.solve``);
* the check: the walk's counts against the baseline's at its points.

    OMP_NUM_THREADS=1 python benchmarks/mode_map_3rpr.py [--n 40] [--baseline 200]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from distributed import Client, LocalCluster  # noqa: E402

import scdk_sym as sc  # noqa: E402
from scdk_sym.atlases import make_grid  # noqa: E402
from scdk_sym.atlases.chunk import mode_counts, model_source  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def example():
    path = ROOT / "examples" / "atlas_3rpr_singularity.py"
    spec = importlib.util.spec_from_file_location("atlas_3rpr_singularity", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=40, help="values per leg (n^2 points)")
    parser.add_argument("--baseline", type=int, default=200, help="points solved from scratch")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    ex = example()
    model = ex.build_model()
    home = model.home
    spec = ex.grid(args.n)
    grid = make_grid(model, spec, home.theta)
    thetas = grid.thetas(0, grid.size)
    sc.assembly_modes(model, home.theta, backend="compiled")  # start system, kernels

    rng = np.random.default_rng(0)
    pick = np.sort(rng.choice(grid.size, min(args.baseline, grid.size), replace=False))
    base_n = np.empty(len(pick), dtype=int)
    t = time.perf_counter()
    for j, i in enumerate(pick):
        sols = sc.assembly_modes(model, thetas[i], backend="compiled")
        base_n[j] = len(sols) if sols.certified else -1
    base = len(pick) / (time.perf_counter() - t)
    print(f"3-RPR slice, {args.n} x {args.n} = {grid.size} points")
    print(f"{'homotopy from scratch (baseline)':<34} {base:>8.0f} points/s")

    t = time.perf_counter()
    n_modes, continued = mode_counts(model, thetas, 0, grid.shape)
    dt = time.perf_counter() - t
    rate = grid.size / dt
    same = bool(np.array_equal(n_modes[pick], base_n))
    counts = dict(zip(*(a.tolist() for a in np.unique(n_modes, return_counts=True)), strict=True))
    print(f"{'mode walk (one chunk)':<34} {rate:>8.0f} points/s ({rate / base:.2f}x baseline; "
          f"{continued} of {grid.size} sets from a neighbour; counts {counts}; equal to the "
          f"baseline at its {len(pick)} points: {same})")  # fmt: skip

    with tempfile.TemporaryDirectory() as tmp:
        run = sc.atlas(model, spec, Path(tmp) / "local.zarr", start=home, modes=True,
                       progress=False)  # fmt: skip
        print(f"{'sc.atlas(modes=True), in process':<34} {run.points / run.busy:>8.0f} points "
              f"per busy second ({run.points / run.busy / base:.2f}x baseline)")  # fmt: skip
        with (
            LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                         dashboard_address=":0") as cluster,
            Client(cluster) as client,
        ):  # fmt: skip
            client.run(warm_worker, model_source(model))
            run = sc.atlas(model, spec, Path(tmp) / "workers.zarr", start=home, modes=True,
                           scheduler=client, chunk=grid.size // (2 * args.workers) or 1,
                           progress=False)  # fmt: skip
        print(f"{f'sc.atlas(modes=True), {args.workers} workers':<34} "
              f"{run.points / run.busy:>8.0f} points per busy worker-second "
              f"({run.points / run.busy / base:.2f}x baseline)")  # fmt: skip


def warm_worker(source) -> None:
    """Build the model, its start system and kernels on a worker (before timing)."""
    from scdk_sym.atlases.chunk import _tracker, worker_model

    model = worker_model(source)
    _tracker(model)
    sc.assembly_modes(model, model.home.theta, backend="compiled")


if __name__ == "__main__":
    main()
