"""Time per step of direct-kinematics trackers on one smooth path of models/stewart_gough.

On the same trajectory (every pose coordinate a sine of its own frequency, leg lengths from the
closed-form inverse kinematics), prints microseconds per step, the median over repeats, the
speed-up over the numpy baseline measured in the same run (its time / the tracker's time) and
the time ratio to the plain-C Newton tracker of the same run (the tracker's time / its time;
the C tracker, ``track(backend="c")`` and the plain-C Newton are timed in turn within each
repeat):

- the generated C tracker (:mod:`scdk_sym.codegen`), the whole trajectory in one ctypes call
  (and :func:`scdk_sym.solvers.track_c.track_c`, which adds the conversion of the charts and
  the crossings; the residual of every sample comes from the C call);
- the CVODES tracker (``sc.track(..., backend="cvodes")`` when available, else a
  singularity-consistent solve with CVODES from each previous sample);
- a plain warm-started Newton tracker in C (``benchmarks/newton_c/newton.c``: analytic leg
  Jacobian, 6x6 elimination, no branch control), compiled here with the flags of the
  generated tracker;
- the baseline: the same warm-started Newton tracker in numpy (the conventional method: leg
  residuals, analytic Jacobian, position and rotation updated from the previous pose).

``--opt=-O1,-O2,-O3`` also compiles the generated tracker at each optimisation level and times
the raw call of each, interleaved in the same run.

Then the errors of the C, CVODES and Newton trackers on a path that turns the platform through
its singular orientation (yaw ~ 90 deg), sampled at 399, 40 and 20 readings: the C and CVODES
trackers judge every reading by the same rule (and refuse a reading they cannot judge), the
Newton tracker turns back on the wrong branch.

    python benchmarks/track_hexapod.py [--samples 3000] [--repeat 20] [--cvodes-samples 0]
                                       [--opt=-O1,-O2,-O3]
"""

from __future__ import annotations

import argparse
import ctypes
import importlib
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.codegen.library import CTracker, tracker_library
from scdk_sym.kernels.compile import compile_parallel
from scdk_sym.model.rotations import rpy_matrix
from scdk_sym.solvers.solve import solve
from scdk_sym.solvers.track_c import track_c

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from stewart import anchors, fold_path, leg_lengths  # noqa: E402  (shared with the tests)

MODEL = ROOT / "models" / "stewart_gough"
NEWTON_C = Path(__file__).resolve().parent / "newton_c" / "newton.c"
# the module, not the function that scdk_sym.codegen re-exports under the same name
generate = importlib.import_module("scdk_sym.codegen.generate")


def c_newton(directory: Path):
    """Compile newton_c/newton.c with the generated tracker's flags; returns a tracker
    ``(A, B, x0, thetas) -> (N, 6) poses`` (x0 = (p, rpy))."""
    target = compile_parallel(
        [NEWTON_C], directory / "libnewton.so", generate.COMPILE_FLAGS, generate.LINK_FLAGS
    )
    fn = ctypes.CDLL(str(target)).newton_track
    dp = ctypes.POINTER(ctypes.c_double)
    fn.restype = ctypes.c_long
    fn.argtypes = [dp, dp, dp, ctypes.c_long, dp, dp, ctypes.c_double, ctypes.c_int]

    def track(A, B, x0, thetas, tol=1e-12):
        A, B, x0, th = (np.ascontiguousarray(a, dtype=float) for a in (A, B, x0, thetas))
        out = np.empty((len(th), 6))
        status = fn(*(a.ctypes.data_as(dp) for a in (A, B, x0)), len(th),
                    th.ctypes.data_as(dp), out.ctypes.data_as(dp), tol, 20)  # fmt: skip
        if status < 0:
            raise RuntimeError(f"C Newton did not converge at sample {-1 - status}")
        return out

    return track


