"""Independent numeric cross-checks with Pinocchio.

Pinocchio loads the same URDF; its frame placements must match the CasADi ones, and the
closure residuals of solutions, evaluated through ``pin.RigidConstraintModel`` objects built
from the YAML (CONTACT_3D for point-type closures, CONTACT_6D for welds), must vanish.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache

import numpy as np

from ..errors import DependencyError
from ..model.rotations import rot_exp
from ..optional import require
from ..products import PINOCCHIO_MODEL
from ..robot import Model

#: Install command of the optional Pinocchio cross-check.
INSTALL_HINT = 'pip install "scdk_sym[verify]"'


def pinocchio():
    """The ``pinocchio`` module (package ``pin``), imported on first use.

    Raises:
        DependencyError: Pinocchio is not installed (the message gives the install command).
    """
    return require(
        "pinocchio",
        needed_for="the Pinocchio cross-check",
        install=f"{INSTALL_HINT} (or pip install pin)",
        error=DependencyError,
    )


@lru_cache(maxsize=32)
def _pin_model(urdf_text: str):
    pin = pinocchio()

    return pin.buildModelFromXML(urdf_text)


def pinocchio_model(model: Model):
    """The Pinocchio model of a model's URDF (cached); of its joint tree where Gepetto's joint
    edits or a locked rod spin changed the URDF's joints (ball joints as Pinocchio's
    spherical joints, universal joints as two revolutes)."""
    if not model.spec.joint_edits and not model.spins:
        return _pin_model(model.urdf_text)
    return model.products.get(PINOCCHIO_MODEL, lambda: _pin_model_of_tree(model.tree))


def _pin_model_of_tree(tree):
    """A Pinocchio model joint by joint from a :class:`~scdk_sym.model.urdf.Tree` (every link a
    BODY frame; fixed joints merged into their parent's body, as Pinocchio's URDF parser does)."""
    pin = pinocchio()
    pm = pin.Model()
    body = {tree.root: (0, pin.SE3.Identity())}
    pm.addFrame(pin.Frame(tree.root, 0, 0, pin.SE3.Identity(), pin.FrameType.BODY))
    for j in tree.joints:
        parent, offset = body[j.parent]
        place = offset * pin.SE3(np.asarray(j.origin)[:3, :3], np.asarray(j.origin)[:3, 3])
        if j.type == "fixed":
            body[j.child] = (parent, place)
        else:
            kinds = {
                "floating": pin.JointModelFreeFlyer,
                "spherical": pin.JointModelSpherical,
            }
            if j.type in kinds:
                jm = kinds[j.type]()
            elif j.type == "prismatic":
                jm = pin.JointModelPrismaticUnaligned(np.asarray(j.axis, dtype=float))
            else:
                jm = pin.JointModelRevoluteUnaligned(np.asarray(j.axis, dtype=float))
            jid = pm.addJoint(parent, jm, place, j.name)
            body[j.child] = (jid, pin.SE3.Identity())
        jid, at = body[j.child]
        pm.addFrame(pin.Frame(j.child, jid, 0, at, pin.FrameType.BODY))
    return pm


def pin_configuration(model: Model, joints: Mapping[str, float]) -> np.ndarray:
    """Pinocchio ``q`` of a joint-coordinate mapping (``Configuration.joints``)."""
    pin = pinocchio()

    pm = pinocchio_model(model)
    q = pin.neutral(pm)
    for jid in range(1, pm.njoints):
        name = pm.names[jid]
        jm = pm.joints[jid]
        i, nq = jm.idx_q, jm.nq
        if nq == 1:
            q[i] = joints[name]
        elif nq == 2:  # continuous joint: (cos, sin)
            q[i : i + 2] = np.cos(joints[name]), np.sin(joints[name])
        elif nq == 4:  # spherical: quaternion (x, y, z, w) of the rotation vector
            R = rot_exp(np.array([joints[f"{name}.{c}"] for c in ("rx", "ry", "rz")]))
            q[i : i + 4] = pin.Quaternion(R).coeffs()
        elif nq == 7:  # free flyer: position + quaternion (x, y, z, w)
            p = [joints[f"{name}.{c}"] for c in ("x", "y", "z")]
            R = rot_exp(np.array([joints[f"{name}.{c}"] for c in ("rx", "ry", "rz")]))
            quat = pin.Quaternion(R)
            q[i : i + 7] = np.concatenate([p, quat.coeffs()])
        else:  # pragma: no cover - the loader refuses other joint types
            raise NotImplementedError(f"joint {name!r} with nq={nq}")
    return q


def frame_placements(model: Model, joints: Mapping[str, float]) -> dict[str, np.ndarray]:
    """World placements (4x4) of every link, computed by Pinocchio."""
    pin = pinocchio()

    pm = pinocchio_model(model)
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, pin_configuration(model, joints))
    out = {}
    for link in model.tree.links:
        fid = pm.getFrameId(link)
        out[link] = data.oMf[fid].homogeneous.copy()
    return out


def placement_errors(model: Model, y, theta) -> dict[str, float]:
    """Max |symbolic - Pinocchio| entry of each link's 4x4 placement at canonical (y, theta).

    Args:
        model: the model.
        y: (m,) canonical unknowns.
        theta: (k,) actuated values [rad or model length unit].

    Returns:
        Link name -> error [model length unit for the translations; rotations unitless].
    """
    cfg = model.configuration(y, theta)
    pin_T = frame_placements(model, cfg.coordinates)
    ours = model.placements(cfg)
    return {n: float(np.abs(ours[n] - pin_T[n]).max()) for n in ours}


def placement_error(model: Model, y, theta) -> float:
    """Max |symbolic - Pinocchio| over every link placement at canonical (y, theta)."""
    return max(placement_errors(model, y, theta).values())


def constraint_models(model: Model) -> list:
    """One ``pin.RigidConstraintModel`` per closure of the YAML."""
    pin = pinocchio()

    pm = pinocchio_model(model)
    out = []
    for c in model.closures:
        kind = pin.ContactType.CONTACT_6D if c.type == "6d" else pin.ContactType.CONTACT_3D
        fa, fb = pm.frames[pm.getFrameId(c.frame_a)], pm.frames[pm.getFrameId(c.frame_b)]
        cm = pin.RigidConstraintModel(
            kind, pm, fa.parentJoint, fa.placement, fb.parentJoint, fb.placement
        )
        cm.name = f"{c.frame_a}|{c.frame_b}"
        out.append(cm)
    return out


def closure_residuals(model: Model, joints: Mapping[str, float]) -> np.ndarray:
    """Per-closure residual norms evaluated by Pinocchio through its constraint models.

    3d: |p_a - p_b|; 2d: |(p_a - p_b)_xy|; distance: ||p_a - p_b| - length|;
    6d: |log6(M_a^-1 M_b)|.
    """
    pin = pinocchio()

    pm = pinocchio_model(model)
    data = pm.createData()
    pin.forwardKinematics(pm, data, pin_configuration(model, joints))
    out = []
    for c, cm in zip(model.closures, constraint_models(model), strict=True):
        Ma = data.oMi[cm.joint1_id] * cm.joint1_placement
        Mb = data.oMi[cm.joint2_id] * cm.joint2_placement
        d = Ma.translation - Mb.translation
        if c.type == "6d":
            out.append(np.linalg.norm(pin.log6(Ma.inverse() * Mb).vector))
        elif c.type == "3d":
            out.append(np.linalg.norm(d))
        elif c.type == "2d":
            out.append(np.linalg.norm(d[:2]))
        else:
            length = joints[c.length_joint] if c.length_joint else c.length
            out.append(abs(np.linalg.norm(d) - length))
    return np.array(out)


def pinocchio_q(model: Model, cfg, pin_model) -> np.ndarray:
    """The ``q`` of any Pinocchio model of the same robot (for instance the model Gepetto's
    loader builds from the same files) that puts its links where ``cfg`` puts them.

    Each joint's coordinates are read off the placements: for Pinocchio joint ``i``, the
    world placement of its frame comes from a link attached to it (a BODY or JOINT frame named
    after one of this model's links), and its motion ``(oM_parent * jointPlacement)^-1 * oM_i``
    gives the angle (revolute, (cos, sin) for continuous), the displacement (prismatic), the
    quaternion (spherical: Gepetto's ball joints and merged revolute triples) or the
    placement (free-flyer, at the base: the base fixed, as solved). Joint order and
    conventions are the Pinocchio model's own; a free-flyer base is the identity.

    Args:
        model: the model that solved ``cfg``.
        cfg: a configuration of ``model``.
        pin_model: a ``pinocchio.Model`` whose BODY frames carry this model's link names.

    Returns:
        (pin_model.nq,) configuration.

    Raises:
        ModelError: a Pinocchio joint carries no link of this model.
    """
    pin = pinocchio()
    from ..errors import ModelError

    ours = model.placements(cfg)
    world: dict[int, object] = {0: pin.SE3.Identity()}
    for f in pin_model.frames:
        kind = f.type in (pin.FrameType.BODY, pin.FrameType.JOINT)
        if kind and f.name in ours and f.parentJoint not in world:
            M = pin.SE3(ours[f.name][:3, :3], ours[f.name][:3, 3])
            world[f.parentJoint] = M * f.placement.inverse()
    q = pin.neutral(pin_model)
    for jid in range(1, pin_model.njoints):
        if jid not in world:
            if pin_model.parents[jid] == 0 and pin_model.joints[jid].nq == 7:
                world[jid] = pin.SE3.Identity()  # free-flyer base, held fixed
            else:
                raise ModelError(
                    f"Pinocchio joint {pin_model.names[jid]!r} carries no link of the model "
                    f"(links: {', '.join(model.tree.links)})"
                )
        jm = pin_model.joints[jid]
        parent = world[pin_model.parents[jid]] * pin_model.jointPlacements[jid]
        motion = parent.inverse() * world[jid]
        q[jm.idx_q : jm.idx_q + jm.nq] = _joint_q(pin, pin_model, jid, motion)
    return q


def _joint_q(pin, pin_model, jid: int, motion) -> np.ndarray:
    """Coordinates of joint ``jid`` whose motion (joint frame, parent side -> child) is
    ``motion``: the q minimising the distance to it (log of the residual motion)."""
    jm = pin_model.joints[jid]
    nq = jm.nq
    if nq == 7:
        return pin.SE3ToXYZQUAT(motion)
    if nq == 4:
        return pin.Quaternion(motion.rotation).normalized().coeffs()
    # one-dof joints: the motion's twist on the joint's own subspace (S of the joint at 0)
    model1 = pin.Model()
    model1.addJoint(0, jm, pin.SE3.Identity(), "j")
    data1 = model1.createData()
    q1 = pin.neutral(model1)
    for _ in range(20):  # Gauss-Newton on log6(M(q)^-1 motion): exact in a step or two
        pin.forwardKinematics(model1, data1, q1)
        err = pin.log6(data1.oMi[1].inverse() * motion).vector
        pin.computeJointJacobians(model1, data1, q1)
        J = np.asarray(pin.getJointJacobian(model1, data1, 1, pin.ReferenceFrame.LOCAL))
        J = J.reshape(6, -1)
        dv = np.linalg.lstsq(J, err, rcond=None)[0]
        q1 = pin.integrate(model1, q1, dv)
        if np.abs(dv).max() < 1e-15:
            break
    return q1
