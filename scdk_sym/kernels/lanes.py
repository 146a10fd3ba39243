"""C source of a CasADi SX Function evaluated on lane vectors: several points at once.

CasADi generates C for one point (``casadi_real`` scalars). The C path tracker
(``scdk_sym/algebraic/paths/continuation.c``) advances a few paths in lock step, one per lane
of a GCC vector type (``vd``: ``SCDK_LANES`` doubles), so that every arithmetic instruction of the
evaluation serves all lanes. :func:`lane_source` writes the Function's algorithm, instruction
by instruction in CasADi's own order, as a static C function on ``vd`` values: each lane gets
exactly the arithmetic of the scalar evaluation (the same operations in the same order, so
the same rounding when the compiler contracts no multiply-add).
"""

from __future__ import annotations

import casadi as ca

from ..errors import BuildError
from ..symbolic.instructions import instructions

_BINARY = {ca.OP_ADD: "+", ca.OP_SUB: "-", ca.OP_MUL: "*", ca.OP_DIV: "/"}
#: Unary operations as C expressions of ``x`` (a ``vd``).
_UNARY = {
    ca.OP_ASSIGN: "{x}",
    ca.OP_NEG: "(-{x})",
    ca.OP_SQ: "({x}*{x})",
    ca.OP_TWICE: "({x}+{x})",
    ca.OP_INV: "(SCDK_SPLAT(1.0)/{x})",
}
#: Transcendental operations, applied lane by lane with the C library's function.
_LIBM = {ca.OP_SIN: "sin", ca.OP_COS: "cos", ca.OP_SINH: "sinh", ca.OP_COSH: "cosh"}


def lane_source(f: ca.Function, name: str) -> str:
    """C source of ``static void name(const vd *const *arg, vd *const *res)``.

    ``arg[i]`` holds input ``i``'s nonzeros and ``res[i]`` receives output ``i``'s, each a
    ``vd`` (one value per lane); outputs are written densely (a structural zero is written
    as 0). The source expects ``vd`` and ``SCDK_SPLAT`` (a ``vd`` with one value in every
    lane) and ``SCDK_LANES`` to be defined, and ``math.h`` included.

    Args:
        f: an SX Function with dense inputs.
        name: the C function's name.

    Returns:
        The C source.

    Raises:
        BuildError: ``f`` uses an operation other than ``+ - * /``, negation, square,
            reciprocal, sin, cos, sinh and cosh (the operations of a complexified algebraic
            form).
    """
    if not f.is_a("SXFunction"):
        raise BuildError(f"lane evaluation needs an SX Function, got {f.class_name()} {f.name()!r}")
    for i in range(f.n_in()):
        if not f.sparsity_in(i).is_dense():
            raise BuildError(f"input {i} of {f.name()!r} is sparse; lane evaluation needs dense")
    body: list[str] = []
    used: set[int] = set()
    for ins in instructions(f):
        op, a, r = ins.op, ins.args, ins.out
        if op == ca.OP_OUTPUT:
            body.append(f"  res[{r}][{ins.position}] = w{a[0]};")
            continue
        used.add(r)
        if op == ca.OP_INPUT:
            expr = f"arg[{a[0]}][{ins.position}]"
        elif op == ca.OP_CONST:
            expr = f"SCDK_SPLAT({ins.constant!r})"
        elif op in _BINARY:
            expr = f"(w{a[0]}{_BINARY[op]}w{a[1]})"
        elif op in _UNARY:
            expr = _UNARY[op].format(x=f"w{a[0]}")
        elif op in _LIBM:
            lane = f"w{r}[l_] = {_LIBM[op]}(w{a[0]}[l_]);"
            body.append(f"  for (int l_ = 0; l_ < SCDK_LANES; ++l_) {lane}")
            continue
        else:
            raise BuildError(
                f"CasADi operation {op} in {f.name()!r} has no lane evaluation; lane "
                "evaluation covers + - * /, negation, square, reciprocal, sin, cos, sinh, cosh"
            )
        body.append(f"  w{r} = {expr};")
    zeros = []
    for i in range(f.n_out()):
        sp = f.sparsity_out(i)
        if not sp.is_dense():
            zeros.append(
                f"  for (int i_ = 0; i_ < {sp.numel()}; ++i_) res[{i}][i_] = SCDK_SPLAT(0.0);"
            )
    decl = [f"  vd {', '.join(f'w{r}' for r in sorted(used)[j:j + 12])};"
            for j in range(0, len(used), 12)]  # fmt: skip
    return "\n".join(
        [
            f"/* {f.name()} on lane vectors (generated from its CasADi algorithm) */",
            f"static void {name}(const vd *const *arg, vd *const *res) {{",
            *decl,
            *zeros,
            *body,
            "}",
            "",
        ]
    )
