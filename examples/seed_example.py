"""The paper's example: both direct-kinematics solutions of the planar HEXA-type robot.

Expected output (x, y in cm, phi in rad):

    convergent: x = [0.0025, -0.0003, 0.2075], crossings: none
    divergent:  x = [0.0023, -0.0022, 0.9999], crossings: phi = 0.5754 at s = -0.2782
"""

from pathlib import Path

import scdk_sym as sc

model = sc.load_model(Path(__file__).resolve().parents[1] / "models" / "planar_hexa")
start = model.inverse_kinematics([0.0, 0.0, 0.4])  # the initial guess x1 of the paper
theta0 = [1.292, -0.802, -2.896]

for branch in ("convergent", "divergent"):
    res = sc.solve(model, theta0, start=start, branch=branch)
    crossings = ", ".join(f"phi = {c.x[2]:.4f} at s = {c.s:.4f}" for c in res.crossings)
    x = ", ".join(f"{v:.4f}" for v in res.x)
    print(f"{branch + ':':<11} x = [{x}], crossings: {crossings or 'none'}")
