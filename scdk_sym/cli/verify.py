"""``scdk verify``: the model cross-checked against Pinocchio and finite differences."""

from __future__ import annotations

import argparse

from .common import add_model_args, command, dump, header, load


def _verify_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument(
        "--samples",
        type=int,
        default=3,
        metavar="N",
        help="random configurations and random solutions checked besides home",
    )
    p.add_argument(
        "--seed", type=int, default=0, metavar="N", help="seed of the random configurations"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")


@command(
    "verify",
    "cross-check the model: frame placements and closures against Pinocchio (an MJCF model: "
    "against MuJoCo itself), Jacobians "
    "against finite differences (exit 1 when a check fails)",
    _verify_args,
    "scdk verify models/planar_hexa --samples 5",
)
def _verify(args: argparse.Namespace) -> int:
    from ..verify.report import verify_model

    model = load(args)
    report = verify_model(model, samples=args.samples, seed=args.seed)
    if args.json:
        dump(report.to_dict())
    else:
        print(header(model))
        print(report.text())
    return 0 if report.passed else 1
