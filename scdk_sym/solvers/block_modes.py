"""Assembly modes one block at a time: a leg's knee, then its ankle given each knee.

A closure system that is block triangular (:func:`scdk_sym.robot.blocks.triangular_blocks`:
a leg's knee four-bar determines the knee, whose angle the ankle mechanism's rows involve)
has as real solutions, block after block, the certified modes of each block at the actuators
and at each solution of the blocks before it (their unknowns are the block model's extra
actuators). Independent blocks (the two legs of a biped) are solved once each, and the
model's modes are the product of their sets. Each block's start system is proven complete
and each block's real solutions certified (:func:`~scdk_sym.solvers.homotopy_modes.
homotopy_modes`); a block after the first is solved at the float values of the earlier
blocks' certified solutions, so the set is certified complete to their rounding. Every
assembled configuration is verified on the whole model.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..results import AssemblyModes, Configuration
from ..robot import Model
from ..robot.blocks import Block, triangular_blocks, triangular_models

#: Smallest number of unknowns at which ``assembly_modes`` solves a block-triangular system
#: one block at a time (below it the whole system is one homotopy: Gepetto's robot_delta,
#: 9 unknowns in five blocks, is certified whole by its root bound).
BLOCK_MIN_UNKNOWNS = 10


@dataclass(frozen=True)
class BlockModes:
    """The modes of one block at one value of its inputs.

    Attributes:
        block: the block (indices into the model's unknowns, rows, actuators).
        inputs: (len(block.inputs),) values of the earlier blocks' unknowns it was solved at
            [rad or model length unit].
        modes: the block model's certified modes there.
    """

    block: Block
    inputs: np.ndarray
    modes: AssemblyModes


def split(model: Model) -> tuple[tuple[Block, ...], tuple[Model, ...]] | None:
    """The blocks and block models of ``model`` if its modes are solved per block, else
    ``None`` (one block, fewer than :data:`BLOCK_MIN_UNKNOWNS` unknowns, or an input that
    cannot be an actuator)."""
    if model.m < BLOCK_MIN_UNKNOWNS or model.block is not None:
        return None
    blocks = triangular_blocks(model)
    if len(blocks) < 2:
        return None
    subs = triangular_models(model)
    if not subs:
        return None
    return blocks, subs


def block_modes(
    model: Model,
    theta0: np.ndarray,
    blocks: tuple[Block, ...],
    subs: tuple[Model, ...],
    **options: Any,
) -> AssemblyModes:
    """Every real assembly mode of ``model`` at ``theta0``, block after block.

    Args:
        model: the model.
        theta0: (k,) actuated values [rad or model length unit].
        blocks: its blocks (:func:`split`).
        subs: their models.
        **options: passed to :func:`~scdk_sym.solvers.homotopy_modes.homotopy_modes`.

    Returns:
        :class:`~scdk_sym.results.AssemblyModes`: every assembled configuration (verified on
        the model, sorted as the homotopy sorts them), ``certified`` when every block's set
        is, ``root_count`` the sum of the complex solutions tracked, ``blocks`` each block's
        sets (:class:`BlockModes`, one per value of its inputs), ``report`` per block.
    """
    from .homotopy_modes import homotopy_modes, sort_key

    theta0 = np.asarray(theta0, dtype=float)
    partial = [np.full(model.m, np.nan)]
    found: list[BlockModes] = []
    for block, sub in zip(blocks, subs, strict=True):
        memo: dict[bytes, AssemblyModes] = {}
        extended = []
        for y in partial:
            inputs = y[list(block.inputs)]
            key = inputs.tobytes()
            if key not in memo:
                params = np.concatenate([theta0[list(block.actuated)], inputs])
                memo[key] = homotopy_modes(sub, params, **options)
                found.append(BlockModes(block, inputs, memo[key]))
            for cfg in memo[key]:
                z = y.copy()
                z[list(block.unknowns)] = cfg.y
                extended.append(z)
        partial = extended
    cfgs: list[Configuration] = []
    failed = 0
    for y in partial:
        cfg = model.configuration(y, theta0)
        if model.residual(cfg.y, cfg.theta) <= model.tolerance:
            cfgs.append(cfg)
        else:
            failed += 1
    cfgs.sort(key=sort_key)
    certified = all(b.modes.certified for b in found) and failed == 0
    sizes = [len(b.unknowns) for b in blocks]
    counts = ", ".join(
        f"block {blocks.index(b.block)}: {len(b.modes)} real of {b.modes.root_count}" for b in found
    )
    if certified:
        report = (
            f"certified complete per block ({len(blocks)} blocks of {sizes} unknowns, "
            f"{len(found)} block solves: {counts}); {len(cfgs)} assemblies, each verified"
        )
    else:
        why = [f"block {blocks.index(b.block)}: {b.modes.report}" for b in found
               if not b.modes.certified]  # fmt: skip
        if failed:
            why.append(f"{failed} assembled configuration(s) fail the model's residual")
        report = "not certified: " + "; ".join(why)
    return AssemblyModes(
        solutions=tuple(cfgs),
        certified=certified,
        root_count=sum(b.modes.root_count for b in found),
        report=report,
        certificates=(),
        method="homotopy",
        blocks=tuple(found),
    )
