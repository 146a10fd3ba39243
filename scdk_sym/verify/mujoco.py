"""Cross-check of a model read from MJCF against MuJoCo itself.

The answers are put into MuJoCo's ``data.qpos`` (through the model's qpos layout) and MuJoCo
computes what it would simulate: every body's placement (``xpos``, ``xmat`` after
``mj_kinematics``), every equality's residual rows (``efc_pos`` of the equality constraints
after ``mj_forward``, contacts and limits disabled so that no other row interferes) and their
Jacobian (``efc_J``).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache
from typing import Any

import numpy as np

from ..errors import InputError
from ..model.mjcf import compile_kinematics, require_mujoco
from ..model.qpos import QposLayout
from ..products import CLOSURE_JACOBIANS
from ..robot import Model


@lru_cache(maxsize=8)
def _compiled(path: str) -> Any:
    """The file's kinematics, compiled once per process, contacts and limits disabled."""
    mujoco = require_mujoco()
    m = compile_kinematics(path)
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_LIMIT)
    return m


def forward(model: Model, qpos: np.ndarray) -> tuple[Any, Any]:
    """``(MjModel, MjData)`` after ``mj_forward`` at ``qpos``."""
    mujoco = require_mujoco()
    m = _compiled(model.source.path)
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    mujoco.mj_forward(m, d)
    return m, d


def equality_rows(model: Model, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(residuals, jacobian, equality ids)`` of MuJoCo's equality rows at ``qpos``:
    ``efc_pos`` (r,), ``efc_J`` (r, nv) and the equality of each row."""
    mujoco = require_mujoco()
    m, d = forward(model, qpos)
    rows = np.flatnonzero(d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    J = np.array(d.efc_J).reshape(d.nefc, m.nv)[rows] if d.nefc else np.zeros((0, m.nv))
    return np.array(d.efc_pos)[rows], J, np.array(d.efc_id)[rows]


def _layout(model: Model) -> QposLayout:
    layout = model.qpos_layout
    if layout is None:
        raise InputError(f"model {model.name!r} was not read from MJCF: check it with Pinocchio")
    return layout


def placement_errors(model: Model, y: np.ndarray, theta: np.ndarray) -> dict[str, float]:
    """Body -> largest difference between the model's placement and MuJoCo's (position
    [m], and rotation matrix entries times the model size) at unknowns ``y`` and inputs
    ``theta`` (closed or not: the spanning tree alone)."""
    cfg = model.configuration(y, theta)
    _, d = forward(model, _layout(model).qpos(cfg.coordinates))
    mine = model.placements(cfg)
    size = max(1.0, model.length_scale)
    out = {}
    for i, body in enumerate(model.source.bodies):
        if i == 0 or body not in mine:
            continue
        T = mine[body]
        dp = np.abs(T[:3, 3] - d.xpos[i]).max()
        dR = np.abs(T[:3, :3] - np.array(d.xmat[i]).reshape(3, 3)).max()
        out[body] = float(max(dp, size * dR))
    return out


def closure_residuals(model: Model, joints: Mapping[str, float]) -> np.ndarray:
    """(closures,) the largest |row| MuJoCo computes for each closure's equality at the joint
    coordinates ``joints`` (``Configuration.coordinates``; 0 for the coupling of a tendon
    input, which MuJoCo has no equality for)."""
    pos, _, ids = equality_rows(model, _layout(model).qpos(joints))
    out = np.zeros(len(model.closures))
    active = np.unique(ids)
    for k, e in enumerate(active):
        out[model.source.equalities[k]] = float(np.abs(pos[ids == e]).max())
    return out


def _closure_jacobian(model: Model) -> Any:
    """``(y, theta, c) -> (dg_all/dy, dg_all/dtheta)`` of ``model``, built once per model."""

    def build() -> Any:
        import casadi as ca

        sym = model.symbolic
        jacobians = [ca.jacobian(sym.g_all, sym.y), ca.jacobian(sym.g_all, sym.theta)]
        return ca.Function("g_all_jac", [sym.y, sym.theta, sym.c], jacobians)

    return model.products.get(CLOSURE_JACOBIANS, build)


def jacobian_error(model: Model, cfg: Any) -> tuple[float, str]:
    """The largest difference, relative to the largest entry, between the model's closure
    Jacobian and MuJoCo's ``efc_J`` over the hinge and slide joints the model moves, on the
    rows written alike (connect rows, a weld's position rows, joint and tendon couplings).

    Returns:
        ``(error, item)``: the error and the entry where it is.
    """
    mujoco = require_mujoco()
    y, c = model.chart.to_local(cfg.y)
    Jy, Jt = (np.array(a, dtype=float) for a in _closure_jacobian(model)(y, cfg.theta, c))
    layout = _layout(model)
    _, J, ids = equality_rows(model, layout.qpos(cfg.coordinates))
    m = _compiled(model.source.path)
    columns = []  # (our column of [Jy, Jt], MuJoCo dof, name)
    for e in layout.entries:
        if e.kind not in ("hinge", "slide"):
            continue
        dof = int(m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, e.name)])
        if e.name in model.unknowns:
            columns.append((model.unknowns.index(e.name), dof, e.name))
        elif e.name in model.actuated:
            columns.append((Jy.shape[1] + model.actuated.index(e.name), dof, e.name))
    mine_all = np.hstack([Jy, Jt])
    labels = model.row_labels()
    mine, theirs, names = [], [], []
    for k, e in enumerate(np.unique(ids)):
        ci = model.source.equalities[k]
        start = int(model.row_offsets[ci])
        count = 3 if model.closures[ci].type == "6d" else model.closures[ci].rows
        mine.append(mine_all[start : start + count][:, [a for a, _, _ in columns]])
        theirs.append(J[ids == e][:count][:, [b for _, b, _ in columns]])
        names += labels[start : start + count]
    A, B = np.vstack(mine), np.vstack(theirs)
    if not A.size:
        return 0.0, "no hinge or slide column"
    size = max(1.0, float(np.abs(B).max()))
    diff = np.abs(A - B) / size
    r, k = (int(i) for i in np.unravel_index(int(np.argmax(diff)), diff.shape))
    return float(diff[r, k]), f"entry [{names[r]}, {columns[k][2]}]"
