"""Command-line interface: ``scdk solve | ...`` (also ``python -m scdk_sym``)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from . import backends
from .errors import InputError, ScdkError, SolveError

if TYPE_CHECKING:
    from .results import Configuration, SolveResult, TrackResult

#: Subcommand name -> (help, add-arguments function, run function); extended by modules below.
COMMANDS: dict[str, tuple[str, Callable, Callable]] = {}


def command(name: str, help: str, arguments: Callable[[argparse.ArgumentParser], None]):
    """Register a subcommand: the decorated function takes the parsed namespace, returns 0."""

    def deco(run: Callable[[argparse.Namespace], int]):
        COMMANDS[name] = (help, arguments, run)
        return run

    return deco


def floats(text: str, what: str = "value") -> np.ndarray:
    """Parse 'a,b,c' into floats.

    Raises:
        InputError: a field is empty or not a number (the option and the text named).
    """
    fields = text.replace(" ", "").split(",")
    if any(f == "" for f in fields):
        hint = "; values are separated by commas" if ";" in text else ""
        raise InputError(
            f"{what}: empty value in {text!r} (field {fields.index('') + 1}); expected "
            f"comma-separated numbers such as 1.0,-2,3e-1{hint}"
        )
    try:
        values = [float(v) for v in fields]
    except ValueError as exc:
        hint = "; values are separated by commas" if ";" in text else ""
        raise InputError(f"{what}: expected comma-separated numbers, got {text!r}{hint}") from exc
    return np.array(values)


def fmt(values, digits: int = 6) -> str:
    """Format numbers for people (round-off below 1e-12 printed as 0)."""
    vals = [0.0 if abs(v) < 1e-12 else v for v in np.asarray(values, float).ravel()]
    return "[" + ", ".join(f"{v:.{digits}g}" for v in vals) + "]"


#: Help of ``--theta``: the units come from the model (``length_unit`` of its YAML).
THETA_HELP = (
    "actuated joint values a,b,c in the model's units: rad for revolute joints, the model's "
    "length unit (robot.yaml length_unit, default m; planar_hexa: cm) for prismatic ones; "
    "the text output states each unit"
)
#: Help of ``--from-x``.
FROM_X_HELP = (
    "start pose in workspace coordinates (default: home), lengths in the model's length unit, "
    "angles in rad"
)


def add_backend_arg(p: argparse.ArgumentParser, function: str, default: str | None = None) -> None:
    """``--backend``: the names ``function`` offers, each with its line of the registry.

    Args:
        p: the subcommand's parser.
        function: a key of :data:`scdk_sym.backends.OFFERS`.
        default: how the default is stated when it is not ``DEFAULTS[function]`` (the option's
            default is then None and the command chooses).
    """
    p.add_argument(
        "--backend",
        default=None if default else backends.DEFAULTS[function],
        metavar="{" + ",".join(backends.offered(function)) + "}",
        help=backends.help_text(function, default),
    )


def backend_of(name: str, function: str) -> str:
    """The concrete backend ``function`` runs for ``--backend name`` (validated by the
    registry, ``auto`` resolved; a deprecated name noted on stderr).

    Raises:
        InputError: ``function`` does not offer ``name`` (the names it offers listed).
    """
    if name in backends.ALIASES:
        new = backends.ALIASES[name]
        print(f"note: --backend {name} is deprecated; use --backend {new}", file=sys.stderr)
        name = new
    return backends.resolve(name, function)


def add_model_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", help="model directory (robot.urdf + robot.yaml) or its YAML file")
    p.add_argument("--frame", help="link whose pose is reported (default: the YAML's platform)")
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="print notes about the model on stderr (e.g. how its closure system was reduced)",
    )


def load(args: argparse.Namespace):
    from .robot import load_model

    model = load_model(args.model, frame=args.frame)
    if model.reduction and getattr(args, "verbose", False):
        print(f"note: {model.reduction}", file=sys.stderr)
    return model


def label(model) -> str:
    """The model's robot name, and its folder when that differs."""
    from pathlib import Path

    if model.path:
        folder = Path(model.path).absolute().parent.name
        if folder != model.name:
            return f"{model.name} ({folder})"
    return model.name


def header(model) -> str:
    """First line of the text output: the model, its workspace coordinates and their units."""
    units = model.units
    ws = ", ".join(model.workspace)
    unit_list = ", ".join(units[w] for w in model.workspace)
    return f"model {label(model)}: x = ({ws}) [{unit_list}] of {model.frame!r}"


def theta_line(model) -> str:
    """The actuated joints and their units."""
    return "theta = (" + ", ".join(f"{a} [{model.units[a]}]" for a in model.actuated) + ")"


