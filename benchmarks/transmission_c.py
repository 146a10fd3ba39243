"""The generated C transmission of a leg controller, per reading, on digit_like's ankle.

``scdk codegen tests/fixtures/gepetto/digit_like --outputs motor_hip_x,...,free_foot2`` is
generated and compiled here with the C helpers below, every source with ``-std=c99 -O2``. On a
2000-reading motion of the ankle motors (motor_shin1, motor_shin2: 0.25 rad sines of 1 and
1.5 Hz from home, 1 kHz readings; the other motors at home), each run in one ctypes call and
timed in turn within each repeat (medians printed, microseconds per reading):

- the C transmission: ``scdk_forward`` (the singularity-consistent tracker, warm-started from
  the last reading), ``scdk_forward`` + ``scdk_jacobian`` (J = d outputs / d motors at the
  reading's solution, with its singular test: its own kernel, ``scdk_loop_jac``, J_p and J_s
  of the closures in each loop's root frame, and the LU of each stage of J_p), and
  ``scdk_margin`` alone (exact singular values of every block);
- the baseline, measured in the same run: a plain warm-started Newton iteration in C on the
  same 18 closure equations with the same generated kernels (``scdk_fwd_gjp``: g and J_p,
  LU of scdk_lu.h, until max |g| <= 1e-12; no branch control, no check), and that Newton
  followed by a plain Jacobian (``scdk_fwd_closure`` and one LU solve of J_p^-1 J_s, no
  singular test); ratios are to the plain Newton. The tracker factors J_p by the blocks of its
  block-triangular form (a 6 x 6 knee block, a 12 x 12 ankle block, instead of the whole
  18 x 18): the same Newton with that block LU is timed too, for the share of the difference
  that the factorisation makes;
- a lookup table of the ankle map (motor_shin1, motor_shin2) -> (free_foot1, free_foot2) on a
  0.4-degree grid over the motor box home +- 0.3 rad (the rest of the leg at home), filled from
  the transmission's forward map (the C one, equal to ``sc.transmission``'s to 1e-10: its
  tests) and assembled in numpy, read by bilinear interpolation in C (the cells with all four
  corners reachable); its time per reading and its worst error against our forward along the
  motion, side by side.

    python benchmarks/transmission_c.py [--repeat 15] [--samples 2000]
"""

from __future__ import annotations

import argparse
import ctypes
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.errors import ModelWarning
from scdk_sym.kernels.compile import compile_parallel
from scdk_sym.robot.blocks import triangular_blocks
from scdk_sym.solvers.transmission_c import write_transmission

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "tests" / "fixtures" / "gepetto" / "digit_like"
OUTPUTS = ("motor_hip_x", "motor_hip_y", "motor_hip_z", "free_knee", "free_foot1", "free_foot2")
ANKLE_MOTORS, ANKLE_OUTPUTS = ("motor_shin1", "motor_shin2"), ("free_foot1", "free_foot2")
FLAGS = ("-std=c99", "-O2", "-fPIC")
BOX, STEP = 0.3, np.deg2rad(0.4)  # the table: home +- BOX rad, STEP between grid lines

