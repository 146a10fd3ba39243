"""Complex evaluation of a real CasADi SX Function, replayed on (real, imaginary) pairs.

CasADi has no complex type. A real SX Function whose algorithm uses only +, -, *, /, integer
powers (CasADi expands them into products), cos, sin and constants has exactly one
holomorphic extension; :func:`complexify` replays its algorithm instruction by instruction on
pairs of SX expressions (real part, imaginary part) and returns an SX Function of the real and
imaginary parts of its inputs, with the complex Jacobians obtained from one real Jacobian
block (Cauchy-Riemann: ``dG/dz = dRe G/dRe z + i dIm G/dRe z``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca

from ..errors import AlgebraicFormError
from ..symbolic.instructions import instructions


@dataclass(frozen=True)
class Pair:
    """A complex scalar ``re + i im`` over CasADi SX.

    Attributes:
        re: real part (scalar SX).
        im: imaginary part (scalar SX).
    """

    re: ca.SX
    im: ca.SX

    def __add__(self, other: Pair) -> Pair:
        return Pair(self.re + other.re, self.im + other.im)

    def __sub__(self, other: Pair) -> Pair:
        return Pair(self.re - other.re, self.im - other.im)

    def __mul__(self, other: Pair) -> Pair:
        a, b, c, d = self.re, self.im, other.re, other.im
        return Pair(a * c - b * d, a * d + b * c)

    def __truediv__(self, other: Pair) -> Pair:
        a, b, c, d = self.re, self.im, other.re, other.im
        den = c * c + d * d
        return Pair((a * c + b * d) / den, (b * c - a * d) / den)

    def __neg__(self) -> Pair:
        return Pair(-self.re, -self.im)

    def cos(self) -> Pair:
        """``cos(a + ib) = cos a cosh b - i sin a sinh b``."""
        a, b = self.re, self.im
        return Pair(ca.cos(a) * ca.cosh(b), -ca.sin(a) * ca.sinh(b))

    def sin(self) -> Pair:
        """``sin(a + ib) = sin a cosh b + i cos a sinh b``."""
        a, b = self.re, self.im
        return Pair(ca.sin(a) * ca.cosh(b), ca.cos(a) * ca.sinh(b))


_BINARY: dict[int, Callable[[Any, Any], Any]] = {
    ca.OP_ADD: lambda x, y: x + y,
    ca.OP_SUB: lambda x, y: x - y,
    ca.OP_MUL: lambda x, y: x * y,
    ca.OP_DIV: lambda x, y: x / y,
}
_UNARY: dict[int, Callable[[Any], Any]] = {
    ca.OP_ASSIGN: lambda x: x,
    ca.OP_NEG: lambda x: -x,
    ca.OP_SQ: lambda x: x * x,
    ca.OP_TWICE: lambda x: x + x,
    ca.OP_COS: lambda x: x.cos(),
    ca.OP_SIN: lambda x: x.sin(),
}


def _pair_constant(value: float) -> Pair:
    return Pair(ca.SX(value), ca.SX(0.0))


def replay(
    f: ca.Function, inputs: list[list], constant: Callable[[float], Any] = _pair_constant
) -> list[list]:
    """Evaluate a real SX Function on complex pairs (or on any other number type).

    Args:
        f: an SX Function with dense inputs and outputs.
        inputs: for each input of ``f``, one :class:`Pair` per element (column-major).
        constant: the number of a real constant; the values (inputs and constants) support
            ``+``, ``-``, ``*``, ``/``, unary ``-``, ``.cos()`` and ``.sin()`` (default:
            :class:`Pair`; e.g. sparse polynomials expand ``f`` instead).

    Returns:
        For each output of ``f``, one value per element (column-major).

    Raises:
        AlgebraicFormError: ``f`` uses an operation with no holomorphic polynomial form
            (e.g. sqrt, atan2, comparisons).
    """
    outputs = [[constant(0.0)] * f.nnz_out(i) for i in range(f.n_out())]
    work: dict[int, Any] = {}
    for ins in instructions(f):
        op, args, r = ins.op, ins.args, ins.out
        if op == ca.OP_INPUT:
            work[r] = inputs[args[0]][args[1]]
        elif op == ca.OP_OUTPUT:
            outputs[r][ins.nz] = work[args[0]]
        elif op == ca.OP_CONST:
            work[r] = constant(ins.constant)
        elif op == ca.OP_INV:
            work[r] = constant(1.0) / work[args[0]]
        elif op in _BINARY:
            work[r] = _BINARY[op](work[args[0]], work[args[1]])
        elif op in _UNARY:
            work[r] = _UNARY[op](work[args[0]])
        else:
            raise AlgebraicFormError(
                f"CasADi operation {op} in {f.name()!r} has no holomorphic polynomial form; "
                "build the rows from +, -, *, integer powers, cos and sin only"
            )
    return outputs


def complexify(f: ca.Function, name: str) -> ca.Function:
    """The holomorphic extension of a real SX Function ``(z[n], p[k]) -> G[r]``, with Jacobians.

    Args:
        f: SX Function with two dense column inputs ``z`` (n,) and ``p`` (k,) and one dense
            column output ``G`` (r,).
        name: name of the returned Function.

    Returns:
        SX Function ``(zr[n], zi[n], pr[k], pi[k]) -> (Gr[r], Gi[r], Jz_r[r,n], Jz_i[r,n],
        Jp_r[r,k], Jp_i[r,k])``: real and imaginary parts of ``G(z, p)``, of ``dG/dz`` and of
        ``dG/dp`` at ``z = zr + i zi``, ``p = pr + i pi`` (dense).
    """
    n, k = f.size1_in(0), f.size1_in(1)
    zr, zi = ca.SX.sym("zr", n), ca.SX.sym("zi", n)
    pr, pi = ca.SX.sym("pr", k), ca.SX.sym("pi", k)
    z = [Pair(zr[i], zi[i]) for i in range(n)]
    p = [Pair(pr[i], pi[i]) for i in range(k)]
    (G,) = replay(f, [z, p])
    Gr = ca.vertcat(*[g.re for g in G]) if G else ca.SX(0, 1)
    Gi = ca.vertcat(*[g.im for g in G]) if G else ca.SX(0, 1)
    # Cauchy-Riemann: the derivative along the real direction is the complex derivative;
    # one Jacobian of the stacked real and imaginary parts shares their common subexpressions
    J = ca.densify(ca.jacobian(ca.vertcat(Gr, Gi), ca.vertcat(zr, pr)))
    r = Gr.numel()
    outs = [Gr, Gi, J[:r, :n], J[r:, :n], J[:r, n:], J[r:, n:]]
    return ca.Function(
        name,
        [zr, zi, pr, pi],
        outs,
        ["zr", "zi", "pr", "pi"],
        ["Gr", "Gi", "Jz_r", "Jz_i", "Jp_r", "Jp_i"],
    )
