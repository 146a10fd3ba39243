"""``scdk modes``: every assembly mode (real direct-kinematics solution) at one reading."""

from __future__ import annotations

import argparse

from .. import backends
from ..errors import InputError
from .common import (
    FROM_X_HELP,
    FROM_X_METAVAR,
    THETA_HELP,
    THETA_METAVAR,
    add_backend_arg,
    add_model_args,
    backend_of,
    command,
    dump,
    floats,
    fmt,
    header,
    load,
    start_configuration,
)


def _modes_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument("--theta", required=True, metavar=THETA_METAVAR, help=THETA_HELP)
    p.add_argument(
        "--method",
        default="homotopy",
        choices=["homotopy", "curves"],
        help="homotopy: every real solution, certified (default); curves: real-curve search",
    )
    p.add_argument("--from-x", metavar=FROM_X_METAVAR, help="curves: " + FROM_X_HELP)
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        metavar="N",
        help="seed of the random choices: start system, search directions",
    )
    p.add_argument(
        "--time-budget",
        type=float,
        metavar="SECONDS",
        help="curves: wall-time limit [s] (default: none)",
    )
    add_backend_arg(
        p,
        "modes",
        default=f"{backends.DEFAULTS['modes']} for --method homotopy, "
        f"{backends.DEFAULTS['curves']} for --method curves",
    )
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="progress bar on stderr (default: off)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")


@command(
    "modes",
    "all assembly modes (the real direct-kinematics solutions) at one joint reading",
    _modes_args,
    "scdk modes models/planar_hexa --theta 1.292,-0.802,-2.896",
)
def _modes(args: argparse.Namespace) -> int:
    import time

    from ..solvers.modes import assembly_modes, curves_result, explore

    function = "curves" if args.method == "curves" else "modes"
    backend = backend_of(args.backend or backends.DEFAULTS[function], function)
    model = load(args)
    theta = floats(args.theta, "--theta")
    t0 = time.perf_counter()
    if args.method == "curves":
        search = explore(
            model,
            theta,
            start=start_configuration(model, args),
            seed=args.seed,
            time_budget=args.time_budget,
            progress=args.progress,
            backend=backend,
        )
        sols = curves_result(search)
    else:
        if args.from_x or args.time_budget is not None:
            raise InputError("--from-x and --time-budget are for --method curves")
        sols = assembly_modes(model, theta, seed=args.seed, progress=args.progress, backend=backend)
    elapsed = time.perf_counter() - t0
    if args.json:
        dump(dict(sols.to_dict(), backend=backend))
        return 0
    print(header(model))
    head = f"theta0 = {fmt(theta)}: {len(sols)} real solution(s), {elapsed:.3f} s, {args.method}"
    if args.method == "homotopy":
        head += f", {sols.root_count} complex solutions tracked"
    print(head)
    print(sols.report)
    for i, s in enumerate(sols):
        mark = ""
        if i < len(sols.certificates):
            mark = "  certified" if sols.certificates[i].proven else "  NOT certified"
        print(f"{i + 1:>4}: x = {fmt(s.x)}  residual {s.residual:.1e}{mark}")
    return 0
