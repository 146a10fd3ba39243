"""Monte Carlo calibration error of a 6-6 hexapod: leg-length errors -> platform pose errors.

``models/stewart_gough`` (SI units) at a nominal pose; every leg length is off by a
zero-mean normal error of 50 um. Each sample's pose is the convergent direct-kinematics
solution from the nominal configuration (``sc.atlas`` on explicit theta rows); the pose
error statistics are compared with the first-order propagation ``J sigma^2 J^T``, ``J =
dx/dtheta`` by central differences of ``sc.solve``.

    python examples/atlas_hexapod_montecarlo.py [--samples 2000] [--workers 2]

The first run compiles the model's sweep into the kernel cache (about a minute here, once).
"""

import argparse
import tempfile
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.atlases import open_atlas


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--workers", type=int, default=0, help="local Dask workers (0: in-process)")
    args = parser.parse_args()

    model = sc.load_model(Path(__file__).resolve().parents[1] / "models" / "stewart_gough")
    x_nom = np.array([0.02, -0.01, 0.58, 0.05, -0.03, 0.10])  # m, rad (URDF roll, pitch, yaw)
    nominal = model.inverse_kinematics(x_nom)
    sigma = 50e-6  # m, per leg
    rng = np.random.default_rng(7)
    thetas = nominal.theta + sigma * rng.standard_normal((args.samples, model.k))

    with tempfile.TemporaryDirectory() as tmp:
        run = sc.atlas(
            model,
            thetas,
            Path(tmp) / "mc.zarr",
            start=nominal,
            workers=args.workers,
            chunk=500,
            progress=False,
        )
        store = open_atlas(run.out)
        status, x = store["status"][:], store["x"][:]
    print(f"{run.points} samples in {run.elapsed:.2f} s, status counts {run.counts}")
    err = x[status == 0] - x_nom
    J = np.empty((6, model.k))
    for j in range(model.k):
        d = np.zeros(model.k)
        d[j] = 1e-6
        xp = sc.solve(model, nominal.theta + d, start=nominal).x
        xm = sc.solve(model, nominal.theta - d, start=nominal).x
        J[:, j] = (xp - xm) / 2e-6
    predicted = np.sqrt(np.diag(J @ J.T)) * sigma
    print(f"{'':>6} {'mean':>10} {'std':>10} {'1st order':>10} {'max |err|':>10}")
    for name, unit, scale, e, p in zip(
        model.workspace, ["um"] * 3 + ["urad"] * 3, [1e6] * 6, err.T, predicted, strict=True
    ):
        print(
            f"{name:>6} {e.mean() * scale:>10.2f} {e.std() * scale:>10.2f} "
            f"{p * scale:>10.2f} {np.abs(e).max() * scale:>10.2f}  {unit}"
        )


if __name__ == "__main__":  # workers are spawned processes: they import this file
    main()
