"""Points per busy worker-second of ``sc.atlas`` on the 6-6 hexapod over an 8^6 leg grid.

``models/stewart_gough`` from its home, every leg length over ``home +- --half`` [m] in
``--n`` values (8^6 = 262,144 points). Prints, measured in the same run (BLAS pinned to one
thread):

* the baseline: a loop of direct solves from home, one ``<prefix>_solve_convergent`` call of
  the same compiled C library per point (what each point costs without its neighbour), over
  ``--baseline`` seeded points of the grid;
* ``sc.atlas`` on a ``LocalCluster`` of ``--workers`` worker processes (started, and the
  model loaded on each, before the clock starts; the store written): points per busy
  worker-second (the chunk tasks' time summed over workers) and per CPU second, and the
  ratio to the baseline;
* ``sc.atlas`` in this process (no Dask) on the same grid, and its ratio to the per-worker
  rate;
* the check: ``--check`` seeded points of each store against ``sc.solve(model, theta,
  start=home, branch="convergent", backend="compiled")`` (the solve the atlas documents its
  points equal to): the largest |x - sc.solve| and whether the same points are unsolved.

    OMP_NUM_THREADS=1 python benchmarks/atlas_hexapod.py [--n 8] [--half 0.05] [--workers 2]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from common import warm_cluster  # noqa: E402

import scdk_sym as sc  # noqa: E402
from scdk_sym.atlases import make_grid, open_atlas  # noqa: E402
from scdk_sym.atlases.chunk import model_source  # noqa: E402
from scdk_sym.codegen.library import OK_PATH, tracker_library  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=8, help="values per leg (n^6 points)")
    parser.add_argument("--half", type=float, default=0.05, help="half-range of a leg [m]")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--chunk", type=int, default=4096)
    parser.add_argument("--baseline", type=int, default=2000, help="points of the direct loop")
    parser.add_argument("--check", type=int, default=200, help="points checked by sc.solve")
    args = parser.parse_args()
    model = sc.load_model(ROOT / "models" / "stewart_gough")
    home = model.home
    spec = {name: (t - args.half, t + args.half, args.n)
            for name, t in zip(model.actuated, home.theta, strict=True)}  # fmt: skip
    grid = make_grid(model, spec, home.theta)
    rng = np.random.default_rng(0)
    lib = tracker_library(model)
    y1, c1 = model.chart.to_local(home.y)

    pick = np.sort(rng.choice(grid.size, min(args.baseline, grid.size), replace=False))
    th = np.concatenate([grid.thetas(int(i), int(i) + 1) for i in pick])
    solved = 0
    t = time.perf_counter()
    for row in th:
        solved += lib.solve_convergent(y1, c1, home.theta, row).status == OK_PATH
    base = len(th) / (time.perf_counter() - t)
    print(f"grid {args.n}^6 legs home +- {args.half} m: {grid.size} points, chunk {args.chunk}")
    print(f"{'direct C solves from home (baseline)':<38} {base:>9.0f} points/s "
          f"({solved} of {len(th)} solved)")  # fmt: skip

    check = np.sort(rng.choice(grid.size, min(args.check, grid.size), replace=False))
    ref_x = np.full((len(check), 6), np.nan)
    for j, i in enumerate(check):
        with contextlib.suppress(sc.ScdkError):
            ref_x[j] = sc.solve(model, grid.thetas(int(i), int(i) + 1)[0], start=home,
                                branch="convergent", backend="compiled").x  # fmt: skip

    with tempfile.TemporaryDirectory() as tmp:
        with warm_cluster(args.workers, warm_worker, model_source(model)) as (client, ready):
            run = sc.atlas(model, spec, Path(tmp) / "workers.zarr", start=home,
                           scheduler=client, chunk=args.chunk, progress=False)  # fmt: skip
        per_worker = report(f"sc.atlas, {args.workers} workers", run, base, check, ref_x)
        print(f"{'':<38} (cluster start and model load on the workers: {ready:.1f} s, "
              "not included)")  # fmt: skip
        run = sc.atlas(model, spec, Path(tmp) / "local.zarr", start=home, chunk=args.chunk,
                       progress=False)  # fmt: skip
        local = report("sc.atlas in this process", run, base, check, ref_x)
    print(f"in-process / per-worker rate: {local / per_worker:.2f}")


def warm_worker(source) -> None:
    """Build the model and load its compiled library on a worker (before timing)."""
    from scdk_sym.atlases.chunk import _tracker, worker_model

    _tracker(worker_model(source))


def report(label: str, run, base: float, check: np.ndarray, ref_x: np.ndarray) -> float:
    rate = run.points / run.busy
    x = open_atlas(run.out)["x"][:][check]
    diff = float(np.nanmax(np.abs(x - ref_x))) if np.any(np.isfinite(ref_x)) else np.nan
    same = bool(np.all(np.isnan(x) == np.isnan(ref_x)))
    print(
        f"{label:<38} {rate:>9.0f} points per busy worker-second ({rate / base:.1f}x "
        f"baseline; {run.points / run.cpu:.0f} per CPU second; wall {run.elapsed:.2f} s; "
        f"swept {run.swept}; status {dict(run.counts)}; {len(check)} checked: max |x - "
        f"sc.solve| {diff:.1e}, same failures {same})"
    )
    return rate


if __name__ == "__main__":
    main()
