"""Krawczyk tests of many points in one C call, in binary64 interval arithmetic.

``krawczyk.c`` (beside this module) replays the instruction lists of a square system's value
and Jacobian Functions on intervals ``[lo, hi]`` of binary64 numbers: each operation rounds to
nearest and moves each bound one binary64 number outward, which encloses the exact result of
the operations IEEE 754 rounds correctly (``+ - * /``, and squares, negation, doubling,
reciprocal and ``|.|`` built from them; the sign function is exact); ``sin`` and ``cos`` are
enclosed from those operations alone (reduction by an enclosure of pi/2, a Taylor polynomial
with the bound of its rest, the extrema an interval may hold), so revolute joints' rows
qualify. The test itself is the first box of its Python twin,
:func:`scdk_sym.algebraic.certify.krawczyk_arb.arb_krawczyk` (the box built the same way from
the Newton correction at the point, the same operator and tightening), so a point proven here
is proven by the same theorem; a point it does not prove (or a Function with other
operations, or no C compiler) goes to the ``arb`` test, which tries more boxes and says why
it fails.

The replays of 2, 4 or 8 points run at once, one per lane of a register of doubles (SSE2,
AVX2, AVX-512): each lane makes the operations of its point alone, so a point's outcome does
not depend on the width (:func:`replay` with ``lanes=True`` checks that a lane's values do
not depend on its neighbours). The library is compiled once and cached
(:func:`~scdk_sym.algebraic.clibrary.source_library`) with flags that keep every operation as
written: no contraction into fused multiply-adds, no value-changing optimisations; the
rounding mode is the default round-to-nearest.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import casadi as ca
import numpy as np

from ...errors import BuildError, InputError
from ...symbolic.instructions import instructions
from ..clibrary import simd_flags, source_library

#: Flags of the interval library (warnings are errors; ISO C without fused multiply-adds or
#: other value-changing optimisations: -O3 inlines and unrolls, every operation still rounds
#: as written).
IKRAWCZYK_CFLAGS = (
    "-std=c99", "-O3", "-ffp-contract=off", "-fno-fast-math", "-shared", "-fPIC", "-Wall",
    "-Wextra", "-Werror",
)  # fmt: skip

#: CasADi opcodes -> tape codes of ``krawczyk.h`` (inputs, constants and outputs apart).
_UNARY = {
    ca.OP_ASSIGN: 3, ca.OP_NEG: 4, ca.OP_SQ: 5, ca.OP_TWICE: 6, ca.OP_INV: 7, ca.OP_FABS: 8,
    ca.OP_SIGN: 13, ca.OP_SIN: 14, ca.OP_COS: 15,
}  # fmt: skip
_BINARY = {ca.OP_ADD: 9, ca.OP_SUB: 10, ca.OP_MUL: 11, ca.OP_DIV: 12}
_CONST, _INPUT, _OUTPUT = 0, 1, 2
PROVEN = 1
_I64 = ctypes.POINTER(ctypes.c_int64)
_DBL = ctypes.POINTER(ctypes.c_double)


class _Tape(ctypes.Structure):
    """``scdk_tape`` of ``krawczyk.h``."""

    _fields_ = [
        ("L", ctypes.c_int64),
        ("W", ctypes.c_int64),
        ("n_out", ctypes.c_int64),
        ("op", _I64),
        ("a", _I64),
        ("b", _I64),
        ("o", _I64),
        ("c", _DBL),
    ]


@dataclass(frozen=True)
class Tape:
    """The instruction list of a Function ``(x, p) -> out`` for the interval replay.

    Attributes:
        struct: the C structure (pointing into ``arrays``).
        arrays: (op, a, b, o) int64 and c float64 arrays, kept alive with the structure.
        in_sizes: entries of ``x`` and ``p``.
    """

    struct: _Tape
    arrays: tuple[np.ndarray, ...]
    in_sizes: tuple[int, int]


def tape(f: ca.Function) -> Tape | None:
    """The tape of an SX Function ``(x, p) -> out`` (output 0, dense, column-major).

    Returns:
        The :class:`Tape`, or ``None`` when ``f`` uses an operation the interval replay does
        not enclose (e.g. ``sqrt``, ``exp``, powers): such a system stays with the ``arb``
        replay.
    """
    if f.n_in() != 2 or f.n_out() < 1:
        return None
    rows: list[tuple[int, int, int, int, float]] = []
    width = 0
    for ins in instructions(f):
        op, a, r = ins.op, ins.args, ins.out
        if op == ca.OP_OUTPUT:
            if r != 0:
                continue
            rows.append((_OUTPUT, a[0], 0, ins.position, 0.0))
            width = max(width, a[0] + 1)
            continue
        if op == ca.OP_CONST:
            rows.append((_CONST, 0, 0, r, ins.constant))
        elif op == ca.OP_INPUT:
            rows.append((_INPUT, a[0], ins.position, r, 0.0))
        elif op in _UNARY:
            rows.append((_UNARY[op], a[0], 0, r, 0.0))
        elif op in _BINARY:
            rows.append((_BINARY[op], a[0], a[1], r, 0.0))
        else:
            return None
        width = max(width, r + 1)
    cols = list(zip(*rows, strict=True)) if rows else [(), (), (), (), ()]
    ops, ia, ib, io = (np.ascontiguousarray(col, dtype=np.int64) for col in cols[:4])
    consts = np.ascontiguousarray(cols[4], dtype=np.float64)
    struct = _Tape(
        len(rows), width, f.numel_out(0),
        ops.ctypes.data_as(_I64), ia.ctypes.data_as(_I64), ib.ctypes.data_as(_I64),
        io.ctypes.data_as(_I64), consts.ctypes.data_as(_DBL),
    )  # fmt: skip
    return Tape(struct, (ops, ia, ib, io, consts), (f.numel_in(0), f.numel_in(1)))


_LIBRARIES: dict[tuple[str, ...], ctypes.CDLL] = {}


def source_dir() -> Path:
    """The directory of ``krawczyk.c`` and ``krawczyk.h`` (package data, beside this
    module)."""
    return Path(str(resources.files("scdk_sym.algebraic.certify")))


def _library(simd: tuple[str, ...] | None = None) -> ctypes.CDLL:
    """The interval library, compiled once per instruction-set flags (default
    :func:`~scdk_sym.algebraic.clibrary.simd_flags`; the points tested at once are the doubles
    of one register of that set, and each point's outcome does not depend on it)."""
    simd = simd_flags() if simd is None else simd
    if simd not in _LIBRARIES:
        source = source_dir() / "krawczyk.c"
        lib = ctypes.CDLL(str(source_library(source, (*IKRAWCZYK_CFLAGS, *simd))))
        f = lib.scdk_ikrawczyk
        dbl = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
        i64 = np.ctypeslib.ndpointer(dtype=np.int64, flags="C_CONTIGUOUS")
        I = ctypes.c_int64  # noqa: E741
        D = ctypes.c_double
        f.argtypes = [ctypes.POINTER(_Tape), ctypes.POINTER(_Tape), I, I, I, dbl, dbl, dbl, I,
                      I, D, D, i64, dbl, dbl]  # fmt: skip
        f.restype = ctypes.c_int
        g = lib.scdk_ireplay
        g.argtypes = [ctypes.POINTER(_Tape), I, I, dbl, dbl, dbl, I]
        g.restype = ctypes.c_int
        _LIBRARIES[simd] = lib
    return _LIBRARIES[simd]


def replay(
    t: Tape, x: np.ndarray, p: np.ndarray, lanes: bool = False, simd: tuple[str, ...] | None = None
) -> np.ndarray | None:
    """One interval evaluation of a tape (the operations the test uses).

    Args:
        t: the tape of ``(x, p) -> out``.
        x: (n, 2) ``[lo, hi]`` of the first input.
        p: (k, 2) ``[lo, hi]`` of the second input.
        lanes: lane 0 on ``x`` and ``p`` and the other lanes of the evaluation on them
            scaled by ``1 + l 2^-10``, each lane checked against an evaluation with its
            inputs in every lane (else every lane on ``x`` and ``p``).
        simd: the library's instruction-set flags (default: this processor's).

    Returns:
        (n_out, 2) ``[lo, hi]`` enclosing every value of ``out`` over the boxes, or ``None``
        where a bound is not finite or a divisor interval holds 0.

    Raises:
        InputError: ``x`` or ``p`` do not have the tape's sizes.
        BuildError: with ``lanes``, a lane's value depends on its lane or its neighbours
            (the library is miscompiled).
    """
    x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1, 2)
    p = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 2)
    if (len(x), len(p)) != t.in_sizes:
        raise InputError(
            f"the tape takes {t.in_sizes[0]} and {t.in_sizes[1]} intervals, got {len(x)} and "
            f"{len(p)}; pass (n, 2) and (k, 2) [lo, hi] arrays"
        )
    out = np.empty((t.struct.n_out, 2))
    rc = _library(simd).scdk_ireplay(ctypes.byref(t.struct), len(x), len(p), x, p, out,
                                     int(lanes))  # fmt: skip
    if rc == 4:
        raise BuildError(
            f"the interval library's lanes {simd_flags() if simd is None else simd} depend on "
            "each other; rebuild it with other flags or report the compiler"
        )
    return None if rc else out


