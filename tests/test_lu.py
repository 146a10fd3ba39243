"""The package's one pivoted elimination in C (``kernels/c/scdk_lu.h``), real and complex,
column- and row-major, plain and transposed solves, against numpy's LAPACK solves and
determinants on seeded random matrices."""

from __future__ import annotations

import ctypes
import warnings

import casadi as ca
import numpy as np
import pytest
from factories import ROOT

import scdk_sym as sc
from scdk_sym.codegen.generate import generate
from scdk_sym.errors import ModelWarning
from scdk_sym.kernels.compile import LU_HEADER, run_compiler

WRAPPER = r"""
#include "scdk_lu.h"
int lu_real(double *a, int n, int rs, int cs, int *piv, double *b, int bs, int transposed,
            double *det) {
    if (!scdk_lu_factor(a, 0, n, rs, cs, piv)) return 0;
    *det = scdk_lu_det(a, n, rs, cs, piv);
    scdk_lu_solve(a, 0, n, rs, cs, piv, b, 0, bs, transposed);
    return 1;
}
int lu_complex(double *ar, double *ai, int n, int rs, int cs, int *piv, double *br, double *bi,
               int bs, int transposed) {
    if (!scdk_lu_factor(ar, ai, n, rs, cs, piv)) return 0;
    scdk_lu_solve(ar, ai, n, rs, cs, piv, br, bi, bs, transposed);
    return 1;
}
"""


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    d = tmp_path_factory.mktemp("lu")
    (d / "wrap.c").write_text(WRAPPER)
    flags = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC"]
    run_compiler([*flags, f"-I{LU_HEADER.parent}", str(d / "wrap.c"), "-o", str(d / "lu.so")])
    return ctypes.CDLL(str(d / "lu.so"))


def _p(a: np.ndarray):
    return a.ctypes.data_as(ctypes.c_void_p)


def _strides(n: int, order: str) -> tuple[int, int]:
    return (1, n) if order == "F" else (n, 1)


@pytest.mark.parametrize("order", ["F", "C"])
@pytest.mark.parametrize("transposed", [0, 1])
@pytest.mark.parametrize("n", [1, 4, 13])
def test_real_solve_and_determinant_equal_lapack(lib, order, transposed, n):
    rng = np.random.default_rng(100 * n + 10 * transposed + (order == "C"))
    for _ in range(5):
        A = rng.standard_normal((n, n))
        A[0] *= 1e-3  # a small first row: the pivoting must swap it away
        b = rng.standard_normal(n)
        a = np.array(A, order=order).ravel(order="K").copy()
        rs, cs = _strides(n, order)
        x, piv, det = b.copy(), np.zeros(n, dtype=np.intc), ctypes.c_double()
        ok = lib.lu_real(_p(a), n, rs, cs, _p(piv), _p(x), 1, transposed, ctypes.byref(det))
        assert ok == 1
        ref = np.linalg.solve(A.T if transposed else A, b)
        assert np.max(np.abs(x - ref)) <= 1e-10 * max(1.0, np.max(np.abs(ref)))
        assert abs(det.value - np.linalg.det(A)) <= 1e-10 * abs(np.linalg.det(A))


@pytest.mark.parametrize("transposed", [0, 1])
def test_complex_split_storage_with_a_strided_right_hand_side_equals_lapack(lib, transposed):
    """The homotopy tracker's layout: [A | b] row-major with the right-hand side as the last
    column (stride n + 1), real and imaginary parts apart."""
    rng = np.random.default_rng(7 + transposed)
    n = 9
    W = n + 1
    for _ in range(5):
        A = rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n))
        b = rng.standard_normal(n) + 1j * rng.standard_normal(n)
        aug = np.zeros((n, W), dtype=complex)
        aug[:, :n], aug[:, n] = A, b
        ar, ai = aug.real.copy().ravel(), aug.imag.copy().ravel()
        piv = np.zeros(n, dtype=np.intc)
        br, bi = ar[n:], ai[n:]  # views: column n of the row-major augmented matrix
        ok = lib.lu_complex(_p(ar), _p(ai), n, W, 1, _p(piv), _p(br), _p(bi), W, transposed)
        assert ok == 1
        x = ar[n::W] + 1j * ai[n::W]
        ref = np.linalg.solve(A.T if transposed else A, b)
        assert np.max(np.abs(x - ref)) <= 1e-10 * max(1.0, np.max(np.abs(ref)))


