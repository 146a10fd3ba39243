"""Spatial builders: Stewart-Gough platforms."""

from __future__ import annotations

import numpy as np

from ..errors import InputError, NonSquareSystemError
from ..model.chart import rot_log
from ..model.model import Model, model_from_tree
from ..model.spec import Closure, Spec
from ..model.urdf import TreeBuilder, rpy_matrix
from .planar import _points

SPATIAL_WORKSPACE = ("x", "y", "z", "roll", "pitch", "yaw")


def stewart_gough(
    base_points,
    platform_points,
    home_x=None,
    name: str = "stewart_gough",
) -> Model:
    """Stewart-Gough platform with six extensible legs (6-6; 3-3 and 6-3 via coincident points).

    The platform hangs on a ``floating`` joint (six unknowns in a re-centred local chart, see
    :mod:`scdk_sym.model.chart`); leg i is a ``distance`` closure between base anchor i and
    platform anchor i whose length is the actuated prismatic joint ``leg_i`` (a U-P-S or S-P-S
    leg: only its length matters to the platform).

    Args:
        base_points: (6, 3) leg anchors on the base, in the base frame [m].
        platform_points: (6, 3) leg anchors on the platform, in the platform frame [m].
        home_x: (6,) home pose [x, y, z, roll, pitch, yaw] ([m], [rad], URDF rpy);
            default: centred, level, at a height equal to the base radius.
        name: robot name.

    Returns:
        The model: ``theta`` = the six leg lengths [m], ``x = [x, y, z, roll, pitch, yaw]``.
    """
    A = _points(base_points, (6, 3), "base_points")
    B = _points(platform_points, (6, 3), "platform_points")
    if home_x is None:
        radius = float(np.max(np.linalg.norm(A[:, :2] - A[:, :2].mean(0), axis=1)))
        home_x = (*A[:, :2].mean(0), A[:, 2].mean() + max(radius, 1e-3), 0.0, 0.0, 0.0)
    xh = _points(home_x, (6,), "home_x")
    R = rpy_matrix(*xh[3:])
    b = TreeBuilder(name)
    b.add("platform_joint", "floating", "base", "platform")
    w = rot_log(R)
    home = {f"platform_joint.{c}": float(v) for c, v in zip(("x", "y", "z"), xh[:3], strict=True)}
    home.update(
        {f"platform_joint.{c}": float(v) for c, v in zip(("rx", "ry", "rz"), w, strict=True)}
    )
    closures = []
    for i in range(6):
        n = i + 1
        b.add(f"base_anchor_{n}_joint", "fixed", "base", f"base_anchor_{n}", xyz=A[i])
        b.add(f"leg_{n}", "prismatic", f"base_anchor_{n}", f"leg_{n}_rod", limits=(0.0, 1e3))
        b.add(f"platform_anchor_{n}_joint", "fixed", "platform", f"platform_anchor_{n}", xyz=B[i])
        length = float(np.linalg.norm(xh[:3] + R @ B[i] - A[i]))
        if length < 1e-9:
            raise InputError(f"leg {n} has zero length at home_x {xh.tolist()}")
        home[f"leg_{n}"] = length
        closures.append(
            Closure(f"base_anchor_{n}", f"platform_anchor_{n}", "distance", length_joint=f"leg_{n}")
        )
    spec = Spec(
        closures=tuple(closures),
        actuated=tuple(f"leg_{n}" for n in range(1, 7)),
        platform="platform",
        workspace=SPATIAL_WORKSPACE,
        home=home,
    )
    try:
        return model_from_tree(b.build(), spec)
    except NonSquareSystemError as exc:
        raise InputError(
            f"base_points/platform_points give a degenerate platform (J_p has rank {exc.rank} of 6 "
            "at home_x): coincident, collinear or architecturally singular anchors"
        ) from exc