@dataclass(frozen=True)
class IntervalKrawczyk:
    """The binary64 interval Krawczyk test of one square system (see the module docs).

    Attributes:
        n: unknowns (and rows).
        n_params: parameters.
        value: tape of ``(x, p) -> f`` (n,).
        jacobian: tape of ``(x, p) -> J^T`` (n x n dense column-major, i.e. J row-major).
    """

    n: int
    n_params: int
    value: Tape
    jacobian: Tape

    def test(
        self,
        m: np.ndarray,
        p_bounds: np.ndarray,
        tighten: int,
        tiny: float,
        max_condition: float,
        simd: tuple[str, ...] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Test ``N`` points in one call.

        Args:
            m: (N, n) points: the centres of the boxes.
            p_bounds: (k, 2) ``[lo, hi]`` of each parameter (``lo == hi``: exact), or
                (N, k, 2) a box per point.
            tighten: most Krawczyk steps that shrink a proven enclosure.
            tiny: smallest box radius.
            max_condition: no test where the condition estimate of ``J(m)`` is not below.
            simd: the library's instruction-set flags (default: this processor's).

        Returns:
            ``(proven (N,) bool, r (N, n) radii of the boxes X, box (N, n, 2) enclosures)``;
            nothing is proven if the C call fails (no memory): the ``arb`` test then runs.
        """
        m = np.ascontiguousarray(m, dtype=np.float64)
        N = len(m)
        status = np.zeros(N, dtype=np.int64)
        r = np.empty((N, self.n))
        box = np.empty((N, self.n, 2))
        stride = self.n_params if p_bounds.ndim == 3 else 0
        lo = np.ascontiguousarray(p_bounds[..., 0], dtype=np.float64)
        hi = np.ascontiguousarray(p_bounds[..., 1], dtype=np.float64)
        rc = _library(simd).scdk_ikrawczyk(
            ctypes.byref(self.value.struct), ctypes.byref(self.jacobian.struct), self.n,
            self.n_params, N, m, lo, hi, stride, int(tighten), float(tiny),
            float(max_condition), status, r, box,
        )  # fmt: skip
        if rc:
            status[:] = 0
        return status == PROVEN, r, box


def interval_krawczyk(
    value: ca.Function, jacobian_t: ca.Function, n: int, n_params: int
) -> IntervalKrawczyk | None:
    """The binary64 interval test of a square system, or ``None`` where it does not apply.

    Args:
        value: SX Function ``(x[n], p[k]) -> f[n]``.
        jacobian_t: SX Function ``(x[n], p[k]) -> J^T`` (n x n).
        n: unknowns.
        n_params: parameters.

    Returns:
        The test, or ``None`` when a Function uses another operation than those of the module
        docs or no C compiler builds the library.
    """
    tv, tj = tape(value), tape(jacobian_t)
    if tv is None or tj is None:
        return None
    try:
        _library()
    except BuildError:
        return None
    return IntervalKrawczyk(n, n_params, tv, tj)
