"""A biped's legs tracked through an ankle singularity (Gepetto's digit_like_2legs).

The right leg's ankle rod motor ``motor_shin1`` is driven so that the leg moves smoothly through
a singular configuration of its ankle mechanism (``det J_p = 0``, the two rods' assembly modes
meeting) and on across it; the left leg stands still. The readings are generated from the
motion itself: an arc-length continuation of the closure curve ``g(y, theta) = 0`` with only
that motor free, passing the fold where the motor reaches its largest value and turns back.
Read alone, the readings go up and come back down: a warm-started Newton on each reading
returns to the assembly it came from, while ``sc.track`` follows the motion onto the other
assembly and reports the fold crossing. Every tracked sample is checked against the curve
that generated the readings.

The model loads as Gepetto's collection writes it (``tests/fixtures/gepetto``, a copy of
robots/digit_like_2legs): no home (assembled from the neutral configuration), ball joints and
universal joints from the YAML's joint edits, and two independent legs solved apart.

    python examples/biped_ankle_singularity.py [--out biped_ankle.png]
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.errors import ModelWarning
from scdk_sym.kernels.fastcall import model_calls

MODEL = (
    Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "gepetto" / "digit_like_2legs"
)
MOTOR = "motor_shin1"
#: Samples of the motion and arc-length step of the generating continuation.
SAMPLES = 400


def closure_curve(model: sc.Model, motor: str, samples: int, step: float):
    """The motion: arc-length continuation of g(y, theta) = 0 with only ``motor`` free, from
    home (the motor increasing), through the fold where that motor turns back.

    Returns:
        (ys (samples, m), thetas (samples, k)) [rad].
    """
    calls = model_calls(model)
    j = model.actuated.index(motor)
    y, theta = model.home.y.copy(), model.home.theta.copy()
    prev = None
    ys, thetas = [], []
    for _ in range(samples):
        y_loc, c = model.chart.to_local(y)
        J_p, J_s = calls.jac(y_loc, theta, c)
        tangent = np.linalg.svd(np.hstack([J_p, -J_s[:, [j]]]))[2][-1]  # dg/dtheta = -J_s
        if prev is None:
            tangent *= np.sign(tangent[-1])
        elif tangent @ prev < 0:
            tangent = -tangent
        prev = tangent
        z = np.concatenate([y_loc, [theta[j]]]) + step * tangent
        th = theta.copy()
        for _ in range(20):  # Newton in the plane normal to the tangent
            th[j] = z[-1]
            J_p, J_s = calls.jac(z[:-1], th, c)
            A = np.vstack([np.hstack([J_p, -J_s[:, [j]]]), tangent])
            dz = np.linalg.solve(A, -np.concatenate([calls.g(z[:-1], th, c).ravel(), [0.0]]))
            z = z + dz
            if np.abs(dz).max() < 1e-14:
                break
        th[j] = z[-1]
        y, theta = model.chart.to_canonical(z[:-1], c), th
        ys.append(y)
        thetas.append(theta)
    return np.array(ys), np.array(thetas)


def warm_newton(model: sc.Model, thetas: np.ndarray) -> np.ndarray:
    """Newton warm-started from the previous sample at each reading (the usual tracker)."""
    calls = model_calls(model)
    y = model.home.y.copy()
    out = []
    for theta in thetas:
        y_loc, c = model.chart.to_local(y)
        for _ in range(30):
            J_p, _ = calls.jac(y_loc, theta, c)
            dy = np.linalg.lstsq(J_p, -calls.g(y_loc, theta, c).ravel(), rcond=None)[0]
            y_loc = y_loc + dy
            if np.abs(dy).max() < 1e-13:
                break
        y = model.chart.to_canonical(y_loc, c)
        out.append(y)
    return np.array(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="biped_ankle.png", help="figure file")
    args = parser.parse_args()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        model = sc.load_model(MODEL)
    print(model.reduction or "square as written")
    print(f"{len(model.blocks)} independent blocks of {[b.m for b in model.blocks]} unknowns")
    ys, thetas = closure_curve(model, MOTOR, SAMPLES, step=0.02)
    j = model.actuated.index(MOTOR)
    fold = int(np.argmax(thetas[:, j]))
    print(f"{MOTOR}: 0 -> {thetas[fold, j]:.4f} rad (fold at sample {fold}) -> {thetas[-1, j]:.4f}")
    result = sc.track(model, thetas, backend="c")
    err = np.abs(result.y - ys).max()
    kinds = [(c.index, c.kind) for c in result.crossings]
    print(
        f"track: {len(kinds)} crossing(s) {kinds}; max |y - motion| over {SAMPLES} samples "
        f"{err:.1e} rad, max residual {result.residual.max():.1e}"
    )
    newton = warm_newton(model, thetas)
    jump = np.abs((newton - ys + np.pi) % (2 * np.pi) - np.pi).max(axis=1)  # angles mod 2 pi
    print(
        f"warm Newton: leaves the motion at sample {int(np.argmax(jump > 1e-3))}, "
        f"max |y - motion| {jump.max():.2f} rad"
    )

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    foot, _ = model.evaluate(ys, thetas, residual=False)  # x: the right foot's position
    foot_track = result.x
    foot_newton, _ = model.evaluate(newton, thetas, residual=False)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    axes[0].plot(thetas[:, j], label="reading " + MOTOR)
    axes[0].axvline(fold, color="grey", ls=":", label="fold (det J_p = 0)")
    axes[0].set_xlabel("sample")
    axes[0].set_ylabel("motor [rad]")
    axes[0].legend()
    axes[1].plot(foot[:, 2], "k-", lw=3, alpha=0.3, label="the motion")
    axes[1].plot(foot_track[:, 2], "C0-", label="sc.track (SC)")
    axes[1].plot(foot_newton[:, 2], "C3--", label="warm Newton")
    axes[1].axvline(fold, color="grey", ls=":")
    axes[1].set_xlabel("sample")
    axes[1].set_ylabel("right foot z [m]")
    axes[1].legend()
    fig.suptitle("digit_like_2legs: the right ankle through a singular configuration")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
