"""Planar 3-RRR builders (the paper's planar HEXA-type robot and its family)."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..model.model import Model, model_from_tree
from ..model.spec import Closure, Spec
from ..model.urdf import TreeBuilder


def _points(value, shape: tuple[int, int], name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be an array of shape {shape}, got {value!r}") from exc
    if arr.shape != shape:
        raise InputError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def _positive(value, name: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0:
        raise InputError(f"{name} must be a positive length, got {value!r}")
    return v


def rrr_leg_angles(
    base: np.ndarray, vertex: np.ndarray, arm: float, rod: float, mode: int
) -> tuple[float, float]:
    """Closed-form IK of one RRR leg: (arm angle theta [rad], rod angle psi [rad]) in the base frame.

    ``mode = -1`` is theta = atan2(d) - acos(...) (the paper's working mode), ``+1`` the other.
    """
    d = vertex - base
    dist = float(np.hypot(*d))
    c = (dist**2 + arm**2 - rod**2) / (2 * arm * dist)
    if not -1.0 <= c <= 1.0:
        raise InputError(
            f"vertex {vertex.tolist()} is out of reach of the leg at {base.tolist()} "
            f"(arm {arm}, rod {rod}, distance {dist:.6g})"
        )
    theta = math.atan2(d[1], d[0]) + mode * math.acos(c)
    elbow = base + arm * np.array([math.cos(theta), math.sin(theta)])
    e = vertex - elbow
    return theta, math.atan2(e[1], e[0])


def _check_triangle(points: np.ndarray, name: str) -> None:
    a, b, c = points
    area = 0.5 * abs((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
    scale = max(np.ptp(points, axis=0).max(), 1e-300)
    if area < 1e-9 * scale**2:
        raise InputError(f"{name} are collinear or coincident: {points.tolist()}")


def _home_pose(home_x, name: str) -> np.ndarray:
    return _points(home_x if home_x is not None else (0.0, 0.0, 0.0), (3,), name)


def planar_3rrr(
    base_points,
    platform_points,
    arm: float,
    rod: float,
    home_x=None,
    working_modes=(-1, -1, -1),
    name: str = "planar_3rrr",
) -> Model:
    """Planar 3-RRR parallel robot modelled with full chains (the paper's HEXA-type robot).

    Leg i: actuated revolute ``theta_i`` at base point i, passive ``elbow_i`` after the arm;
    leg 1 carries the platform through ``wrist_1`` at platform vertex 1; the vertices 2 and 3
    are closed with ``2d`` closures on the rod ends. All joints turn about z.

    Args:
        base_points: (3, 2) base joint positions in the base frame [length].
        platform_points: (3, 2) platform vertices in the platform frame [length].
        arm: arm length (actuated link) [length].
        rod: rod length (passive link) [length].
        home_x: (3,) home pose [x, y, phi] ([length, length, rad]), default zero.
        working_modes: per leg, -1 or +1: theta = atan2(d) + mode * acos(...) at home.
        name: robot name.

    Returns:
        The loaded model; ``theta`` = the three arm angles, ``x = [x, y, phi]``.
    """
    A = _points(base_points, (3, 2), "base_points")
    C = _points(platform_points, (3, 2), "platform_points")
    _check_triangle(A, "base_points")
    _check_triangle(C, "platform_points")
    arm = _positive(arm, "arm")
    rod = _positive(rod, "rod")
    xh = _home_pose(home_x, "home_x")
    modes = [int(m) for m in working_modes]
    if len(modes) != 3 or any(m not in (-1, 1) for m in modes):
        raise InputError(f"working_modes must be three of -1/+1, got {working_modes!r}")
    b = TreeBuilder(name)
    home: dict[str, float] = {}
    R = np.array([[math.cos(xh[2]), -math.sin(xh[2])], [math.sin(xh[2]), math.cos(xh[2])]])
    for i in range(3):
        n = i + 1
        vertex = xh[:2] + R @ C[i]
        theta, psi = rrr_leg_angles(A[i], vertex, arm, rod, modes[i])
        b.add(f"theta_{n}", "revolute", "base", f"arm_{n}", xyz=(*A[i], 0.0))
        b.add(f"elbow_{n}", "revolute", f"arm_{n}", f"rod_{n}", xyz=(arm, 0.0, 0.0))
        home[f"theta_{n}"] = theta
        home[f"elbow_{n}"] = psi - theta
        if n == 1:
            b.add("wrist_1", "revolute", "rod_1", "vertex_1", xyz=(rod, 0.0, 0.0))
            b.add("platform_joint", "fixed", "vertex_1", "platform", xyz=(-C[0, 0], -C[0, 1], 0.0))
            home["wrist_1"] = xh[2] - psi
        else:
            b.add(f"rod_end_{n}_joint", "fixed", f"rod_{n}", f"rod_end_{n}", xyz=(rod, 0.0, 0.0))
    for n in (2, 3):
        b.add(f"vertex_{n}_joint", "fixed", "platform", f"vertex_{n}", xyz=(*C[n - 1], 0.0))
    spec = Spec(
        closures=tuple(Closure(f"vertex_{n}", f"rod_end_{n}", "2d") for n in (2, 3)),
        actuated=("theta_1", "theta_2", "theta_3"),
        platform="platform",
        workspace=("x", "y", "phi"),
        home=home,
    )
    return model_from_tree(b.build(), spec)


def planar_3rrr_reduced(
    base_points,
    platform_points,
    arm: float,
    rod: float,
    home_x=None,
    working_modes=(-1, -1, -1),
    name: str = "planar_3rrr_reduced",
) -> Model:
    """The paper's own formulation of a planar 3-RRR robot: the unknowns are the platform pose.

    A planar chain (prismatic ``px``, prismatic ``py``, revolute ``phi``) carries the
    platform; each arm ends at an elbow frame and ``distance`` closures of length ``rod``
    join elbow i to platform vertex i. Arguments as :func:`planar_3rrr`.
    """
    A = _points(base_points, (3, 2), "base_points")
    C = _points(platform_points, (3, 2), "platform_points")
    _check_triangle(A, "base_points")
    _check_triangle(C, "platform_points")
    arm = _positive(arm, "arm")
    rod = _positive(rod, "rod")
    xh = _home_pose(home_x, "home_x")
    modes = [int(m) for m in working_modes]
    b = TreeBuilder(name)
    b.add("px", "prismatic", "base", "slider_x", axis=(1.0, 0.0, 0.0))
    b.add("py", "prismatic", "slider_x", "slider_y", axis=(0.0, 1.0, 0.0))
    b.add("phi", "revolute", "slider_y", "platform")
    home = {"px": float(xh[0]), "py": float(xh[1]), "phi": float(xh[2])}
    R = np.array([[math.cos(xh[2]), -math.sin(xh[2])], [math.sin(xh[2]), math.cos(xh[2])]])
    for i in range(3):
        n = i + 1
        b.add(f"vertex_{n}_joint", "fixed", "platform", f"vertex_{n}", xyz=(*C[i], 0.0))
        b.add(f"theta_{n}", "revolute", "base", f"arm_{n}", xyz=(*A[i], 0.0))
        b.add(f"elbow_{n}_joint", "fixed", f"arm_{n}", f"elbow_{n}", xyz=(arm, 0.0, 0.0))
        theta, _ = rrr_leg_angles(A[i], xh[:2] + R @ C[i], arm, rod, modes[i])
        home[f"theta_{n}"] = theta
    spec = Spec(
        closures=tuple(Closure(f"elbow_{n}", f"vertex_{n}", "distance", rod) for n in (1, 2, 3)),
        actuated=("theta_1", "theta_2", "theta_3"),
        platform="platform",
        workspace=("x", "y", "phi"),
        home=home,
    )
    return model_from_tree(b.build(), spec)


def seed_geometry() -> dict:
    """The paper's planar HEXA-type robot (section 5): cm and rad.

    Arm = rod = 7 cm; base triangle side 20 cm, platform side 10 cm, both centred at the
    origin, vertex i at polar angle -30, -150, 90 deg.
    """
    angles = np.radians([-30.0, -150.0, 90.0])
    unit = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    return {
        "base_points": unit * 20.0 / math.sqrt(3.0),
        "platform_points": unit * 10.0 / math.sqrt(3.0),
        "arm": 7.0,
        "rod": 7.0,
    }
