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
from scdk_sym.plot import plot_range
from scdk_sym.solvers.transmission_range import margin_grid

MODEL = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "gepetto" / "digit_like"
OUTPUTS = ("motor_hip_x", "motor_hip_y", "motor_hip_z", "free_knee", "free_foot1", "free_foot2")


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

    home = T.inverse_model.home.theta  # the outputs at home
    lower, upper = home.copy(), home.copy()
    lower[4:] -= 0.6
    upper[4:] += 0.6
    grid = margin_grid(T, lower, upper, n=args.n)  # a serpentine sweep continuing each cell
    plot_range(grid, args.out, title="digit_like ankle: margin of the motor <-> joint map")
    m = grid.margin
    print(
        f"wrote {args.out}: margin from {np.nanmin(m):.2e} to {np.nanmax(m):.2e}, "
        f"{int(np.isnan(m).sum())} of {m.size} cells not reached"
    )


if __name__ == "__main__":
    main()
