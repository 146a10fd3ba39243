"""MJCF (MuJoCo XML) models: the kinematics as MuJoCo's own compiler reads them.

The file is compiled by MuJoCo (PyPI ``mujoco``, the optional extra ``scdk_sym[mjcf]``), so
every rule of the format is MuJoCo's: defaults and ``childclass``, hinge ``ref``, ``xyaxes``,
``zaxis``, ``axisangle``, ``euler`` with ``eulerseq``, ``angle``, joint ``pos``, ``<include>``,
``<frame>``. Mesh, texture, height-field and skin files are not read (kinematics does not need
them: each mesh geom becomes a small sphere before compiling).

The compiled model becomes a spanning :class:`~scdk_sym.model.urdf.Tree` and a
:class:`~scdk_sym.model.spec.Spec`:

- a body is a link of its name; its joints are joints of their names, applied in order, each
  about its own ``pos`` (an intermediate link ``<body>~<joint>`` between two); a hinge's or
  slide's ``ref`` is folded into its origin, so a joint coordinate equals MuJoCo's ``qpos``;
- a ball joint is a spherical joint (its rotation vector; its ``qpos`` is the quaternion);
- a free joint of a body tied to the rest by no equality (a robot's root) is held at home;
  one whose body an equality ties to another subtree (a floating platform) is a floating joint;
- ``<equality>``: ``connect`` (3 rows, the second anchor where MuJoCo puts it from ``qpos0``),
  ``weld`` (6 rows, ``relpose`` or from ``qpos0``), site-to-site ``connect`` and ``weld``,
  ``joint`` couplings (``polycoef``) and fixed-``tendon`` equalities (one row each); inactive
  ones are skipped and said;
- the inputs are the joints the actuators drive; an actuator on a fixed tendon drives an
  input of its own (``<actuator name>``, a joint of no body) that a coupling row ties to the
  tendon's length;
- joints with ``stiffness > 0`` that no actuator drives (springs) are held at ``springref``;
- home is the keyframe ``home`` when there is one, else ``qpos0``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from os import PathLike
from typing import Any

from ..errors import ModelError
from .mjcf_builder import Builder
from .mjcf_compile import INSTALL, compile_kinematics, require_mujoco
from .qpos import QposLayout
from .spec import Spec
from .urdf import Tree

__all__ = ["INSTALL", "MjcfSource", "compile_kinematics", "describe", "read_mjcf",
           "require_mujoco"]  # fmt: skip


@dataclass(frozen=True)
class MjcfSource:
    """What an MJCF file says beyond the tree and the closures.

    Attributes:
        path: the file.
        layout: where each MJCF joint sits in MuJoCo's ``qpos``.
        springs: spring joints held at ``springref`` -> value [rad or m].
        preloaded: the springs whose ``springref`` lies outside their range -> a label.
        passive_tendons: limited fixed tendons no actuator or equality uses -> their joints.
        skipped: labels of the inactive equalities.
        home_name: ``"keyframe 'home'"`` or ``"qpos0"``.
        notes: lines saying what loading decided.
        equalities: the closure index of each active equality, in MuJoCo's order (the
            model's closures hold the frame closures first, then the couplings).
        bodies: MuJoCo's body names by body id (``world`` first); each is a link.
        frame: the default reported link: the leaf body with the most joints above it.
        settle_home: home is projected onto the closures and moved off a singular
            configuration (see :mod:`scdk_sym.robot.home`).
    """

    path: str
    layout: QposLayout
    springs: Mapping[str, float] = field(default_factory=dict)
    preloaded: Mapping[str, str] = field(default_factory=dict)
    passive_tendons: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    skipped: tuple[str, ...] = ()
    home_name: str = "qpos0"
    notes: tuple[str, ...] = ()
    frame: str | None = None
    equalities: tuple[int, ...] = ()
    bodies: tuple[str, ...] = ()
    settle_home: bool = True

    @property
    def home_hint(self) -> str:
        """What to try when home does not assemble."""
        held = ", ".join(f"{k}={v:g}" for k, v in self.springs.items())
        if held:
            return (
                f"the springs {held} are held at their springref: lock them at values that "
                "assemble (locked={...}) or make them inputs (inputs=[...])"
            )
        return f"check the file's {self.home_name}, or lock joints (locked={{...}})"


def read_mjcf(path: str | PathLike[str]) -> tuple[Tree, Spec, MjcfSource]:
    """Read an MJCF file into a spanning tree, its closures and its qpos layout.

    Raises:
        DependencyError: ``mujoco`` is not installed.
        ModelError: MuJoCo cannot compile the file, or it uses what has no kinematic meaning
            here (a flex or distance equality, a spatial tendon, an actuator on a site).
    """
    m = compile_kinematics(path)
    return describe(m, str(path))


def describe(m: Any, path: str) -> tuple[Tree, Spec, MjcfSource]:
    """The tree, closures and qpos layout of a compiled ``MjModel`` (see :func:`read_mjcf`)."""
    b = Builder(m, path)
    b.add_bodies()
    closures, skipped = b.closures()
    inputs, rows = b.inputs()
    tree = b.spanning_tree()
    if not closures:
        raise ModelError("no active equality (connect, weld, joint, tendon): not a closed "
                         "chain", path)  # fmt: skip
    if not inputs:
        raise ModelError("no actuator: give the inputs (inputs=[joint names])", path)
    springs, outside = b.springs(inputs)
    notes = list(b.notes)
    if skipped:
        notes.append(f"inactive equalities skipped: {', '.join(skipped)}")
    spec = Spec(tuple(closures) + tuple(rows), tuple(inputs), home=dict(b.home))
    layout = QposLayout(int(m.nq), tuple(b.entries), tuple(map(float, b.qhome)))
    source = MjcfSource(
        path,
        layout,
        springs=springs,
        preloaded=outside,
        passive_tendons=b.limited_tendons(inputs),
        skipped=tuple(skipped),
        home_name=b.home_name,
        notes=tuple(notes),
        frame=_deepest_body(tree, set(b.bodies)),
        equalities=b.equalities,
        bodies=tuple(b.bodies),
    )
    return tree, spec, source


def _deepest_body(tree: Tree, bodies: set[str]) -> str:
    """The leaf body (anchor, site and input links aside) with the most movable joints
    between it and the root, then the most bodies; the first in the file among equals."""
    parents = {j.child: j for j in tree.joints}
    inner = {j.parent for j in tree.joints if j.child in bodies or "~" in j.child}
    best, rank = tree.links[-1], (-1, -1)
    for link in tree.links:
        if link not in bodies or link in inner:
            continue
        n, depth, at = 0, 0, link
        while at in parents:
            n += parents[at].movable
            depth += 1
            at = parents[at].parent
        if (n, depth) > rank:
            best, rank = link, (n, depth)
    return best
