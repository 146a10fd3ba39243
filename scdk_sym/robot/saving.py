"""A model written back as files: ``robot.urdf`` and ``robot.yaml`` in a folder."""

from __future__ import annotations

from pathlib import Path

from ..errors import OutputError
from ..model.spec import Spec


def save(directory: str | Path, urdf_text: str, spec: Spec) -> Path:
    """Write ``robot.urdf`` (``urdf_text``) and ``robot.yaml`` (``spec``) into ``directory``
    (created if needed).

    Returns:
        The folder written.

    Raises:
        OutputError: ``directory`` is a file or cannot be written.
    """
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise OutputError("is a file, not a folder; choose a folder to save the model in", d)
    try:
        d.mkdir(parents=True, exist_ok=True)
        (d / "robot.urdf").write_text(urdf_text)
        (d / "robot.yaml").write_text(spec.to_yaml())
    except OSError as exc:
        raise OutputError(f"cannot save the model: {exc.strerror or exc}", d) from exc
    return d