def opt_levels(model, levels: list[str], thetas: np.ndarray, n: int, repeat: int) -> None:
    """Compile the generated tracker at each optimisation level, time the raw calls
    (interleaved) and print us/step and the ratio to the first level."""
    y0, c0 = model.chart.to_local(model.home.y)
    libs, build = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        src = generate.generate(model, Path(tmp), "scdk", split=True)
        for opt in levels:
            flags = tuple(opt if f.startswith("-O") else f for f in generate.COMPILE_FLAGS)
            t = time.perf_counter()
            target = Path(tmp) / f"lib{opt.strip('-')}.so"
            compile_parallel(src.sources, target, flags, generate.LINK_FLAGS, cwd=Path(tmp))
            build[opt] = time.perf_counter() - t
            libs[opt] = CTracker(target, model.m, model.k, model.chart.size, len(model.workspace))
        times = {opt: [] for opt in levels}
        for _ in range(repeat):
            for opt, lib in libs.items():
                t = time.perf_counter()
                lib.track(y0, c0, model.home.theta, thetas)
                times[opt].append(time.perf_counter() - t)
    base = float(np.median(times[levels[0]]))
    print(f"\ngenerated tracker by optimisation level (raw call, {n} samples, interleaved):")
    for opt in levels:
        med = float(np.median(times[opt]))
        print(f"  {opt}: compile {build[opt]:6.2f} s (2 parallel jobs), {1e6 * med / n:7.2f} "
              f"us/step, {med / base:.3f}x the time of {levels[0]}")  # fmt: skip


