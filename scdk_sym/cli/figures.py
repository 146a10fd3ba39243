"""``scdk plot`` (PNG figures) and ``scdk view`` (the mechanism in 3-D)."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from .common import (
    FROM_X_HELP,
    FROM_X_METAVAR,
    THETA_HELP,
    THETA_METAVAR,
    THETAS_HELP,
    add_model_args,
    command,
    floats,
    load,
    start_configuration,
)
from .track import read_thetas

if TYPE_CHECKING:
    from ..results import Configuration, SolveResult, TrackResult


def _plot_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument(
        "--theta",
        metavar=THETA_METAVAR,
        help="solve on both branches and draw the paper's Figs. 4-6; " + THETA_HELP,
    )
    what.add_argument(
        "--thetas",
        metavar="CSV",
        help="track the readings and draw the pose against time; " + THETAS_HELP,
    )
    p.add_argument("--from-x", metavar=FROM_X_METAVAR, help=FROM_X_HELP)
    p.add_argument(
        "--out", default=".", metavar="DIR", help="output directory, created if needed (default: .)"
    )
    p.add_argument("--prefix", help="file name prefix (default: the model name)")


@command(
    "plot",
    "PNG figures of a solve (configurations, det J_p, phase) or of a track",
    _plot_args,
    "scdk plot models/planar_hexa --theta 1.292,-0.802,-2.896 --from-x 0,0,0.4 --out figures",
)
def _plot(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .. import plot

    plot.require_matplotlib()  # before any work
    model = load(args)
    start = start_configuration(model, args)
    prefix = args.prefix or model.name
    if args.theta:
        paths = plot.plot_solve(model, floats(args.theta, "--theta"), start, args.out, prefix)
    else:
        from ..solvers.track import track

        result = track(model, read_thetas(args.thetas, model), start=start)
        paths = [plot.plot_track(model, result, Path(args.out) / f"{prefix}_track.png")]
    for path in paths:
        print(f"wrote {path}")
    return 0


def _view_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    what = p.add_mutually_exclusive_group()
    what.add_argument(
        "--theta", metavar=THETA_METAVAR, help="solve and animate the path; " + THETA_HELP
    )
    what.add_argument(
        "--thetas", metavar="CSV", help="track and animate the samples; " + THETAS_HELP
    )
    p.add_argument("--from-x", metavar=FROM_X_METAVAR, help=FROM_X_HELP)
    p.add_argument(
        "--branch",
        default="convergent",
        choices=["convergent", "divergent"],
        help="branch of the --theta solve (default: convergent)",
    )
    p.add_argument(
        "--html",
        metavar="FILE",
        help="write a self-contained HTML page to this file instead of serving (default: serve)",
    )
    p.add_argument(
        "--host",
        default="127.0.0.1",
        metavar="ADDRESS",
        help="address the viewer listens on; 0.0.0.0 for every interface (default: 127.0.0.1)",
    )
    p.add_argument("--port", type=int, default=8080, help="port the viewer listens on")
    p.add_argument(
        "--seconds", type=float, default=4.0, help="duration of one pass of the animation [s]"
    )


@command(
    "view",
    "the mechanism in 3-D in a browser (viser), or a self-contained HTML page",
    _view_args,
    "scdk view models/planar_hexa --theta 1.292,-0.802,-2.896 --from-x 0,0,0.4 --html seed.html",
)
def _view(args: argparse.Namespace) -> int:
    from .. import view

    view.require_viser()  # before any work
    model = load(args)
    start = start_configuration(model, args)
    what: SolveResult | TrackResult | Configuration
    if args.theta:
        from ..solvers.solve import solve

        theta = floats(args.theta, "--theta")
        what = solve(model, theta, start=start, branch=args.branch, record_path=True)
    elif args.thetas:
        from ..solvers.track import track

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
