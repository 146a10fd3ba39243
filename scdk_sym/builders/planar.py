"""Planar builders: 3-RRR (the paper's planar HEXA-type robot and its family), 3-RPR, five-bar."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..model.spec import Closure, Spec
from ..model.urdf import TreeBuilder
from ..robot import Model, model_from_tree
from .common import (
    affine_rank,
    conditioning,
    duplicate_legs,
    finish,
    lengths,
    line_jacobian,
    pick,
)
from .common import points as _points
from .common import positive as _positive


def rrr_leg_angles(
    base: np.ndarray, vertex: np.ndarray, arm: float, rod: float, mode: int
) -> tuple[float, float]:
    """Closed-form IK of one RRR leg: (arm angle theta, rod angle psi) [rad] in the base frame.

    ``mode = -1`` is theta = atan2(d) - acos(...) (the paper's working mode), ``+1`` the other.
    """
    d = vertex - base
    dist = float(np.hypot(*d))
    if not dist > 1e-12 * max(arm, rod):
        raise InputError(
            f"vertex {vertex.tolist()} coincides with the leg's base joint {base.tolist()}: the "
            "leg's angles are undefined; move the platform point or the home pose"
        )
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
    scale = float(np.ptp(points, axis=0).max())
    if not scale > 0 or area < 1e-9 * scale**2:
        raise InputError(f"{name} are collinear or coincident: {points.tolist()}")


def _home_pose(home_x, name: str) -> np.ndarray:
    return _points(home_x if home_x is not None else (0.0, 0.0, 0.0), (3,), name)


def planar_3rrr(
    base_points: ArrayLike,
    platform_points: ArrayLike,
    arm: float,
    rod: float,
    home_x: ArrayLike | None = None,
    working_modes: Sequence[int] = (-1, -1, -1),
    name: str = "planar_3rrr",
    length_unit: str = "m",
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
        length_unit: unit of the lengths above (``length_unit`` of the saved YAML).

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
        length_unit=length_unit,
    )
    return model_from_tree(b.build(), spec)


def planar_3rrr_reduced(
    base_points: ArrayLike,
    platform_points: ArrayLike,
    arm: float,
    rod: float,
    home_x: ArrayLike | None = None,
    working_modes: Sequence[int] = (-1, -1, -1),
    name: str = "planar_3rrr_reduced",
    length_unit: str = "m",
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
        length_unit=length_unit,
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
        "length_unit": "cm",
    }


def _rot2(phi: float) -> np.ndarray:
    return np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])


def _rpr_conditioning(A: np.ndarray, C: np.ndarray, pose: np.ndarray) -> float:
    """Unit-free conditioning of the 3-RPR leg-length Jacobian at ``pose`` = [x, y, phi]."""
    arms = (_rot2(pose[2]) @ C.T).T
    d = pose[:2] + arms - A
    norms = np.linalg.norm(d, axis=1)
    if norms.min() <= 1e-12 * max(1.0, float(np.abs(A).max())):
        return 0.0
    size = max(float(np.linalg.norm(C - C.mean(0), axis=1).max()), 1e-300)
    return conditioning(line_jacobian(d / norms[:, None], arms, size))


def planar_3rpr(
    base_points: ArrayLike,
    platform_points: ArrayLike,
    home_x: ArrayLike | None = None,
    name: str = "planar_3rpr",
) -> Model:
    """Planar 3-RPR parallel robot: three extensible legs between base and platform pivots.

    The platform rides on a planar chain (prismatic ``px``, prismatic ``py``, revolute
    ``phi``), so the unknowns are the platform pose itself; leg i is a ``distance`` closure
    between base pivot i and platform pivot i whose length is the actuated prismatic joint
    ``leg_i`` (only its length matters to the platform).

    Args:
        base_points: (3, 2) base pivots in the base frame [m].
        platform_points: (3, 2) platform pivots in the platform frame [m].
        home_x: (3,) home pose [x, y, phi] ([m, m, rad]); it fixes the assembly mode that
            the solvers start from. Default: the platform centroid over the base centroid,
            at the first of phi = 0, +-15, +-30, +-45 deg whose leg Jacobian is at least half
            as well conditioned as the best of them.
        name: robot name.

    Returns:
        The loaded model: ``theta`` = the three leg lengths [m], ``x = [x, y, phi]``.

    Raises:
        InputError: wrong shapes, non-finite values, coincident pivots (all platform pivots
            in one point, all base pivots in one point, or two legs on the same pair), a
            zero-length leg or a singular home pose.
    """
    A = _points(base_points, (3, 2), "base_points")
    C = _points(platform_points, (3, 2), "platform_points")
    if affine_rank(C) == 0:
        raise InputError(f"platform_points coincide: {C.tolist()} (the angle is undetermined)")
    if affine_rank(A) == 0:
        raise InputError(f"base_points coincide: {A.tolist()} (the platform turns freely)")
    duplicate_legs(A, C, "base_points/platform_points")
    if home_x is None:
        cands = []
        for deg in (0.0, 15.0, -15.0, 30.0, -30.0, 45.0, -45.0):
            phi = math.radians(deg)
            cands.append(np.array([*(A.mean(0) - _rot2(phi) @ C.mean(0)), phi]))
        chosen = pick(cands, lambda p: _rpr_conditioning(A, C, p))
        if chosen is None:
            raise InputError(
                "base_points/platform_points: no regular default home pose; pass home_x"
            )
        xh = chosen
        names = "base_points/platform_points"
    else:
        xh = _points(home_x, (3,), "home_x")
        names = "base_points/platform_points/home_x"
    R = _rot2(xh[2])
    b = TreeBuilder(name)
    b.add("px", "prismatic", "base", "slider_x", axis=(1.0, 0.0, 0.0))
    b.add("py", "prismatic", "slider_x", "slider_y", axis=(0.0, 1.0, 0.0))
    b.add("phi", "revolute", "slider_y", "platform")
    home = {"px": float(xh[0]), "py": float(xh[1]), "phi": float(xh[2])}
    closures = []
    for i in range(3):
        n = i + 1
        b.add(f"base_anchor_{n}_joint", "fixed", "base", f"base_anchor_{n}", xyz=(*A[i], 0.0))
        b.add(f"leg_{n}", "prismatic", f"base_anchor_{n}", f"leg_{n}_rod", limits=(0.0, 1e3))
        b.add(
            f"platform_anchor_{n}_joint",
            "fixed",
            "platform",
            f"platform_anchor_{n}",
            xyz=(*C[i], 0.0),
        )
        length = float(np.linalg.norm(xh[:2] + R @ C[i] - A[i]))
        if length < 1e-9 * max(1.0, float(np.abs(A).max())):
            raise InputError(f"home_x {xh.tolist()}: leg {n} has zero length")
        home[f"leg_{n}"] = length
        closures.append(
            Closure(f"base_anchor_{n}", f"platform_anchor_{n}", "distance", length_joint=f"leg_{n}")
        )
    spec = Spec(
        closures=tuple(closures),
        actuated=("leg_1", "leg_2", "leg_3"),
        platform="platform",
        workspace=("x", "y", "phi"),
        home=home,
    )
    return finish(b.build(), spec, names)


def five_bar(
    base_points: ArrayLike,
    arm: float | ArrayLike,
    rod: float | ArrayLike,
    home_x: ArrayLike | None = None,
    working_modes: Sequence[int] = (1, -1),
    name: str = "five_bar",
) -> Model:
    """Planar five-bar linkage (2 dof): two actuated arms, two rods meeting at the effector.

    Arm i turns about z at base point i (actuated revolute ``theta_i``, measured from the base
    x axis); its elbow is joined to the effector by a rod, modelled as a ``distance`` closure
    of fixed length. The effector rides on a planar chain (prismatic ``px``, ``py``), so the
    unknowns are its position.

    Args:
        base_points: (2, 2) pivots of the two arms in the base frame [m].
        arm: length of the arms [m], one value or one per arm.
        rod: length of the rods [m], one value or one per rod.
        home_x: (2,) home position of the effector [m]; it fixes the working modes and the
            assembly mode. Default: on the left of the line from base point 1 to base point
            2 ("above" when point 1 is the left one), on its perpendicular bisector, where
            arm and rod of the first leg would be at right angles (or at mid reach).
        working_modes: per leg, +1 or -1: ``theta_i = atan2(d) + mode * acos(...)`` at home
            with ``d`` from base point i to the effector; the default (+1, -1) puts both
            elbows outside the effector's triangle when base point 1 is the left one.
        name: robot name.

    Returns:
        The loaded model: ``theta`` = the two arm angles [rad], ``x = [x, y]``.

    Raises:
        InputError: wrong shapes, non-positive lengths, a home position out of reach, or a
            singular home configuration.
    """
    A = _points(base_points, (2, 2), "base_points")
    arms = lengths(arm, 2, "arm")
    rods = lengths(rod, 2, "rod")
    modes = [int(m) for m in np.atleast_1d(working_modes)]
    if len(modes) != 2 or any(m not in (-1, 1) for m in modes):
        raise InputError(f"working_modes must be two of -1/+1, got {working_modes!r}")
    if home_x is None:
        base = A[1] - A[0]
        span = float(np.linalg.norm(base))
        mid = A.mean(0)
        normal = np.array([-base[1], base[0]]) / span if span > 0 else np.array([0.0, 1.0])
        reach = float(np.sqrt(arms[0] ** 2 + rods[0] ** 2))
        h2 = reach**2 - (span / 2) ** 2
        if h2 <= (0.1 * reach) ** 2:
            lo, hi = abs(arms[0] - rods[0]), arms[0] + rods[0]
            h2 = ((lo + hi) / 2) ** 2 - (span / 2) ** 2
        if h2 <= 0:
            raise InputError(
                f"arm {arms.tolist()} and rod {rods.tolist()} are too short for base points "
                f"{span:.6g} apart; pass home_x"
            )
        xh = mid + math.sqrt(h2) * normal
        names = "base_points/arm/rod"
    else:
        xh = _points(home_x, (2,), "home_x")
        names = "base_points/arm/rod/home_x"
    b = TreeBuilder(name)
    b.add("px", "prismatic", "base", "slider_x", axis=(1.0, 0.0, 0.0))
    b.add("py", "prismatic", "slider_x", "effector", axis=(0.0, 1.0, 0.0))
    home = {"px": float(xh[0]), "py": float(xh[1])}
    closures = []
    for i in range(2):
        n = i + 1
        d = float(np.linalg.norm(xh - A[i]))
        if not abs(arms[i] - rods[i]) < d < arms[i] + rods[i]:
            raise InputError(
                f"home_x {xh.tolist()} is out of reach of leg {n} (arm {arms[i]:.6g}, rod "
                f"{rods[i]:.6g}, distance {d:.6g} from base point {A[i].tolist()})"
            )
        theta, _ = rrr_leg_angles(A[i], xh, float(arms[i]), float(rods[i]), modes[i])
        b.add(f"theta_{n}", "revolute", "base", f"arm_{n}", xyz=(*A[i], 0.0))
        b.add(f"elbow_{n}_joint", "fixed", f"arm_{n}", f"elbow_{n}", xyz=(arms[i], 0.0, 0.0))
        home[f"theta_{n}"] = theta
        closures.append(Closure(f"elbow_{n}", "effector", "distance", float(rods[i])))
    spec = Spec(
        closures=tuple(closures),
        actuated=("theta_1", "theta_2"),
        platform="effector",
        workspace=("x", "y"),
        home=home,
    )
    return finish(b.build(), spec, names)
