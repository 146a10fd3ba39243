"""Checks of what a model is given: numeric vectors, the joint names of ``inputs=`` and
``locked=``, the names a closure side file uses, and its workspace; each refusal says what is
wrong."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import InputError, ModelError, UnknownNameError
from ..model.spec import Spec
from ..model.urdf import Tree


def as_vector(value, size: int, what: str) -> np.ndarray:
    """Validate a finite 1-D array of a given size (raises :class:`InputError`)."""
    if value is None or isinstance(value, (str, bytes, dict)):
        raise InputError(f"{what} must be {size} numbers, got {value!r}")
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what} must be {size} numbers, got {value!r}") from exc
    if arr.size != size:
        raise InputError(f"{what} must have {size} values, got {arr.size}: {arr.tolist()}")
    if not np.isfinite(arr).all():
        raise InputError(f"{what} must be finite, got {arr.tolist()}")
    return arr


def check_names(tree: Tree, spec: Spec, joint_frames: dict[str, str], path: str | None) -> None:
    """Every name of the spec exists in the tree: closure frames (links or joints), actuated
    joints (movable, one coordinate), length joints, home coordinates."""
    links, movable, single = tree.links, tree.coordinates, tree.single_coordinate_joints
    frames = (*links, *joint_frames)
    for c in spec.closures:
        if c.type == "coupling":
            for j in c.joints:
                if j not in single:
                    raise UnknownNameError(
                        "joint",
                        j,
                        single,
                        path,
                        None if j not in movable else "in a coupling is not a one-coordinate joint",
                    )
            continue
        for f in (c.frame_a, c.frame_b):
            if f not in links and f not in joint_frames:
                raise UnknownNameError("frame", f, frames, path)
    kinds = {j.name: j.type for j in tree.joints}
    for a in spec.actuated:
        if a not in single:
            if kinds.get(a) in ("fixed", "floating", "spherical"):
                reason = (
                    f"in 'name_mot' is a {kinds[a]} joint: only a movable joint with one "
                    "coordinate can be actuated"
                )
                raise UnknownNameError("movable joint", a, single, path, reason)
            raise UnknownNameError("joint", a, single, path)
    for c in spec.closures:
        if c.length_joint is not None and c.length_joint not in single:
            raise UnknownNameError("joint", c.length_joint, single, path)
    for j in spec.home:
        if j not in movable:
            raise UnknownNameError("joint", j, movable, path)


def names_list(value: Any, what: str, path: str | None) -> tuple[str, ...]:
    """A list of distinct joint names (``inputs=``)."""
    if isinstance(value, str) or not all(isinstance(v, str) for v in value):
        raise InputError(f"{what} must be a list of joint names, got {value!r}")
    names = tuple(value)
    if not names:
        raise InputError(f"{what} is empty: at least one input joint is needed")
    if len(set(names)) != len(names):
        raise InputError(f"{what} has duplicates: {list(names)}")
    return names


def held_joints(
    tree: Tree, spec: Spec, locked: Mapping[str, float] | None, path: str | None
) -> dict[str, float]:
    """``locked=``: one-coordinate joints, not inputs, each with a finite value."""
    if locked is None:
        return {}
    if not isinstance(locked, Mapping):
        raise InputError(f"locked must map joint names to values, got {locked!r}")
    single = tree.single_coordinate_joints
    out = {}
    for name, value in locked.items():
        if name not in single:
            raise UnknownNameError("joint", name, single, path,
                                   None if name not in tree.coordinates
                                   else "in locked= is not a one-coordinate joint")  # fmt: skip
        if name in spec.actuated:
            raise InputError(f"joint {name!r} is both an input and locked; choose one")
        try:
            v = float(value)
        except (TypeError, ValueError):
            v = float("nan")
        if not np.isfinite(v):
            raise InputError(f"locked value of {name!r} must be a finite number, got {value!r}")
        out[name] = v
    return out


def workspace_coordinates(spec: Spec, path: str | None) -> tuple[str, ...]:
    """The spec's workspace coordinates, else the pose (with a platform) or the position."""
    if spec.workspace is not None:
        workspace = spec.workspace
    elif spec.platform is not None:
        workspace = ("x", "y", "z", "roll", "pitch", "yaw")
    else:
        workspace = ("x", "y", "z")
    rot = {"roll", "pitch", "yaw"} & set(workspace)
    if rot and rot != {"yaw"} and rot != {"roll", "pitch", "yaw"}:
        raise ModelError(
            f"workspace {list(workspace)}: give all of roll, pitch, yaw or only yaw", path
        )
    return tuple(workspace)
