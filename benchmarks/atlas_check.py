"""Every point of small atlas grids against ``sc.solve``, on any models.

For each model directory given: a grid over its first three actuators (``home +- --half``,
``--n`` values each; the others at home), solved in chunks of ``--chunk`` points as the atlas
solves them (:func:`scdk_sym.atlases.chunk.solve_chunk`: the C sweep, each point continued
from its grid neighbour, then ``sc.solve`` for the points it leaves), and every point solved
again by ``sc.solve(model, theta, start=home, branch="convergent", backend="compiled")``.
Prints per model: points, points the sweep settled, statuses, points where the two disagree
(one solved and not the other) and the largest |x - sc.solve| over the rest.

    OMP_NUM_THREADS=1 python benchmarks/atlas_check.py models/planar_hexa models/delta ...
        [--half 0.15] [--n 6] [--chunk 50]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import scdk_sym as sc
from scdk_sym.atlases import make_grid
from scdk_sym.atlases.chunk import SINGULAR, SOLVED, solve_chunk


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="+", help="model directories")
    parser.add_argument("--half", type=float, default=0.15, help="half-range of an axis")
    parser.add_argument("--n", type=int, default=6, help="values per axis")
    parser.add_argument("--chunk", type=int, default=50)
    args = parser.parse_args()
    for path in args.models:
        model = sc.load_model(path)
        home = model.home
        spec = {name: (home.theta[i] - args.half, home.theta[i] + args.half, args.n)
                for i, name in enumerate(model.actuated[:3])}  # fmt: skip
        grid = make_grid(model, spec, home.theta)
        th = grid.thetas(0, grid.size)
        t = time.perf_counter()
        parts = [solve_chunk(model, home, th[a : a + args.chunk], offset=a, shape=grid.shape)
                 for a in range(0, grid.size, args.chunk)]  # fmt: skip
        elapsed = time.perf_counter() - t
        x = np.concatenate([p.x for p in parts])
        status = np.concatenate([p.status for p in parts])
        mismatched, worst = 0, 0.0
        for i in range(grid.size):
            solved = status[i] in (SOLVED, SINGULAR)
            try:
                r = sc.solve(model, th[i], start=home, branch="convergent", backend="compiled")
            except sc.ScdkError:
                mismatched += solved
                continue
            if not solved:
                mismatched += 1
            else:
                worst = max(worst, float(np.max(np.abs(r.x - x[i]))))
        counts = dict(zip(*(a.tolist() for a in np.unique(status, return_counts=True)),
                          strict=True))  # fmt: skip
        print(f"{path}: {grid.size} points, swept {sum(p.swept for p in parts)}, statuses "
              f"{counts}, mismatched {mismatched}, max |x - sc.solve| {worst:.1e} "
              f"(atlas chunks {elapsed:.2f} s)", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