def start_configuration(model, args: argparse.Namespace):
    if getattr(args, "from_x", None):
        return model.inverse_kinematics(floats(args.from_x, "--from-x"))
    return model.home


def dump(obj) -> None:
    print(json.dumps(obj, default=float))


# ---------------------------------------------------------------------------- solve


def _solve_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument("--theta", required=True, help=THETA_HELP)
    p.add_argument("--from-x", help=FROM_X_HELP)
    p.add_argument(
        "--branch",
        default="convergent",
        choices=["convergent", "divergent", "both"],
        help="convergent: stay in the start's compartment; divergent: cross the singular manifold",
    )
    p.add_argument("--b", type=float, help="the paper's signed scalar b (overrides --branch)")
    add_backend_arg(p, "solve")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _one_line(exc: Exception) -> str:
    """The message of an exception on one line."""
    return " ".join(str(exc).split())


def _failed_record(branch: str, exc: Exception, backend: str) -> dict:
    """JSON record of a branch whose solve failed."""
    return {
        "branch": branch,
        "status": "failed",
        "error": _one_line(exc),
        "error_type": type(exc).__name__,
        "backend": backend,
    }


@command("solve", "direct kinematics by the singularity-consistent method", _solve_args)
def _solve(args: argparse.Namespace) -> int:
    """Solve one branch, or both (``--branch both``).

    With both branches, a branch whose solver fails (:class:`SolveError`: the path did not reach
    ``s = 1``, the result failed verification, ...) is reported in place of its solution and
    the other branch is still printed; the exit code is 1 only when every branch failed. Errors
    that do not depend on the branch (bad input, model, start, build) end the command as usual.
    """
    from .solvers import sc

    backend = backend_of(args.backend, "solve")
    model = load(args)
    theta = floats(args.theta, "--theta")
    start = start_configuration(model, args)
    both = args.branch == "both" and args.b is None
    branches = ["convergent", "divergent"] if both else [args.branch]
    results: list[tuple[str, SolveResult | SolveError]] = []
    for br in branches:
        try:
            res = sc.solve(model, theta, start=start, branch=br, b=args.b, backend=backend)
        except SolveError as exc:
            if not both:
                raise
            results.append((br, exc))
        else:
            results.append((br, res))
    failed = [(br, r) for br, r in results if isinstance(r, SolveError)]
    if args.json:
        records = [
            _failed_record(br, r, backend)
            if isinstance(r, SolveError)
            else dict(r.to_dict(), backend=backend)
            for br, r in results
        ]
        dump(records[0] if not both else {"solutions": records})
    else:
        print(header(model))
        print(f"start x = {fmt(start.x)}  theta0 = {fmt(theta)}")
        for br, r in results:
            if isinstance(r, SolveError):
                print(f"{br:>10}: error: {_one_line(r)}")
                continue
            n = len(r.crossings)
            print(f"{r.branch:>10}: x = {fmt(r.x)}  residual {r.residual:.1e}  crossings {n}")
            for c in r.crossings:
                print(f"{'':>12}singular crossing ({c.kind}) at s = {c.s:.6f}: x = {fmt(c.x)}")
    if len(failed) == len(results):
        for br, err in failed:
            print(f"scdk {args.command}: error: {br}: {_one_line(err)}", file=sys.stderr)
        return 1
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
    p.add_argument(
        "--out", required=True, help="output directory (created if needed; its parent must exist)"
    )
    p.add_argument("--prefix", default="scdk", help="C prefix of every name (default: scdk)")
    p.add_argument(
        "--no-shared", action="store_true", help="write the sources only (no shared library)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")


@command("codegen", "standalone C sources of the tracker (+ a shared library)", _codegen_args)
def _codegen(args: argparse.Namespace) -> int:
    from .codegen.generate import compile_library, generate
    from .kernels.compile import compiler_command

    if not args.no_shared:
        compiler_command()  # a missing compiler ends the command before any work
    model = load(args)
    src = generate(model, args.out, args.prefix)
    library = None
    if not args.no_shared:
        library = compile_library(src, src.directory / f"lib{src.prefix}_tracker.so")
    files = [src.kernels_c, src.kernels_h, src.tracker_c, src.tracker_h]
    if args.json:
        dump({"files": [str(f) for f in files], "library": str(library) if library else None})
        return 0
    print(f"model {label(model)}: y = ({', '.join(model.unknowns)}), {theta_line(model)}")
    for f in files:
        print(f"wrote {f}")
    if library:
        print(f"wrote {library}")
    print(
        f"compile: gcc -std=c99 -O2 -Wall {src.kernels_c.name} {src.tracker_c.name} "
        f"your_program.c -lm   (include {src.tracker_h.name})"
    )
    return 0


