"""Gepetto's joint edits (``joint_name`` / ``joint_type``) applied to a URDF spanning tree.

Gepetto's loader (example-parallel-robots, ``completeRobotLoader``) replaces named URDF joints
before the loops are closed:

- ``SPHERICAL``: a ball joint at the joint's origin (three rotation unknowns in a local chart,
  see :mod:`scdk_sym.model.chart`: no Euler-angle singularity);
- ``FIXED``: the joint held at zero (its origin kept);
- ``UJOINT_AB`` (A, B in X, Y, Z): a universal joint, two revolutes at the joint's origin, about
  the joint frame's A axis, then about the B axis of the frame it turned. They are named
  ``<joint>_A`` and ``<joint>_B`` as in Gepetto's model; the first carries a new massless link
  of the same name.

The joint's own URDF axis and type are ignored by every edit, as in Gepetto's loader. An edit
naming a joint the URDF does not have is applied to the one URDF joint whose name is that
close (difflib ratio >= 0.9: a slip such as ``sĥerical`` for ``spherical``, which Gepetto's
loader would leave as the URDF's revolute, over-constraining its loop), else skipped, with a
:class:`~scdk_sym.errors.ModelWarning` either way.
"""

from __future__ import annotations

import difflib
import warnings
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..errors import ModelError, ModelWarning
from .urdf import Joint, Tree

#: Unit axes of the joint frame, by letter.
AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def apply_joint_edits(
    tree: Tree, edits: Sequence[tuple[str, str]], path: str | None = None
) -> Tree:
    """The tree with Gepetto's joint edits applied (the tree itself when there are none).

    Args:
        tree: the URDF spanning tree.
        edits: (joint name, edit) pairs, edits from :data:`scdk_sym.model.spec.JOINT_EDITS`.
        path: file named in error messages.

    Raises:
        ModelError: a universal joint's new names collide with existing ones.
    """
    if not edits:
        return tree
    wanted = dict(edits)
    names = {j.name for j in tree.joints}
    for name in list(wanted):
        if name not in names:
            wanted = _near_miss(name, wanted, names, path)
    joints: list[Joint] = []
    links = list(tree.links)
    for j in tree.joints:
        edit = wanted.get(j.name)
        if edit is None:
            joints.append(j)
        elif edit == "SPHERICAL":
            joints.append(_edited(j, "spherical"))
        elif edit == "FIXED":
            joints.append(_edited(j, "fixed"))
        else:
            first, second = _universal(j, edit[-2], edit[-1])
            taken = set(links) | names
            for new in (first.name, second.name):
                if new in taken:
                    raise ModelError(
                        f"joint {j.name!r} ({edit}) makes joint and link {new!r}, a name the "
                        "URDF already uses; rename it in the URDF",
                        path,
                    )
            links.insert(links.index(j.child), first.child)
            joints.extend((first, second))
    return Tree(tree.name, tree.root, tuple(links), tuple(joints))


#: Similarity (difflib ratio) above which an edit naming a missing joint is applied to the
#: one URDF joint that close to it (a typing slip in the URDF or the YAML).
NEAR_MISS = 0.9


def _near_miss(
    name: str, wanted: dict[str, str], names: set[str], path: str | None
) -> dict[str, str]:
    """Edits with ``name`` (missing from the URDF) moved to its near miss, or dropped."""
    edit = wanted.pop(name)
    free = sorted(names - set(wanted))
    close = difflib.get_close_matches(name, free, n=2, cutoff=NEAR_MISS)
    where = f"{path}: " if path else ""
    if len(close) == 1:
        wanted[close[0]] = edit
        what = f"applied to {close[0]!r}, the one URDF joint that close to it"
    else:
        hint = difflib.get_close_matches(name, free, n=1)
        what = "skipped" + (f" (closest joint: {hint[0]!r})" if hint else "")
    warnings.warn(
        f"{where}'joint_name' lists {name!r}, which the URDF does not have; its edit {edit} "
        f"is {what}",
        ModelWarning,
        stacklevel=4,
    )
    return wanted


def _edited(joint: Joint, kind: str) -> Joint:
    return replace(joint, type=kind, lower=-np.inf, upper=np.inf)


def _universal(joint: Joint, a: str, b: str) -> tuple[Joint, Joint]:
    """The two revolutes of a universal joint replacing ``joint`` (axes A then B)."""
    name_a, name_b = f"{joint.name}_{a}", f"{joint.name}_{b}"
    first = Joint(
        name_a, "revolute", joint.parent, name_a, np.array(joint.origin), np.array(AXES[a])
    )
    second = Joint(name_b, "revolute", name_a, joint.child, np.eye(4), np.array(AXES[b]))
    return first, second


def ball_to_universal(tree: Tree, name: str, rotation: np.ndarray, spin: np.ndarray) -> Tree:
    """The tree with spherical joint ``name`` turned into a universal joint whose missing
    third rotation is the spin about ``spin``: the spin of a rod between two ball joints,
    which moves nothing but the rod, is locked this way.

    The ball's rotation ``rotation`` (at an assembled configuration) is folded into the
    joint's origin, so the two revolutes ``<name>_U1`` (axis ``a`` normal to the spin) and
    ``<name>_U2`` (axis ``spin x a``) are zero there.

    Args:
        tree: the tree.
        name: a spherical joint of ``tree``.
        rotation: (3, 3) the ball's rotation at the configuration to keep.
        spin: (3,) spin axis in the ball's child frame.
    """
    u = np.asarray(spin, dtype=float) / np.linalg.norm(spin)
    a = np.cross(u, np.eye(3)[int(np.argmin(np.abs(u)))])
    a /= np.linalg.norm(a)
    b = np.cross(u, a)
    joints: list[Joint] = []
    links = list(tree.links)
    for j in tree.joints:
        if j.name != name:
            joints.append(j)
            continue
        origin = np.array(j.origin)
        origin[:3, :3] = origin[:3, :3] @ rotation
        first = Joint(f"{name}_U1", "revolute", j.parent, f"{name}_U1", origin, a)
        second = Joint(f"{name}_U2", "revolute", first.child, j.child, np.eye(4), b)
        links.insert(links.index(j.child), first.child)
        joints.extend((first, second))
    return Tree(tree.name, tree.root, tuple(links), tuple(joints))
