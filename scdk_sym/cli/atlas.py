"""``scdk atlas`` (a joint grid solved into a Zarr store) and ``scdk plot-atlas``."""

from __future__ import annotations

import argparse
import sys

from ..errors import InputError
from .common import add_model_args, command, dump, floats, load, start_configuration


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
    from ..atlas import STATUS, atlas

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
    from ..atlas.plot import plot_atlas

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
