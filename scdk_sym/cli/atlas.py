"""``scdk atlas`` (a joint grid solved into a Zarr store) and ``scdk plot-atlas``."""

from __future__ import annotations

import argparse

from ..errors import InputError
from .common import (
    FROM_X_HELP,
    FROM_X_METAVAR,
    add_model_args,
    command,
    dump,
    floats,
    load,
    start_configuration,
)


def _atlas_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument(
        "--grid",
        required=True,
        metavar="NAME=LO:HI:N,...",
        help="the grid: for each actuated joint NAME, n values from lo to hi (the model's "
        "units); point i is the C-order flattening in the order given; joints not named stay "
        "at the start's value",
    )
    p.add_argument(
        "--out",
        required=True,
        metavar="DIR.zarr",
        help="Zarr store directory (created; an interrupted run of the same command resumes it)",
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="local worker processes (a Dask LocalCluster; default: solve in this process)",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="address of a running Dask scheduler, e.g. tcp://host:8786 (default: none)",
    )
    p.add_argument(
        "--modes",
        action="store_true",
        help="also count the certified real assembly modes at each point (each point's set "
        "from its grid neighbour's by a parameter homotopy; about 0.3 ms a point on a 3-RPR, "
        "against microseconds for a swept solve; default: off)",
    )
    p.add_argument(
        "--modes-only",
        action="store_true",
        help="a mode map alone: the certified counts of --modes without the convergent "
        "solves (status 5 everywhere; default: off)",
    )
    p.add_argument("--from-x", metavar=FROM_X_METAVAR, help=FROM_X_HELP)
    p.add_argument("--chunk", type=int, default=4096, metavar="N", help="points per chunk")
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="progress bar on stderr (default: on)",
    )
    p.add_argument(
        "--wait",
        action="store_true",
        help="when another run is writing --out, wait for it to end, then solve what it "
        "left (default: refuse in one line)",
    )
    p.add_argument(
        "--json",
        action="store_true",
        help="print the run's summary as one JSON object instead of the text",
    )


@command(
    "atlas",
    "convergent direct kinematics over a grid of joint values, written to a Zarr store",
    _atlas_args,
    "scdk atlas models/planar_hexa --grid theta_1=1.0:1.6:50,theta_2=-1.1:-0.5:50 "
    "--from-x 0,0,0.4 --out seed.zarr",
)
def _atlas(args: argparse.Namespace) -> int:
    from ..atlases import STATUS, atlas

    model = load(args)
    start = start_configuration(model, args)
    run = atlas(
        model,
        args.grid,
        args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        modes=args.modes or args.modes_only,
        solve=not args.modes_only,
        start=start,
        chunk=args.chunk,
        progress=args.progress,
        wait=args.wait,
    )
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
    p.add_argument("--out", required=True, metavar="FILE.png", help="PNG file written")
    p.add_argument(
        "--axes",
        metavar="NAME,NAME",
        help="the two grid axes drawn, horizontal then vertical (default: the first two)",
    )
    p.add_argument(
        "--at",
        metavar="NAME=VALUE,...",
        help="values of the other grid axes, in the model's units; the nearest grid value is "
        "drawn (default: their middle)",
    )


@command(
    "plot-atlas",
    "a PNG of a 2-D slice of an atlas store (status, sign of det J_p, modes)",
    _plot_atlas_args,
    "scdk plot-atlas seed.zarr --out seed.png --axes theta_1,theta_2 --at theta_3=-2.9",
)
def _plot_atlas(args: argparse.Namespace) -> int:
    from ..atlases.plot import plot_atlas

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
