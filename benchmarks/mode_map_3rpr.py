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
  (points per busy worker-second), as a mode map alone (``solve=False``) and with the
  convergent solves (a point the C sweep leaves, past a fold of its straight path or
  unreachable, costs a full ``sc.solve``);
* the check: the walk's counts against the baseline's at its points.

    OMP_NUM_THREADS=1 python benchmarks/mode_map_3rpr.py [--n 40] [--baseline 200] [--chunk N]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from common import example, warm_cluster  # noqa: E402

import scdk_sym as sc  # noqa: E402
from scdk_sym.atlases import make_grid  # noqa: E402
from scdk_sym.atlases.chunk import mode_counts, model_source  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=40, help="values per leg (n^2 points)")
    parser.add_argument("--baseline", type=int, default=200, help="points solved from scratch")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--chunk", type=int, default=0, help="points per worker task (default: 2 per worker)"
    )
    args = parser.parse_args()
    ex = example("atlas_3rpr_singularity")
    model = ex.build_model()
    home = model.home
    spec = ex.grid(args.n)
    grid = make_grid(model, spec, home.theta)
    thetas = grid.thetas(0, grid.size)
    sc.assembly_modes(model, home.theta, backend="compiled")  # start system, kernels
    mode_counts(model, thetas[:50], 0, grid.shape)  # as on the workers (warm_worker)

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
        for solve in (False, True):
            run = sc.atlas(model, spec, Path(tmp) / f"local{solve}.zarr", start=home,
                           modes=True, solve=solve, progress=False)  # fmt: skip
            report(run, solve, "in process", base, pick, base_n)
        with warm_cluster(args.workers, warm_worker, model_source(model), spec) as (client, _):
            chunk = args.chunk or grid.size // (2 * args.workers) or 1
            for solve in (False, True):
                run = sc.atlas(model, spec, Path(tmp) / f"workers{solve}.zarr", start=home,
                               modes=True, solve=solve, scheduler=client, chunk=chunk,
                               progress=False)  # fmt: skip
                report(run, solve, f"{args.workers} workers", base, pick, base_n)


def report(run, solve: bool, where: str, base: float, pick, base_n) -> None:
    """One line of an atlas run: its rate against the baseline's, its stored counts against
    the baseline's at its points."""
    what = "mode map alone (solve=False)" if not solve else "with the convergent solves"
    rate = run.points / run.busy
    same = bool(np.array_equal(sc.open_atlas(run.out)["n_modes"][:][pick], base_n))
    print(f"sc.atlas(modes=True), {what}, {where}: {rate:.0f} points per busy worker-second "
          f"({rate / base:.2f}x baseline; {run.points / run.cpu:.0f} per CPU-second of the "
          f"tasks' threads; counts equal to the baseline at its {len(pick)} points: "
          f"{same})")  # fmt: skip


def warm_worker(source, spec) -> None:
    """Build the model, its start system and kernels on a worker, walk 50 points of the grid
    and import Zarr (the C libraries loaded, the kernels' maps made, the store's module
    imported: costs paid once per process)."""
    import zarr  # noqa: F401

    from scdk_sym.atlases.chunk import _tracker, worker_model

    model = worker_model(source)
    _tracker(model)
    sc.assembly_modes(model, model.home.theta, backend="compiled")
    grid = make_grid(model, spec, model.home.theta)
    mode_counts(model, grid.thetas(0, min(50, grid.size)), 0, grid.shape)


if __name__ == "__main__":
    main()
