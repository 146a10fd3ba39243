"""Solves per second of ``sc.atlas`` on the paper's robot, against a serial sc.solve loop.

The planar HEXA-type robot from x1 = (0, 0, 0.4) over a theta grid around the paper's
theta0 (every point reachable on the convergent branch unless ``--wide``). Prints, measured
in the same run:

* the baseline: a Python loop of ``sc.solve(model, theta, start, branch="convergent")``
  (defaults) over ``--baseline`` points of the grid;
* ``sc.atlas`` in this process (no Dask), and on a ``LocalCluster`` of 1 and 2 worker
  processes (started, and the model built on every worker, before the clock starts; the
  store written), with the speed-up over the baseline and from 1 to 2 workers;
* the largest difference of the atlas's x from the baseline solves.

    python benchmarks/atlas.py [--n 80] [--chunk 4096] [--baseline 100] [--wide]
"""

from __future__ import annotations

import argparse
import contextlib
import tempfile
import time
from pathlib import Path

import numpy as np
from common import warm_cluster

import scdk_sym as sc
from scdk_sym.atlases import make_grid, open_atlas
from scdk_sym.atlases.chunk import model_source

ROOT = Path(__file__).resolve().parents[1]
THETA0 = np.array([1.292, -0.802, -2.896])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=80, help="points per axis (n^3 points)")
    parser.add_argument("--chunk", type=int, default=4096)
    parser.add_argument("--baseline", type=int, default=100, help="points of the serial loop")
    parser.add_argument("--wide", action="store_true", help="+-0.3 rad: includes unreachable")
    args = parser.parse_args()
    model = sc.load_model(ROOT / "models" / "planar_hexa")
    start = model.inverse_kinematics([0.0, 0.0, 0.4])
    half = 0.3 if args.wide else 0.1
    spec = {
        name: (t - half, t + half, args.n) for name, t in zip(model.actuated, THETA0, strict=True)
    }
    grid = make_grid(model, spec, start.theta)
    thetas = grid.thetas(0, grid.size)
    rng = np.random.default_rng(0)
    pick = np.sort(rng.choice(grid.size, min(args.baseline, grid.size), replace=False))

    sc.solve(model, thetas[0], start=start)  # build the kernels before timing
    base_x = np.full((len(pick), 3), np.nan)
    t = time.perf_counter()
    for j, i in enumerate(pick):
        with contextlib.suppress(sc.ScdkError):
            base_x[j] = sc.solve(model, thetas[i], start=start, branch="convergent").x
    base = len(pick) / (time.perf_counter() - t)
    print(f"grid {grid.to_text()}: {grid.size} points, chunk {args.chunk}")
    print(f"{'serial sc.solve loop (baseline)':<30} {base:>10.0f} solves/s")

    rates = {}
    with tempfile.TemporaryDirectory() as tmp:
        small = {name: (lo, hi, 4) for name, (lo, hi, _) in spec.items()}
        sc.atlas(model, small, Path(tmp) / "warm.zarr", start=start, chunk=16, progress=False)
        run = sc.atlas(
            model, spec, Path(tmp) / "0.zarr", start=start, chunk=args.chunk, progress=False
        )
        report("sc.atlas in this process", run, base, base_x, pick)
        for workers in (1, 2):
            with warm_cluster(workers, warm_worker, model_source(model)) as (client, ready):
                run = sc.atlas(
                    model,
                    spec,
                    Path(tmp) / f"{workers}.zarr",
                    start=start,
                    scheduler=client,
                    chunk=args.chunk,
                    progress=False,
                )
            rates[workers] = report(f"sc.atlas {workers} worker(s)", run, base, base_x, pick)
            print(
                f"{'':<30} (cluster start and model build on the workers: {ready:.1f} s, "
                "not included)"
            )
    print(f"2 workers / 1 worker: {rates[2] / rates[1]:.2f}x")


def warm_worker(source) -> None:
    """Build the model and load its compiled kernels on a worker (before timing)."""
    from scdk_sym.atlases.chunk import _tracker, worker_model
    from scdk_sym.follower.cvodes import engine

    model = worker_model(source)
    _tracker(model)
    engine(model, "compiled")


def report(label: str, run, base: float, base_x: np.ndarray, pick: np.ndarray) -> float:
    rate = run.points / run.elapsed
    x = open_atlas(run.out)["x"][:][pick]
    diff = np.nanmax(np.abs(x - base_x)) if np.any(np.isfinite(base_x)) else np.nan
    same = bool(np.all(np.isnan(x) == np.isnan(base_x)))
    print(
        f"{label:<30} {rate:>8.0f} solves/s ({rate / base:.0f}x baseline; {run.elapsed:.2f} s; "
        f"per worker: {run.points / run.busy:.0f} solves/s busy, {run.points / run.cpu:.0f} "
        f"per CPU second; swept {run.swept}; "
        f"status {run.counts}; max |x - baseline| {diff:.1e}; same failures {same})"
    )
    return rate


if __name__ == "__main__":
    main()
