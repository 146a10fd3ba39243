"""Command-line interface: ``scdk solve | ...`` (also ``python -m scdk_sym``)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence

import numpy as np

from .errors import InputError, ScdkError

#: Subcommand name -> (help, add-arguments function, run function); extended by modules below.
COMMANDS: dict[str, tuple[str, Callable, Callable]] = {}


def command(name: str, help: str, arguments: Callable[[argparse.ArgumentParser], None]):
    """Register a subcommand: the decorated function takes the parsed namespace, returns 0."""

    def deco(run: Callable[[argparse.Namespace], int]):
        COMMANDS[name] = (help, arguments, run)
        return run

    return deco


def floats(text: str, what: str = "value") -> np.ndarray:
    """Parse 'a,b,c' into floats (raises InputError naming the option)."""
    try:
        values = [float(v) for v in text.replace(" ", "").split(",") if v != ""]
    except ValueError as exc:
        raise InputError(f"{what}: expected comma-separated numbers, got {text!r}") from exc
    return np.array(values)


def fmt(values, digits: int = 6) -> str:
    """Format numbers for people (round-off below 1e-12 printed as 0)."""
    vals = [0.0 if abs(v) < 1e-12 else v for v in np.asarray(values, float).ravel()]
    return "[" + ", ".join(f"{v:.{digits}g}" for v in vals) + "]"


def add_model_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", help="model directory (robot.urdf + robot.yaml) or its YAML file")
    p.add_argument("--frame", help="link whose pose is reported (default: the YAML's platform)")


def load(args: argparse.Namespace):
    from .model.model import load_model

    model = load_model(args.model, frame=args.frame)
    if model.reduction and not getattr(args, "json", False):
        print(f"note: {model.reduction}", file=sys.stderr)
    return model


def start_configuration(model, args: argparse.Namespace):
    if getattr(args, "from_x", None):
        return model.inverse_kinematics(floats(args.from_x, "--from-x"))
    return model.home


def dump(obj) -> None:
    print(json.dumps(obj, default=float))


# ---------------------------------------------------------------------------- solve


def _solve_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument("--theta", required=True, help="actuated joint values a,b,c [rad or m]")
    p.add_argument("--from-x", help="start pose in workspace coordinates (default: home)")
    p.add_argument(
        "--branch",
        default="convergent",
        choices=["convergent", "divergent", "both"],
        help="convergent: stay in the start's compartment; divergent: cross the singular manifold",
    )
    p.add_argument("--b", type=float, help="the paper's signed scalar b (overrides --branch)")
    p.add_argument("--backend", default="casadi", choices=["casadi", "compiled"])
    p.add_argument("--json", action="store_true", help="print one JSON object")


@command("solve", "direct kinematics by the singularity-consistent method", _solve_args)
def _solve(args: argparse.Namespace) -> int:
    from .solvers.sc import solve

    model = load(args)
    theta = floats(args.theta, "--theta")
    start = start_configuration(model, args)
    branches = (
        ["convergent", "divergent"] if args.branch == "both" and args.b is None else [args.branch]
    )
    results = [
        solve(model, theta, start=start, branch=br, b=args.b, backend=args.backend)
        for br in branches
    ]
    if args.json:
        dump(
            results[0].to_dict()
            if len(results) == 1
            else {"solutions": [r.to_dict() for r in results]}
        )
        return 0
    print(f"model {model.name}: x = ({', '.join(model.workspace)}) of {model.frame!r}")
    print(f"start x = {fmt(start.x)}  theta0 = {fmt(theta)}")
    for r in results:
        n = len(r.crossings)
        print(f"{r.branch:>10}: x = {fmt(r.x)}  residual {r.residual:.1e}  crossings {n}")
        for c in r.crossings:
            print(f"{'':>12}singular crossing at s = {c.s:.6f}: x = {fmt(c.x)}")
    return 0


# ---------------------------------------------------------------------------- cache


def _cache_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--clear", action="store_true", help="delete every cached product")


@command("cache", "show or clear the on-disk cache of compiled kernels", _cache_args)
def _cache(args: argparse.Namespace) -> int:
    from .kernels.cache import cache_dir, clear_cache

    if args.clear:
        print(f"removed {clear_cache()} cached item(s) from {cache_dir()}")
    else:
        entries = sorted(cache_dir().iterdir())
        size = sum(e.stat().st_size for e in entries if e.is_file())
        print(f"{cache_dir()}: {len(entries)} item(s), {size / 1e6:.1f} MB")
    return 0


# ---------------------------------------------------------------------------- codegen


def _codegen_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument("--out", required=True, help="output directory (created if needed)")
    p.add_argument("--prefix", default="scdk", help="C prefix of every name (default: scdk)")
    p.add_argument(
        "--no-shared", action="store_true", help="write the sources only (no shared library)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")


@command("codegen", "standalone C sources of the tracker (+ a shared library)", _codegen_args)
def _codegen(args: argparse.Namespace) -> int:
    from .codegen.generate import compile_library, generate

    model = load(args)
    src = generate(model, args.out, args.prefix)
    library = None
    if not args.no_shared:
        library = compile_library(src, src.directory / f"lib{src.prefix}_tracker.so")
    files = [src.kernels_c, src.kernels_h, src.tracker_c, src.tracker_h]
    if args.json:
        dump({"files": [str(f) for f in files], "library": str(library) if library else None})
        return 0
    print(
        f"model {model.name}: y = ({', '.join(model.unknowns)}), theta = "
        f"({', '.join(model.actuated)})"
    )
    for f in files:
        print(f"wrote {f}")
    if library:
        print(f"wrote {library}")
    print(
        f"compile: gcc -std=c99 -O2 -Wall {src.kernels_c.name} {src.tracker_c.name} "
        f"your_program.c -lm   (include {src.tracker_h.name})"
    )
    return 0


# ---------------------------------------------------------------------------- main


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="scdk", description="Singularity-consistent direct kinematics of parallel robots."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (help_text, arguments, run) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        arguments(p)
        p.set_defaults(run=run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 error of the package, 2 usage)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args))
    except ScdkError as exc:
        print(f"scdk {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
