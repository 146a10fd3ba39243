"""Warm direct-kinematics solves on Gepetto's ``5bar_linkage_iso3d`` (a control loop).

A smooth random walk of the two motor angles (seeded, steps of about 0.01 rad, N samples) is
solved sample after sample, each solve starting from the previous solution. Printed: the median
and 90th percentile time per solve and the worst closure residual of

- ``sc.solve(..., start=previous, record_path=False)`` with the CasADi SX Functions and with
  the compiled (generated C) kernels: the package's public warm solve (SC fast path: one RK4
  sweep in s with a Newton polish, the branch and the residual verified, else the full path);
- the baseline, measured in the same run: a plain numpy Newton iteration on the same kernels
  (``g`` and ``J_p``, tolerance 1e-12), which verifies nothing and has no branch control;
- the same Newton through zero-copy kernel calls (``casadi.Function.buffer``, as the warm
  solve itself calls its kernel): what the Python call overhead of CasADi (numpy -> DM ->
  numpy, tens of microseconds per call) costs.

Ratios are to the zero-copy Newton baseline.

    python benchmarks/gepetto_warm.py [--samples 2000]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.kernels.fastcall import Buffered
from scdk_sym.solvers.solve import solve

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "tests" / "fixtures" / "gepetto" / "5bar_linkage_iso3d"
TOL = 1e-12


def walk(model: sc.Model, samples: int, seed: int = 0) -> np.ndarray:
    """(samples, k) smooth motor angles: a random walk with a little momentum [rad]."""
    rng = np.random.default_rng(seed)
    theta = np.array(model.home.theta, dtype=float)
    v = np.zeros(model.k)
    out = []
    for _ in range(samples):
        v = 0.9 * v + 0.1 * rng.normal(0.0, 0.01, model.k)
        v -= 0.002 * (theta - model.home.theta)  # stay around home
        theta = theta + v
        out.append(theta.copy())
    return np.array(out)


def run_solve(model: sc.Model, thetas: np.ndarray, backend: str):
    solve(model, thetas[0], start=model.home, record_path=False, backend=backend)  # warm up
    cfg, times, worst, xs = model.home, [], 0.0, []
    for th in thetas:
        t = time.perf_counter()
        res = solve(model, th, start=cfg, record_path=False, backend=backend)
        times.append(time.perf_counter() - t)
        cfg = res.configuration
        worst = max(worst, res.residual)
        xs.append(res.x)
    return np.array(times), worst, np.array(xs)


def run_newton(model: sc.Model, thetas: np.ndarray):
    kern = model.kernels
    y, c = model.chart.to_local(model.home.y)
    times, worst, xs = [], 0.0, []
    for th in thetas:
        t = time.perf_counter()
        for _ in range(20):
            g = np.array(kern.g(y, th, c)).ravel()
            if np.abs(g).max() <= TOL:
                break
            y = y - np.linalg.solve(np.array(kern.jac(y, th, c)[0]), g)
        times.append(time.perf_counter() - t)
        worst = max(worst, float(np.abs(g).max()))
        xs.append(np.array(kern.pose(y, th, c)[1]).ravel())
    return np.array(times), worst, np.array(xs)


def run_newton_buffered(model: sc.Model, thetas: np.ndarray):
    kern = model.kernels
    g_f, jac = Buffered(kern.g), Buffered(kern.jac)
    m = model.m
    y, c = model.chart.to_local(model.home.y)
    times, worst = [], 0.0
    for th in thetas:
        t = time.perf_counter()
        for _ in range(20):
            g = g_f(y, th, c)[0]
            if np.abs(g).max() <= TOL:
                break
            y = y - np.linalg.solve(jac(y, th, c)[0].reshape(m, m, order="F"), g)
        times.append(time.perf_counter() - t)
        worst = max(worst, float(np.abs(g).max()))
    return np.array(times), worst


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2000)
    args = parser.parse_args(argv)
    model = sc.load_model(MODEL, frame="effector")
    thetas = walk(model, args.samples)
    t_newton, r_newton, x_newton = run_newton(model, thetas)
    t_sc, r_sc, x_sc = run_solve(model, thetas, "cvodes")
    t_cc, r_cc, x_cc = run_solve(model, thetas, "compiled")
    t_nb, r_nb = run_newton_buffered(model, thetas)
    base = np.median(t_nb)
    rows = [
        ("numpy Newton, DM calls", t_newton, r_newton),
        ("numpy Newton, zero-copy calls (baseline)", t_nb, r_nb),
        ("sc.solve warm, SX Functions", t_sc, r_sc),
        ("sc.solve warm, compiled kernels", t_cc, r_cc),
    ]
    print(f"5bar_linkage_iso3d: {args.samples} warm solves, each from the previous solution")
    print(f"{'method':44s} {'median us':>10s} {'p90 us':>8s} {'ratio':>6s} {'max residual':>13s}")
    for label, t, r in rows:
        print(
            f"{label:44s} {1e6 * np.median(t):10.1f} {1e6 * np.percentile(t, 90):8.1f} "
            f"{np.median(t) / base:6.2f} {r:13.1e}"
        )
    agree = max(np.abs(x_sc - x_newton).max(), np.abs(x_cc - x_sc).max())
    print(f"max |x| difference between the methods: {agree:.1e} m")
    return 0 if max(r_sc, r_cc) <= TOL else 1


if __name__ == "__main__":
    raise SystemExit(main())
