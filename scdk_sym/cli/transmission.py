"""``scdk range``: a leg's motor <-> joint map certified over a box of its output joints, and
its margin over the box as a figure."""

from __future__ import annotations

import argparse

from ..errors import InputError
from .common import add_model_args, command, dump, header, load


def _range_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument(
        "--outputs",
        required=True,
        metavar="J1,J2,...",
        help="the output joints, as many as the motors (a motor may be its own output)",
    )
    p.add_argument(
        "--box",
        required=True,
        metavar="NAME=LO:HI,...",
        help="the outputs that vary and their bounds [rad or length unit]; the others stay "
        "at their home values",
    )
    p.add_argument("--depth", type=int, default=8, help="halvings of a part before it is left open")
    p.add_argument("--max-boxes", type=int, default=1000, help="parts tested at most")
    p.add_argument("--out", metavar="FILE.png", help="draw the margin over the box")
    p.add_argument("--n", type=int, default=21, help="grid points per axis of the figure")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")


def _box(text: str, outputs: tuple[str, ...], home) -> tuple[list[float], list[float]]:
    lower, upper = [float(v) for v in home], [float(v) for v in home]
    for item in text.split(","):
        name, eq, bounds = item.partition("=")
        lo, colon, hi = bounds.partition(":")
        try:
            a, b = float(lo), float(hi)
        except ValueError:
            colon = ""
        if not eq or not colon:
            raise InputError(f"--box: expected NAME=LO:HI pairs separated by commas, got {item!r}")
        if name.strip() not in outputs:
            raise InputError(f"--box: {name.strip()!r} is not an output; outputs: {list(outputs)}")
        k = outputs.index(name.strip())
        lower[k], upper[k] = a, b
    return lower, upper


@command(
    "range",
    "certify a leg's motor <-> joint map over a box of its outputs (invertible, no singular "
    "configuration; interval arithmetic) and draw its margin over the box",
    _range_args,
    "scdk range tests/fixtures/gepetto/digit_like --outputs motor_hip_x,motor_hip_y,"
    "motor_hip_z,free_knee,free_foot1,free_foot2 --box free_foot1=-0.014:-0.008,"
    "free_foot2=0.042:0.048 --out range.png",
)
def _range(args: argparse.Namespace) -> int:
    from ..solvers.transmission import transmission
    from ..solvers.transmission_range import margin_grid

    model = load(args)
    outputs = tuple(n.strip() for n in args.outputs.split(",") if n.strip())
    T = transmission(model, outputs)
    lower, upper = _box(args.box, T.outputs, T.inverse_model.home.theta)
    cert = T.certify_range(lower, upper, depth=args.depth, max_boxes=args.max_boxes)
    figure = None
    if args.out:
        from ..plot import plot_range

        figure = str(plot_range(margin_grid(T, lower, upper, n=args.n), args.out, cert))
    if args.json:
        dump({"proven": cert.proven, "proven_boxes": len(cert.boxes),
              "open_boxes": cert.open_boxes.tolist(), "sigma_lower": cert.sigma_lower,
              "margin_lower": cert.margin_lower, "reasons": list(cert.reasons),
              "figure": figure})  # fmt: skip
        return 0
    print(header(model))
    verdict = "proven" if cert.proven else "NOT proven"
    print(f"{verdict}: {len(cert.boxes)} part(s) proven, {len(cert.open_boxes)} open; "
          f"margin >= {cert.margin_lower:.2e} (sigma_min of J_p >= {cert.sigma_lower:.2e}) "
          "over the proven parts")  # fmt: skip
    for b, why in list(zip(cert.open_boxes, cert.reasons, strict=True))[:5]:
        varied = [f"{o}=[{lo:.6g}, {hi:.6g}]" for o, (lo, hi) in zip(T.outputs, b, strict=True)
                  if hi > lo]  # fmt: skip
        print(f"  open: {', '.join(varied)}: {why}")
    if figure:
        print(f"wrote {figure}")
    return 0