def test_a_zero_column_or_a_nan_fails_the_factorisation(lib):
    n = 3
    for bad in (0.0, np.nan):
        A = np.eye(n)
        A[:, 1] = bad
        a, x = np.asfortranarray(A).ravel(order="F").copy(), np.ones(n)
        piv, det = np.zeros(n, dtype=np.intc), ctypes.c_double()
        assert lib.lu_real(_p(a), n, 1, n, _p(piv), _p(x), 1, 0, ctypes.byref(det)) == 0


TRACKER_WRAPPER = r"""
#include "scdk_tracker.c"
int blocks(void) { return LU_BLOCKS; }
int factor_solve(double *a, int *piv, double *b, int transposed, double *det) {
    if (!lu_factor(a, piv)) return 0;
    *det = lu_det(a, piv);
    lu_solve(a, piv, b, transposed);
    return 1;
}
double rcond(double *a, int *piv) { return lu_factor(a, piv) ? rcond_lu(a, piv) : -1.0; }
"""


@pytest.fixture(scope="module")
def tracker_lu(tmp_path_factory):
    """name -> (the tracker's LU of J_p compiled from its generated source, model)."""
    out = {}
    for name in ("robot_delta", "digit_like"):
        d = tmp_path_factory.mktemp(name)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ModelWarning)
            model = sc.load_model(ROOT / "tests" / "fixtures" / "gepetto" / name)
        src = generate(model, d)
        (d / "wrap.c").write_text(TRACKER_WRAPPER)
        flags = ["-std=c99", "-O1", "-shared", "-fPIC", f"-I{d}"]
        run_compiler([*flags, str(d / "wrap.c"), str(src.kernels_c), "-o", str(d / "lu.so"), "-lm"])
        out[name] = (ctypes.CDLL(str(d / "lu.so")), model)
    return out


@pytest.mark.parametrize("name, count", [("robot_delta", 5), ("digit_like", 2)])
@pytest.mark.parametrize("transposed", [0, 1])
def test_the_trackers_block_lu_of_j_p_equals_lapack(tracker_lu, name, count, transposed):
    """The generated tracker factors J_p block by block (its fine block-triangular form):
    determinant and solves of matrices with J_p's structural sparsity and random entries equal
    numpy's (the sign of det decides the tracker's branches)."""
    lib, model = tracker_lu[name]
    lib.rcond.restype = ctypes.c_double
    assert lib.blocks() == count
    pattern = np.array(ca.DM(model.symbolic.J_p.sparsity(), 1), dtype=bool)
    m = model.m
    rng = np.random.default_rng(31 + m + transposed)
    for _ in range(5):
        A = np.where(pattern, rng.standard_normal((m, m)), 0.0)
        b = rng.standard_normal(m)
        a, x = np.asfortranarray(A).ravel(order="F").copy(), b.copy()
        piv, det = np.zeros(m, dtype=np.intc), ctypes.c_double()
        assert lib.factor_solve(_p(a), _p(piv), _p(x), transposed, ctypes.byref(det)) == 1
        ref = np.linalg.solve(A.T if transposed else A, b)
        assert np.max(np.abs(x - ref)) <= 1e-9 * max(1.0, np.max(np.abs(ref)))
        assert abs(det.value - np.linalg.det(A)) <= 1e-10 * abs(np.linalg.det(A))
        a = np.asfortranarray(A).ravel(order="F").copy()
        ref = 1.0 / (m * np.linalg.norm(A, 1) * np.linalg.norm(np.linalg.inv(A), 1))
        assert abs(lib.rcond(_p(a), _p(piv)) - ref) <= 1e-9 * ref  # the atlas sweep's bound
