"""``scdk solve``: direct kinematics at one joint reading, one branch or both."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from ..errors import SolveError
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
    one_line,
    start_configuration,
)

if TYPE_CHECKING:
    from ..results import SolveResult


def _solve_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument("--theta", required=True, metavar=THETA_METAVAR, help=THETA_HELP)
    p.add_argument("--from-x", metavar=FROM_X_METAVAR, help=FROM_X_HELP)
    p.add_argument(
        "--branch",
        default="convergent",
        choices=["convergent", "divergent", "both"],
        help="convergent: the solution on the start's side of the singular surface; divergent: "
        "the one across the nearest singular surface; both: the two, side by side",
    )
    p.add_argument(
        "--b",
        type=float,
        help="the paper's signed scalar b: its sign picks the direction along the paper's "
        "straight path (overrides --branch; default: none)",
    )
    add_backend_arg(p, "solve")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")


def _failed_record(branch: str, exc: Exception, backend: str) -> dict:
    """JSON record of a branch whose solve failed."""
    return {
        "branch": branch,
        "status": "failed",
        "error": one_line(exc),
        "error_type": type(exc).__name__,
        "backend": backend,
    }


@command(
    "solve",
    "direct kinematics at one joint reading by the singularity-consistent method",
    _solve_args,
    "scdk solve models/planar_hexa --theta 1.292,-0.802,-2.896 --from-x 0,0,0.4 --branch both",
)
def _solve(args: argparse.Namespace) -> int:
    """Solve one branch, or both (``--branch both``).

    With both branches, a branch whose solver fails (:class:`SolveError`: the path did not reach
    ``s = 1``, the result failed verification, ...) is reported in place of its solution and
    the other branch is still printed; the exit code is 1 only when every branch failed. Errors
    that do not depend on the branch (bad input, model, start, build) end the command as usual.
    """
    from ..solvers import solve as solving  # looked up at each call (tests replace it)

    backend = backend_of(args.backend, "solve")
    model = load(args)
    theta = floats(args.theta, "--theta")
    start = start_configuration(model, args)
    both = args.branch == "both" and args.b is None
    branches = ["convergent", "divergent"] if both else [args.branch]
    results: list[tuple[str, SolveResult | SolveError]] = []
    for br in branches:
        try:
            res = solving.solve(model, theta, start=start, branch=br, b=args.b, backend=backend,
                                record_path=False)  # fmt: skip
        except SolveError as exc:
            if not both:
                raise
            results.append((br, exc))
        else:
            results.append((br, res))
    failed = [(br, r) for br, r in results if isinstance(r, SolveError)]
    if args.json:
        records = [
            _failed_record(br, r, backend) if isinstance(r, SolveError) else r.to_dict()
            for br, r in results
        ]
        dump(records[0] if not both else {"solutions": records})
    else:
        print(header(model))
        print(f"start x = {fmt(start.x)}  theta0 = {fmt(theta)}")
        for br, r in results:
            if isinstance(r, SolveError):
                print(f"{br:>10}: error: {one_line(r)}")
                continue
            n = len(r.crossings)
            print(f"{r.branch:>10}: x = {fmt(r.x)}  residual {r.residual:.1e}  crossings {n}")
            for c in r.crossings:
                print(f"{'':>12}singular crossing ({c.kind}) at s = {c.s:.6f}: x = {fmt(c.x)}")
            if r.fallback:
                print(f"{'':>12}{r.fallback}")
    if len(failed) == len(results):
        for br, err in failed:
            print(f"scdk {args.command}: error: {br}: {one_line(err)}", file=sys.stderr)
        return 1
    return 0