# ---------------------------------------------------------------------------- modes


def _modes_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument("--theta", required=True, help=THETA_HELP)
    p.add_argument(
        "--method",
        default="homotopy",
        choices=["homotopy", "curves"],
        help="homotopy: every real solution, certified (default); curves: real-curve search",
    )
    p.add_argument("--from-x", help="curves: " + FROM_X_HELP)
    p.add_argument("--seed", type=int, default=0, help="seed of the random choices")
    p.add_argument("--time-budget", type=float, help="curves: wall-time limit [s] (default: none)")
    add_backend_arg(
        p,
        "modes",
        default=f"{backends.DEFAULTS['modes']} for --method homotopy, "
        f"{backends.DEFAULTS['curves']} for --method curves",
    )
    p.add_argument("--progress", action="store_true", help="progress bar on stderr")
    p.add_argument("--json", action="store_true", help="print one JSON object")


@command("modes", "all assembly modes (real direct-kinematics solutions)", _modes_args)
def _modes(args: argparse.Namespace) -> int:
    import time

    from .solvers.modes import assembly_modes, curves_result, explore

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


# ---------------------------------------------------------------------------- track


def read_thetas(path: str, model) -> np.ndarray:
    """Joint readings from a CSV file: one row per sample, one column per actuated joint.

    A first line of names (the model's actuated joints, any order) is optional; ``#`` starts
    a comment.
    """
    try:
        from pathlib import Path

        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"--thetas: cannot read {path!r}: {exc.strerror or exc}") from exc
    lines = [ln.split("#")[0].strip() for ln in text.splitlines()]
    lines = [ln for ln in lines if ln]
    if not lines:
        raise InputError(f"--thetas: {path!r} has no rows")
    for n, ln in enumerate(lines[:2], 1):
        for sep, name in ((";", "semicolons"), ("\t", "tabs")):
            if sep in ln and "," not in ln:
                raise InputError(
                    f"--thetas: {path!r} line {n} is separated by {name}; expected commas "
                    f"(one row per sample, {model.k} comma-separated values: "
                    f"{', '.join(model.actuated)})"
                )
    order = list(range(model.k))
    first = [c.strip() for c in lines[0].split(",")]
    if not any(_is_number(c) for c in first):  # a header of joint names
        from .errors import UnknownNameError

        for name in first:
            if name not in model.actuated:
                raise UnknownNameError("actuated joint", name, model.actuated)
        if sorted(first) != sorted(model.actuated):
            raise InputError(
                f"--thetas: {path!r} header {first} must name each of {list(model.actuated)}"
            )
        order = [first.index(a) for a in model.actuated]
        lines = lines[1:]
    rows = []
    for n, ln in enumerate(lines, 1):
        vals = floats(ln, f"--thetas {path!r} row {n}")
        if vals.size != model.k:
            raise InputError(
                f"--thetas: {path!r} row {n} has {vals.size} values, expected {model.k} "
                f"({', '.join(model.actuated)})"
            )
        rows.append(vals[order])
    return np.array(rows)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _track_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument("--thetas", required=True, help="CSV file of joint readings (N rows, k columns)")
    p.add_argument("--from-x", help=FROM_X_HELP)
    add_backend_arg(p, "track")
    p.add_argument("--json", action="store_true", help="print one JSON object")


@command("track", "direct kinematics along joint readings, through singularities", _track_args)
def _track(args: argparse.Namespace) -> int:
    from .solvers.track import track

    backend = backend_of(args.backend, "track")
    model = load(args)
    thetas = read_thetas(args.thetas, model)
    start = start_configuration(model, args)
    result = track(model, thetas, start=start, backend=backend)
    if args.json:
        dump(result.to_dict(model))
        return 0
    print(header(model))
    crossed = {c.index: c for c in result.crossings}
    for i, x in enumerate(result.x):
        print(f"{i:>5}: x = {fmt(x)}")
        if i in crossed:
            print(f"{'':>7}singular crossing: x = {fmt(crossed[i].x)}")
    print(f"{len(result.x)} samples, {len(result.crossings)} singular crossing(s)")
    return 0


# ---------------------------------------------------------------------------- plot


def _plot_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument(
        "--theta",
        help="solve at a,b,c on both branches: the paper's Figs. 4-6 (rad for revolute joints, "
        "the model's length unit for prismatic ones)",
    )
    what.add_argument("--thetas", help="track the CSV joint readings: pose against time")
    p.add_argument("--from-x", help=FROM_X_HELP)
    p.add_argument("--out", default=".", help="output directory (default: .)")
    p.add_argument("--prefix", help="file name prefix (default: the model name)")


