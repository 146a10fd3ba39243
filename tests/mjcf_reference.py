"""MuJoCo's own kinematics of MJCF mechanisms: an independent reference for the MJCF loader.

Nothing here imports scdk_sym. A model is compiled by MuJoCo (``mujoco.MjSpec``) with its
meshes, textures, height fields and skins removed (kinematics do not need them, and the
Menagerie copies in ``tests/fixtures/mjcf/menagerie`` come without their asset folders). The
closure residual is MuJoCo's own: the ``efc_pos`` rows of the equality constraints after
``mj_forward``, and their Jacobian the matching ``efc_J`` rows (columns: the ``nv`` dofs).

What MuJoCo 4.0.1 computes for those rows (checked numerically to 1e-15; the formulas are
written out in tests/fixtures/mjcf/README.md and tested in tests/test_mjcf_reference.py):
``connect`` (bodies) ``x1 + R1 a1 - (x2 + R2 a2)`` with ``a1, a2 = eq_data[0:3], eq_data[3:6]``
(``a2`` computed from qpos0); ``connect`` (sites) ``site_xpos[s1] - site_xpos[s2]``; ``weld``
(bodies) ``x1 + R1 eq_data[3:6] - (x2 + R2 eq_data[0:3])`` and
``torquescale * Im(conj(q2) q1 eq_data[6:10])``; ``joint``/``tendon``
``y1 - y1_0 - sum_k c_k (y2 - y2_0)^k`` (``y1 - y1_0 - c0`` without a second object).

Units: those of the model (metres and radians).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import mujoco
import numpy as np

#: Newton has converged when max |equality row| is below this [m or rad].
TOL = 1e-12
#: Newton iterations allowed per continuation step.
MAX_NEWTON = 30

_EQUALITY = int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
_BALL = int(mujoco.mjtJoint.mjJNT_BALL)
_SCALAR_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_ASSET_GEOMS = (
    int(mujoco.mjtGeom.mjGEOM_MESH),
    int(mujoco.mjtGeom.mjGEOM_HFIELD),
    int(mujoco.mjtGeom.mjGEOM_SDF),
)


def _prepare(m: mujoco.MjModel) -> None:
    """Make only equality constraints (and all of them) appear in ``efc``, Jacobian dense.

    Contacts, joint/tendon limits and friction loss are disabled through
    ``m.opt.disableflags``; the constraint and equality switches are cleared. Modifies ``m``.
    """
    flags = mujoco.mjtDisableBit
    m.opt.disableflags |= flags.mjDSBL_CONTACT | flags.mjDSBL_LIMIT | flags.mjDSBL_FRICTIONLOSS
    m.opt.disableflags &= ~(flags.mjDSBL_CONSTRAINT | flags.mjDSBL_EQUALITY)
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE


def load_kinematics(path: str | Path) -> mujoco.MjModel:
    """Compile an MJCF file for kinematics only, without any mesh or image asset.

    Every mesh (or height field, or SDF) geom becomes a sphere of radius 0.01 m; every mesh,
    texture, height field and skin is deleted and materials lose their textures, so the file
    compiles without its asset folder. Includes are resolved relative to the file.

    Args:
        path: the MJCF (``.xml``) file.

    Returns:
        The compiled model, with contacts, limits and friction loss disabled and a dense
        constraint Jacobian (see ``equality_residual``).
    """
    spec = mujoco.MjSpec.from_file(str(path))
    for geom in spec.geoms:
        if int(geom.type) in _ASSET_GEOMS:
            geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
            geom.size = [0.01, 0.0, 0.0]
            geom.meshname = ""
            geom.hfieldname = ""
    for items in (spec.meshes, spec.textures, spec.hfields, spec.skins):
        for item in list(items):
            spec.delete(item)
    for material in spec.materials:
        material.textures = [""] * len(material.textures)
    model = spec.compile()
    _prepare(model)
    return model


def home_qpos(m: mujoco.MjModel) -> np.ndarray:
    """The configuration of the keyframe named ``home`` if there is one, else ``qpos0``."""
    key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home")
    return (m.key_qpos[key] if key >= 0 else m.qpos0).copy()


def _forward(m: mujoco.MjModel, d: mujoco.MjData, qpos: np.ndarray) -> np.ndarray:
    """Run ``mj_forward`` at ``qpos`` (zero velocity); indices of the equality rows."""
    d.qpos[:] = qpos
    d.qvel[:] = 0.0
    mujoco.mj_forward(m, d)
    return np.flatnonzero(np.asarray(d.efc_type[: d.nefc]) == _EQUALITY)


def _dense_jacobian(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """``efc_J`` as an ``(nefc, nv)`` array, whatever the storage."""
    if mujoco.mj_isSparse(m):
        dense = np.zeros((d.nefc, m.nv))
        mujoco.mju_sparse2dense(dense, d.efc_J, d.efc_J_rownnz, d.efc_J_rowadr, d.efc_J_colind)
        return dense
    return np.asarray(d.efc_J).reshape(d.nefc, m.nv)


def equality_residual(m: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """MuJoCo's equality-constraint residual at a configuration.

    Sets ``qpos`` (zero velocity), runs ``mj_forward`` and returns the ``efc_pos`` rows whose
    ``efc_type`` is ``mjCNSTR_EQUALITY``, in MuJoCo's order (equality by equality, 3 rows per
    connect, 6 per weld, 1 per joint or tendon equality). Only active equalities
    (``eq_active0``) produce rows. Contact, limit and friction-loss constraints are disabled
    on ``m`` (``m.opt.disableflags``, which this function sets) so that no other constraint
    can hide or shift an equality row; rows are in any case selected by type.

    Args:
        m: the model (its ``opt`` is modified as described).
        qpos: configuration, shape ``(nq,)``.

    Returns:
        The residual, shape ``(n_rows,)``.
    """
    _prepare(m)
    d = mujoco.MjData(m)
    rows = _forward(m, d, np.asarray(qpos, dtype=float))
    return np.asarray(d.efc_pos)[rows].copy()


def equality_jacobian(m: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Jacobian of ``equality_residual`` with respect to the dofs (``efc_J`` rows).

    Columns are the ``nv`` dofs: one per hinge or slide (d/dqpos), three per ball joint and
    three translations then three rotations per free joint (angular velocity in the body
    frame for balls and free joints, world translation for free joints), as MuJoCo's
    velocities.

    Args:
        m: the model (its ``opt`` is modified as in ``equality_residual``).
        qpos: configuration, shape ``(nq,)``.

    Returns:
        The Jacobian, shape ``(n_rows, nv)``.
    """
    _prepare(m)
    d = mujoco.MjData(m)
    rows = _forward(m, d, np.asarray(qpos, dtype=float))
    return _dense_jacobian(m, d)[rows].copy()


