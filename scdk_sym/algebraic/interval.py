"""Interval evaluation of CasADi SX Functions in ball arithmetic (python-flint ``arb``).

The algorithm of an SX Function (``Function.instruction_id/input/output/constant``: inputs,
constants, elementary operations, outputs, on a work vector) is translated once into
straight-line Python that performs the same operations on ``arb`` balls. Arb rounds every
operation outward, so each output ball contains the exact value of the Function's expression
graph for every input in the input balls (the Function's constants are the binary64 numbers
CasADi stores, taken as exact). Comparisons and ``if_else`` (e.g. in the derivatives of
``fmin``/``fmax``) give ``1`` or ``0`` where decided over the balls and the ball ``[0, 1]``
where not, so the result still encloses every branch.

The translation is cached per Function (up to :data:`CACHE_SIZE` Functions, least recently
used dropped), so repeated evaluations cost only the ball operations.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
from flint import arb

from ..errors import InputError, IntervalError
from ..symbolic.instructions import instructions

#: Number of Functions whose translation is kept.
CACHE_SIZE = 64

ZERO = arb(0)
ONE = arb(1)
#: The ball [0, 1]: an undecided comparison.
UNDECIDED = arb(0.5, 0.5)

_NAMES = {getattr(ca, n): n[3:].lower() for n in dir(ca) if n.startswith("OP_")}

#: Unary operations: CasADi opcode -> Python expression of the argument ``{0}``.
_UNARY = {
    ca.OP_ASSIGN: "{0}",
    ca.OP_NEG: "-{0}",
    ca.OP_SQ: "{0} * {0}",
    ca.OP_TWICE: "{0} + {0}",
    ca.OP_INV: "ONE / {0}",
    ca.OP_SQRT: "{0}.sqrt()",
    ca.OP_EXP: "{0}.exp()",
    ca.OP_LOG: "{0}.log()",
    ca.OP_EXPM1: "{0}.expm1()",
    ca.OP_LOG1P: "{0}.log1p()",
    ca.OP_SIN: "{0}.sin()",
    ca.OP_COS: "{0}.cos()",
    ca.OP_TAN: "{0}.tan()",
    ca.OP_ASIN: "{0}.asin()",
    ca.OP_ACOS: "{0}.acos()",
    ca.OP_ATAN: "{0}.atan()",
    ca.OP_SINH: "{0}.sinh()",
    ca.OP_COSH: "{0}.cosh()",
    ca.OP_TANH: "{0}.tanh()",
    ca.OP_ASINH: "{0}.asinh()",
    ca.OP_ACOSH: "{0}.acosh()",
    ca.OP_ATANH: "{0}.atanh()",
    ca.OP_ERF: "{0}.erf()",
    ca.OP_FABS: "abs({0})",
    ca.OP_SIGN: "{0}.sgn()",
    ca.OP_FLOOR: "{0}.floor()",
    ca.OP_CEIL: "{0}.ceil()",
    ca.OP_NOT: "_not({0})",
}

#: Binary operations: CasADi opcode -> Python expression of the arguments ``{0}``, ``{1}``.
_BINARY = {
    ca.OP_ADD: "{0} + {1}",
    ca.OP_SUB: "{0} - {1}",
    ca.OP_MUL: "{0} * {1}",
    ca.OP_DIV: "{0} / {1}",
    ca.OP_ATAN2: "_atan2({0}, {1})",
    ca.OP_FMIN: "{0}.min({1})",
    ca.OP_FMAX: "{0}.max({1})",
    ca.OP_HYPOT: "({0} * {0} + {1} * {1}).sqrt()",
    ca.OP_POW: "_pow({0}, {1})",
    ca.OP_CONSTPOW: "_pow({0}, {1})",
    ca.OP_LT: "_lt({0}, {1})",
    ca.OP_LE: "_le({0}, {1})",
    ca.OP_EQ: "_eq({0}, {1})",
    ca.OP_NE: "_ne({0}, {1})",
    ca.OP_AND: "_and({0}, {1})",
    ca.OP_OR: "_or({0}, {1})",
    ca.OP_IF_ELSE_ZERO: "_if_else_zero({0}, {1})",
}

#: Names of the supported operations (CasADi ``OP_*`` without the prefix, lower case).
SUPPORTED_OPERATIONS = tuple(
    sorted(_NAMES[op] for op in (*_UNARY, *_BINARY, ca.OP_CONST, ca.OP_INPUT, ca.OP_OUTPUT))
)


def _ipow(x: arb, n: int) -> arb:
    """``x ** n`` for an integer ``n`` by repeated products (defined for balls around 0)."""
    if n < 0:
        return ONE / _ipow(x, -n)
    result, base = ONE, x
    while n:
        if n & 1:
            result = result * base
        n >>= 1
        if n:
            base = base * base
    return result


def _pow(x: arb, y: arb) -> arb:
    """``x ** y``: repeated products for an exact integer ``y``, else ``exp(y log x)``."""
    if y.is_exact() and y.is_integer() and abs(y) <= 64:
        return _ipow(x, int(y.mid().unique_fmpz()))  # type: ignore[arg-type]
    return x**y


def _truth(c: arb) -> bool | None:
    """True / False where every point of ``c`` is nonzero / zero, None where undecided."""
    if c == 0:
        return False
    if c != 0:
        return True
    return None


def _boolean(value: bool | None) -> arb:
    return UNDECIDED if value is None else (ONE if value else ZERO)


def _lt(a: arb, b: arb) -> arb:
    return ONE if a < b else ZERO if a >= b else UNDECIDED


def _le(a: arb, b: arb) -> arb:
    return ONE if a <= b else ZERO if a > b else UNDECIDED


def _eq(a: arb, b: arb) -> arb:
    return ONE if a == b else ZERO if a != b else UNDECIDED


def _ne(a: arb, b: arb) -> arb:
    return ONE if a != b else ZERO if a == b else UNDECIDED


def _not(a: arb) -> arb:
    t = _truth(a)
    return _boolean(None if t is None else not t)


def _and(a: arb, b: arb) -> arb:
    ta, tb = _truth(a), _truth(b)
    if ta is False or tb is False:
        return ZERO
    return _boolean(True if ta and tb else None)


def _or(a: arb, b: arb) -> arb:
    ta, tb = _truth(a), _truth(b)
    if ta or tb:
        return ONE
    return _boolean(False if ta is False and tb is False else None)


def _if_else_zero(c: arb, x: arb) -> arb:
    t = _truth(c)
    if t is None:
        return x.union(ZERO)
    return x if t else ZERO


def _atan2(y: arb, x: arb) -> arb:
    return arb.atan2(y, x)


_HELPERS: dict[str, Any] = {
    "ZERO": ZERO,
    "ONE": ONE,
    "_ipow": _ipow,
    "_pow": _pow,
    "_lt": _lt,
    "_le": _le,
    "_eq": _eq,
    "_ne": _ne,
    "_not": _not,
    "_and": _and,
    "_or": _or,
    "_if_else_zero": _if_else_zero,
    "_atan2": _atan2,
}


def _power_expression(base: str, exponent: float) -> str | None:
    """Specialised Python expression of ``base ** exponent`` for a known constant exponent."""
    if math.isfinite(exponent) and exponent == int(exponent) and abs(exponent) <= 64:
        n = int(exponent)
        if n == 0:
            return "ONE"
        product = " * ".join([base] * abs(n)) if abs(n) <= 4 else f"_ipow({base}, {abs(n)})"
        return product if n > 0 else f"ONE / ({product})"
    if exponent == 0.5:
        return f"{base}.sqrt()"
    return None


@dataclass(frozen=True)
class IntervalFunction:
    """A CasADi SX Function replayed in ``arb`` ball arithmetic.

    Call it with one sequence of ``arb`` balls per input (the dense entries, column-major);
    it returns one list of balls per output (dense, column-major; structural zeros are exact
    zeros).

    Attributes:
        function: the SX Function replayed.
        in_sizes: number of dense entries of each input.
        out_shapes: (rows, columns) of each output.
        source: the generated straight-line Python (one line per instruction).
    """

    function: ca.Function
    in_sizes: tuple[int, ...]
    out_shapes: tuple[tuple[int, int], ...]
    source: str = field(repr=False)
    _replay: Callable[..., tuple[list[arb], ...]] = field(repr=False, compare=False)

    def __call__(self, *args: Sequence[arb]) -> tuple[list[arb], ...]:
        if len(args) != len(self.in_sizes):
            raise InputError(
                f"{self.function.name()} takes {len(self.in_sizes)} inputs, got {len(args)}; "
                f"pass one sequence of balls per input"
            )
        for i, (a, size) in enumerate(zip(args, self.in_sizes, strict=True)):
            if len(a) != size:
                raise InputError(
                    f"input {i} of {self.function.name()} has {size} entries, got {len(a)}; "
                    f"pass the dense entries column-major"
                )
        return self._replay(*args)


def _translate(f: ca.Function) -> IntervalFunction:
    """Translate the instruction list of an SX Function into straight-line ``arb`` code."""
    constants: dict[float, str] = {}
    known: dict[int, float] = {}  # work slot -> constant value it holds now
    body: list[str] = []
    for ins in instructions(f):
        op, a, r = ins.op, ins.args, ins.out
        if op == ca.OP_OUTPUT:
            body.append(f"o{r}[{ins.position}] = w{a[0]}")
            continue
        if op == ca.OP_CONST:
            expr = constants.setdefault(ins.constant, f"c{len(constants)}")
        elif op == ca.OP_INPUT:
            expr = f"i{a[0]}[{ins.position}]"
        elif op in _UNARY:
            expr = _UNARY[op].format(f"w{a[0]}")
        elif op in (ca.OP_POW, ca.OP_CONSTPOW) and a[1] in known:
            expr = _power_expression(f"w{a[0]}", known[a[1]]) or f"w{a[0]} ** w{a[1]}"
        elif op in _BINARY:
            expr = _BINARY[op].format(f"w{a[0]}", f"w{a[1]}")
        else:
            raise IntervalError(
                f"{f.name()}: operation {_NAMES.get(op, op)!r} (instruction {ins.index}) has "
                f"no interval counterpart here; rewrite the expression without it (supported: "
                f"{', '.join(SUPPORTED_OPERATIONS)})",
                operation=_NAMES.get(op, str(op)),
            )
        known.pop(r, None)
        if op == ca.OP_CONST:
            known[r] = ins.constant
        body.append(f"w{r} = {expr}")
    head = [f"def replay({', '.join(f'i{i}' for i in range(f.n_in()))}):"]
    if constants:
        head.append(f"    {', '.join(constants.values())}, = CONSTANTS")
    for i in range(f.n_out()):
        head.append(f"    o{i} = [ZERO] * {f.numel_out(i)}")
    outputs = ", ".join(f"o{i}" for i in range(f.n_out()))
    source = "\n".join([*head, *(f"    {line}" for line in body), f"    return ({outputs},)"])
    namespace = dict(_HELPERS, CONSTANTS=tuple(arb(v) for v in constants))
    exec(compile(source, f"<interval replay of {f.name()}>", "exec"), namespace)  # noqa: S102
    return IntervalFunction(
        function=f,
        in_sizes=tuple(f.numel_in(i) for i in range(f.n_in())),
        out_shapes=tuple((f.size1_out(i), f.size2_out(i)) for i in range(f.n_out())),
        source=source,
        _replay=namespace["replay"],
    )


class FunctionCache:
    """A small least-recently-used cache keyed by CasADi Function identity.

    CasADi Functions hash by their shared node, so two Python handles of one Function share an
    entry; the Function is kept alive with its entry, so a key is never reused by another.
    """

    def __init__(self, build: Callable[[ca.Function], Any], size: int = CACHE_SIZE) -> None:
        self._build = build
        self._size = size
        self._entries: OrderedDict[int, tuple[ca.Function, Any]] = OrderedDict()

    def __call__(self, f: ca.Function) -> Any:
        key = hash(f)
        hit = self._entries.get(key)
        if hit is not None:
            self._entries.move_to_end(key)
            return hit[1]
        value = self._build(f)
        self._entries[key] = (f, value)
        if len(self._entries) > self._size:
            self._entries.popitem(last=False)
        return value


def as_sx_function(f: ca.Function) -> ca.Function:
    """``f`` itself if it is an SX Function, else its expansion (MX Functions without calls).

    Raises:
        InputError: ``f`` is not a CasADi Function.
        IntervalError: ``f`` cannot be expanded to SX.
    """
    if not isinstance(f, ca.Function):
        raise InputError(f"expected a casadi.Function, got {type(f).__name__}; wrap the expression")
    if f.is_a("SXFunction"):
        return f
    try:
        return f.expand()
    except RuntimeError as err:
        raise IntervalError(
            f"{f.name()} is not an SX Function and does not expand to one "
            f"({str(err).splitlines()[0]}); build it from SX symbols",
            operation="expand",
        ) from err


_CACHE = FunctionCache(lambda f: _translate(as_sx_function(f)))


def interval_function(f: ca.Function) -> IntervalFunction:
    """The ``arb`` replay of ``f`` (translated once per Function, then cached).

    Args:
        f: a CasADi SX Function (an MX Function is expanded first).

    Raises:
        IntervalError: an operation of ``f`` has no interval counterpart (named in the
            message), or ``f`` does not expand to SX.
    """
    return _CACHE(f)


def balls(values: Sequence[float], radius: float | Sequence[float] = 0.0) -> list[arb]:
    """Balls ``values[i] +/- radius[i]`` (radius rounded up by Arb; 0: exact points)."""
    if isinstance(radius, (int, float)):
        if not radius:
            return [arb(float(v)) for v in values]
        return [arb(float(v), float(radius)) for v in values]
    return [arb(float(v), float(r)) for v, r in zip(values, radius, strict=True)]
