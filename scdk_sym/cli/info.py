"""``scdk info``: what a model is made of, before the first solve."""

from __future__ import annotations

import argparse

from .common import add_model_args, command, load


@command(
    "info",
    "describe the model: inputs, unknowns, closures, held joints and springs, home, joint "
    "ranges, blocks and the reduction made",
    add_model_args,
    "scdk info models/planar_hexa",
)
def _info(args: argparse.Namespace) -> int:
    from ..robot.info import describe

    print(describe(load(args)))
    return 0