HELPERS = r"""
#include <math.h>
#include <string.h>

#include "scdk_lu.h"
#include "scdk_transmission.h"

#define K SCDK_NMOTORS
#define N SCDK_NOUTPUTS
#define M SCDK_FWD_NY

static double residual(const double *y, const double *theta, double *g, double *Jp);

/* the transmission along n readings (n x K): what = 1 forward, 3 forward + Jacobian,
 * 5 forward + margin; outputs n x N. Returns 0 or the first error. */
int bench_transmission(scdk_transmission *t, long n, const double *thetas, int what,
                       double *outs) {
    double J[N * K], value;
    int worst, s;
    long i;
    for (i = 0; i < n; ++i) {
        s = scdk_forward(t, thetas + i * K, K, outs + i * N, N);
        if (s < 0) return s;
        if ((what & 2) && (s = scdk_jacobian(t, J, N * K)) < 0) return s;
        if ((what & 4) && (s = scdk_margin(t, &value, &worst, NULL, 0)) < 0) return s;
    }
    return 0;
}

/* plain Newton on g(y, theta) = 0 warm-started from the last reading (from home), with g
 * and J_p of the generated kernel, until max |g| <= 1e-12; with_jacobian: then
 * J_p^-1 J_s (closure kernel, one LU). out_y: output i is unknown out_y[i] (>= 0) or motor
 * -1 - out_y[i]. Returns the iterations, or -1 if one reading did not converge. */
long bench_newton(long n, const double *thetas, int with_jacobian, const int *out_y,
                  double *outs) {
    const casadi_real *arg[SCDK_FWD_SZ_ARG];
    casadi_real *res[SCDK_FWD_SZ_RES];
    casadi_int iw[SCDK_FWD_SZ_IW];
    casadi_real w[SCDK_FWD_SZ_W];
    double y[M], g[M], Jp[M * M], Js[M * K];
    int piv[M], it, r, j;
    long i, iterations = 0;
    memcpy(y, scdk_fwd_home_y, sizeof y);
    for (i = 0; i < n; ++i) {
        const double *th = thetas + i * K;
        for (it = 0; it < 30; ++it) {
            double big = 0.0;
            arg[0] = y, arg[1] = th, arg[2] = scdk_fwd_home_c, res[0] = g, res[1] = Jp;
            scdk_fwd_gjp(arg, res, iw, w, 0);
            for (r = 0; r < M; ++r) big = fabs(g[r]) > big ? fabs(g[r]) : big;
            if (big <= 1e-12) break;
            if (!scdk_lu_factor(Jp, NULL, M, 1, M, piv)) return -1;
            scdk_lu_solve(Jp, NULL, M, 1, M, piv, g, NULL, 1, 0);
            for (r = 0; r < M; ++r) y[r] -= g[r];
            ++iterations;
        }
        if (it == 30) return -1;
        if (with_jacobian) {
            arg[0] = y, arg[1] = th, arg[2] = scdk_fwd_home_c, res[0] = NULL, res[1] = Jp;
            res[2] = Js;
            scdk_fwd_closure(arg, res, iw, w, 0);
            if (!scdk_lu_factor(Jp, NULL, M, 1, M, piv)) return -1;
            for (j = 0; j < K; ++j) scdk_lu_solve(Jp, NULL, M, 1, M, piv, Js + j * M, NULL, 1, 0);
        }
        for (r = 0; r < N; ++r) outs[i * N + r] = out_y[r] >= 0 ? y[out_y[r]] : th[-1 - out_y[r]];
    }
    return iterations;
}

/* bench_newton (no Jacobian) with J_p factored as the tracker does (its block-triangular form:
 * rows, cols in block order, block b on start[b] .. start[b + 1] - 1; each diagonal block by
 * scdk_lu.h, the blocks below the diagonal applied in the forward substitution) */
long bench_newton_blocks(long n, const double *thetas, const int *out_y, const int *rows,
                         const int *cols, const int *start, int nblocks, double *outs) {
    double y[M], g[M], Jp[M * M], B[M * M], x[M];
    int piv[M], it, r, c, b;
    long i, iterations = 0;
    memcpy(y, scdk_fwd_home_y, sizeof y);
    for (i = 0; i < n; ++i) {
        const double *th = thetas + i * K;
        for (it = 0; it < 30 && residual(y, th, g, Jp) > 1e-12; ++it, ++iterations) {
            for (c = 0; c < M; ++c)
                for (r = 0; r < M; ++r) B[r + c * M] = Jp[rows[r] + cols[c] * M];
            for (r = 0; r < M; ++r) x[r] = g[rows[r]];
            for (b = 0; b < nblocks; ++b) {
                const int s = start[b], m = start[b + 1] - s;
                for (c = 0; c < s; ++c)
                    for (r = s; r < s + m; ++r) x[r] -= B[r + c * M] * x[c];
                if (!scdk_lu_factor(B + s + s * M, NULL, m, 1, M, piv + s)) return -1;
                scdk_lu_solve(B + s + s * M, NULL, m, 1, M, piv + s, x + s, NULL, 1, 0);
            }
            for (r = 0; r < M; ++r) y[cols[r]] -= x[r];
        }
        if (it == 30) return -1;
        for (r = 0; r < N; ++r) outs[i * N + r] = out_y[r] >= 0 ? y[out_y[r]] : th[-1 - out_y[r]];
    }
    return iterations;
}

/* g and J_p at (y, theta) by the generated kernel (home chart); returns max |g| */
static double residual(const double *y, const double *theta, double *g, double *Jp) {
    const casadi_real *arg[SCDK_FWD_SZ_ARG];
    casadi_real *res[SCDK_FWD_SZ_RES];
    casadi_int iw[SCDK_FWD_SZ_IW];
    casadi_real w[SCDK_FWD_SZ_W];
    double big = 0.0;
    int r;
    arg[0] = y, arg[1] = theta, arg[2] = scdk_fwd_home_c, res[0] = g, res[1] = Jp;
    scdk_fwd_gjp(arg, res, iw, w, 0);
    for (r = 0; r < M; ++r) big = fabs(g[r]) > big ? fabs(g[r]) : big;
    return big;
}

/* bilinear interpolation of a table (na x nb x 2, row-major) over the grid a0 + h i,
 * b0 + h j at n points ab (n x 2) into out (n x 2); NaN outside */
void bench_lookup(long n, const double *ab, const double *table, int na, int nb, double a0,
                  double b0, double h, double *out) {
    long p;
    for (p = 0; p < n; ++p) {
        const double u = (ab[2 * p] - a0) / h, v = (ab[2 * p + 1] - b0) / h;
        const int i = (int)floor(u), j = (int)floor(v);
        const double fu = u - i, fv = v - j;
        int c;
        if (i < 0 || j < 0 || i >= na - 1 || j >= nb - 1) {
            out[2 * p] = out[2 * p + 1] = NAN;
            continue;
        }
        for (c = 0; c < 2; ++c) {
            const double *q = table + ((long)i * nb + j) * 2 + c;
            out[2 * p + c] = (1 - fu) * ((1 - fv) * q[0] + fv * q[2]) +
                             fu * ((1 - fv) * q[2 * nb] + fv * q[2 * nb + 2]);
        }
    }
}
"""