def _joint_id(m: mujoco.MjModel, name: str) -> int:
    """Id of the joint ``name``; ``KeyError`` if there is none."""
    jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
    if jid < 0:
        raise KeyError(f"no joint named {name!r}")
    return int(jid)


def _is_floating_base(m: mujoco.MjModel, joint: int) -> bool:
    """A free joint whose body carries other bodies (the root of a tree, e.g. a pelvis)."""
    if int(m.jnt_type[joint]) != _FREE:
        return False
    body = m.jnt_bodyid[joint]
    return bool(np.any(m.body_parentid[1:] == body))


def solved_dofs(m: mujoco.MjModel, inputs: Sequence[str], fixed: Sequence[str] = ()) -> np.ndarray:
    """Dof indices that ``continuation`` solves for.

    Every dof of every joint except the ``inputs``, the joints named in ``fixed`` and free
    joints at the root of a tree of bodies (a floating base); a free joint on a body without
    children (e.g. a platform held only by equalities) is solved for.

    Args:
        m: the model.
        inputs: names of the input joints.
        fixed: names of further joints held at their value.

    Returns:
        Sorted dof indices.
    """
    held = {_joint_id(m, name) for name in (*inputs, *fixed)}
    dofs: list[int] = []
    for j in range(m.njnt):
        if j in held or _is_floating_base(m, j):
            continue
        n = {_FREE: 6, _BALL: 3}.get(int(m.jnt_type[j]), 1)
        dofs.extend(range(m.jnt_dofadr[j], m.jnt_dofadr[j] + n))
    return np.array(sorted(dofs), dtype=int)


