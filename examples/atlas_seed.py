"""An atlas of the paper's robot: the convergent solution over a theta_1 x theta_2 grid.

The planar HEXA-type robot (cm, rad) from the paper's start x1 = (0, 0, 0.4), around its
example theta0 = (1.292, -0.802, -2.896) (theta_3 held there). Each point is
``sc.solve(model, theta, start, branch="convergent")``; grid points the start's assembly mode
cannot reach (beyond the singular surface) get status 1 (PathError). Writes
``atlas_seed.zarr`` and the figure ``atlas_seed.png`` into ``--out`` (default: the current
directory); run it again and it finds the store complete.

    python examples/atlas_seed.py [--workers 2] [--out DIR]
"""

import argparse
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.atlases import open_atlas
from scdk_sym.atlases.plot import plot_atlas


def main() -> None:
    here = Path(__file__).resolve().parent
    parser = argparse.ArgumentParser()
    parser.add_argument("--workers", type=int, default=0, help="local Dask workers (0: in-process)")
    parser.add_argument("--out", default=".", help="directory of the store and the figure")
    args = parser.parse_args()

    model = sc.load_model(here.parent / "models" / "planar_hexa")
    start = model.inverse_kinematics([0.0, 0.0, 0.4])
    theta0 = np.array([1.292, -0.802, -2.896])
    grid = {
        "theta_1": (theta0[0] - 0.3, theta0[0] + 0.3, 31),
        "theta_2": (theta0[1] - 0.3, theta0[1] + 0.3, 31),
        "theta_3": (theta0[2], theta0[2], 1),
    }
    run = sc.atlas(
        model,
        grid,
        Path(args.out) / "atlas_seed.zarr",
        start=start,
        workers=args.workers,
        chunk=128,
    )
    store = open_atlas(run.out)
    status, x = store["status"][:], store["x"][:]
    ok = status == 0
    print(f"{run.points} points, {run.computed} chunks solved now in {run.elapsed:.1f} s")
    print(f"solved {ok.sum()}, unreachable from the start's side {np.sum(status == 1)}")
    print(f"phi over the solved points: {x[ok, 2].min():.4f} .. {x[ok, 2].max():.4f} rad")
    centre = np.argmin(np.linalg.norm(store["theta"][:] - theta0, axis=1))
    print(f"at theta0: x = {np.round(x[centre], 4)} (the paper's convergent phi = 0.2074)")
    print(f"wrote {plot_atlas(run.out, Path(args.out) / 'atlas_seed.png')}")


if __name__ == "__main__":  # workers are spawned processes: they import this file
    main()
