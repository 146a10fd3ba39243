"""``scdk assemble``: the home configuration a model assembles to, written back as ``home``."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from ..errors import OutputError
from .common import add_model_args, command, header, load


def _assemble_args(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument(
        "--write",
        action="store_true",
        help="write the assembled configuration into the model's YAML as 'home' (the rest of "
        "the file is kept as it is)",
    )


def home_block(joints: dict[str, float]) -> str:
    """The YAML ``home:`` block of a joint-coordinate mapping [rad or length unit]."""
    lines = ["home:"]
    lines += [f"  {name!r}: {value!r}" for name, value in joints.items()]
    return "\n".join(lines) + "\n"


def write_home(yaml_path: Path, joints: dict[str, float]) -> None:
    """Replace (or append) the top-level ``home:`` block of a YAML file.

    Raises:
        OutputError: the file cannot be written.
    """
    text = yaml_path.read_text(encoding="utf-8")
    block = home_block(joints)
    pattern = re.compile(r"^home:.*?(?=^\S|\Z)", re.MULTILINE | re.DOTALL)
    if pattern.search(text):
        text = pattern.sub(lambda _: block, text, count=1)
    else:
        text = text.rstrip("\n") + "\n" + block
    try:
        yaml_path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"cannot write 'home': {exc.strerror or exc}", yaml_path) from exc


@command(
    "assemble",
    "assemble the model from its neutral configuration when its YAML gives no home "
    "(continuation from a relaxed closure), print it, and write it back as 'home' with --write",
    _assemble_args,
    "scdk assemble tests/fixtures/gepetto/wl16_like --write",
)
def _assemble(args: argparse.Namespace) -> int:
    model = load(args)
    print(header(model))
    print(model.assembly or "home: as given in the YAML, or closed by least squares at neutral")
    if model.reduction:
        print(model.reduction)
    joints = model.file_joints(model.home)
    print(f"home closes every loop to {model.home.residual:.1e}")
    if args.write:
        if model.source is not None:
            raise OutputError(
                "an MJCF model's home is its keyframe 'home' (or qpos0): write the printed "
                "configuration's qpos there",
                model.path,
            )
        if model.path is None:
            raise OutputError("the model has no YAML file to write 'home' into", "model")
        write_home(Path(model.path), joints)
        print(f"wrote 'home' ({len(joints)} joint coordinates) into {model.path}")
    else:
        print(home_block(joints), end="")
    return 0
