"""A biped leg's motor <-> joint maps: knee and ankle both ways, and the margin over the ankle's
range as a picture (Gepetto's digit_like: a knee four-bar and a two-rod parallel ankle).

The controller's joints are the serial equivalent of the leg (hip motors, knee angle
``free_knee``, ankle pitch and roll ``free_foot1``, ``free_foot2``); the motors sit elsewhere.
``sc.transmission`` maps motors to those joints (the SC tracker, continuing from the last
reading) and back (the same machinery with the roles swapped), with Jacobians, velocities,
torques and a margin per block of the leg (knee loop, ankle loop). The figure sweeps the
ankle's two joints over a box, row after row (a serpentine, so each reading continues the
last), and draws the ankle block's margin: where it falls to zero the map is not invertible.

    python examples/leg_transmission.py [--out leg_transmission.png] [--n 25]
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.errors import ModelWarning

MODEL = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "gepetto" / "digit_like"
#: Readings between two cells of the sweep.
STEPS = 8
OUTPUTS = ("motor_hip_x", "motor_hip_y", "motor_hip_z", "free_knee", "free_foot1", "free_foot2")


def margin_map(T: sc.Transmission, half: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The ankle block's margin over ``home +- half`` of (free_foot1, free_foot2) on an
    n x n grid, and the grid's offsets [rad]."""
    home = T.inverse_model.home.theta  # the outputs at home
    i1, i2 = T.outputs.index("free_foot1"), T.outputs.index("free_foot2")
    offsets = np.linspace(-half, half, n)
    out = np.full((n, n), np.nan)
    block = [b for _, b in T.blocks()].index(("free_foot1", "free_foot2"))
    last = home.copy()
    for r, d1 in enumerate(offsets):
        cols = range(n) if r % 2 == 0 else range(n - 1, -1, -1)
        for c in cols:
            q = home.copy()
            q[i1], q[i2] = home[i1] + d1, home[i2] + offsets[c]
            # readings at a steady rate between cells (what a controller's readings are)
            path = last + np.linspace(0, 1, STEPS + 1)[1:, None] * (q - last)
            try:
                T.forward_many(T.inverse_many(path))  # the motors, then the leg along them
                out[r, c] = T.margin().blocks[block]
                last = q
            except sc.ScdkError:
                pass  # blank: not reached from the last cell (the maps keep their state)
    return out, offsets


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="leg_transmission.png", help="figure file")
    parser.add_argument("--n", type=int, default=25, help="grid points per joint")
    args = parser.parse_args()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        model = sc.load_model(MODEL)
    T = sc.transmission(model, OUTPUTS)
    theta = model.home.theta + np.array([0.0, 0.0, 0.0, 0.1, 0.05, -0.05])
    q = T.forward(theta)
    print("motors ", np.round(theta, 4))
    print("joints ", np.round(q, 4), " (forward)")
    print("motors ", np.round(T.inverse(q), 4), " (inverse)")
    print("d joints / d motors, ankle block:")
    print(np.round(T.jacobian(theta)[4:, 4:], 4))
    tau = T.torques(theta, [0] * 4 + [1, 0])
    print("motor torques holding 1 N m of ankle pitch:", np.round(tau, 4))
    print("margin per block:", [round(b, 4) for b in T.margin(theta).blocks])

    T.reset()
    grid, offsets = margin_map(T, 0.6, args.n)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    im = ax.pcolormesh(offsets, offsets, grid, shading="auto", cmap="viridis")
    ax.set_xlabel("ankle roll free_foot2 - home [rad]")
    ax.set_ylabel("ankle pitch free_foot1 - home [rad]")
    ax.set_title("digit_like ankle: margin of the motor <-> joint map")
    fig.colorbar(im, label="relative smallest singular value")
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(
        f"wrote {args.out}: margin from {np.nanmin(grid):.2e} to {np.nanmax(grid):.2e}, "
        f"{int(np.isnan(grid).sum())} of {grid.size} cells without an assembly"
    )


if __name__ == "__main__":
    main()
