"""Inverse kinematics: the configuration whose platform has given workspace coordinates, by
continuation from home (it stays in home's working modes)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError, UnreachableError
from ..model.rotations import rot_exp, rot_log
from ..results import Configuration
from .evaluation import ModelEvaluation
from .validation import as_vector


def inverse_kinematics(model: ModelEvaluation, x: ArrayLike) -> Configuration:
    """An assembled configuration of ``model`` whose platform has workspace coordinates ``x``.

    Continuation from the home configuration along a straight line in position and a
    geodesic in orientation, with Newton corrections on ``[g; pose error]`` over all
    joints: the result stays in the working modes of ``home``.

    Args:
        model: the model.
        x: (n,) workspace coordinates, in the order of ``model.workspace``.

    Raises:
        InputError: wrong size or non-finite values.
        UnreachableError: no configuration in the home working mode reaches ``x``.
    """
    if len(model.workspace) != model.k:
        raise InputError(
            f"inverse kinematics needs as many workspace coordinates as actuators: "
            f"workspace {list(model.workspace)} vs actuated {list(model.actuated)}"
        )
    T_goal = model.target_pose(x)
    T0 = np.array(model.home.platform_pose)
    dp = T_goal[:3, 3] - T0[:3, 3]
    w = rot_log(T0[:3, :3].T @ T_goal[:3, :3])
    y_loc, c = model.chart.to_local(model.home.y)
    z = np.concatenate([y_loc, model.home.theta])
    lam, step = 0.0, 1.0
    tol = model.tolerance * 1e-2
    scale = max(1.0, model.length_scale)
    while lam < 1.0:
        trial = min(1.0, lam + step)
        T = np.eye(4)
        T[:3, 3] = T0[:3, 3] + trial * dp
        T[:3, :3] = T0[:3, :3] @ rot_exp(trial * w)
        zk, ok = z.copy(), False
        for _ in range(12):
            zn, res = model.kernels.ik_step(zk, T, c)
            zn = np.array(zn).ravel()
            if not np.all(np.isfinite(zn)) or np.linalg.norm(zn - z, np.inf) > 0.5 * scale:
                break
            zk = zn
            if float(res) < tol:
                ok = True
                break
        if ok:
            z, lam = zk, trial
            step = min(1.0, step * 2)
            y_loc, c = model.chart.recentre(z[: model.m], c)
            z = np.concatenate([y_loc, z[model.m :]])
        else:
            step /= 2
            if step < 1e-5:
                raise UnreachableError(
                    f"pose x={list(map(float, as_vector(x, len(model.workspace), 'x')))} "
                    f"is not reachable in the home working mode (continuation stalled at "
                    f"{lam:.3f} of the way from home)"
                )
    cfg = model.configuration(z[: model.m], z[model.m :], c)
    if cfg.residual > model.tolerance:
        raise UnreachableError(f"inverse kinematics did not assemble (residual {cfg.residual:.2e})")
    return cfg
