"""Solve and track a model one independent block at a time (the legs of a biped).

See :mod:`scdk_sym.robot.blocks`: each block is a model of its own; ``solve`` and ``track``
call themselves on each block with the block's actuators and start, and assemble the model's
answer (every block's unknowns, then the model's own verification of the whole). A branch
applies to every block: ``branch="divergent"`` is the answer across the nearest singular
surface of each block. A crossing of one block is reported with the other blocks' unknowns
at their answers.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..products import PLACING_BLOCK
from ..results import Configuration, Crossing, SolveResult, TrackResult
from ..robot import Model
from ..robot.blocks import Block
from .result import solve_result
from .track_errors import verify_samples


def _block(sub: Model) -> Block:
    """The block of a block model."""
    if sub.block is None:  # pragma: no cover - the block models of model.blocks have one
        raise ValueError(f"{sub!r} is not a block model")
    return sub.block[1]


def _expand(model: Model, sub: Model, c: Crossing, y: np.ndarray, theta: np.ndarray) -> Crossing:
    """A block's crossing in the model's terms (other blocks at ``y``, ``theta``; the inputs
    of a triangular block, the last of its actuated values, at the crossing's)."""
    block = _block(sub)
    full_y, full_theta = np.array(y, dtype=float), np.array(theta, dtype=float)
    full_y[list(block.unknowns)] = c.y
    k = len(block.actuated)
    full_theta[list(block.actuated)] = c.theta[:k]
    full_y[list(block.inputs)] = c.theta[k:]
    x = model.configuration(full_y, full_theta).x
    return Crossing(c.s, x, full_y, full_theta, c.index, c.kind)


def _placing_block(model: Model, subs: tuple[Model, ...]) -> int | None:
    """The index of the block whose unknowns and actuators alone place the reported frame
    (every other joint fixed), or ``None`` (computed once per model and set of blocks)."""
    variant = tuple(_block(sub).unknowns for sub in subs)  # blocks or stages
    return model.products.get(PLACING_BLOCK, lambda: _find_placing_block(model, subs), variant)


def _find_placing_block(model: Model, subs: tuple[Model, ...]) -> int | None:
    import casadi as ca

    sym = model.symbolic
    used = np.array(ca.DM(ca.jacobian(sym.x, ca.vertcat(sym.y, sym.theta)).sparsity(), 1))
    cols = set(np.flatnonzero(used.any(axis=0)).tolist())
    for i, sub in enumerate(subs):
        block = _block(sub)
        own = {*block.unknowns, *block.inputs, *(model.m + a for a in block.actuated)}
        if cols <= own:
            return i
    return None


def _actuated(block: Block, theta: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A block model's actuated values: the model's actuators of the block, then its inputs
    (unknowns of earlier blocks); rows of samples when ``theta`` and ``y`` are 2-D."""
    return np.concatenate([theta[..., list(block.actuated)], y[..., list(block.inputs)]], axis=-1)


def _starts(model: Model, subs, start: Configuration) -> list[Configuration]:
    out = []
    for sub in subs:
        block = _block(sub)
        theta = _actuated(block, start.theta, start.y)
        out.append(sub.configuration(start.y[list(block.unknowns)], theta))
    return out


def solve_blocks(
    model: Model,
    subs: tuple[Model, ...],
    theta0: np.ndarray,
    start: Configuration,
    solve: Callable[..., SolveResult],
    **options,
) -> SolveResult:
    """``solve`` on each block, the answer assembled and verified on the model.

    Args:
        model: the model.
        subs: its block models (:func:`scdk_sym.robot.blocks.block_models`).
        theta0: (k,) actuated values [rad or model length unit].
        start: the model's assembled start configuration.
        solve: the solve to call on each block.
        **options: passed to ``solve`` (branch, b, backend, ...).
    """
    y = np.array(start.y, dtype=float)
    results = []
    for sub, s0 in zip(subs, _starts(model, subs, start), strict=True):
        block = _block(sub)
        r = solve(sub, theta0[list(block.actuated)], start=s0, **options)
        y[list(block.unknowns)] = r.y
        results.append((sub, r))
    crossings = tuple(_expand(model, sub, c, y, theta0) for sub, r in results for c in r.crossings)
    first = results[0][1]
    res = solve_result(model, y, theta0, crossings, first.branch, first.b, start, None)
    # each block's way, in block order, where the divergent branch answered
    ways = ",".join(r.strategy for _sub, r in results)
    return replace(res, strategy=ways) if any(r.strategy for _sub, r in results) else res


def track_blocks(
    model: Model,
    subs: tuple[Model, ...],
    thetas: np.ndarray,
    start: Configuration,
    track: Callable[..., TrackResult],
    **options,
) -> TrackResult:
    """``track`` on each block, the samples assembled and verified on the model.

    ``subs``: independent blocks (:attr:`Model.blocks`) or the blocks of the block-triangular
    decomposition in dependency order (:attr:`Model.stages`): a block's readings are the
    model's readings of its actuators and the samples of its inputs, tracked before it.
    """
    N = len(thetas)
    ys = np.tile(np.asarray(start.y, dtype=float), (N, 1))
    results = []
    for sub, s0 in zip(subs, _starts(model, subs, start), strict=True):
        block = _block(sub)
        r = track(sub, _actuated(block, thetas, ys), start=s0, **options)
        ys[:, list(block.unknowns)] = r.y
        results.append((sub, r))
    # every closure belongs to one block: the model's residual is the worst block's; the
    # reported frame placed by one block's joints alone: x is that block's
    covered = sorted(ci for sub, _ in results for ci in _block(sub).closures)
    whole = covered != list(range(len(model.closures)))
    placer = _placing_block(model, subs)
    if placer is None or whole:
        xs, residual = model.evaluate(ys, thetas, residual=whole)
    else:
        xs, residual = results[placer][1].x, None
    if residual is None:
        residual = np.max([r.residual for _, r in results], axis=0)
    crossings = []
    for sub, r in results:
        for c in r.crossings:
            crossings.append(_expand(model, sub, c, ys[max(c.index, 0)], thetas[max(c.index, 0)]))
    crossings.sort(key=lambda c: (c.index, c.s))
    verify_samples(model, residual, thetas)
    return TrackResult(
        x=xs,
        y=ys,
        theta=thetas,
        residual=residual,
        crossings=tuple(crossings),
        status="converged",
        backend=results[0][1].backend,
    )