_dp = ctypes.POINTER(ctypes.c_double)


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_dp)


class Library:
    """The generated transmission and the helpers, compiled into one shared library."""

    def __init__(self, model: sc.Model, work: Path) -> None:
        src = write_transmission(model, OUTPUTS, work)
        (work / "bench.c").write_text(HELPERS)
        path = compile_parallel([*src.sources, work / "bench.c"], work / "libbench.so",
                                FLAGS, ("-shared",), cwd=work)  # fmt: skip
        self.lib = ctypes.CDLL(str(path))
        self.lib.bench_newton.restype = ctypes.c_long
        self.lib.bench_newton_blocks.restype = ctypes.c_long
        self.state = ctypes.create_string_buffer(self.lib.scdk_transmission_size())
        self.k, self.n = model.k, len(OUTPUTS)
        index = [model.unknowns.index(o) if o in model.unknowns else -1 - model.actuated.index(o)
                 for o in OUTPUTS]  # fmt: skip
        self.out_y = np.array(index, dtype=np.intc)
        parts = triangular_blocks(model)  # the tracker's blocks of J_p
        self.blocks = [np.array([i for b in parts for i in b.rows], dtype=np.intc),
                       np.array([i for b in parts for i in b.unknowns], dtype=np.intc)]  # fmt: skip
        self.start = np.cumsum([0] + [len(b.rows) for b in parts]).astype(np.intc)

    def forward(self, thetas: np.ndarray, what: int = 1) -> np.ndarray:
        """(N, n) outputs along the readings from home (what: 1, 3 with J, 5 with margin)."""
        th = np.ascontiguousarray(thetas, dtype=float)
        out = np.full((len(th), self.n), np.nan)
        assert self.lib.scdk_transmission_init(self.state, None, None) == 0
        status = self.lib.bench_transmission(self.state, len(th), _ptr(th), what, _ptr(out))
        if status < 0:
            raise RuntimeError(f"C transmission refused a reading: status {status}")
        return out

    def margins(self, thetas: np.ndarray) -> np.ndarray:
        """(N,) the margin at each reading, from home."""
        assert self.lib.scdk_transmission_init(self.state, None, None) == 0
        out, value, q = np.empty(len(thetas)), ctypes.c_double(), np.empty(self.n)
        for i, th in enumerate(np.ascontiguousarray(thetas, dtype=float)):
            assert self.lib.scdk_forward(self.state, _ptr(th), self.k, _ptr(q), self.n) >= 0
            self.lib.scdk_margin(self.state, ctypes.byref(value), None, None, 0)
            out[i] = value.value
        return out

    def newton(self, thetas: np.ndarray, with_jacobian: bool = False) -> tuple[np.ndarray, int]:
        th = np.ascontiguousarray(thetas, dtype=float)
        out = np.full((len(th), self.n), np.nan)
        index = self.out_y.ctypes.data_as(ctypes.c_void_p)
        iters = self.lib.bench_newton(len(th), _ptr(th), int(with_jacobian), index, _ptr(out))
        if iters < 0:
            raise RuntimeError("plain Newton did not converge")
        return out, iters

    def newton_blocks(self, thetas: np.ndarray) -> tuple[np.ndarray, int]:
        th = np.ascontiguousarray(thetas, dtype=float)
        out = np.full((len(th), self.n), np.nan)
        rows, cols = self.blocks
        iters = self.lib.bench_newton_blocks(
            len(th), _ptr(th), self.out_y.ctypes.data_as(ctypes.c_void_p),
            rows.ctypes.data_as(ctypes.c_void_p), cols.ctypes.data_as(ctypes.c_void_p),
            self.start.ctypes.data_as(ctypes.c_void_p), len(self.start) - 1, _ptr(out),
        )  # fmt: skip
        if iters < 0:
            raise RuntimeError("plain Newton (block LU) did not converge")
        return out, iters

    def lookup(self, table: np.ndarray, ab: np.ndarray, origin: np.ndarray) -> np.ndarray:
        ab = np.ascontiguousarray(ab, dtype=float)
        out = np.empty_like(ab)
        self.lib.bench_lookup(len(ab), _ptr(ab), _ptr(table), table.shape[0], table.shape[1],
                              ctypes.c_double(origin[0]), ctypes.c_double(origin[1]),
                              ctypes.c_double(STEP), _ptr(out))  # fmt: skip
        return out