def _gauss_newton_step(
    m: mujoco.MjModel, d: mujoco.MjData, qpos: np.ndarray, dofs: np.ndarray, rows: np.ndarray
) -> np.ndarray:
    """``qpos`` after one minimum-norm least-squares step on ``dofs`` (``d`` evaluated)."""
    jac = _dense_jacobian(m, d)[np.ix_(rows, dofs)]
    step, *_ = np.linalg.lstsq(jac, -np.asarray(d.efc_pos)[rows], rcond=None)
    dq = np.zeros(m.nv)
    dq[dofs] = step
    new = qpos.copy()
    mujoco.mj_integratePos(m, new, dq, 1.0)
    return new


def _newton(
    m: mujoco.MjModel, d: mujoco.MjData, qpos: np.ndarray, dofs: np.ndarray, polish: bool = False
) -> None:
    """Minimum-norm Gauss-Newton on ``dofs`` until max |row| < TOL (``qpos`` in place).

    With ``polish``, one more step is then taken and kept if it lowers max |row|.
    """
    for _ in range(MAX_NEWTON):
        rows = _forward(m, d, qpos)
        residual = np.asarray(d.efc_pos)[rows]
        if residual.size == 0:
            return
        size = np.max(np.abs(residual))
        if size < TOL:
            if polish:
                new = _gauss_newton_step(m, d, qpos, dofs, rows)
                if np.max(np.abs(np.asarray(d.efc_pos)[_forward(m, d, new)])) < size:
                    qpos[:] = new
            return
        qpos[:] = _gauss_newton_step(m, d, qpos, dofs, rows)
    residual = np.asarray(d.efc_pos)[_forward(m, d, qpos)]
    if residual.size and np.max(np.abs(residual)) >= TOL:
        raise RuntimeError(
            f"Newton did not converge in {MAX_NEWTON} iterations: "
            f"max |residual| = {np.max(np.abs(residual)):.3e}"
        )


def continuation(
    m: mujoco.MjModel,
    qpos_start: np.ndarray,
    inputs: Mapping[str, float],
    fixed: Sequence[str] = (),
    steps: int = 50,
) -> np.ndarray:
    """Track an assembled configuration while input joints move to target values.

    The inputs move linearly from their values in ``qpos_start`` to ``inputs`` in ``steps``
    equal steps; after each step (and once at the start) Newton corrects the dofs of
    ``solved_dofs(m, inputs, fixed)`` with minimum-norm least-squares steps on the equality
    Jacobian until max |equality row| < ``TOL``, plus one polishing step at the end (kept
    if it lowers the residual). Increments are integrated into ``qpos`` with
    ``mj_integratePos`` (quaternion update for ball and free joints).

    Args:
        m: the model (its ``opt`` is modified as in ``equality_residual``).
        qpos_start: an assembled configuration, shape ``(nq,)``.
        inputs: target value of each input joint (hinge [rad] or slide [m]), by name.
        fixed: names of joints held at their ``qpos_start`` value.
        steps: number of continuation steps (at least 1).

    Returns:
        The final configuration, shape ``(nq,)``.

    Raises:
        ValueError: an input is not a hinge or slide joint, or ``steps`` < 1.
        RuntimeError: Newton failed to converge at some step.
    """
    if steps < 1:
        raise ValueError("steps must be at least 1")
    _prepare(m)
    adrs, targets = [], []
    for name, value in inputs.items():
        jid = _joint_id(m, name)
        if int(m.jnt_type[jid]) not in _SCALAR_JOINTS:
            raise ValueError(f"input joint {name!r} is not a hinge or slide joint")
        adrs.append(m.jnt_qposadr[jid])
        targets.append(float(value))
    adr = np.array(adrs, dtype=int)
    qpos = np.array(qpos_start, dtype=float)
    start = qpos[adr].copy()
    dofs = solved_dofs(m, list(inputs), fixed)
    d = mujoco.MjData(m)
    _newton(m, d, qpos, dofs)
    for k in range(1, steps + 1):
        qpos[adr] = start + (np.array(targets) - start) * (k / steps)
        _newton(m, d, qpos, dofs, polish=k == steps)
    return qpos


def body_poses(m: mujoco.MjModel, qpos: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """World pose of every named body at a configuration (``mj_kinematics``).

    Args:
        m: the model.
        qpos: configuration, shape ``(nq,)``.

    Returns:
        ``{body name: (position (3,), rotation matrix (3, 3))}``, the world body included.
    """
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(m, d)
    poses = {}
    for b in range(m.nbody):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        if name:
            poses[name] = (d.xpos[b].copy(), d.xmat[b].reshape(3, 3).copy())
    return poses
