"""Time per solve of the paper's example (planar HEXA-type robot, section 5).

Prints the median time per solve of both branches with the CasADi SX Functions, with the
compiled (generated C) kernels and with ``backend="c"`` (each branch in one call of the
generated C follower where that call decides it, else the compiled solve: column ``via``), for
both modelings, and the ratio to a baseline measured in the same run: a plain numpy Newton
iteration (x in R^3, the reduced model's closed-form residual) from the same start, which finds
one solution and has no branch control.

Then, for the convergent branch with ``backend="c"``, what a repeated call costs beyond its C:
the C follower with its arguments bound (``tracker_library(model).bound_solve(...)``: the C
work and one ctypes call), the binding's call alone
(``tracker_library(model).solve_convergent``, which converts its arguments each call),
``sc.solve`` (validation, the call, the verified result) and ``sc.solve_many`` over
``--batch`` copies of the reading (per reading), each with its excess over the bound call and
over the binding's call; and a track of 10 readings with ``backend="c"``: the binding's call
(``tracker_library(model).track``) and ``sc.track``, with its excess.

    python benchmarks/seed_example.py [--repeat 200] [--clock cpu] [--batch 200]

``--clock cpu`` times with the process's CPU time instead of the wall clock: on a machine
shared with other work the wall clock also counts the time the process waits for a core.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.builders.planar import seed_geometry
from scdk_sym.codegen.library import OK_PATH, tracker_library
from scdk_sym.solvers.solve import solve

ROOT = Path(__file__).resolve().parents[1]
X1 = np.array([0.0, 0.0, 0.4])
THETA0 = np.array([1.292, -0.802, -2.896])


def newton_baseline(theta0: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Plain Newton on the residual |elbow_i - vertex_i(x)|^2 - rod^2 (finite differences)."""
    g = seed_geometry()
    A, C, arm, rod = g["base_points"], g["platform_points"], g["arm"], g["rod"]
    E = A + arm * np.c_[np.cos(theta0), np.sin(theta0)]

    def f(x):
        c, s = math.cos(x[2]), math.sin(x[2])
        V = x[:2] + C @ np.array([[c, s], [-s, c]])
        return np.sum((V - E) ** 2, axis=1) - rod**2

    for _ in range(50):
        r = f(x)
        if np.max(np.abs(r)) < 1e-12:
            break
        J = np.column_stack([(f(x + 1e-7 * e) - r) / 1e-7 for e in np.eye(3)])
        x = x - np.linalg.solve(J, r)
    return x


CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def via(model, start, branch: str, backend: str) -> str:
    """What answers a solve: "C call" (one call of the generated C follower), "fallback" (the
    compiled solve, where that call refuses) or "-" (not ``backend="c"``)."""
    if backend != "c":
        return "-"
    lib = tracker_library(model)
    y1, c1 = model.chart.to_local(start.y)
    call = lib.solve_convergent if branch == "convergent" else lib.solve_divergent
    return "C call" if call(y1, c1, start.theta, THETA0).status == OK_PATH else "fallback"


def median_time(fn, repeat: int, clock=time.perf_counter) -> float:
    fn()  # warm up
    times = []
    for _ in range(repeat):
        t = clock()
        fn()
        times.append(clock() - t)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=200)
    parser.add_argument("--clock", choices=sorted(CLOCKS), default="wall")
    parser.add_argument("--batch", type=int, default=200)
    args = parser.parse_args()
    clock = CLOCKS[args.clock]
    base = median_time(lambda: newton_baseline(THETA0, X1.copy()), args.repeat, clock)
    print(f"baseline numpy Newton (one solution, no branch control): {base * 1e3:.3f} ms/solve")
    print(f"({args.clock} clock, medians of {args.repeat})")
    print(
        f"{'model':<22}{'backend':<10}{'branch':<12}{'via':<10}{'phi':>9}{'ms/solve':>10}"
        f"{'ratio':>8}"
    )
    for name in ("planar_hexa", "planar_hexa_reduced"):
        model = sc.load_model(ROOT / "models" / name)
        start = model.inverse_kinematics(X1)
        for backend in ("cvodes", "compiled", "c"):
            for branch in ("convergent", "divergent"):
                res = solve(model, THETA0, start=start, branch=branch, backend=backend)

                def run(model=model, start=start, branch=branch, backend=backend):
                    solve(
                        model,
                        THETA0,
                        start=start,
                        branch=branch,
                        backend=backend,
                        record_path=False,
                    )

                t = median_time(run, args.repeat, clock)
                how = via(model, start, branch, backend)
                print(
                    f"{name:<22}{backend:<10}{branch:<12}{how:<10}{res.x[2]:>9.4f}"
                    f"{t * 1e3:>10.3f}{t / base:>8.2f}"
                )
    repeated_calls(base, args.repeat, args.batch, clock)


def repeated_calls(base: float, repeat: int, batch: int, clock) -> None:
    """The convergent C solve of planar_hexa: the C follower with its arguments bound (the C
    work and one ctypes call), the binding's call, sc.solve and sc.solve_many (per reading),
    medians, with their excess over the bound call and over the binding's call."""
    model = sc.load_model(ROOT / "models" / "planar_hexa")
    start = model.inverse_kinematics(X1)
    lib = tracker_library(model)
    y1, c1 = model.chart.to_local(start.y)
    thetas = np.repeat(THETA0[None], batch, axis=0)
    bound_call = lib.bound_solve(y1, c1, start.theta)
    bound = median_time(lambda: bound_call(THETA0), repeat, clock)
    raw = median_time(lambda: lib.solve_convergent(y1, c1, start.theta, THETA0), repeat, clock)
    one = median_time(
        lambda: solve(model, THETA0, start, backend="c", record_path=False), repeat, clock
    )
    many = median_time(lambda: sc.solve_many(model, thetas, start), max(5, repeat // 20), clock)
    many /= batch
    print("planar_hexa, convergent, backend c, per reading (us; ratio to the numpy Newton;")
    print("excess over the bound call / over the binding's call):")
    for label, t in (
        ("C follower, arguments bound (1 ctypes call)", bound),
        ("binding's call (C follower + ctypes)", raw),
        ("sc.solve", one),
        (f"sc.solve_many over {batch} readings", many),
    ):
        excess = "" if t is bound else f"  (+{(t - bound) * 1e6:.1f} us"
        if t is not bound and t is not raw:
            excess += f" / +{(t - raw) * 1e6:.1f} us"
        excess += ")" if excess else ""
        print(f"  {label:<44}{t * 1e6:8.1f}{t / base:8.2f}{excess}")
    motion = start.theta + np.linspace(0.0, 0.05, 10)[:, None] * np.array([1.0, -0.5, 0.3])
    raw = median_time(lambda: lib.track(y1, c1, start.theta, motion), repeat, clock)
    tracked = median_time(lambda: sc.track(model, motion, start, backend="c"), repeat, clock)
    print("planar_hexa, a track of 10 readings, backend c, per call (us):")
    label = "binding's call (C tracker + ctypes)"
    print(f"  {label:<44}{raw * 1e6:8.1f}")
    print(f"  {'sc.track':<44}{tracked * 1e6:8.1f}  (+{(tracked - raw) * 1e6:.1f} us)")


if __name__ == "__main__":
    main()