@command("plot", "PNG figures of a solve (configurations, det J_p, phase) or a track", _plot_args)
def _plot(args: argparse.Namespace) -> int:
    from pathlib import Path

    from . import plot

    plot.require_matplotlib()  # before any work
    model = load(args)
    start = start_configuration(model, args)
    prefix = args.prefix or model.name
    if args.theta:
        paths = plot.plot_solve(model, floats(args.theta, "--theta"), start, args.out, prefix)
    else:
        from .solvers.track import track

        result = track(model, read_thetas(args.thetas, model), start=start)
        paths = [plot.plot_track(model, result, Path(args.out) / f"{prefix}_track.png")]
    for path in paths:
        print(f"wrote {path}")
    return 0


# ---------------------------------------------------------------------------- view


def _view_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    what = p.add_mutually_exclusive_group()
    what.add_argument("--theta", help="solve at a,b,c and animate the path; " + THETA_HELP)
    what.add_argument("--thetas", help="track the CSV joint readings and animate the samples")
    p.add_argument("--from-x", help=FROM_X_HELP)
    p.add_argument(
        "--branch",
        default="convergent",
        choices=["convergent", "divergent"],
        help="branch of the --theta solve (default: convergent)",
    )
    p.add_argument("--html", help="write a self-contained HTML page to this file (no server)")
    p.add_argument("--host", default="127.0.0.1", help="viewer address (0.0.0.0: every one)")
    p.add_argument("--port", type=int, default=8080, help="viewer port (default: 8080)")
    p.add_argument(
        "--seconds", type=float, default=4.0, help="duration of one pass of the animation [s]"
    )


@command(
    "view", "the mechanism in 3-D in a browser (viser), or a self-contained HTML page", _view_args
)
def _view(args: argparse.Namespace) -> int:
    from . import view

    view.require_viser()  # before any work
    model = load(args)
    start = start_configuration(model, args)
    what: SolveResult | TrackResult | Configuration
    if args.theta:
        from .solvers.sc import solve

        theta = floats(args.theta, "--theta")
        what = solve(model, theta, start=start, branch=args.branch, record_path=True)
    elif args.thetas:
        from .solvers.track import track

        what = track(model, read_thetas(args.thetas, model), start=start)
    else:
        what = start
    for note in view.robot_scene(model, start).notes:  # URDF geometry that is not drawn
        print(f"note: {note}", file=sys.stderr)
    if args.html:
        path = view.write_html(model, what, args.html, seconds=args.seconds)
        print(f"wrote {path}")
        return 0
    viewer = view.show(model, what, host=args.host, port=args.port, seconds=args.seconds,
                       block=False)  # fmt: skip
    print(f"viewer at {viewer.url} ({len(viewer.frames)} frame(s)); Ctrl-C to stop", flush=True)
    viewer.wait()
    return 0


# ---------------------------------------------------------------------------- atlas


def _atlas_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument(
        "--grid",
        required=True,
        help="NAME=lo:hi:n[,NAME=lo:hi:n...] over actuated joints; point i is the C-order "
        "flattening in the order given; joints not named stay at the start's value",
    )
    p.add_argument("--out", required=True, help="Zarr store directory (DIR.zarr); resumes")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="local worker processes (Dask LocalCluster)")
    where.add_argument("--scheduler", help="address of a running Dask scheduler (tcp://host:8786)")
    p.add_argument("--modes", action="store_true", help="also count the real assembly modes")
    p.add_argument("--from-x", help="start pose in workspace coordinates (default: home)")
    p.add_argument("--chunk", type=int, default=4096, help="points per chunk (default: 4096)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--json", action="store_true", help="print the run's summary as one JSON object")


