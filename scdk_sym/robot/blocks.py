"""Independent blocks of a closure system: the legs of a biped, solved one at a time.

The closure Jacobian ``J_p`` of a model with several mechanisms on one base (the two legs of a
biped) is block-diagonal after a permutation: each block's rows involve its own unknowns only.
Each block is then a model of its own (:func:`block_models`): its unknowns, its closure rows,
the actuators its rows involve; every other joint is held at its home value, which the block's
rows do not see. Solving or tracking the blocks one at a time costs what their loops cost (a
dense 36 x 36 system of a biped becomes two of 18), and the answer is assembled from them.

The blocks come from the structural sparsity of the symbolic ``J_p`` (connected components of
its row-column graph), so they do not depend on a configuration.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeVar

import casadi as ca
import numpy as np

from ..graphs import triangular_decomposition
from .evaluation import ModelEvaluation

#: A model class (the models of a model's blocks are of its class).
ModelT = TypeVar("ModelT", bound=ModelEvaluation)

#: Smallest number of unknowns at which a block-triangular system is worked one block at a
#: time (``assembly_modes``, :attr:`Model.stages`); below it the whole system is one: Gepetto's
#: robot_delta, 9 unknowns in five blocks, is certified whole by its root bound and tracked
#: whole through its flat parallelograms.
BLOCK_MIN_UNKNOWNS = 10


@dataclass(frozen=True)
class Block:
    """One independent block of a model's closure system.

    Attributes:
        unknowns: (m_b,) indices into ``model.unknowns``.
        actuated: (k_b,) indices into ``model.actuated`` of the actuators its rows involve.
        rows: (m_b,) indices into the model's kept closure rows ``g``.
        closures: indices into ``model.closures`` of the closures its rows belong to.
        inputs: indices into ``model.unknowns`` of the unknowns of earlier blocks that its
            rows involve (a block of :func:`triangular_blocks`; empty for an independent one).
    """

    unknowns: tuple[int, ...]
    actuated: tuple[int, ...]
    rows: tuple[int, ...]
    closures: tuple[int, ...]
    inputs: tuple[int, ...] = ()


def independent_blocks(model: ModelEvaluation) -> tuple[Block, ...]:
    """The independent blocks of ``model`` (one block when the system does not split), in
    the order of their first unknown."""
    sym = model.symbolic
    P = np.array(ca.DM(sym.J_p.sparsity(), 1), dtype=bool)
    S = np.array(ca.DM(sym.J_s.sparsity(), 1), dtype=bool)  # J_s = -dg/dtheta
    m = model.m
    # union-find over unknowns: the unknowns of one row belong together
    parent = list(range(m))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for row in P:
        cols = [int(c) for c in np.flatnonzero(row)]
        for c in cols[1:]:
            parent[find(c)] = find(cols[0])
    owner = row_closures(model)
    groups: dict[int, list[int]] = {}
    for i in range(m):
        groups.setdefault(find(i), []).append(i)
    blocks = []
    for cols in sorted(groups.values()):
        rows = [r for r in range(m) if P[r, cols].any()]
        actuated = [a for a in range(model.k) if S[rows, a].any()]
        closures = sorted({owner[model.rows[r]] for r in rows})
        blocks.append(Block(tuple(cols), tuple(actuated), tuple(rows), tuple(closures)))
    return tuple(blocks)


def triangular_blocks(model: ModelEvaluation) -> tuple[Block, ...]:
    """The block-triangular decomposition of ``model``'s closure system, dependencies first.

    The rows are matched to the unknowns they determine (a perfect matching of the
    structural sparsity of ``J_p``); a row that involves the unknown matched to another row
    depends on that row; the strongly connected components of that dependency graph are the
    blocks (Dulmage-Mendelsohn's fine decomposition of a square system). Each block solves
    its unknowns from its rows once the unknowns of earlier blocks it involves (its
    ``inputs``) are known: a leg's knee four-bar, then its ankle mechanism. One block when the
    system does not split, or when its sparsity has no perfect matching.
    """
    sym = model.symbolic
    P = np.array(ca.DM(sym.J_p.sparsity(), 1), dtype=bool)
    S = np.array(ca.DM(sym.J_s.sparsity(), 1), dtype=bool)  # J_s = -dg/dtheta
    m = model.m
    whole = Block(tuple(range(m)), tuple(range(model.k)), tuple(range(m)),
                  tuple(range(len(model.closures))))  # fmt: skip
    parts = triangular_decomposition([set(np.flatnonzero(row).tolist()) for row in P])
    if m == 0 or parts is None:
        return (whole,)
    owner = row_closures(model)
    blocks = []
    for rows, cols in parts:
        involved = set(np.flatnonzero(P[rows].any(axis=0)).tolist())
        actuated = [a for a in range(model.k) if S[rows, a].any()]
        closures = sorted({owner[model.rows[r]] for r in rows})
        blocks.append(Block(tuple(cols), tuple(actuated), tuple(rows), tuple(closures),
                            tuple(sorted(involved - set(cols)))))  # fmt: skip
    return tuple(blocks)


def triangular_models(model: ModelT) -> tuple[ModelT, ...]:
    """One model per block of :func:`triangular_blocks`, the model itself when it does not
    split. A block's inputs (unknowns of earlier blocks) are actuators of its model, after
    the model's own: its modes at ``(theta, inputs)`` are the block's solutions given the
    earlier blocks' (see :func:`scdk_sym.solvers.block_modes.block_modes`). ``None`` when an
    input is not a one-coordinate joint (a ball's rotation cannot be an actuator)."""
    blocks = triangular_blocks(model)
    if len(blocks) == 1:
        return (model,)
    single = set(model.tree.single_coordinate_joints)
    if any(model.unknowns[i] not in single for b in blocks for i in b.inputs):
        return ()
    return tuple(_block_model(model, b, i) for i, b in enumerate(blocks))


def row_closures(model: ModelEvaluation) -> list[int]:
    """Closure index of each row of ``g_all``."""
    return np.repeat(np.arange(len(model.closures)), np.diff(model.row_offsets)).tolist()


def block_models(model: ModelT) -> tuple[ModelT, ...]:
    """One model per independent block (the model itself when it does not split).

    Each block model has the block's unknowns (in the model's order), its closures and rows,
    and the actuators its rows involve; every other joint is held at its home value. Its
    reported frame and workspace are the model's (its ``x`` is not the model's answer: the
    answer is assembled by the model from every block's ``y``).
    """
    blocks = independent_blocks(model)
    if len(blocks) == 1:
        return (model,)
    return tuple(_block_model(model, b, i) for i, b in enumerate(blocks))


def _block_model(model: ModelT, block: Block, index: int) -> ModelT:
    """The model of one block (see :meth:`~scdk_sym.robot.model.Model.restricted`)."""
    unknowns = tuple(model.unknowns[i] for i in block.unknowns)
    actuated = tuple(model.actuated[a] for a in block.actuated)
    actuated += tuple(model.unknowns[i] for i in block.inputs)
    held = dict(model.home.coordinates)
    for name in (*unknowns, *actuated):
        held.pop(name, None)
    # rows of the block in the block's own closure rows (its closures, in the model's order)
    offsets, start = {}, 0
    for ci in block.closures:
        offsets[ci] = start
        start += model.closures[ci].rows
    owner = row_closures(model)

    def local(r: int) -> int:  # a row of the full closure system, in the block's rows
        return offsets[owner[r]] + int(r - model.row_offsets[owner[r]])

    rows = tuple(local(model.rows[r]) for r in block.rows)
    closures = tuple(model.closures[ci] for ci in block.closures)
    unchecked = tuple(local(r) for r in model.unchecked if owner[r] in offsets)
    return type(model).restricted(
        model, unknowns, actuated, closures, rows, held, (index, block), unchecked
    )
