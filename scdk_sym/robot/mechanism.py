"""The mechanism a model is reduced from: a description with every name checked and resolved
(closure frames to links, the reported frame, the inputs, the held joints, the workspace), its
size and tolerance, and what its closure rows are called."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np

from ..errors import ModelError, UnknownNameError
from ..model.spec import Closure, Spec
from ..model.urdf import Tree
from ..symbolic.kinematics import link_placements
from .validation import check_names, held_joints, workspace_coordinates

#: Relative tolerance of the assembled-configuration checks (scaled by the model size).
RESIDUAL_TOL = 1e-9
#: Redundant closure rows may disagree with the others by this much of the model's size (a
#: file's rounding) and be left out of the verification; more is an over-constraint.
REDUNDANT_TOL = 1e-5

#: The least-squares projection of unknowns onto the closures, ``(f_all, y, theta) -> y``
#: (see :func:`scdk_sym.robot.home_assembly.project`).
Projection = Callable[[ca.Function, np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Mechanism:
    """What the square reduction works on: a checked description, names resolved.

    Attributes:
        tree: the spanning tree (joint edits applied; ball joints whose rod spin is locked
            turned into universal joints).
        spec: the closure side file (its ``name_mot`` replaced by ``inputs=`` when given).
        closures: the spec's closures, frames resolved to links.
        actuated: actuated joint names (theta order).
        held: joints held at given values -> value [rad or length unit].
        frame: the link whose pose is x.
        workspace: names of the workspace coordinates x.
        path: where the description was read from (for messages), or ``None``.
        source: what an MJCF file's loading decided, or ``None``.
        length_scale: characteristic size of the model [model length unit].
        tolerance: absolute tolerance of the closure checks [model length unit].
        project: the least-squares projection onto the closures the reduction uses.
    """

    tree: Tree
    spec: Spec
    closures: tuple[Closure, ...]
    actuated: tuple[str, ...]
    held: dict[str, float]
    frame: str
    workspace: tuple[str, ...]
    path: str | None
    source: Any
    length_scale: float
    tolerance: float
    project: Projection

    @property
    def candidates(self) -> tuple[str, ...]:
        """The joint coordinates the closures may determine (see :func:`free_coordinates`)."""
        return free_coordinates(self.tree, self.actuated, self.held)

    def row_labels(self) -> list[str]:
        """A label per closure row of the full system (see :func:`row_labels`)."""
        return row_labels(self.spec.closures)

    def violation(self, check: np.ndarray) -> str:
        """The closure that the verification rows ``check`` say is violated most, and by how
        much."""
        sizes = [c.rows + (9 if c.type == "6d" else 0) for c in self.spec.closures]
        i = int(np.argmax(check))
        start = 0
        for c, n in zip(self.spec.closures, sizes, strict=True):
            if i < start + n:
                return f"closure {c.label} violated by {check[i]:.3g}"
            start += n
        return f"residual {check.max():.3g}"


def free_coordinates(
    tree: Tree, actuated: Sequence[str], held: Mapping[str, float]
) -> tuple[str, ...]:
    """The joint coordinates of ``tree`` (URDF order) neither actuated nor held."""
    return tuple(j for j in tree.coordinates if j not in actuated and j not in held)


def row_labels(closures: Sequence[Closure]) -> list[str]:
    """A label per closure row of the full (unreduced) system, ``"<closure>.<row>"``
    (``x``, ``y``, ``z``, ``rx``, ``ry``, ``rz`` or ``d``)."""
    labels: list[str] = []
    for c in closures:
        comps = {
            "3d": "xyz",
            "2d": "xy",
            "distance": ["d"],
            "6d": ["x", "y", "z", "rx", "ry", "rz"],
            "coupling": ["q"],
        }
        labels.extend(f"{c.label}.{k}" for k in comps[c.type])
    return labels


def distal_link(tree: Tree, closures, actuated: Sequence[str] = ()) -> str:
    """The default reported link of a model without ``platform``: the leaf link with the most
    movable joints between it and the root (a leg's foot), closure frames excluded, among the
    leaves that a joint the closures determine moves (not an arm or a gripper whose joints
    are all actuated, on a whole humanoid) when there are such; the first in URDF order among
    equals (the first leg's foot on a biped)."""
    parents = {j.child: j for j in tree.joints}
    ends = {f for c in closures for f in (c.frame_a, c.frame_b)}
    inner = {j.parent for j in tree.joints}
    best, rank = tree.links[-1], (False, -1)
    for link in tree.links:
        if link in inner or link in ends:
            continue
        n, passive, at = 0, False, link
        while at in parents:
            joint = parents[at]
            n += joint.movable
            passive = passive or (joint.movable and joint.name not in actuated)
            at = joint.parent
        if (passive, n) > rank:
            best, rank = link, (passive, n)
    return best


def reported_frame(
    tree: Tree, spec: Spec, joint_frames: dict[str, str], frame: str | None, path: str | None
) -> str:
    """The link whose pose is reported: ``frame``, else the spec's platform, else a link
    named ``effector``, else the distal link of the closures (a joint stands for its child)."""
    chosen = frame or spec.platform
    if chosen is None:
        chosen = (
            "effector"
            if "effector" in tree.links
            else distal_link(tree, spec.closures, spec.actuated)
        )
    if chosen not in tree.links and chosen not in joint_frames:
        raise UnknownNameError("frame", chosen, (*tree.links, *joint_frames), path)
    return joint_frames.get(chosen, chosen)


def model_size(tree: Tree) -> float:
    """The largest distance of a link origin from the root's with every joint at zero
    [model length unit]."""
    # a numeric forward pass with every joint at zero
    T = link_placements(tree, dict.fromkeys(tree.coordinates, 0.0))
    pos = np.array([np.array(ca.DM(t[:3, 3])).ravel() for t in T.values()])
    return float(np.max(np.linalg.norm(pos - pos[0], axis=1)))


def resolve(
    tree: Tree,
    spec: Spec,
    path: str | None,
    frame: str | None,
    locked: Mapping[str, float] | None,
    source: Any,
    project: Projection,
) -> Mechanism:
    """The mechanism of a description (joint edits and ``inputs=`` already applied to
    ``tree`` and ``spec``): names checked, ``locked=`` held, the frame chosen, closure frames
    resolved to links (a frame is a link, or a joint: as in Pinocchio, the joint frame is its
    child link's).

    Raises:
        UnknownNameError: a name that the tree does not have.
        InputError: a malformed ``locked=``.
        ModelError: a malformed workspace, no unknown joint, or no closure.
    """
    joint_frames = {j.name: j.child for j in tree.joints if j.name not in tree.links}
    check_names(tree, spec, joint_frames, path)
    held = held_joints(tree, spec, locked, path)
    chosen = reported_frame(tree, spec, joint_frames, frame, path)
    workspace = workspace_coordinates(spec, path)
    closures = tuple(
        replace(
            c,
            frame_a=joint_frames.get(c.frame_a, c.frame_a),
            frame_b=joint_frames.get(c.frame_b, c.frame_b),
        )
        for c in spec.closures
    )
    actuated = tuple(spec.actuated)
    if not free_coordinates(tree, actuated, held):
        raise ModelError("no unknown joints: every movable joint is actuated", path)
    if not spec.closures:
        raise ModelError("no loop closures: 'closed_loop' is empty", path)
    size = model_size(tree)
    return Mechanism(tree, spec, closures, actuated, held, chosen, workspace, path, source,
                     size, RESIDUAL_TOL * max(1.0, size), project)  # fmt: skip
