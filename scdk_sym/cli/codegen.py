"""``scdk cache`` and ``scdk codegen``: the compiled kernels on disk and standalone C."""

from __future__ import annotations

import argparse

from .common import add_model_args, command, dump, label, load, theta_line


def _cache_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--clear", action="store_true", help="delete every cached product (default: only show)"
    )


@command(
    "cache",
    "show or clear the on-disk cache of compiled kernels ($SCDK_CACHE_DIR, "
    "default ~/.cache/scdk_sym)",
    _cache_args,
    "scdk cache --clear",
)
def _cache(args: argparse.Namespace) -> int:
    from ..kernels.cache import cache_dir, clear_cache

    if args.clear:
        print(f"removed {clear_cache()} cached item(s) from {cache_dir()}")
    else:
        entries = sorted(cache_dir().iterdir())
        size = sum(e.stat().st_size for e in entries if e.is_file())
        print(f"{cache_dir()}: {len(entries)} item(s), {size / 1e6:.1f} MB")
    return 0


def _codegen_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument(
        "--out",
        required=True,
        metavar="DIR",
        help="output directory (created if needed; its parent must exist)",
    )
    p.add_argument("--prefix", default="scdk", help="C prefix of every name (default: scdk)")
    p.add_argument(
        "--no-shared",
        action="store_true",
        help="write the sources only (default: also compile a shared library with $CC or gcc)",
    )
    p.add_argument(
        "--stages",
        action="store_true",
        help="one tracker per block of the block-triangular decomposition (a leg's knee, then "
        "its ankle: model.stages), in DIR/stage<i> with prefix <prefix>_s<i>; a stage's "
        "actuators are the model's it involves, then the earlier stages' unknowns it reads",
    )
    p.add_argument(
        "--outputs",
        metavar="NAME1,NAME2,...",
        help="write the C transmission of a leg controller instead (motor <-> output-joint maps: "
        "forward, inverse, Jacobian, velocities, torques, margin; one header "
        "<prefix>_transmission.h): the output joints, one per motor (a motor may be its own)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")


@command(
    "codegen",
    "write standalone C sources of the model's tracker (and compile a shared library)",
    _codegen_args,
    "scdk codegen models/planar_hexa --out planar_hexa_c",
)
def _codegen(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..codegen.generate import compile_library, generate
    from ..kernels.compile import compiler_command

    if not args.no_shared:
        compiler_command()  # a missing compiler ends the command before any work
    if args.outputs is not None:
        return _codegen_transmission(args)
    model = load(args)
    parts = model.stages if args.stages else (model,)
    staged = len(parts) > 1
    written = []
    for i, part in enumerate(parts):
        out = Path(args.out) / f"stage{i}" if staged else args.out
        if staged:
            Path(args.out).mkdir(exist_ok=True)
        src = generate(part, out, f"{args.prefix}_s{i}" if staged else args.prefix)
        library = None
        if not args.no_shared:
            library = compile_library(src, src.directory / f"lib{src.prefix}_tracker.so")
        files = [src.kernels_c, src.kernels_h, src.tracker_c, src.tracker_h, src.lu_h]
        written.append((part, src, files, library))
    if args.json:
        entries = [
            {"files": [str(f) for f in files], "library": str(library) if library else None}
            for _part, _src, files, library in written
        ]
        if staged:
            for entry, (part, *_rest) in zip(entries, written, strict=True):
                entry.update(unknowns=list(part.unknowns), actuated=list(part.actuated))
        dump({"stages": entries} if staged else entries[0])
        return 0
    print(f"model {label(model)}: y = ({', '.join(model.unknowns)}), {theta_line(model)}")
    if args.stages and not staged:
        print("the model does not split into stages: one tracker")
    for i, (part, src, files, library) in enumerate(written):
        if staged:
            print(f"stage {i}: y = ({', '.join(part.unknowns)}), "
                  f"theta = ({', '.join(part.actuated)})")  # fmt: skip
        for f in files:
            print(f"wrote {f}")
        if library:
            print(f"wrote {library}")
        print(
            f"compile: gcc -std=c99 -O2 -Wall {src.kernels_c.name} {src.tracker_c.name} "
            f"your_program.c -lm   (include {src.tracker_h.name})"
        )
    if staged:
        print("track the stages in order: a stage's theta is the model's actuators it names, "
              "then the unknowns it names from the stages before it")  # fmt: skip
    return 0


def _codegen_transmission(args: argparse.Namespace) -> int:
    """``scdk codegen MODEL --outputs ...``: the C transmission (solvers/transmission_c.py)."""
    from ..errors import InputError
    from ..solvers.transmission_c import compile_transmission, write_transmission

    if args.stages:
        raise InputError("--outputs and --stages do not go together: choose one")
    outputs = [name.strip() for name in args.outputs.split(",") if name.strip()]
    model = load(args)
    src = write_transmission(model, outputs, args.out, args.prefix)
    library = None
    if not args.no_shared:
        library = compile_transmission(src, src.directory / f"lib{src.prefix}_transmission.so")
    if args.json:
        dump({"files": [str(f) for f in src.files], "library": str(library) if library else None,
              "header": str(src.header), "outputs": outputs})  # fmt: skip
        return 0
    print(f"model {label(model)}: {theta_line(model)}; outputs = ({', '.join(outputs)})")
    for f in src.files:
        print(f"wrote {f}")
    if library:
        print(f"wrote {library}")
    print(f"compile: gcc -std=c99 -O2 -Wall *.c your_controller.c -lm   (in {src.directory}; "
          f"include {src.header.name})")  # fmt: skip
    return 0
