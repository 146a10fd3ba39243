"""The square system ``f(x, p) = 0`` a Krawczyk test works on: its value and Jacobian
replayed in Arb balls, in binary64, and on binary64 intervals in C (rational systems), built
once per CasADi Function."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
from flint import arb_mat

from ...errors import InputError
from ...kernels.fastcall import Buffered
from ..interval import FunctionCache, IntervalFunction, as_sx_function, interval_function
from .krawczyk_c import IntervalKrawczyk, interval_krawczyk


@dataclass(frozen=True)
class Square:
    """The replays a Krawczyk test needs for one square system."""

    n: int
    n_params: int
    value: IntervalFunction  # (x, p) -> f, (n,)
    jacobian_t: IntervalFunction  # (x, p) -> J^T, dense column-major = J row-major
    numeric: Buffered  # (x, p) -> (f, J column-major) in binary64
    identity: arb_mat
    fast: IntervalKrawczyk | None  # the binary64 interval test (rational systems)


def _build_square(f: ca.Function) -> Square:
    f = as_sx_function(f)
    name = f.name()
    if f.n_in() not in (1, 2) or f.n_out() < 1:
        raise InputError(
            f"{name}: a system f(x) or f(x, p) has 1 or 2 inputs and an output, got "
            f"{f.n_in()} inputs, {f.n_out()} outputs; wrap it as casadi.Function([x, p], [f])"
        )
    n = f.numel_in(0)
    n_params = f.numel_in(1) if f.n_in() == 2 else 0
    x = ca.SX.sym("x", n)
    p = ca.SX.sym("p", n_params)
    args = [ca.reshape(x, f.size_in(0))]
    if f.n_in() == 2:
        args.append(ca.reshape(p, f.size_in(1)))
    g = ca.densify(ca.vec(f.call(args)[0]))
    if g.numel() != n:
        raise InputError(
            f"{name}: not square: {g.numel()} rows (output 0) for {n} unknowns (input 0); "
            f"select as many rows as unknowns"
        )
    J = ca.jacobian(g, x)
    value = ca.Function(f"{name}_value", [x, p], [g])
    jacobian_t = ca.Function(f"{name}_jacobian", [x, p], [J.T])
    return Square(
        n=n,
        n_params=n_params,
        value=interval_function(value),
        jacobian_t=interval_function(jacobian_t),
        numeric=Buffered(ca.Function(f"{name}_newton", [x, p], [g, ca.densify(J)])),
        identity=arb_mat(n, n, [1.0 if i == j else 0.0 for i in range(n) for j in range(n)]),
        fast=interval_krawczyk(value, jacobian_t, n, n_params),
    )


_SQUARES = FunctionCache(_build_square)


def square_system(f: ca.Function) -> Square:
    """The :class:`Square` of a system ``f(x) -> f`` or ``f(x, p) -> f``, built once per
    Function (kept while the Function lives).

    Raises:
        InputError: ``f`` is not a square system.
        IntervalError: ``f`` uses an operation without an interval counterpart.
    """
    return _SQUARES(f)