def ankle_table(lib: Library, model: sc.Model) -> tuple[np.ndarray, np.ndarray]:
    """``(table (na, nb, 2), origin (2,))``: the ankle outputs on the grid over the motor box,
    each grid column walked from home along motor_shin1, then along motor_shin2 outwards
    (NaN where the forward map refuses: outside the reachable set)."""
    j1, j2 = (model.actuated.index(a) for a in ANKLE_MOTORS)
    count = int(np.ceil(2 * BOX / STEP)) + 1
    grid = -BOX + STEP * np.arange(count)
    middle = int(np.argmin(np.abs(grid)))
    table = np.full((count, count, 2), np.nan)
    cols = [OUTPUTS.index(o) for o in ANKLE_OUTPUTS]
    for i, a in enumerate(grid):
        approach = np.linspace(0.0, a, max(2, int(abs(a) / STEP) + 2))
        for half in (grid[middle:], grid[middle::-1]):
            th = np.repeat(model.home.theta[None], len(approach) + len(half), axis=0)
            th[: len(approach), j1] += approach
            th[len(approach) :, j1] += a
            th[len(approach) :, j2] += half
            out = _reachable_prefix(lib, th)
            done = max(0, len(out) - len(approach))
            rows = np.arange(middle, middle + done) if half[0] <= half[-1] else \
                np.arange(middle, middle - done, -1)  # fmt: skip
            table[i, rows] = out[len(approach) :][:, cols]
    return table, model.home.theta[[j1, j2]] - BOX


