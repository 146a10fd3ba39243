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

import operator
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import VerificationError
from ..results import AssemblyModes, Configuration, mode_order
from ..robot import Model
from ..robot.blocks import BLOCK_MIN_UNKNOWNS, Block, triangular_blocks, triangular_models
from ..robot.rods import rod_reduction


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


def groups(blocks: tuple[Block, ...]) -> list[list[int]]:
    """The blocks that depend on one another, grouped: indices into ``blocks``, each group in
    block order, groups in the order of their first block. Blocks of different groups share
    no unknown (the two legs of a biped), so the model's modes are the product of the
    groups' sets."""
    owner = {u: i for i, b in enumerate(blocks) for u in b.unknowns}
    parent = list(range(len(blocks)))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, b in enumerate(blocks):
        for u in b.inputs:
            parent[find(i)] = find(owner[u])
    out: dict[int, list[int]] = {}
    for i in range(len(blocks)):
        out.setdefault(find(i), []).append(i)
    return list(out.values())


class ModeProduct(Sequence[Configuration]):
    """Every combination of one part per group of blocks, each a :class:`Configuration`
    built (and verified on the whole model) when it is read; the last group varies fastest.

    Args:
        model: the model.
        theta: (k,) actuated values [rad or model length unit].
        unknowns: per group, the indices into ``model.unknowns`` it solves.
        parts: per group, (n_g, len(unknowns[g])) its verified solutions' unknowns.
    """

    def __init__(
        self,
        model: Model,
        theta: np.ndarray,
        unknowns: tuple[tuple[int, ...], ...],
        parts: tuple[np.ndarray, ...],
    ) -> None:
        self.model = model
        self.theta = np.asarray(theta, dtype=float)
        self.unknowns = unknowns
        self.parts = parts
        self.sizes = tuple(len(p) for p in parts)

    def __len__(self) -> int:
        return int(np.prod(self.sizes, dtype=np.int64)) if self.sizes else 0

    def __repr__(self) -> str:
        return f"ModeProduct({' x '.join(map(str, self.sizes))} = {len(self)} assemblies)"

    def __getitem__(self, index):
        if isinstance(index, slice):
            return tuple(self[i] for i in range(*index.indices(len(self))))
        n = len(self)
        i = operator.index(index)
        if not -n <= i < n:
            raise IndexError(f"assembly {index} of {n}")
        i %= n
        y = np.empty(self.model.m)
        for g in reversed(range(len(self.sizes))):
            i, j = divmod(i, self.sizes[g])
            y[list(self.unknowns[g])] = self.parts[g][j]
        cfg = self.model.configuration(y, self.theta)
        residual = self.model.residual(cfg.y, cfg.theta)
        if not residual <= self.model.tolerance:  # the groups' rows are disjoint: never met
            raise VerificationError(
                f"assembly {index} of {n} (a product of per-group sets) fails the model's "
                f"closure by {residual:.3g} > {self.model.tolerance:.3g} at theta="
                f"{self.theta.tolist()}; report it with the model",
                residual,
            )
        return cfg


def _group_parts(
    model: Model,
    theta0: np.ndarray,
    blocks: tuple[Block, ...],
    subs: tuple[Model, ...],
    group: list[int],
    found: list[BlockModes],
    options: dict[str, Any],
) -> list[np.ndarray]:
    """The group's solutions, block after block: (m,) unknowns, NaN outside the group."""
    from .homotopy_modes import homotopy_modes

    partial = [np.full(model.m, np.nan)]
    for bi in group:
        block, sub = blocks[bi], subs[bi]
        memo: dict[bytes, AssemblyModes] = {}
        extended = []
        for y in partial:
            inputs = y[list(block.inputs)]
            key = inputs.tobytes()
            if key not in memo:
                params = np.concatenate([theta0[list(block.actuated)], inputs])
                memo[key] = homotopy_modes(sub, params, **options)
                found.append(BlockModes(block, inputs, memo[key]))
                if options.get("certified_only") and not memo[key].certified:
                    return []  # the caller uses only a certified set: no further block
            for cfg in memo[key]:
                z = y.copy()
                z[list(block.unknowns)] = cfg.y
                extended.append(z)
        partial = extended
    return partial


