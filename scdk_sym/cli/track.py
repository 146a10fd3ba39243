"""``scdk track``: direct kinematics along a CSV file of joint readings."""

from __future__ import annotations

import argparse

import numpy as np

from ..errors import InputError
from .common import (
    FROM_X_HELP,
    FROM_X_METAVAR,
    THETAS_HELP,
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
        from ..errors import UnknownNameError

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
    p.add_argument("--thetas", required=True, metavar="CSV", help=THETAS_HELP)
    p.add_argument("--from-x", metavar=FROM_X_METAVAR, help=FROM_X_HELP)
    add_backend_arg(p, "track")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")


@command(
    "track",
    "direct kinematics along a file of joint readings, through singularities",
    _track_args,
    "scdk track models/planar_hexa --thetas readings.csv --from-x 0,0,0.4",
)
def _track(args: argparse.Namespace) -> int:
    from ..solvers.track import track

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
