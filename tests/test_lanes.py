"""Lane evaluation of SX Functions (scdk_sym.kernels.lanes) against CasADi's own evaluation."""

from __future__ import annotations

import ctypes

import casadi as ca
import numpy as np
import pytest

from scdk_sym.algebraic.pairs import complexify
from scdk_sym.errors import BuildError
from scdk_sym.kernels.compile import run_compiler
from scdk_sym.kernels.lanes import lane_source

LANES = 4
#: A C wrapper: lane-major doubles in and out (input i's nonzero j of lane l at
#: (offset_i + j) * LANES + l), every output dense.
WRAPPER = """
#include <math.h>
#define SCDK_LANES 4
typedef double vd __attribute__((vector_size(8 * SCDK_LANES)));
#define SCDK_SPLAT(x) ((vd){0} + (x))
#include "f.c"
void run(const double *in, double *out, const long long *sizes_in, long long n_in,
         const long long *sizes_out, long long n_out) {
    const vd *arg[8];
    vd *res[8];
    const vd *x = (const vd *)in;
    vd *y = (vd *)out;
    for (long long i = 0; i < n_in; ++i) { arg[i] = x; x += sizes_in[i]; }
    for (long long i = 0; i < n_out; ++i) { res[i] = y; y += sizes_out[i]; }
    scdk_eval(arg, res);
}
"""


def lane_eval(f: ca.Function, tmp_path, points: list[list[np.ndarray]]) -> list[list[np.ndarray]]:
    """Evaluate ``f`` at LANES points in one call of its compiled lane source."""
    (tmp_path / "f.c").write_text(lane_source(f, "scdk_eval"))
    (tmp_path / "w.c").write_text(WRAPPER)
    lib_path = tmp_path / "w.so"
    run_compiler(["-O2", "-shared", "-fPIC", f"-I{tmp_path}", str(tmp_path / "w.c"), "-o",
                  str(lib_path), "-lm"])  # fmt: skip
    lib = ctypes.CDLL(str(lib_path))
    sin = np.array([f.nnz_in(i) for i in range(f.n_in())], dtype=np.int64)
    sout = np.array([f.numel_out(i) for i in range(f.n_out())], dtype=np.int64)
    x = np.stack([np.concatenate([np.ravel(a, order="F") for a in pt]) for pt in points], axis=1)
    x = np.ascontiguousarray(x)
    y = np.zeros((int(sout.sum()), LANES))
    p = ctypes.POINTER(ctypes.c_double)
    q = ctypes.POINTER(ctypes.c_longlong)
    lib.run(x.ctypes.data_as(p), y.ctypes.data_as(p), sin.ctypes.data_as(q), len(sin),
            sout.ctypes.data_as(q), len(sout))  # fmt: skip
    outs, start = [], np.r_[0, np.cumsum(sout)]
    for lane in range(LANES):
        outs.append([y[start[i] : start[i + 1], lane] for i in range(f.n_out())])
    return outs


def test_lanes_equal_casadi_on_a_complexified_trigonometric_system(tmp_path):
    z, p = ca.SX.sym("z", 3), ca.SX.sym("p", 2)
    rows = ca.vertcat(
        z[0] ** 3 - p[0] * z[1] * z[2] + 2.5,
        ca.sin(z[0]) * ca.cos(z[1]) - z[2] / p[1],
        z[1] * z[1] - 1.0 / (z[0] + 3.0) + p[0] * p[1],
    )
    f = complexify(ca.Function("G", [z, p], [rows]), "G_pairs")
    rng = np.random.default_rng(5)
    points = [[rng.normal(size=3), rng.normal(size=3), rng.normal(size=2) + 2.0,
               rng.normal(size=2)] for _ in range(LANES)]  # fmt: skip
    got = lane_eval(f, tmp_path, points)
    for lane, pt in enumerate(points):
        want = [np.ravel(np.asarray(o), order="F") for o in f(*pt)]
        for g, w in zip(got[lane], want, strict=True):
            np.testing.assert_allclose(g, w, rtol=1e-14, atol=1e-14)


def test_an_operation_with_no_lane_form_is_refused():
    x = ca.SX.sym("x")
    with pytest.raises(BuildError, match="no lane evaluation"):
        lane_source(ca.Function("f", [x], [ca.sqrt(x)]), "scdk_eval")
