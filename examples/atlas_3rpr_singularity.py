"""The singularity locus of a planar 3-RPR in its joint space: regions of 2, 4 and 6 modes.

The geometry is the classic cuspidal 3-RPR of Innocenti & Parenti-Castelli ("Singularity-free
evolution from one configuration to another in serial and fully-parallel manipulators",
ASME J. Mech. Des. 120(1), 1998), studied in joint space by Zein, Wenger & Chablat
("Non-singular assembly-mode changing motions for 3-RPR parallel manipulators", Mech. Mach.
Theory 43(4), 2008): base pivots A1 = (0, 0), A2 = (15.91, 0), A3 = (0, 10); platform
triangle B1 B2 = 17.04, B2 B3 = 16.54, B3 B1 = 20.84; the slice rho1 = 14.98 of the joint
space. The published values carry no unit; they are read here as centimetres (the model is
in metres).

Over a rho2 x rho3 grid at rho1 = 14.98 cm the atlas stores, at every point, the convergent
solution from one assembled start (status and the sign of det J_p: the start's region of
the joint space, bounded by the singular curves it meets) and, with ``modes=True``, the
certified number of real assembly modes (:func:`scdk_sym.assembly_modes`, homotopy). The
count changes by two across a singular curve, where two assembly modes meet (det J_p = 0):
the count panel of the figure shows the regions of 0, 2, 4 and 6 modes, the singular curves
drawn as their boundaries. Writes the model (``rpr_innocenti/``), ``atlas_3rpr.zarr`` and
``atlas_3rpr.png`` into ``--out`` (default: the current directory); run it again and it finds
the store complete.

    python examples/atlas_3rpr_singularity.py [--n 18] [--workers 2] [--out DIR]

The same with the command line, from the saved model (the start is its home):

    scdk atlas rpr_innocenti --grid leg_2=0.04:0.26:18,leg_3=0.02:0.26:18,leg_1=0.1498:0.1498:1 \\
        --modes --out atlas_3rpr.zarr --chunk 64
    scdk plot-atlas atlas_3rpr.zarr --out atlas_3rpr.png
"""

import argparse
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.atlases import open_atlas
from scdk_sym.atlases.plot import plot_atlas

#: Base pivots [m] (the paper's cm / 100).
BASE = np.array([[0.0, 0.0], [15.91, 0.0], [0.0, 10.0]]) / 100
#: Platform sides B1B2, B2B3, B3B1 [m].
SIDES = np.array([17.04, 16.54, 20.84]) / 100
#: The slice of the joint space [m].
RHO1 = 0.1498
#: The start's leg lengths [m] (in the slice, in a region of four assembly modes).
START_RHO = np.array([RHO1, 0.20, 0.10])
#: The start's pose (x, y, phi) [m, m, rad]: of the real assembly modes at START_RHO, the one
#: of largest |det J_p| (sc.assembly_modes); the model's home, so the atlas starts there.
START_X = np.array([0.14625482411769547, 0.032397012552116064, 1.3403720117324454])
#: The grid of the slice: (lo, hi) of leg_2 and leg_3 [m].
LEG2, LEG3 = (0.04, 0.26), (0.02, 0.26)


def platform_points() -> np.ndarray:
    """(3, 2) platform pivots [m]: B1 at the origin, B2 on the x axis, B3 above it."""
    d1, d2, d3 = SIDES
    x3 = (d3**2 - d2**2 + d1**2) / (2 * d1)
    return np.array([[0.0, 0.0], [d1, 0.0], [x3, np.sqrt(d3**2 - x3**2)]])


def build_model():
    """The 3-RPR model (theta = leg lengths [m], x = (x, y, phi) [m, m, rad]), at home in
    the start :data:`START_X`."""
    return sc.builders.planar_3rpr(BASE, platform_points(), home_x=START_X, name="rpr_innocenti")


def grid(n: int) -> dict:
    """The grid: leg_2 x leg_3 with leg_1 held at :data:`RHO1`."""
    return {"leg_2": (*LEG2, n), "leg_3": (*LEG3, n), "leg_1": (RHO1, RHO1, 1)}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--n", type=int, default=18, help="grid points per axis")
    parser.add_argument("--workers", type=int, default=0, help="local Dask workers (0: in-process)")
    parser.add_argument("--out", default=".", help="directory of the store and the figure")
    args = parser.parse_args()

    model = build_model()
    model.save(Path(args.out) / "rpr_innocenti")
    start = model.home
    print(f"start (home): theta = {np.round(start.theta, 6)} m, x = {np.round(start.x, 6)}")
    run = sc.atlas(
        model,
        grid(args.n),
        Path(args.out) / "atlas_3rpr.zarr",
        start=start,
        modes=True,
        workers=args.workers,
        chunk=64,
    )
    store = open_atlas(run.out)
    status, n_modes = store["status"][:], store["n_modes"][:]
    counts = {int(c): int(np.sum(n_modes == c)) for c in np.unique(n_modes)}
    print(f"{run.points} points, {run.computed} chunks solved now in {run.elapsed:.1f} s")
    print(f"assembly modes (count: points; -1 not certified): {counts}")
    print(f"start's region (convergent solution found): {np.sum(status == 0)} points")
    print(f"wrote {plot_atlas(run.out, Path(args.out) / 'atlas_3rpr.png')}")


if __name__ == "__main__":  # workers are spawned processes: they import this file
    main()