@command("atlas", "convergent direct kinematics over a joint grid into a Zarr store", _atlas_args)
def _atlas(args: argparse.Namespace) -> int:
    from .atlas import STATUS, atlas

    model = load(args)
    start = start_configuration(model, args)
    try:
        run = atlas(
            model,
            args.grid,
            args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            modes=args.modes,
            start=start,
            chunk=args.chunk,
            progress=not args.no_progress,
        )
    except KeyboardInterrupt:
        print(
            f"scdk atlas: interrupted; the chunks written are kept: re-run the same command "
            f"to resume ({args.out})",
            file=sys.stderr,
        )
        return 130
    statuses = [
        (code, STATUS.get(code, "not written").split(":")[0], n)
        for code, n in sorted(run.counts.items())
    ]
    if args.json:
        dump(
            {
                "out": str(run.out),
                "points": run.points,
                "chunks": run.chunks,
                "computed": run.computed,
                "statuses": [
                    {"code": code, "name": name, "count": n} for code, name, n in statuses
                ],
                "elapsed": run.elapsed,
                "busy": run.busy,
                "cpu": run.cpu,
                "swept": run.swept,
            }
        )
        return 0
    print(
        f"{run.out}: {run.points} points in {run.chunks} chunks ({run.computed} solved now, "
        f"{run.elapsed:.1f} s)"
    )
    for code, name, n in statuses:
        print(f"  status {code} ({name}): {n}")
    return 0


def _plot_atlas_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("store", help="atlas store written by scdk atlas (DIR.zarr)")
    p.add_argument("--out", required=True, help="PNG file")
    p.add_argument("--axes", help="the two grid axes drawn, NAME,NAME (default: the first two)")
    p.add_argument(
        "--at", help="values of the other grid axes, NAME=value,... (default: their middle)"
    )


@command(
    "plot-atlas", "2-D slices of an atlas store (status, det J_p sign, modes)", _plot_atlas_args
)
def _plot_atlas(args: argparse.Namespace) -> int:
    from .atlas.plot import plot_atlas

    axes = tuple(a.strip() for a in args.axes.split(",")) if args.axes else None
    at = None
    if args.at:
        at = {}
        for part in args.at.split(","):
            name, _, value = part.partition("=")
            vals = floats(value, f"--at {name.strip()}")
            if vals.size != 1:
                raise InputError(f"--at: expected NAME=value, got {part!r}")
            at[name.strip()] = float(vals[0])
    print(f"wrote {plot_atlas(args.store, args.out, axes=axes, at=at)}")
    return 0


def _verify_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument(
        "--samples",
        type=int,
        default=3,
        help="random configurations and random solutions checked besides home (default 3)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the random configurations")
    p.add_argument("--json", action="store_true", help="print one JSON object")


@command(
    "verify",
    "cross-check the model: frame placements and closures against Pinocchio, Jacobians "
    "against finite differences (exit 1 when a check fails)",
    _verify_args,
)
def _verify(args: argparse.Namespace) -> int:
    from .verify.report import verify_model

    model = load(args)
    report = verify_model(model, samples=args.samples, seed=args.seed)
    if args.json:
        dump(report.to_dict())
    else:
        print(header(model))
        print(report.text())
    return 0 if report.passed else 1


# ---------------------------------------------------------------------------- main


def version() -> str:
    """The installed package's version (from its metadata)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as metadata_version

    try:
        return metadata_version("scdk_sym")
    except PackageNotFoundError:  # pragma: no cover - run from a source tree
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="scdk", description="Singularity-consistent direct kinematics of parallel robots."
    )
    parser.add_argument("--version", action="version", version=f"scdk_sym {version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (help_text, arguments, run) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        arguments(p)
        p.set_defaults(run=run)
    return parser


def _help_in_model_units(parser: argparse.ArgumentParser, argv: list[str]) -> None:
    """For ``scdk COMMAND MODEL --help``: state ``--theta`` and ``--from-x`` in that model's
    names and units (the generic help stays when the model cannot be loaded)."""
    if not {"-h", "--help"} & set(argv):
        return
    words = [a for a in argv if not a.startswith("-")]
    if len(words) < 2 or words[0] not in COMMANDS:
        return
    from .robot import load_model

    try:
        model = load_model(words[1])
    except ScdkError:
        return
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    units = model.units
    joints = ", ".join(f"{a} [{units[a]}]" for a in model.actuated)
    coords = ", ".join(f"{w} [{units[w]}]" for w in model.workspace)
    for action in sub.choices[words[0]]._actions:
        if action.dest in ("theta", "thetas"):
            action.help = f"{action.help}; this model: {joints}"
        elif action.dest == "from_x":
            action.help = f"start pose (default: home); this model: {coords}"


#: Exit code after the reader of the output went away (128 + SIGPIPE, as Unix tools report).
EXIT_BROKEN_PIPE = 141


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 error of the package, 2 usage, 141 when the
    reader of the output closed it early, e.g. ``| head``, which ends the command quietly)."""
    parser = build_parser()
    _help_in_model_units(parser, sys.argv[1:] if argv is None else list(argv))
    args = parser.parse_args(argv)
    try:
        code = int(args.run(args))
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except ScdkError as exc:
        print(f"scdk {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 1


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush does not fail again."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # not a real file (e.g. captured)
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
