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
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")


@command(
    "codegen",
    "write standalone C sources of the model's tracker (and compile a shared library)",
    _codegen_args,
    "scdk codegen models/planar_hexa --out planar_hexa_c",
)
def _codegen(args: argparse.Namespace) -> int:
    from ..codegen.generate import compile_library, generate
    from ..kernels.compile import compiler_command

    if not args.no_shared:
        compiler_command()  # a missing compiler ends the command before any work
    model = load(args)
    src = generate(model, args.out, args.prefix)
    library = None
    if not args.no_shared:
        library = compile_library(src, src.directory / f"lib{src.prefix}_tracker.so")
    files = [src.kernels_c, src.kernels_h, src.tracker_c, src.tracker_h, src.lu_h]
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
