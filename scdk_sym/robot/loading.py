"""Models made from files or from memory: a directory of ``robot.urdf`` + ``robot.yaml``, an
MJCF file (its springs held, its preloaded springs and passive tendons named when they keep the
model from reducing), or an in-memory tree and spec."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from os import PathLike
from pathlib import Path
from typing import Any

from ..errors import ModelError, NonSquareSystemError
from ..model.files import read_description
from ..model.spec import Spec
from ..model.urdf import Tree
from .model import Model


def load_model(
    path: str | Path,
    frame: str | None = None,
    *,
    inputs: Sequence[str] | None = None,
    locked: Mapping[str, float] | None = None,
) -> Model:
    """Load a model: a directory holding ``robot.urdf`` + ``robot.yaml`` (or the YAML path),
    or an MJCF file (``.xml``, read by MuJoCo's compiler: ``pip install "scdk_sym[mjcf]"``).

    Args:
        path: model directory, the path of its YAML file (the URDF is ``robot.urdf`` beside
            it, or the YAML's name with ``.urdf``), or an MJCF ``.xml`` file.
        frame: link whose pose is reported as x, or a joint (its child link's frame, as in
            Pinocchio) (default: the YAML's ``platform``, else ``effector`` if present).
        inputs: the joints given to the solvers (theta), instead of the YAML's ``name_mot``
            or the MJCF actuators' joints: motors plus measured spring joints, or a leg's
            output joints so that the motors become unknowns.
        locked: joints held at given values [rad or length unit]; of an MJCF file, added to
            its springs (held at ``springref``), whose values it overrides.

    Raises:
        ModelError: missing files, malformed URDF/YAML/MJCF, unknown names, non-square
            systems (a choice of inputs that leaves freedoms undetermined, or binds inputs).
        DependencyError: an MJCF file without ``mujoco`` installed.
    """
    if isinstance(path, (str, PathLike)) and Path(path).suffix.lower() == ".xml":
        from ..model.mjcf import read_mjcf

        tree, spec, source = read_mjcf(path)
        chosen = set(inputs) if inputs is not None and not isinstance(inputs, str) else set()
        chosen |= set(locked or {})
        held = {k: v for k, v in source.springs.items() if k not in chosen}
        preloaded = [label for k, label in source.preloaded.items() if k not in chosen]
        if preloaded:
            _refuse_preloaded(tree, spec, str(path), source, preloaded, held, inputs)
        held.update(locked or {})
        try:
            return Model(tree, spec, str(path), frame or source.frame, inputs=inputs,
                         locked=held, source=source)  # fmt: skip
        except NonSquareSystemError as exc:
            _name_passive_tendons(exc, source, held)
            raise
    tree, spec, yaml_path, urdf_text = read_description(path)
    return Model(tree, spec, yaml_path, frame, urdf_text, inputs=inputs, locked=locked)


def _name_passive_tendons(exc: NonSquareSystemError, source: Any, held: Mapping) -> None:
    """Raise ``exc`` again naming the passive tendons whose limits alone would hold the
    freedoms it reports (limits are inequalities, not closures), if there are such."""
    text = str(exc)
    named = {t: [j for j in joints if repr(j) in text and j not in held]
             for t, joints in source.passive_tendons.items()}  # fmt: skip
    named = {t: js for t, js in named.items() if js}
    if not named:
        return
    listed = "; ".join(f"tendon {t!r}: {', '.join(js)}" for t, js in named.items())
    raise NonSquareSystemError(
        f"{text.removeprefix(str(exc.path) + ': ')}; joints held only by the limits of a "
        f"passive tendon ({listed}), an inequality, not a closure: lock them (locked={{...}}) "
        "or make them inputs (inputs=[...])",
        exc.rows,
        exc.unknowns,
        exc.rank,
        exc.path,
    ) from exc


def _refuse_preloaded(tree, spec, path, source, preloaded, held, inputs) -> None:
    """Refuse springs that cannot be held at their springref, naming the freedoms they hold
    (the reduction's message with them free)."""
    free = {k: v for k, v in held.items() if k not in source.preloaded}
    names = ", ".join(preloaded)
    fix = "lock them at values that assemble (locked={...}) or give them as inputs (inputs=[...])"
    try:
        Model(tree, spec, path, source.frame, inputs=inputs, locked=free, source=source)
    except ModelError as exc:
        raise ModelError(
            f"springs {names} cannot be held at springref, and without them: "
            f"{str(exc).removeprefix(path + ': ')}; {fix}",
            path,
        ) from exc
    raise ModelError(f"springs {names} cannot be held at springref; {fix}", path)


def model_from_tree(tree: Tree, spec: Spec, frame: str | None = None) -> Model:
    """Make a model from an in-memory tree and spec (used by the builders)."""
    return Model(tree, spec, None, frame)
