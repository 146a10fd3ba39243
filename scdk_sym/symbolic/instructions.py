"""The algorithm of a CasADi SX Function, one instruction at a time.

Every translation of an SX Function into other arithmetic walks this list: complex pairs
(:mod:`scdk_sym.algebraic.pairs`), Arb balls (:mod:`scdk_sym.algebraic.interval`), the binary64
interval tape (:mod:`scdk_sym.algebraic.certify.krawczyk_c`) and lane vectors
(:mod:`scdk_sym.kernels.lanes`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import casadi as ca


@dataclass(frozen=True)
class Instruction:
    """One instruction of an SX Function's algorithm.

    Attributes:
        index: its place in the algorithm.
        op: the CasADi opcode (``casadi.OP_*``).
        args: the operands as CasADi lists them: work slots; for ``OP_INPUT`` the input's
            index and the nonzero read; for ``OP_OUTPUT`` the work slot written out.
        out: the work slot written; for ``OP_OUTPUT`` the output's index.
        nz: for ``OP_OUTPUT``, the nonzero of the output written; else -1.
        position: the dense (column-major) position of the nonzero an ``OP_INPUT`` reads or
            an ``OP_OUTPUT`` writes; else -1.
        constant: the value of an ``OP_CONST``; else 0.
    """

    index: int
    op: int
    args: tuple[int, ...]
    out: int
    nz: int = -1
    position: int = -1
    constant: float = 0.0


def instructions(f: ca.Function) -> Iterator[Instruction]:
    """The instructions of an SX Function, in order."""
    in_dense = [f.sparsity_in(i).find() for i in range(f.n_in())]
    out_dense = [f.sparsity_out(i).find() for i in range(f.n_out())]
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        args, res = tuple(f.instruction_input(k)), f.instruction_output(k)
        if op == ca.OP_INPUT:
            yield Instruction(k, op, args, res[0], position=int(in_dense[args[0]][args[1]]))
        elif op == ca.OP_OUTPUT:
            yield Instruction(k, op, args, res[0], res[1], int(out_dense[res[0]][res[1]]))
        elif op == ca.OP_CONST:
            yield Instruction(k, op, args, res[0], constant=float(f.instruction_constant(k)))
        else:
            yield Instruction(k, op, args, res[0])
