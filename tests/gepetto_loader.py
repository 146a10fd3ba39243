"""Gepetto's closed-chain loader and a closure solver, on Pinocchio alone.

An independent reference for the package: nothing here imports scdk_sym.

``complete_robot_loader`` and ``simplify_model`` are ported from Gepetto's
example-parallel-robots, ``example_parallel_robots/loader_tools.py`` (functions
``completeRobotLoader`` and ``simplifyModel``, Virgile Batto & Ludovic De Matteis), BSD 3-Clause
licence, Copyright (C) 2024 LAAS-CNRS, INRIA; the licence notice is reproduced below. The
algorithm is kept as published: the YAML ``joint_name`` / ``joint_type`` edits (``SPHERICAL``,
``FIXED``, ``UJOINT_XY`` / ``_YZ`` / ``_ZX`` / ``_ZY``), the reduction of the ``FIXED`` joints at
the neutral configuration, the closures as ``pin.RigidConstraintModel`` in the ``LOCAL`` frame
(``3D`` / ``3d``: ``CONTACT_3D``, anything else: ``CONTACT_6D``), then ``simplifyModel``'s merge
of three consecutive revolute joints (first two massless, axes pairwise non-collinear, origins
within 0.1 mm at neutral) into one spherical joint, the first two frozen at neutral by
``toolbox_parallel_robots.freezeJoints``. Differences, all needed to run without meshes or
CasADi: the model is built by ``pin.buildModelFromUrdf`` and the visual / collision models are
empty ``pin.GeometryModel()``; the loader's prints are silenced; when the installed
``toolbox_parallel_robots`` package cannot be imported (its ``__init__`` needs
``pinocchio.casadi``), its two pure-Pinocchio modules ``freeze_joints.py`` and
``actuation_model.py`` are loaded from the installed files and run unchanged; the constraint
names (``name1 + "C" + name2``), which ``freezeJoints`` drops, are copied back.

The solver part is written here: closure residuals through the constraint models' placements
(Gepetto's toolbox residuals: ``6d`` = ``log6(oMc1^-1 oMc2)``, ``3d`` = ``p1 - p2``), a
Gauss-Newton / Levenberg-Marquardt projection with minimum-norm steps, a continuation along
the straight motor line, the assembly from the neutral configuration and the link placements.
Units: metres and radians.

Licence of the ported code (Gepetto/example-parallel-robots, file LICENSE)::

    BSD 3-Clause License

    Copyright (C) 2024 LAAS-CNRS, INRIA
    All rights reserved.

    Redistribution and use in source and binary forms, with or without
    modification, are permitted provided that the following conditions are met:

    * Redistributions of source code must retain the above copyright notice, this
      list of conditions and the following disclaimer.

    * Redistributions in binary form must reproduce the above copyright notice,
      this list of conditions and the following disclaimer in the documentation
      and/or other materials provided with the distribution.

    * Neither the name of the copyright holder nor the names of its
      contributors may be used to endorse or promote products derived from
      this software without specific prior written permission.

    THIS SOFTWARE IS PROVIDED BY THE COPYRIGHT HOLDERS AND CONTRIBUTORS "AS IS"
    AND ANY EXPRESS OR IMPLIED WARRANTIES, INCLUDING, BUT NOT LIMITED TO, THE
    IMPLIED WARRANTIES OF MERCHANTABILITY AND FITNESS FOR A PARTICULAR PURPOSE ARE
    DISCLAIMED. IN NO EVENT SHALL THE COPYRIGHT HOLDER OR CONTRIBUTORS BE LIABLE
    FOR ANY DIRECT, INDIRECT, INCIDENTAL, SPECIAL, EXEMPLARY, OR CONSEQUENTIAL
    DAMAGES (INCLUDING, BUT NOT LIMITED TO, PROCUREMENT OF SUBSTITUTE GOODS OR
    SERVICES; LOSS OF USE, DATA, OR PROFITS; OR BUSINESS INTERRUPTION) HOWEVER
    CAUSED AND ON ANY THEORY OF LIABILITY, WHETHER IN CONTRACT, STRICT LIABILITY,
    OR TORT (INCLUDING NEGLIGENCE OR OTHERWISE) ARISING IN ANY WAY OUT OF THE USE
    OF THIS SOFTWARE, EVEN IF ADVISED OF THE POSSIBILITY OF SUCH DAMAGE.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import io
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pinocchio as pin
import yaml

#: Gepetto's default root joint per robot directory (``robot_options.py``: ``free_flyer``);
#: directories it does not list (``digit_like_2legs_old``) are world-fixed.
FREE_FLYER: dict[str, bool] = {
    "5bar_linkage": False,
    "5bar_linkage_iso3d": False,
    "5bar_linkage_iso6d": False,
    "cassie_like": False,
    "digit_like": False,
    "digit_like_2legs": True,
    "digit_like_2legs_6D": True,
    "disney_like": True,
    "disney_robot": True,
    "kangaroo_like": False,
    "kangaroo_like_2legs": False,
    "robot_delta": False,
    "talos_like": False,
    "wl16_like": False,
    "battobot_6d": True,
}

#: Relative cut-off of the singular values in the minimum-norm steps.
RCOND = 1e-10

# ---------------------------------------------------------------------------- toolbox


_TOOLBOX = "toolbox_parallel_robots"


@cache
def _toolbox() -> tuple[ModuleType, ModuleType]:
    """(freeze_joints, actuation_model) modules of the installed ``toolbox_parallel_robots``.

    The package itself when it imports; otherwise (its ``__init__`` imports
    ``pinocchio.casadi``, absent from pip's ``pin``) the two modules loaded from the installed
    files, which need only Pinocchio and numpy.
    """
    if importlib.util.find_spec("pinocchio.casadi") is not None:  # else a failed import
        try:  # would leave half the package in sys.modules
            importlib.import_module(_TOOLBOX)
        except ImportError:
            pass
        else:
            return (
                importlib.import_module(f"{_TOOLBOX}.freeze_joints"),
                importlib.import_module(f"{_TOOLBOX}.actuation_model"),
            )
    spec = importlib.util.find_spec(_TOOLBOX)
    if spec is None or not spec.submodule_search_locations:
        raise ImportError(f"{_TOOLBOX} is not installed (pip install toolbox-parallel-robots)")
    folder = Path(next(iter(spec.submodule_search_locations)))
    modules = []
    for stem in ("freeze_joints", "actuation_model"):
        sub = importlib.util.spec_from_file_location(f"{_TOOLBOX}.{stem}", folder / f"{stem}.py")
        assert sub is not None and sub.loader is not None
        module = importlib.util.module_from_spec(sub)
        sub.loader.exec_module(module)
        modules.append(module)
    return modules[0], modules[1]


@contextlib.contextmanager
def _toolbox_importable() -> Iterator[None]:
    """``from toolbox_parallel_robots.actuation_model import ActuationModel`` works inside.

    ``freezeJoints`` runs that import at call time; where the package cannot be imported, the
    loaded module stands in for it during the call and ``sys.modules`` is restored after.
    """
    _, actuation = _toolbox()
    name = f"{_TOOLBOX}.actuation_model"
    if sys.modules.get(name) is actuation:
        yield
        return
    saved = sys.modules.get(name)
    sys.modules[name] = actuation
    try:
        yield
    finally:
        if saved is None:
            sys.modules.pop(name, None)
        else:
            sys.modules[name] = saved


def _freeze_joints(*args: Any) -> tuple[Any, ...]:
    """``toolbox_parallel_robots.freezeJoints(*args)``, its prints silenced."""
    freeze, _ = _toolbox()
    with _toolbox_importable(), contextlib.redirect_stdout(io.StringIO()):
        return tuple(freeze.freezeJoints(*args))


def _actuation_model(model: pin.Model, names: Sequence[str]) -> Any:
    """``toolbox_parallel_robots.ActuationModel(model, names)``."""
    _, actuation = _toolbox()
    return actuation.ActuationModel(model, list(names))


# ---------------------------------------------------------------------------- loader (port)


def complete_robot_loader(
    path: str | Path,
    name_urdf: str = "robot.urdf",
    name_yaml: str = "robot.yaml",
    freeflyer: bool = False,
) -> tuple[pin.Model, list[pin.RigidConstraintModel], Any, pin.GeometryModel, pin.GeometryModel]:
    """Port of Gepetto's ``completeRobotLoader(path, name_urdf, name_yaml, freeflyer)``.

    Returns:
        (model, constraint models, ``ActuationModel``, visual model, collision model), the
        geometry models empty (no meshes are read).
    """
    path = str(path)
    urdf = path + "/" + name_urdf
    if freeflyer:
        model = pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer())
    else:
        model = pin.buildModelFromUrdf(urdf)
    visual_in, collision_in = pin.GeometryModel(), pin.GeometryModel()

    with open(path + "/" + name_yaml) as yaml_file:
        yaml_content = yaml.safe_load(yaml_file)

    # Update model
    if "joint_name" in yaml_content:
        update_joint = yaml_content["joint_name"]
        joints_types = yaml_content["joint_type"]
    else:
        update_joint = []
        joints_types = []

    fixed_joints_names = []
    new_model = pin.Model()

    ujoints_type = {"X": pin.JointModelRX, "Y": pin.JointModelRY, "Z": pin.JointModelRZ}

    for old_place, old_iner, old_name, old_parent, old_joint in list(
        zip(
            model.jointPlacements,
            model.inertias,
            model.names,
            model.parents,
            model.joints,
            strict=True,
        )
    )[1:]:
        parent = new_model.getJointId(model.names[old_parent])
        place = old_place
        name = old_name
        if old_name in update_joint:
            joint_type = joints_types[update_joint.index(old_name)]
            if joint_type == "SPHERICAL":
                joint_model = pin.JointModelSpherical()
            elif joint_type == "FIXED":
                joint_model = old_joint
                fixed_joints_names.append(old_joint.id)
            if "UJOINT" in joint_type:
                type1 = ujoints_type[joint_type[-2]]
                type2 = ujoints_type[joint_type[-1]]
                parent = new_model.addJoint(parent, type1(), place, old_name + f"_{joint_type[-2]}")
                joint_model = type2()
                place = pin.SE3.Identity()
                name = old_name + f"_{joint_type[-1]}"
        else:
            joint_model = old_joint
        jid = new_model.addJoint(parent, joint_model, place, name)
        new_model.appendBodyToJoint(jid, old_iner, pin.SE3.Identity())

    # Frames - Add ujoints frames
    for f in model.frames:
        old_name, old_parent, old_place, old_type = f.name, f.parentJoint, f.placement, f.type
        if old_name in update_joint:  # the joint frame of an updated joint
            assert old_type == pin.JOINT, "Frame type should be JOINT"
            assert model.names[old_parent] == old_name, "Frame parent should be the joint"
            assert old_place == pin.SE3.Identity(), "Frame placement should be Identity"
            joint_type = joints_types[update_joint.index(old_name)]
            if "UJOINT" in joint_type:
                for axis in (joint_type[-2], joint_type[-1]):
                    ujoint_frame = pin.Frame(
                        old_name + f"_{axis}",
                        new_model.getJointId(old_name + f"_{axis}"),
                        pin.SE3.Identity(),
                        pin.FrameType.JOINT,
                    )
                    new_model.addFrame(ujoint_frame, False)
            else:
                parent = new_model.getJointId(model.names[old_parent])
                joint_frame = pin.Frame(old_name, parent, old_place, old_type)
                new_model.addFrame(joint_frame, False)
        elif model.names[old_parent] in update_joint:  # a frame on a modified joint
            joint_type = joints_types[update_joint.index(model.names[old_parent])]
            if "UJOINT" in joint_type:  # carried by the second joint of the U-joint
                parent = new_model.getJointId(model.names[old_parent] + f"_{joint_type[-1]}")
            else:
                parent = new_model.getJointId(model.names[old_parent])
            new_model.addFrame(pin.Frame(old_name, parent, old_place, old_type), False)
        else:
            parent = new_model.getJointId(model.names[old_parent])
            new_model.addFrame(pin.Frame(old_name, parent, old_place, old_type), False)

    # Geometry models (empty here; the re-parenting is kept as published)
    geometry_models = []
    for old_geom_model in (visual_in, collision_in):
        geom_model = old_geom_model.copy()
        for go in geom_model.geometryObjects:
            parent_name = model.names[go.parentJoint]
            if parent_name in update_joint and "UJOINT" in (
                jt := joints_types[update_joint.index(parent_name)]
            ):
                second = {
                    "UJOINT_XY": "_Y",
                    "UJOINT_YZ": "_Z",
                    "UJOINT_ZX": "_X",
                    "UJOINT_ZY": "_Y",
                }
                if jt in second:  # other U-joints keep their old parent id, as published
                    go.parentJoint = new_model.getJointId(parent_name + second[jt])
            else:
                go.parentJoint = new_model.getJointId(parent_name)
            go.parentFrame = new_model.getFrameId(model.frames[go.parentFrame].name)
        geometry_models.append(geom_model)
    visual_model, collision_model = geometry_models[0], geometry_models[1]

    new_model.frames.__delitem__(0)
    new_model, [visual_model, collision_model] = pin.buildReducedModel(
        new_model, [visual_model, collision_model], fixed_joints_names, pin.neutral(new_model)
    )

    model = new_model
    constraints_models = []
    # check if type is associated, else 6D is used
    try:
        name_frame_constraint = yaml_content["closed_loop"]
        constraint_type = yaml_content["type"]
        # as published, a short ``type`` list drops the closures past its end
        for (name1, name2), ctype in zip(name_frame_constraint, constraint_type, strict=False):
            id1 = model.getFrameId(name1)
            id2 = model.getFrameId(name2)
            se3joint1 = model.frames[id1].placement
            se3joint2 = model.frames[id2].placement
            parentjoint1 = model.frames[id1].parentJoint
            parentjoint2 = model.frames[id2].parentJoint
            if ctype == "3D" or ctype == "3d":
                contact = pin.ContactType.CONTACT_3D
            else:
                contact = pin.ContactType.CONTACT_6D
            constraint = pin.RigidConstraintModel(
                contact,
                model,
                parentjoint1,
                se3joint1,
                parentjoint2,
                se3joint2,
                pin.ReferenceFrame.LOCAL,
            )
            constraint.name = name1 + "C" + name2
            constraints_models.append(constraint)
    except RuntimeError:
        pass  # Gepetto prints "no constraint"

    actuation_model = _actuation_model(model, yaml_content["name_mot"])
    return simplify_model(model, constraints_models, actuation_model, visual_model, collision_model)


def simplify_model(
    model: pin.Model,
    constraint_models: list[pin.RigidConstraintModel],
    actuation_model: Any,
    visual_model: pin.GeometryModel,
    collision_model: pin.GeometryModel,
) -> tuple[pin.Model, list[pin.RigidConstraintModel], Any, pin.GeometryModel, pin.GeometryModel]:
    """Port of Gepetto's ``simplifyModel``: revolute triples merged into spherical joints.

    Three consecutive joints (by id) of types RX / RY / RZ whose first two are massless
    (< 1e-5 kg), whose axes are pairwise non-collinear and whose origins coincide (1e-4 m) at
    the neutral configuration become one spherical joint at the third; the first two are
    frozen at neutral (``freezeJoints``), which also re-attaches the constraints and rebuilds
    the actuation model.
    """
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    new_model = pin.Model()
    fixed_joints_ids: list[int] = []
    spherical = False
    last_joint = -1
    for jid, place, iner, name, parent_old, jtype in list(
        zip(
            range(len(model.joints)),
            model.jointPlacements,
            model.inertias,
            model.names,
            model.parents,
            model.joints,
            strict=True,
        )
    ):
        vectors = []
        joints_mass = []
        points = []
        parent = new_model.getJointId(model.names[parent_old])
        for jid2, jtype2 in enumerate(model.joints[jid : jid + 3]):
            joint_id = jid + jid2
            oMi = data.oMi[joint_id]
            if "RX" in jtype2.shortname():
                vec = oMi.rotation[:, 0]
            elif "RY" in jtype2.shortname():
                vec = oMi.rotation[:, 1]
            elif "RZ" in jtype2.shortname():
                vec = oMi.rotation[:, 2]
            else:
                break
            joints_mass.append(model.inertias[joint_id].mass)
            vectors.append(vec)
            points.append(oMi.translation)
        if (
            len(vectors) == 3
            and joints_mass[0] < 1e-5
            and joints_mass[1] < 1e-5
            and np.linalg.norm(np.cross(vectors[0], vectors[1])) > 1e-6
            and np.linalg.norm(np.cross(vectors[0], vectors[2])) > 1e-6
            and np.linalg.norm(np.cross(vectors[2], vectors[1])) > 1e-6
            and np.linalg.norm(points[0] - points[1]) < 1e-4
            and np.linalg.norm(points[2] - points[1]) < 1e-4
        ):
            spherical = True
            last_joint = jid
            fixed_joints_ids += [jid + 0, jid + 1]
        if jid != 0:
            if spherical and jid == last_joint + 2:
                jtype = pin.JointModelSpherical()
                spherical = False
            test = new_model.addJoint(parent, jtype, place, name)
            new_model.appendBodyToJoint(test, iner, pin.SE3.Identity())
    for f in model.frames:
        parent = new_model.getJointId(model.names[f.parentJoint])
        frame = pin.Frame(f.name, parent, f.placement, f.type)
        new_model.addFrame(frame, False)  # We assume that there is no inertial frame

    q0 = pin.neutral(new_model)
    reduced = _freeze_joints(
        new_model,
        constraint_models,
        actuation_model,
        visual_model,
        collision_model,
        fixed_joints_ids,
        q0,
    )
    # freezeJoints rebuilds the constraint models unnamed, dropping (in place) those whose two
    # joints became one: the names of the others are copied back, in order
    kept = [cm.name for cm in constraint_models if cm.joint1_id != cm.joint2_id]
    reduced_constraints = list(reduced[1])
    if len(kept) == len(reduced_constraints):
        for cm, name in zip(reduced_constraints, kept, strict=True):
            cm.name = name
    return reduced[0], reduced_constraints, reduced[2], reduced[3], reduced[4]


# ---------------------------------------------------------------------------- model


@dataclass(frozen=True)
class GepettoModel:
    """A robot as Gepetto's loader builds it.

    Attributes:
        name: the fixture directory name.
        model: the Pinocchio model after ``completeRobotLoader`` (and ``simplifyModel``).
        constraint_models: the closures, ``CONTACT_3D`` or ``CONTACT_6D``, ``LOCAL``.
        actuated_joint_names: the YAML ``name_mot``, in its order.
        mot_ids_q: ``ActuationModel.mot_ids_q``: q indices of the motors, sorted.
        free_ids_q: ``ActuationModel.free_ids_q``: every other q index, sorted.
        motor_q_indices: q index of each motor of ``actuated_joint_names``, in that order.
        free_flyer: whether the root joint is a free-flyer (q[:7] = position, quaternion).
    """

    name: str
    model: pin.Model
    constraint_models: list[pin.RigidConstraintModel]
    actuated_joint_names: tuple[str, ...]
    mot_ids_q: np.ndarray
    free_ids_q: tuple[int, ...]
    motor_q_indices: tuple[int, ...]
    free_flyer: bool


def load(directory: str | Path, free_flyer: bool = False) -> GepettoModel:
    """Gepetto's ``completeRobotLoader(directory, freeflyer=free_flyer)`` as a GepettoModel.

    Raises:
        ValueError: a motor of ``name_mot`` is missing from the model or is not 1-dof.
    """
    directory = Path(directory)
    with contextlib.redirect_stdout(io.StringIO()):
        model, cmodels, actuation, _, _ = complete_robot_loader(directory, freeflyer=free_flyer)
    names = tuple(yaml.safe_load((directory / "robot.yaml").read_text())["name_mot"])
    motor_q = []
    for n in names:
        if not model.existJointName(n):
            raise ValueError(f"{directory.name}: motor {n!r} is not a joint of the model")
        joint = model.joints[model.getJointId(n)]
        if joint.nq != 1 or joint.nv != 1:
            raise ValueError(f"{directory.name}: motor {n!r} has nq={joint.nq}, nv={joint.nv}")
        motor_q.append(joint.idx_q)
    return GepettoModel(
        name=directory.name,
        model=model,
        constraint_models=list(cmodels),
        actuated_joint_names=names,
        mot_ids_q=np.asarray(actuation.mot_ids_q, dtype=int),
        free_ids_q=tuple(int(i) for i in actuation.free_ids_q),
        motor_q_indices=tuple(motor_q),
        free_flyer=free_flyer,
    )


# ---------------------------------------------------------------------------- closures


def _anchors(gm: GepettoModel, data: pin.Data, cm: pin.RigidConstraintModel) -> tuple[Any, Any]:
    """(oMc1, oMc2): the two constrained placements, from ``data.oMi``."""
    return (
        data.oMi[cm.joint1_id] * cm.joint1_placement,
        data.oMi[cm.joint2_id] * cm.joint2_placement,
    )


def closure_residuals(gm: GepettoModel, q: np.ndarray) -> np.ndarray:
    """(n_constraints,) residual norm of each closure at ``q`` [m or rad].

    6D: ``|log6(oMc1^-1 oMc2)|``; 3D: ``|p1 - p2|``, with ``oMc = oMi[joint_id] *
    joint_placement`` of the constraint model.
    """
    data = gm.model.createData()
    pin.forwardKinematics(gm.model, data, np.asarray(q, dtype=float))
    out = []
    for cm in gm.constraint_models:
        oMc1, oMc2 = _anchors(gm, data, cm)
        if cm.type == pin.ContactType.CONTACT_3D:
            out.append(np.linalg.norm(oMc1.translation - oMc2.translation))
        else:
            out.append(np.linalg.norm(pin.log6(oMc1.inverse() * oMc2).vector))
    return np.array(out, dtype=float)


def _local_jacobian(model: pin.Model, data: pin.Data, joint: int, jMc: Any) -> np.ndarray:
    """(6, nv) Jacobian of the placement ``oMi[joint] * jMc`` in its own frame."""
    if joint == 0:
        return np.zeros((6, model.nv))
    Jj = pin.getJointJacobian(model, data, joint, pin.ReferenceFrame.LOCAL)
    return jMc.inverse().action @ Jj


def stacked_residual(
    gm: GepettoModel, q: np.ndarray, data: pin.Data | None = None, jacobian: bool = True
) -> tuple[np.ndarray, np.ndarray | None]:
    """(r, dr/dv): the closures stacked as Gepetto's toolbox writes them, and their Jacobian.

    6D rows: ``log6(c1Mc2)`` (6, in the frame of c1) with Jacobian ``Jlog6(c1Mc2) (J2 -
    Ad(c2Mc1) J1)``; 3D rows: ``p1 - p2`` (3, world axes) with ``R1 J1[:3] - R2 J2[:3]``,
    ``Ji`` the local Jacobians of the placements and v the tangent (nv) of ``pin.integrate``.
    """
    model = gm.model
    data = model.createData() if data is None else data
    q = np.asarray(q, dtype=float)
    if jacobian:
        pin.computeJointJacobians(model, data, q)
    else:
        pin.forwardKinematics(model, data, q)
    rows, jacs = [], []
    for cm in gm.constraint_models:
        oMc1, oMc2 = _anchors(gm, data, cm)
        if jacobian:
            J1 = _local_jacobian(model, data, cm.joint1_id, cm.joint1_placement)
            J2 = _local_jacobian(model, data, cm.joint2_id, cm.joint2_placement)
        if cm.type == pin.ContactType.CONTACT_3D:
            rows.append(oMc1.translation - oMc2.translation)
            if jacobian:
                jacs.append(oMc1.rotation @ J1[:3] - oMc2.rotation @ J2[:3])
        else:
            c1Mc2 = oMc1.inverse() * oMc2
            rows.append(pin.log6(c1Mc2).vector)
            if jacobian:
                jacs.append(pin.Jlog6(c1Mc2) @ (J2 - c1Mc2.inverse().action @ J1))
    r = np.concatenate(rows) if rows else np.zeros(0)
    if not jacobian:
        return r, None
    J = np.vstack(jacs) if jacs else np.zeros((0, model.nv))
    return r, J


def _free_v_indices(model: pin.Model, fixed_q_indices: Sequence[int]) -> np.ndarray:
    """Tangent indices of the joints none of whose q is fixed.

    Raises:
        ValueError: an index out of range, or a joint with only part of its q fixed.
    """
    fixed = {int(i) for i in fixed_q_indices}
    if any(i < 0 or i >= model.nq for i in fixed):
        raise ValueError(f"fixed q indices out of range(0, {model.nq}): {sorted(fixed)}")
    free: list[int] = []
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        qs = set(range(joint.idx_q, joint.idx_q + joint.nq))
        held = qs & fixed
        if held and held != qs:
            raise ValueError(f"joint {model.names[jid]!r}: q {sorted(held)} of {sorted(qs)} fixed")
        if not held:
            free.extend(range(joint.idx_v, joint.idx_v + joint.nv))
    return np.array(free, dtype=int)


class ProjectionError(RuntimeError):
    """``project`` did not converge.

    Attributes:
        q: (nq,) the iterate of least ``|r|`` (a least-squares point where no step helps).
        residual: ``max |r|`` over the stacked closure rows there [m or rad].
    """

    def __init__(self, message: str, q: np.ndarray, residual: float) -> None:
        super().__init__(message)
        self.q = q
        self.residual = residual


def project(
    gm: GepettoModel,
    q0: np.ndarray,
    fixed_q_indices: Sequence[int] = (),
    tol: float = 1e-12,
    max_iter: int = 200,
) -> np.ndarray:
    """A configuration closing every loop, from ``q0``, the q's in ``fixed_q_indices`` held.

    Gauss-Newton with minimum-norm steps (truncated SVD of the Jacobian of the free tangent
    coordinates), each step accepted only if it lowers ``|r|``, else damped
    (Levenberg-Marquardt, damping raised tenfold); the update is ``pin.integrate``. Once
    ``max |r| < tol``, one more step is taken if it lowers ``|r|`` (to rounding level).

    Args:
        q0: (nq,) start.
        fixed_q_indices: q indices held at their ``q0`` value (whole joints).
        tol: converged when ``max |r| < tol`` over the stacked closure rows [m or rad].

    Raises:
        ProjectionError (a RuntimeError): no convergence (no step lowers ``|r|``, or
            ``max_iter`` steps).
    """
    model = gm.model
    data = model.createData()
    free_v = _free_v_indices(model, fixed_q_indices)
    q = np.array(q0, dtype=float)
    if q.shape != (model.nq,):
        raise ValueError(f"q0 has shape {q.shape}, the model nq={model.nq}")
    r, J = stacked_residual(gm, q, data)
    polished = False
    for _ in range(max_iter):
        if r.size == 0:
            return q
        converged = bool(np.abs(r).max() < tol)
        if converged and polished:
            return q
        polished = converged
        assert J is not None
        Jf = J[:, free_v]
        if Jf.size == 0:
            break
        U, s, Vt = np.linalg.svd(Jf, full_matrices=False)
        if s[0] == 0.0:
            break
        keep = s > RCOND * s[0]
        Ur = U.T @ r
        cost = float(r @ r)
        lam = 0.0
        for _ in range(1 if converged else 25):
            w = np.zeros_like(s)
            w[keep] = s[keep] / (s[keep] ** 2 + lam)
            dv = np.zeros(model.nv)
            dv[free_v] = -(Vt.T @ (w * Ur))
            q_new = pin.integrate(model, q, dv)
            r_new, J_new = stacked_residual(gm, q_new, data)
            if float(r_new @ r_new) < cost:
                q, r, J = q_new, r_new, J_new
                break
            lam = 1e-8 * s[0] ** 2 if lam == 0.0 else 10.0 * lam
        else:
            if converged:
                return q
            break
    worst = float(np.abs(r).max(initial=0.0))
    if worst < tol:
        return q
    raise ProjectionError(
        f"{gm.name}: projection did not converge: max |r| = {worst:.3e} > {tol:g}", q, worst
    )


# ---------------------------------------------------------------------------- continuation


@dataclass(frozen=True)
class ContinuationInfo:
    """How a continuation went.

    Attributes:
        residual: max closure residual (``closure_residuals``) at the final q [m or rad].
        max_residual: the largest such value over all accepted steps.
        steps: accepted steps.
        halvings: rejected steps (each halved the step).
        max_correction: largest corrector move ``|pin.difference(predictor, q)|_inf`` over
            the accepted steps [rad or m].
    """

    residual: float
    max_residual: float
    steps: int
    halvings: int
    max_correction: float


class ContinuationError(RuntimeError):
    """``continuation`` stopped before the target.

    Attributes:
        q: (nq,) the last assembled configuration reached.
        s: its place on the motor line (0 at ``q_start``, 1 at the target).
        sigma_min: smallest singular value of the closure Jacobian with the motors held
            there, among those above ``RCOND`` relative (near 0: a fold or a singularity).
    """

    def __init__(self, message: str, q: np.ndarray, s: float, sigma_min: float) -> None:
        super().__init__(message)
        self.q = q
        self.s = s
        self.sigma_min = sigma_min


def _sigma_min(gm: GepettoModel, q: np.ndarray, fixed_q_indices: Sequence[int]) -> float:
    """Smallest singular value of the held closure Jacobian above ``RCOND`` relative."""
    _, J = stacked_residual(gm, q)
    assert J is not None
    Jf = J[:, _free_v_indices(gm.model, fixed_q_indices)]
    if Jf.size == 0:
        return 0.0
    s = np.linalg.svd(Jf, compute_uv=False)
    kept = s[s > RCOND * s[0]] if s[0] > 0 else s
    return float(kept[-1]) if kept.size else 0.0


def continuation(
    gm: GepettoModel,
    q_start: np.ndarray,
    theta_target: Sequence[float] | np.ndarray,
    steps: int | None = None,
    max_step: float = 0.005,
    max_correction: float = 0.1,
    min_fraction: float = 1e-7,
    tol: float = 1e-12,
) -> tuple[np.ndarray, ContinuationInfo]:
    """Follow the assembly of ``q_start`` while the motors move straight to ``theta_target``.

    The motors (``gm.actuated_joint_names`` order) go along ``theta(s) = theta0 + s (target -
    theta0)``, ``s`` from 0 to 1, ``theta0`` read from ``q_start``. Each step predicts by
    linear extrapolation of the last two solutions (the previous solution at the first step),
    sets the motors to ``theta(s)`` and corrects by ``project`` with the motors held. A step
    whose corrector fails or moves more than ``max_correction`` is halved.

    Args:
        q_start: (nq,) an assembled configuration (closures hold).
        theta_target: (k,) motor values [rad] in ``name_mot`` order.
        steps: number of equal steps to start with; default: the fewest whose motor increment
            is at most ``max_step`` (infinity norm) [rad].
        min_fraction: the smallest step (fraction of the line) before giving up.

    Raises:
        RuntimeError: ``q_start`` is not assembled.
        ContinuationError (a RuntimeError): the step fell below ``min_fraction`` (a fold of
            the motor line, or motors that the closures couple).
    """
    model = gm.model
    motors = np.array(gm.motor_q_indices, dtype=int)
    q = np.array(q_start, dtype=float)
    start_res = float(closure_residuals(gm, q).max(initial=0.0))
    if start_res > 1e-9:
        raise RuntimeError(f"{gm.name}: q_start is not assembled (residual {start_res:.3e})")
    theta0 = q[motors].copy()
    target = np.asarray(theta_target, dtype=float)
    if target.shape != theta0.shape:
        raise ValueError(f"theta_target has shape {target.shape}, expected {theta0.shape}")
    span = float(np.abs(target - theta0).max(initial=0.0))
    n = steps if steps is not None else max(1, int(np.ceil(span / max_step)))
    ds = 1.0 / n
    s = 0.0
    q_prev: np.ndarray | None = None
    ds_prev = 0.0
    accepted = halvings = 0
    worst_res = start_res
    worst_corr = 0.0
    while s < 1.0:
        step = min(ds, 1.0 - s)
        if q_prev is None:
            pred = q.copy()
        else:
            pred = pin.integrate(model, q, pin.difference(model, q_prev, q) * (step / ds_prev))
        pred[motors] = theta0 + (s + step) * (target - theta0) if s + step < 1.0 else target
        try:
            q_new = project(gm, pred, fixed_q_indices=motors, tol=tol)
            corr = float(np.abs(pin.difference(model, pred, q_new)).max(initial=0.0))
            ok = corr <= max_correction
        except RuntimeError:
            ok, corr = False, np.inf
        if not ok:
            halvings += 1
            ds = step / 2
            if ds < min_fraction:
                smin = _sigma_min(gm, q, motors)
                raise ContinuationError(
                    f"{gm.name}: continuation stalled at s = {s:.6g} (step < {min_fraction:g}),"
                    f" smallest singular value of the held closure Jacobian {smin:.2e}",
                    q,
                    s,
                    smin,
                )
            continue
        q_prev, q, ds_prev = q, q_new, step
        s = 1.0 if s + step >= 1.0 else s + step
        accepted += 1
        worst_corr = max(worst_corr, corr)
        worst_res = max(worst_res, float(closure_residuals(gm, q).max(initial=0.0)))
        ds = min(2 * step, 1.0 / n)  # grow back after a halving
    res = float(closure_residuals(gm, q).max(initial=0.0))
    return q, ContinuationInfo(res, max(worst_res, res), accepted, halvings, worst_corr)


# ---------------------------------------------------------------------------- assembly, links


def assemble_from_neutral(gm: GepettoModel, tol: float = 1e-12) -> np.ndarray:
    """A configuration closing every loop, by minimum-norm projection from ``pin.neutral``.

    Every joint moves, motors included (as Gepetto's ``configurationProjection`` would,
    which needs CasADi and IPOPT: ``project`` with nothing fixed stands in for it).

    ``kangaroo_like`` and ``kangaroo_like_2legs`` cannot be closed as published: their ankle
    and knee linear actuators slide along the axis of the revolute joint that carries them
    (so the actuator line never moves), and each of those loops alone keeps a least-squares
    residual of millimetres; the ``ProjectionError`` carries that least-squares point.

    Raises:
        ProjectionError (a RuntimeError): the projection does not converge.
    """
    return project(gm, pin.neutral(gm.model), fixed_q_indices=(), tol=tol)


def link_placements(gm: GepettoModel, q: np.ndarray) -> dict[str, np.ndarray]:
    """name -> (4, 4) world placement of every BODY frame (the URDF links) at ``q`` [m]."""
    model = gm.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    return {
        f.name: data.oMf[i].homogeneous.copy()
        for i, f in enumerate(model.frames)
        if f.type == pin.FrameType.BODY
    }