def _reachable_prefix(lib: Library, thetas: np.ndarray) -> np.ndarray:
    """The outputs of the longest prefix of the readings the forward map follows."""
    lo, hi = 0, len(thetas)
    while lo < hi:  # bisection on the first refused reading
        mid = (lo + hi + 1) // 2
        try:
            lib.forward(thetas[:mid])
            lo = mid
        except RuntimeError:
            hi = mid - 1
    return lib.forward(thetas[:lo]) if lo else np.zeros((0, len(OUTPUTS)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--samples", type=int, default=2000)
    args = parser.parse_args()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        model = sc.load_model(MODEL)
    j1, j2 = (model.actuated.index(a) for a in ANKLE_MOTORS)
    t = np.arange(1, args.samples + 1)[:, None] * 1e-3
    thetas = np.repeat(model.home.theta[None], args.samples, axis=0)
    thetas[:, [j1, j2]] += 0.25 * np.sin(2 * np.pi * np.array([1.0, 1.5]) * t)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        lib = Library(model, Path(tmp))
        print(f"generated and compiled in {time.perf_counter() - t0:.1f} s ({' '.join(FLAGS)})")
        ours = lib.forward(thetas, what=3)
        plain, iters = lib.newton(thetas)
        blocked, _ = lib.newton_blocks(thetas)
        t0 = time.perf_counter()
        table, origin = ankle_table(lib, model)
        built = time.perf_counter() - t0
        cols = [OUTPUTS.index(o) for o in ANKLE_OUTPUTS]
        looked = lib.lookup(table, thetas[:, [j1, j2]], origin)
        margins = lib.margins(thetas)
        runs = {
            "forward": lambda: lib.forward(thetas, 1),
            "forward + jacobian": lambda: lib.forward(thetas, 3),
            "forward + margin": lambda: lib.forward(thetas, 5),
            "newton": lambda: lib.newton(thetas),
            "newton + jacobian": lambda: lib.newton(thetas, True),
            "newton blocks": lambda: lib.newton_blocks(thetas),
            "lookup": lambda: lib.lookup(table, thetas[:, [j1, j2]], origin),
        }
        times: dict[str, list[float]] = {name: [] for name in runs}
        for _ in range(args.repeat):
            for name, run in runs.items():
                t0 = time.perf_counter()
                run()
                times[name].append(time.perf_counter() - t0)
    us = {name: float(np.median(v)) / args.samples * 1e6 for name, v in times.items()}
    base = us["newton"]
    print(f"digit_like, {args.samples} readings of the ankle motors (0.25 rad sines, 1 kHz), "
          f"medians of {args.repeat}, us per reading (ratio to the plain Newton):")  # fmt: skip
    for name, label in (
        ("newton", "baseline: plain C Newton on the 18 closures (g, J_p kernel)"),
        ("newton + jacobian", "plain C Newton + plain Jacobian (no singular test)"),
        ("newton blocks", "C Newton with J_p factored by blocks, as the tracker does"),
        ("forward", "C transmission forward (SC tracker)"),
        ("forward + jacobian", "C transmission forward + jacobian (with singular test)"),
        ("forward + margin", "C transmission forward + margin (exact SVDs)"),
        ("lookup", "lookup table, bilinear (C)"),
    ):
        print(f"  {label:<58}{us[name]:8.3f} us  {us[name] / base:6.2f}")
    print(f"  plain Newton: {iters / args.samples:.2f} iterations per reading, its outputs "
          f"within {np.abs(plain - ours).max():.1e} rad of the transmission's (by blocks: "
          f"{np.abs(blocked - ours).max():.1e})")  # fmt: skip
    reach = ~np.isnan(table[..., 0])
    error = np.abs(looked - ours[:, cols]).max(axis=1)
    worst, outside = int(np.nanargmax(error)), int(np.isnan(error).sum())
    print(f"lookup table: {table.shape[0]} x {table.shape[1]} points at 0.4 deg over home +- "
          f"{BOX} rad ({reach.sum()} reachable, {table.nbytes / 1024:.0f} KiB), filled in "
          f"{built:.1f} s; {outside} readings in cells not all reachable")  # fmt: skip
    print(f"  its error against our forward along the motion: worst {error[worst]:.2e} rad "
          f"({np.rad2deg(error[worst]):.2e} deg), median {np.nanmedian(error):.2e} rad; "
          f"ours: max |g| <= {model.tolerance:g} checked at every reading")  # fmt: skip
    print(f"  the worst at motor offsets {np.round(thetas[worst, [j1, j2]] - origin - BOX, 3)} "
          f"rad, where the margin is {margins[worst]:.1e} (at home {margins[0]:.1e})")  # fmt: skip


if __name__ == "__main__":
    main()
