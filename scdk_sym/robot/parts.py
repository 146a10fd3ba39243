"""A model's parts: its independent blocks and the stages of its block-triangular
decomposition, each a model of part of its closure system (:mod:`scdk_sym.robot.blocks`)."""

from __future__ import annotations

from functools import cached_property
from typing import TypeVar

from .blocks import BLOCK_MIN_UNKNOWNS, block_models, triangular_models
from .evaluation import ModelEvaluation

#: A model class (a model's parts are of its class).
ModelT = TypeVar("ModelT", bound="ModelParts")


class ModelParts(ModelEvaluation):
    """A model's blocks and stages (see :class:`~scdk_sym.robot.model.Model`)."""

    @cached_property
    def blocks(self: ModelT) -> tuple[ModelT, ...]:
        """One model per independent block of the closure system (the legs of a biped; see
        :mod:`scdk_sym.robot.blocks`), or ``(self,)`` when it does not split (or for a block
        model). Assign ``(model,)`` to solve the whole system at once."""
        if self.block is not None:
            return (self,)
        return block_models(self)

    @cached_property
    def stages(self: ModelT) -> tuple[ModelT, ...]:
        """One model per block of the block-triangular decomposition of the closure system,
        dependencies first (a leg's knee four-bar, then its ankle mechanism, whose model takes
        the knee's unknowns as extra actuators; see
        :func:`~scdk_sym.robot.blocks.triangular_models`): what ``track`` runs, one block
        after the other, each sample of a block read from the samples of the blocks before it.
        :attr:`blocks` below :data:`~scdk_sym.robot.blocks.BLOCK_MIN_UNKNOWNS` unknowns, or
        when the decomposition refines nothing (or an input is not a one-coordinate joint).
        Assign ``(model,)`` to track the whole system at once."""
        if self.block is not None or self.m < BLOCK_MIN_UNKNOWNS:
            return self.blocks
        stages = triangular_models(self)
        return stages if len(stages) > 1 else self.blocks
