"""Model files: the URDF spanning tree and the loop-closure YAML of a model, read and parsed.

Description only (no symbolic build): the model directory layout and the two parsers.
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path

from ..errors import InputError, ModelError
from .spec import Spec, parse_spec
from .urdf import Tree, parse_urdf


def read_description(path: str | PathLike[str]) -> tuple[Tree, Spec, str, str]:
    """Read and parse a model's ``robot.urdf`` + ``robot.yaml``.

    Args:
        path: model directory, or the path of its YAML file (the URDF is the YAML's name with
            ``.urdf`` beside it, else ``robot.urdf`` in the same folder, else the folder's one
            ``.urdf`` file if it holds only one, as some of Gepetto's robots do).

    Returns:
        The spanning tree, the closure spec, the YAML path and the URDF text.

    Raises:
        InputError: ``path`` is not a string or a path.
        ModelError: missing or unreadable files, malformed URDF or YAML.
    """
    if not isinstance(path, (str, PathLike)):
        raise InputError(
            f"load_model: path must be a model directory or its YAML file (str or path), got "
            f"{path!r} of type {type(path).__name__}"
        )
    p = Path(path)
    if p.is_dir():
        yaml_path, urdf_path = p / "robot.yaml", p / "robot.urdf"
    elif p.suffix in (".yaml", ".yml"):
        yaml_path = p
        urdf_path = p.with_suffix(".urdf")
        if not urdf_path.exists():
            urdf_path = p.parent / "robot.urdf"
    elif not p.exists():
        raise ModelError(
            "not found: expected a model directory, a .yaml file or an MJCF .xml file", str(p)
        )
    else:
        raise ModelError("expected a model directory, a .yaml file or an MJCF .xml file", str(p))
    if not urdf_path.exists():
        urdf_path = _only_urdf(urdf_path)
    for f in (yaml_path, urdf_path):
        if not f.exists():
            raise ModelError("file not found", str(f))
    urdf_text = _read(urdf_path)
    tree = parse_urdf(urdf_text, str(urdf_path))
    spec = parse_spec(_read(yaml_path), str(yaml_path))
    return tree, spec, str(yaml_path), urdf_text


def _only_urdf(expected: Path) -> Path:
    """The one ``.urdf`` file of ``expected``'s folder, or ``expected`` if there is not
    exactly one."""
    found = sorted(expected.parent.glob("*.urdf"))
    return found[0] if len(found) == 1 else expected


def _read(path: Path) -> str:
    """The text of a model file (UTF-8), or a :class:`ModelError` saying why not."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ModelError(
            f"not a UTF-8 text file ({exc.reason} at byte {exc.start})", str(path)
        ) from exc
    except OSError as exc:
        raise ModelError(f"cannot read: {exc.strerror or exc}", str(path)) from exc
