"""A model's reduced loop-closure system written as polynomials in its unknowns.

The URDF tree is walked once more (joint origins and axes, as in
:mod:`scdk_sym.symbolic.kinematics`), with every unknown joint coordinate replaced by
algebraic unknowns ``z``:

- a revolute or continuous joint angle -> ``(c, s)``, structural row ``c^2 + s^2 - 1``; its
  rotation ``I + s K + (1 - c) K^2`` (``K`` the skew matrix of the axis);
- a prismatic coordinate stays (it enters linearly);
- a floating joint -> its translation ``(x, y, z)``, a quaternion ``q = (q0, q1, q2, q3)`` in a
  real random affine chart (structural row ``a . q - 1``, so ``q`` and ``-q`` are not two
  roots) and ``w`` with structural row ``w (q . q) - 1`` (so ``q . q != 0``: no spurious
  component); the rotation is ``w N(q)``, ``N`` the quadratic numerator of the quaternion
  rotation matrix.

The parameters ``p`` are the actuated joint values in ``model.actuated`` order: a length for a
prismatic actuator, the angle for a revolute one, which enters through ``cos p`` and
``sin p`` (holomorphic in ``p``). Joints locked by the model's square reduction are constants
at their home value. The closure rows are those of the model (3d point, 6d weld with the
same rotation rows as the model, 2d planar point, distance as ``|a - b|^2 - L^2``), and the
reduction's dropped rows stay dropped, so the system is square and its real solutions are the
model's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from ..errors import AlgebraicFormError
from ..model.rotations import axis_rotation, quaternion_numerator
from ..model.spec import Closure
from ..symbolic.kinematics import closure_residual

if TYPE_CHECKING:
    from ..robot import Model

#: Seed of the real random affine charts of the quaternions (one 4-vector per floating joint).
CHART_SEED = 7_250_118
#: Components of the unknowns of a floating joint in z.
FLOATING_PARTS = ("x", "y", "z", "q0", "q1", "q2", "q3", "w")
_ROW_PARTS = {"3d": "xyz", "2d": "xy", "distance": ("d",), "6d": ("x", "y", "z", "rx", "ry", "rz")}


@dataclass(frozen=True)
class Slot:
    """Where one unknown joint of the model lives in ``z``.

    Attributes:
        joint: the joint name.
        kind: ``"angle"`` (z = (c, s)), ``"length"`` (z = the coordinate [model length unit])
            or ``"floating"`` (z = (x, y, z, q0, q1, q2, q3, w)).
        z: indices of its unknowns in ``z``.
        y: indices of its coordinates in the model's ``y`` (floating: x, y, z, rx, ry, rz).
        chart: (4,) the real affine chart ``a`` of the quaternion (``a . q = 1``) of a floating
            joint; empty otherwise.
    """

    joint: str
    kind: str
    z: tuple[int, ...]
    y: tuple[int, ...]
    chart: tuple[float, ...] = ()


@dataclass(frozen=True)
class PolynomialRows:
    """The polynomial system ``G(z, p) = 0`` of a model, as CasADi SX.

    Attributes:
        z: (n,) SX unknowns.
        p: (k,) SX parameters (actuated joint values).
        G: (n,) SX rows: the model's kept closure rows, then the structural rows.
        offset_rows: (n,) bool, True on closure rows.
        slots: one :class:`Slot` per unknown joint, in the model's ``y`` order.
        names: (n,) names of the unknowns (``elbow.c``, ``elbow.s``, ``leg``,
            ``platform.q0``, ...).
        labels: (n,) one label per row (the model's closure row labels, ``elbow.circle``,
            ``platform.chart``, ``platform.norm``).
        param_kinds: (k,) ``"angle"`` or ``"length"`` per parameter.
    """

    z: ca.SX
    p: ca.SX
    G: ca.SX
    offset_rows: np.ndarray
    slots: tuple[Slot, ...]
    names: tuple[str, ...]
    labels: tuple[str, ...]
    param_kinds: tuple[str, ...]

    @property
    def n(self) -> int:
        return int(self.z.numel())

    @property
    def k(self) -> int:
        return int(self.p.numel())


def polynomial_motion(kind: str, axis: np.ndarray, value) -> ca.SX:
    T = ca.SX.eye(4)
    if kind == "prismatic":
        T[:3, 3] = ca.DM(axis) * value
    elif kind in ("revolute", "continuous"):
        T[:3, :3] = axis_rotation(axis, *value)
    else:  # floating: (translation (3,), rotation (3, 3))
        T[:3, :3] = value[1]
        T[:3, 3] = value[0]
    return T


def _chart_vectors(count: int) -> list[np.ndarray]:
    rng = np.random.default_rng(CHART_SEED)
    out = []
    for _ in range(count):
        a = rng.normal(size=4)
        out.append(a / np.linalg.norm(a))
    return out


def _slots(model: Model) -> tuple[tuple[Slot, ...], tuple[str, ...]]:
    slots: list[Slot] = []
    names: list[str] = []
    charts = iter(_chart_vectors(len(model.tree.floating_joints)))
    owner = {c: j for j in model.tree.joints for c in j.coordinates}
    seen: set[str] = set()
    for i, name in enumerate(model.unknowns):
        joint = owner[name] if name in owner else model.tree.joint(name)
        if joint.type == "floating":
            if joint.name in seen:
                continue
            seen.add(joint.name)
            yi = tuple(model.unknowns.index(c) for c in joint.coordinates)
            zi = tuple(range(len(names), len(names) + len(FLOATING_PARTS)))
            names.extend(f"{joint.name}.{part}" for part in FLOATING_PARTS)
            chart = tuple(float(v) for v in next(charts))
            slots.append(Slot(joint.name, "floating", zi, yi, chart))
            continue
        kind = joint.type
        if kind in ("revolute", "continuous"):
            slots.append(Slot(name, "angle", (len(names), len(names) + 1), (i,)))
            names.extend((f"{name}.c", f"{name}.s"))
        elif kind == "prismatic":
            slots.append(Slot(name, "length", (len(names),), (i,)))
            names.append(name)
        else:
            raise AlgebraicFormError(
                f"unknown joint {name!r} of type {kind!r} has no algebraic form; "
                "use revolute, continuous, prismatic or floating joints"
            )
    return tuple(slots), tuple(names)


def polynomial_joint_values(
    model: Model, slots: tuple[Slot, ...], z: ca.SX, p: ca.SX
) -> tuple[dict, list[str]]:
    values: dict[str, object] = {}
    for name, v in model.locked.items():
        kind = model.tree.joint(name).type
        values[name] = (math.cos(v), math.sin(v)) if kind != "prismatic" else v
    kinds = []
    for i, name in enumerate(model.actuated):
        kind = model.tree.joint(name).type
        if kind == "prismatic":
            values[name] = p[i]
            kinds.append("length")
        elif kind in ("revolute", "continuous"):
            values[name] = (ca.cos(p[i]), ca.sin(p[i]))
            kinds.append("angle")
        else:
            raise AlgebraicFormError(
                f"actuated joint {name!r} of type {kind!r} has no algebraic form; "
                "use revolute, continuous or prismatic actuators"
            )
    for s in slots:
        if s.kind == "angle":
            values[s.joint] = (z[s.z[0]], z[s.z[1]])
        elif s.kind == "length":
            values[s.joint] = z[s.z[0]]
        else:
            q, w = z[list(s.z[3:7])], z[s.z[7]]
            values[s.joint] = (z[list(s.z[:3])], w * quaternion_numerator(q))
    return values, kinds


def _closure_rows(closure: Closure, T_a: ca.SX, T_b: ca.SX, values: dict) -> ca.SX:
    if closure.type == "coupling":
        raise AlgebraicFormError(
            f"closure {closure.label} couples joint angles linearly, which has no polynomial "
            "form in the joints' cosines and sines; use assembly_modes(method='curves') or "
            "solve/track"
        )
    length = values.get(closure.length_joint) if closure.type == "distance" else None
    if isinstance(length, tuple):
        raise AlgebraicFormError(
            f"distance closure {closure.label}: length joint {closure.length_joint!r} "
            "is revolute; give a prismatic joint or a number as its length"
        )
    return closure_residual(closure, T_a, T_b, values, polynomial=True)


def polynomial_rows(model: Model) -> PolynomialRows:
    """Write a loaded model's reduced closure system as the polynomial system ``G(z, p)``.

    Args:
        model: a loaded :class:`~scdk_sym.robot.Model`.

    Returns:
        The rows, unknowns and parameters as SX (see :class:`PolynomialRows`).

    Raises:
        AlgebraicFormError: a joint type with no algebraic form, or a non-square result.
    """
    tree = model.tree
    slots, names = _slots(model)
    z = ca.SX.sym("z", len(names))
    p = ca.SX.sym("p", model.k)
    values, kinds = polynomial_joint_values(model, slots, z, p)
    T: dict[str, ca.SX] = {tree.root: ca.SX.eye(4)}
    for j in tree.joints:
        M = T[j.parent] @ ca.DM(j.origin)
        if j.movable:
            M = M @ polynomial_motion(j.type, j.axis, values[j.name])
        T[j.child] = M
    rows: list[ca.SX] = []
    labels: list[str] = []
    for cl in model.closures:
        rows.append(_closure_rows(cl, T[cl.frame_a], T[cl.frame_b], values))
        labels.extend(f"{cl.label}.{part}" for part in _ROW_PARTS[cl.type])
    closure = ca.vertcat(*rows)[list(model.rows)]
    labels = [labels[r] for r in model.rows]
    structural = []
    for s in slots:
        if s.kind == "angle":
            c, sn = z[s.z[0]], z[s.z[1]]
            structural.append(c * c + sn * sn - 1)
            labels.append(f"{s.joint}.circle")
        elif s.kind == "floating":
            q, w = z[list(s.z[3:7])], z[s.z[7]]
            structural.append(ca.dot(ca.DM(s.chart), q) - 1)
            structural.append(w * ca.dot(q, q) - 1)
            labels.extend((f"{s.joint}.chart", f"{s.joint}.norm"))
    G = ca.densify(ca.vertcat(closure, *structural))
    n_closure = int(closure.numel())
    if G.numel() != z.numel():
        raise AlgebraicFormError(
            f"model {model.name!r}: the algebraic form has {G.numel()} rows for {z.numel()} "
            f"unknowns ({n_closure} closure rows); check the model's square reduction"
        )
    offset = np.zeros(len(names), dtype=bool)
    offset[:n_closure] = True
    offset.setflags(write=False)
    return PolynomialRows(z, p, G, offset, slots, names, tuple(labels), tuple(kinds))