def smooth_path(home: np.ndarray, n: int) -> np.ndarray:
    """(n, 6) poses [x y z roll pitch yaw] around home [m, rad]."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    amp = np.array([0.04, 0.04, 0.03, 0.10, 0.10, 0.20])
    freq = np.array([1.0, 2.0, 1.5, 1.0, 2.5, 0.5])
    phase = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5])
    return home + amp * (np.sin(2 * np.pi * freq * t + phase) - np.sin(phase))


def rpy(R: np.ndarray) -> np.ndarray:
    """URDF roll, pitch, yaw of a rotation matrix."""
    return np.array(
        [
            math.atan2(R[2, 1], R[2, 2]),
            math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0])),
            math.atan2(R[1, 0], R[0, 0]),
        ]
    )


def newton_tracker(A, B, x0: np.ndarray, thetas: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """The conventional tracker: Newton on the leg lengths, warm-started at the previous pose.

    Unknowns: platform position p [m] and orientation R (updated by a rotation vector in the
    base frame); residual f_i = |p + R b_i - a_i| - theta_i [m]; analytic Jacobian.
    """
    p = np.array(x0[:3], dtype=float)
    R = rpy_matrix(*x0[3:])
    out = np.empty((len(thetas), 6))
    for k, theta in enumerate(thetas):
        for _ in range(20):
            rb = B @ R.T
            d = p + rb - A
            length = np.sqrt(np.einsum("ij,ij->i", d, d))
            f = length - theta
            if np.max(np.abs(f)) < tol:
                break
            u = d / length[:, None]
            J = np.hstack([u, np.cross(rb, u)])
            step = np.linalg.solve(J, -f)
            p += step[:3]
            w = step[3:]
            angle = np.linalg.norm(w)
            if angle > 0:
                K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / angle
                R = (np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K) @ R
        out[k, :3] = p
        out[k, 3:] = rpy(R)
    return out


def _cvodes_track():
    try:
        from scdk_sym.solvers.track import track
    except ImportError:
        return None
    return track


def cvodes_tracker(model, thetas: np.ndarray, start) -> np.ndarray:
    """The CVODES reference: the package's track (CVODES backend) when it has one, else an SC
    solve with CVODES from each previous sample."""
    track = _cvodes_track()
    if track is not None:
        return np.asarray(track(model, thetas, start=start, backend="cvodes").x)
    out, prev = [], start
    for theta in thetas:
        res = solve(model, theta, start=prev, record_path=False, fast=False)
        out.append(res.x)
        prev = res.configuration
    return np.array(out)


def per_step(fn, n: int, repeat: int) -> float:
    """Median over repeats of the time of fn() divided by n [us]."""
    return interleaved([fn], n, repeat)[0]


def interleaved(fns, n: int, repeat: int) -> list[float]:
    """Median over repeats of the time of each fn() divided by n [us], the functions called in
    turn within each repeat (a change of the machine's load affects them alike)."""
    times = [[] for _ in fns]
    for _ in range(repeat):
        for fn, out in zip(fns, times, strict=True):
            t = time.perf_counter()
            fn()
            out.append(time.perf_counter() - t)
    return [1e6 * float(np.median(t)) / n for t in times]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=3000, help="poses on the smooth path")
    parser.add_argument("--repeat", type=int, default=20, help="repeats of the fast trackers")
    parser.add_argument("--repeat-cvodes", type=int, default=1, help="repeats of CVODES")
    parser.add_argument(
        "--cvodes-samples", type=int, default=0, help="CVODES on the first samples only (0: all)"
    )
    parser.add_argument("--opt", default="", help="e.g. -O1,-O2,-O3: time each level")
    args = parser.parse_args()

    model = sc.load_model(MODEL)
    A, B = anchors(MODEL)
    X = smooth_path(model.home.x, args.samples)
    thetas = leg_lengths(X, A, B)
    start = model.home
    lib = tracker_library(model)  # compiled once, cached on disk
    y0, c0 = model.chart.to_local(start.y)
    n = len(thetas)

    x_c = sc.track(model, thetas, start=start, backend="c").x
    x_newton = newton_tracker(A, B, start.x, thetas)
    workdir = tempfile.TemporaryDirectory()
    newton_in_c = c_newton(Path(workdir.name))
    x_newton_c = newton_in_c(A, B, start.x, thetas)
    nc = args.cvodes_samples if 0 < args.cvodes_samples < n else n
    t0 = time.perf_counter()
    x_cvodes = cvodes_tracker(model, thetas[:nc], start)
    first_cvodes = 1e6 * (time.perf_counter() - t0) / nc

    t_c, t_track_c, t_newton_c = interleaved(
        [
            lambda: lib.track(y0, c0, start.theta, thetas),
            lambda: sc.track(model, thetas, start=start, backend="c"),
            lambda: newton_in_c(A, B, start.x, thetas),
        ],
        n,
        args.repeat,
    )
    t_newton = per_step(lambda: newton_tracker(A, B, start.x, thetas), n, max(3, args.repeat // 4))
    t_cvodes = first_cvodes
    if args.repeat_cvodes > 1:
        t_cvodes = per_step(
            lambda: cvodes_tracker(model, thetas[:nc], start), nc, args.repeat_cvodes
        )

    source = "track(backend='cvodes')" if _cvodes_track() else "chained solve"
    if nc < n:
        source += f", first {nc} samples"
    print(f"models/stewart_gough, smooth 6-dof path of {n} samples (legs from closed-form IK)")
    print(f"{'tracker':<46}{'us/step':>10}{'speed-up':>10}{'vs C Newton':>13}"
          f"{'max |x - x_IK|':>16}")  # fmt: skip
    rows = [
        ("C tracker, one ctypes call", t_c, x_c, X),
        ("track(backend='c') (C call + Python)", t_track_c, x_c, X),
        (f"CVODES ({source})", t_cvodes, x_cvodes, X[:nc]),
        ("Newton, warm-started, plain C", t_newton_c, x_newton_c, X),
        ("Newton, warm-started (numpy baseline)", t_newton, x_newton, X),
    ]
    for name, t, x, truth in rows:
        err = float(np.max(np.abs(x - truth)))
        print(f"{name:<46}{t:>10.2f}{t_newton / t:>9.3g}x{t / t_newton_c:>12.3g}x{err:>16.1e}")
    print(f"C tracker vs CVODES: max |dx| = {np.max(np.abs(x_c[:nc] - x_cvodes)):.1e}")
    if args.opt:
        opt_levels(model, args.opt.split(","), thetas, n, args.repeat)
    workdir.cleanup()

    Xf = fold_path(model.home.x, 400)
    th_f = leg_lengths(Xf, A, B)
    start_f = model.inverse_kinematics(Xf[0])
    newton_f = newton_tracker(A, B, Xf[0], th_f[1:])
    print(f"\nthrough the singular orientation (yaw 1.40 -> 1.75 rad, {len(th_f) - 1} samples):")
    track = _cvodes_track()
    for every in (1, 10, 20):
        X_k, th_k = Xf[1::every], th_f[1::every]
        rows = [("C tracker", lambda th=th_k: track_c(model, th, start_f))]
        if track is not None:
            rows.append(
                ("CVODES", lambda th=th_k: track(model, th, start=start_f, backend="cvodes"))
            )
        for name, run in rows:
            try:
                res = run()
            except sc.ScdkError as exc:  # a refusal names the sample it could not judge
                print(f"  {len(th_k):>3} samples, {name:<9}: {type(exc).__name__}: {exc}")
                continue
            at = ", ".join(f"{c.x[5]:.4f} (after sample {c.index})" for c in res.crossings)
            err = np.max(np.abs(res.x - X_k))
            print(
                f"  {len(th_k):>3} samples, {name:<9}: max |x - x_IK| = {err:.1e}, "
                f"crossings at yaw = [{at}] rad"
            )
    err_n = np.max(np.abs(newton_f - Xf[1:]))
    name = "Newton"
    print(f"  {len(th_f) - 1:>3} samples, {name:<9}: max |x - x_IK| = {err_n:.1e} (turns back on "
          "the wrong branch)")  # fmt: skip


if __name__ == "__main__":
    main()