def _verified(
    model: Model, theta0: np.ndarray, parts: list[list[np.ndarray]]
) -> tuple[list[list[Configuration]], int]:
    """Each group's parts verified on the whole model, sorted: (kept, number that failed).

    Each part is verified with every other group at its first part (rows of different groups
    share no unknown, so any combination of verified parts closes); a group without a
    solution means no assembly, and nothing to verify."""

    base = np.full(model.m, np.nan)
    for p in parts:
        if p:
            base[np.isfinite(p[0])] = p[0][np.isfinite(p[0])]
    if not all(parts):
        return [[] for _ in parts], 0
    kept: list[list[Configuration]] = []
    failed = 0
    for p in parts:
        cfgs = []
        for y in p:
            z = np.where(np.isfinite(y), y, base)
            cfg = model.configuration(z, theta0) if np.all(np.isfinite(z)) else None
            if cfg is not None and model.residual(cfg.y, cfg.theta) <= model.tolerance:
                cfgs.append(cfg)
            else:
                failed += 1
        cfgs.sort(key=mode_order)
        kept.append(cfgs)
    return kept, failed


def _assemblies(model, theta0, blocks, grouped, kept) -> Sequence[Configuration]:
    """One group's sorted set as a tuple, several groups' as a :class:`ModeProduct`."""
    if len(kept) == 1:
        return tuple(kept[0])
    unknowns = tuple(tuple(u for bi in g for u in blocks[bi].unknowns) for g in grouped)
    return ModeProduct(
        model,
        theta0,
        unknowns,
        tuple(np.array([c.y[list(u)] for c in cs]).reshape(len(cs), len(u))
              for cs, u in zip(kept, unknowns, strict=True)),
    )  # fmt: skip


def _report(blocks, found, kept, total: int, certified: bool, failed: int, rods: int) -> str:
    """What :func:`block_modes` says about its set."""
    sizes = [len(b.unknowns) for b in blocks]
    counts = ", ".join(
        f"block {blocks.index(b.block)}: {len(b.modes)} real of {b.modes.root_count}" for b in found
    )
    product = (
        f" ({' x '.join(str(len(k)) for k in kept)} from {len(kept)} independent groups)"
        if len(kept) > 1
        else ""
    )
    if certified:
        return (
            f"certified complete per block ({len(blocks)} blocks of {sizes} unknowns, "
            f"{len(found)} block solves: {counts}); {total} assemblies{product}, each verified"
        ) + (
            f"; {rods} rod(s) between ball joints solved as distances (each assembly once)"
            if rods
            else ""
        )
    why = [f"block {blocks.index(b.block)}: {b.modes.report}" for b in found
           if not b.modes.certified]  # fmt: skip
    if failed:
        why.append(f"{failed} assembled configuration(s) fail the model's residual")
    return "not certified: " + "; ".join(why)


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
        the model), ``certified`` when every block's set is, ``root_count`` the sum of the
        complex solutions tracked, ``blocks`` each block's sets (:class:`BlockModes`, one per
        value of its inputs), ``report`` per block. With one group of blocks
        (:func:`groups`) the configurations are a tuple sorted as the homotopy sorts them;
        with several (a biped's legs) they are a :class:`ModeProduct` of the groups' sorted
        sets, ``groups`` their sizes, built when read.
    """
    theta0 = np.asarray(theta0, dtype=float)
    found: list[BlockModes] = []
    grouped = groups(blocks)
    parts = [_group_parts(model, theta0, blocks, subs, g, found, dict(options)) for g in grouped]
    kept, failed = _verified(model, theta0, parts)
    solutions = _assemblies(model, theta0, blocks, grouped, kept)
    certified = all(b.modes.certified for b in found) and failed == 0
    rods = sum(len(r) for r, reduced in map(rod_reduction, subs) if reduced is not None)
    report = _report(blocks, found, kept, len(solutions), certified, failed, rods)
    return AssemblyModes(
        solutions=solutions,
        certified=certified,
        root_count=sum(b.modes.root_count for b in found),
        report=report,
        certificates=(),
        method="homotopy",
        blocks=tuple(found),
        groups=tuple(len(k) for k in kept) if len(kept) > 1 else (),
    )
