"""Spatial builders: Stewart-Gough platforms, Clavel's Delta and Uchiyama's HEXA."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..model.rotations import rot_log, rpy_matrix
from ..model.spec import Closure, Spec
from ..model.urdf import TreeBuilder
from ..robot import Model
from .common import (
    affine_rank,
    conditioning,
    duplicate_legs,
    finish,
    line_jacobian,
    pick,
    points,
    positive,
)

SPATIAL_WORKSPACE = ("x", "y", "z", "roll", "pitch", "yaw")
#: Polar angles [deg] of the three legs (or leg pairs) of the Delta and the HEXA: leg 1 on -y.
LEG_ANGLES = (-90.0, 30.0, 150.0)


def _floating_home(xh: np.ndarray) -> dict[str, float]:
    """Home values of the six coordinates of ``platform_joint`` at pose [x, y, z, r, p, y]."""
    w = rot_log(rpy_matrix(*xh[3:]))
    home = {f"platform_joint.{c}": float(v) for c, v in zip("xyz", xh[:3], strict=True)}
    home.update({f"platform_joint.r{c}": float(v) for c, v in zip("xyz", w, strict=True)})
    return home


def _leg_conditioning(A: np.ndarray, B: np.ndarray, xh: np.ndarray) -> float:
    """Unit-free conditioning of the 6x6 leg Jacobian of a hexapod at pose ``xh``."""
    R = rpy_matrix(*xh[3:])
    arms = B @ R.T
    d = xh[:3] + arms - A
    norms = np.linalg.norm(d, axis=1)
    if norms.min() <= 1e-12 * max(1.0, float(np.abs(A).max())):
        return 0.0
    size = max(float(np.linalg.norm(B - B.mean(0), axis=1).max()), 1e-300)
    return conditioning(line_jacobian(d / norms[:, None], arms, size))


def stewart_gough(
    base_points: ArrayLike,
    platform_points: ArrayLike,
    home_x: ArrayLike | None = None,
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
        home_x: (6,) home pose [x, y, z, roll, pitch, yaw] ([m], [rad], URDF rpy:
            ``R = Rz(yaw) Ry(pitch) Rx(roll)``); it fixes the assembly mode the solvers start
            from. Default: level, the platform centroid above the base centroid at a height
            equal to the base radius.
        name: robot name.

    Returns:
        The model: ``theta`` = the six leg lengths [m], ``x = [x, y, z, roll, pitch, yaw]``.

    Raises:
        InputError: wrong shapes, non-finite values, collinear (or coincident) base or
            platform anchors, two legs on the same pair of anchors, a zero-length leg, or a
            singular home pose (e.g. an architecturally singular design).
    """
    A = points(base_points, (6, 3), "base_points")
    B = points(platform_points, (6, 3), "platform_points")
    if affine_rank(A) < 2:
        raise InputError(f"base_points are collinear or coincident: {A.tolist()}")
    if affine_rank(B) < 2:
        raise InputError(f"platform_points are collinear or coincident: {B.tolist()}")
    duplicate_legs(A, B, "base_points/platform_points")
    if home_x is None:
        radius = float(np.max(np.linalg.norm(A[:, :2] - A[:, :2].mean(0), axis=1)))
        xh = np.array([*(A[:, :2].mean(0) - B[:, :2].mean(0)), 0.0, 0.0, 0.0, 0.0])
        xh[2] = A[:, 2].mean() - B[:, 2].mean() + radius
        names = "base_points/platform_points"
    else:
        xh = points(home_x, (6,), "home_x")
        names = "base_points/platform_points/home_x"
    R = rpy_matrix(*xh[3:])
    b = TreeBuilder(name)
    b.add("platform_joint", "floating", "base", "platform")
    home = _floating_home(xh)
    closures = []
    for i in range(6):
        n = i + 1
        b.add(f"base_anchor_{n}_joint", "fixed", "base", f"base_anchor_{n}", xyz=A[i])
        b.add(f"leg_{n}", "prismatic", f"base_anchor_{n}", f"leg_{n}_rod", limits=(0.0, 1e3))
        b.add(f"platform_anchor_{n}_joint", "fixed", "platform", f"platform_anchor_{n}", xyz=B[i])
        length = float(np.linalg.norm(xh[:3] + R @ B[i] - A[i]))
        if length < 1e-9 * max(1.0, float(np.abs(A).max())):
            raise InputError(f"home_x {xh.tolist()}: leg {n} has zero length")
        home[f"leg_{n}"] = length
        closures.append(
            Closure(f"base_anchor_{n}", f"platform_anchor_{n}", "distance", length_joint=f"leg_{n}")
        )
    if _leg_conditioning(A, B, xh) < 1e-6:
        raise InputError(
            f"{names} give a singular home pose (the six leg lines are linearly dependent at "
            f"{xh.tolist()}): architecturally singular anchors, or pass another home_x"
        )
    spec = Spec(
        closures=tuple(closures),
        actuated=tuple(f"leg_{n}" for n in range(1, 7)),
        platform="platform",
        workspace=SPATIAL_WORKSPACE,
        home=home,
    )
    return finish(b.build(), spec, names)


# ---------------------------------------------------------------------------- R-U-S legs


def _arm_rod_legs(
    b: TreeBuilder, base: np.ndarray, plane: np.ndarray, arm: float, platform: np.ndarray
) -> None:
    """Add rotary arms at the base and the platform anchors of R-U-S / R-(SS)2 legs.

    Leg i: actuated revolute ``theta_i`` at ``base[i]`` about the horizontal axis
    perpendicular to the polar direction ``plane[i]`` [rad]; ``theta_i = 0`` is the arm
    horizontal and pointing along that direction, positive turns it down. The elbow frame
    ``elbow_i`` sits at the arm's end, the anchor ``platform_anchor_i`` on the platform.
    """
    for i in range(len(base)):
        n = i + 1
        b.add(f"theta_{n}", "revolute", "base", f"arm_{n}", xyz=base[i], rpy=(0, 0, plane[i]),
              axis=(0.0, 1.0, 0.0))  # fmt: skip
        b.add(f"elbow_{n}_joint", "fixed", f"arm_{n}", f"elbow_{n}", xyz=(arm, 0.0, 0.0))
        b.add(f"platform_anchor_{n}_joint", "fixed", "platform", f"platform_anchor_{n}",
              xyz=platform[i])  # fmt: skip


def _elbows(base: np.ndarray, plane: np.ndarray, arm: float, theta: np.ndarray) -> np.ndarray:
    radial = np.column_stack([np.cos(plane), np.sin(plane), np.zeros(len(plane))])
    down = np.array([0.0, 0.0, 1.0])
    return base + arm * (np.cos(theta)[:, None] * radial - np.sin(theta)[:, None] * down)


def _symmetric_home(
    base: np.ndarray, plane: np.ndarray, arm: float, rod: float, anchors: np.ndarray, theta: float
) -> float | None:
    """Height z of the level platform centred on the z axis with every arm at ``theta``."""
    E = _elbows(base, plane, arm, np.full(len(base), theta))
    horizontal = np.linalg.norm((E - anchors)[:, :2], axis=1)
    if not np.allclose(horizontal, horizontal[0], rtol=1e-9, atol=1e-12):
        return None
    h2 = rod**2 - horizontal[0] ** 2
    if h2 <= (1e-3 * rod) ** 2:
        return None
    return float(E[0, 2] - math.sqrt(h2))  # the platform below the elbows


def delta(
    base_radius: float,
    platform_radius: float,
    arm: float,
    rod: float,
    home_x: ArrayLike | None = None,
    name: str = "delta",
) -> Model:
    """Clavel's Delta robot: three rotary arms, parallelogram rods, a translating platform.

    The platform rides on three prismatic joints ``px``, ``py``, ``pz`` (it only translates:
    the parallelograms keep it level), so the unknowns are its position. Arm i (actuated
    revolute ``theta_i``) turns about a horizontal axis tangent to the base circle at polar
    angle -90, 30, 150 deg; ``theta_i = 0`` is the arm horizontal pointing outwards, positive
    turns it down. Each parallelogram is a ``distance`` closure of length ``rod`` between the
    elbow and the platform anchor at the same polar angle.

    Args:
        base_radius: distance of the arm axes from the base centre [m].
        platform_radius: distance of the rod ends from the platform centre [m] (may be 0).
        arm: arm length (actuated link) [m].
        rod: parallelogram length [m].
        home_x: (3,) home position (x, y, z) [m]; with the working mode (elbows out) and the
            assembly mode (platform below the elbows). Default: centred, every arm at the first
            of 20, 10, 30, 0, 40 deg down whose rod Jacobian is at least half as well
            conditioned as the best of them.
        name: robot name.

    Returns:
        The model: ``theta`` = the three arm angles [rad], ``x = [x, y, z]``.

    Raises:
        InputError: non-positive lengths, a home position out of reach, or a singular home.
    """
    R = positive(base_radius, "base_radius")
    r = positive(platform_radius, "platform_radius", allow_zero=True)
    arm = positive(arm, "arm")
    rod = positive(rod, "rod")
    plane = np.radians(LEG_ANGLES)
    radial = np.column_stack([np.cos(plane), np.sin(plane), np.zeros(3)])
    base, anchors = R * radial, r * radial
    if home_x is None:

        def score(theta: float) -> float:
            z = _symmetric_home(base, plane, arm, rod, anchors, theta)
            if z is None:
                return 0.0
            d = np.array([0.0, 0.0, z]) + anchors - _elbows(base, plane, arm, np.full(3, theta))
            return conditioning(d / np.linalg.norm(d, axis=1)[:, None])

        theta_h = pick([math.radians(a) for a in (20.0, 10.0, 30.0, 0.0, 40.0)], score)
        if theta_h is None:
            raise InputError(
                f"rod {rod} cannot reach the platform from the arms (base_radius {R}, "
                f"platform_radius {r}, arm {arm}): no regular home pose"
            )
        xh = np.array([0.0, 0.0, _symmetric_home(base, plane, arm, rod, anchors, theta_h)])
        names = "base_radius/platform_radius/arm/rod"
    else:
        xh = points(home_x, (3,), "home_x")
        names = "base_radius/platform_radius/arm/rod/home_x"
    thetas = _rus_inverse(base, plane, arm, rod, xh + anchors, "home_x")
    b = TreeBuilder(name)
    b.add("px", "prismatic", "base", "slider_x", axis=(1.0, 0.0, 0.0))
    b.add("py", "prismatic", "slider_x", "slider_y", axis=(0.0, 1.0, 0.0))
    b.add("pz", "prismatic", "slider_y", "platform", axis=(0.0, 0.0, 1.0))
    _arm_rod_legs(b, base, plane, arm, anchors)
    home = {"px": float(xh[0]), "py": float(xh[1]), "pz": float(xh[2])}
    home.update({f"theta_{i + 1}": float(t) for i, t in enumerate(thetas)})
    spec = Spec(
        closures=tuple(
            Closure(f"elbow_{n}", f"platform_anchor_{n}", "distance", rod) for n in (1, 2, 3)
        ),
        actuated=("theta_1", "theta_2", "theta_3"),
        platform="platform",
        workspace=("x", "y", "z"),
        home=home,
    )
    return finish(b.build(), spec, names)


def _rus_inverse(
    base: np.ndarray, plane: np.ndarray, arm: float, rod: float, targets: np.ndarray, what: str
) -> np.ndarray:
    """Arm angles [rad] putting each elbow at distance ``rod`` from its target, elbow out.

    In the plane of arm i (radial direction e, vertical z), with ``p`` the target relative to
    the arm axis: ``|arm (cos t e - sin t z) - p|^2 = rod^2`` is
    ``a cos t + b sin t = c`` with ``a = 2 arm p.e``, ``b = -2 arm p.z``,
    ``c = arm^2 + |p|^2 - rod^2``: ``t = atan2(b, a) +- acos(c / |(a, b)|)``; the elbow-out
    solution is the one whose elbow lies farther along ``e``.
    """
    out = []
    for i in range(len(base)):
        e = np.array([math.cos(plane[i]), math.sin(plane[i]), 0.0])
        p = targets[i] - base[i]
        a, bb = 2 * arm * float(p @ e), -2 * arm * float(p[2])
        c = arm**2 + float(p @ p) - rod**2
        rho = math.hypot(a, bb)
        if rho == 0 or abs(c) > rho:
            raise InputError(
                f"{what}: anchor {i + 1} at {targets[i].tolist()} is out of reach of its arm "
                f"(arm {arm}, rod {rod})"
            )
        phi, delta_ = math.atan2(bb, a), math.acos(c / rho)
        sols = [phi + delta_, phi - delta_]
        reach = [math.cos(t) for t in sols]  # elbow position along e, relative to the axis
        t = sols[int(np.argmax(reach))]
        out.append(math.atan2(math.sin(t), math.cos(t)))
    return np.array(out)


def _hexa_points(Rb: float, Rp: float, base_spread: float, platform_spread: float):
    """HEXA's arm planes' angles (6,), base pivots (6, 3) and platform anchors (6, 3)."""
    bs = float(base_spread)
    ps = float(platform_spread)
    if not (math.isfinite(bs) and 0 < bs < 2 * math.pi / 3):
        raise InputError(f"base_spread must be in (0, 2 pi / 3) rad, got {base_spread!r}")
    if not (math.isfinite(ps) and 0 <= ps < 2 * math.pi / 3):
        raise InputError(f"platform_spread must be in [0, 2 pi / 3) rad, got {platform_spread!r}")
    centres = np.radians(LEG_ANGLES)
    plane = np.repeat(centres, 2)
    sides = np.tile([-1.0, 1.0], 3)
    tangent = np.column_stack([-np.sin(plane), np.cos(plane), np.zeros(6)])
    radial = np.column_stack([np.cos(plane), np.sin(plane), np.zeros(6)])
    # pivots on the line tangent to the base circle at the pair's centre angle
    base = Rb * radial + (Rb * math.tan(bs / 2)) * sides[:, None] * tangent
    anchor_angles = plane + sides * ps / 2
    anchors = Rp * np.column_stack([np.cos(anchor_angles), np.sin(anchor_angles), np.zeros(6)])
    return plane, base, anchors


def hexa(
    base_radius: float,
    platform_radius: float,
    arm: float,
    rod: float,
    base_spread: float = 0.4,
    platform_spread: float = 1.6,
    home_x: ArrayLike | None = None,
    name: str = "hexa",
) -> Model:
    """Uchiyama's HEXA: six R-U-S legs, rotary actuators on the base, a 6-dof platform.

    The six arm axes lie in the base plane in three pairs: pair k is tangent to the base
    circle at polar angle ``a_k`` = -90, 30, 150 deg, its two axes collinear, the arm pivots at
    polar angles ``a_k -+ base_spread / 2`` on that line; leg (k, j) joins its elbow to the
    platform anchor at polar angle ``a_k -+ platform_spread / 2`` on the platform circle. Arm
    angles as in :func:`delta` (0 horizontal outwards, positive down). The platform hangs on
    a ``floating`` joint; each rod is a ``distance`` closure of length ``rod``.

    Args:
        base_radius: radius of the circle the arm axes are tangent to [m].
        platform_radius: radius of the platform anchor circle [m].
        arm: arm length [m].
        rod: rod length [m].
        base_spread: angle between the two pivots of a pair, seen from the base centre [rad],
            in (0, 2 pi / 3).
        platform_spread: angle between the two anchors of a pair on the platform [rad],
            in [0, 2 pi / 3).
        home_x: (6,) home pose [x, y, z, roll, pitch, yaw] ([m], [rad], URDF rpy). Default:
            level and centred, every arm at the first of 20, 10, 30, 0, 40 deg down whose rod
            Jacobian is at least half as well conditioned as the best of them.
        name: robot name.

    Returns:
        The model: ``theta`` = the six arm angles [rad], ``x = [x, y, z, roll, pitch, yaw]``.

    Raises:
        InputError: non-positive lengths, spreads out of range, a home pose out of reach, or a
            singular home pose.
    """
    Rb = positive(base_radius, "base_radius")
    Rp = positive(platform_radius, "platform_radius")
    arm = positive(arm, "arm")
    rod = positive(rod, "rod")
    plane, base, anchors = _hexa_points(Rb, Rp, base_spread, platform_spread)

    def pose_conditioning(xh: np.ndarray) -> float:
        Rm = rpy_matrix(*xh[3:])
        arms_w = anchors @ Rm.T
        try:
            th = _rus_inverse(base, plane, arm, rod, xh[:3] + arms_w, "home_x")
        except InputError:
            return 0.0
        d = xh[:3] + arms_w - _elbows(base, plane, arm, th)
        J = line_jacobian(d / np.linalg.norm(d, axis=1)[:, None], arms_w, Rp)
        return conditioning(J)

    if home_x is None:

        def candidate(theta: float) -> np.ndarray:
            z = _symmetric_home(base, plane, arm, rod, anchors, theta)
            return np.array([0.0, 0.0, np.nan if z is None else z, 0.0, 0.0, 0.0])

        cands = [candidate(math.radians(a)) for a in (20.0, 10.0, 30.0, 0.0, 40.0)]
        cands = [c for c in cands if np.isfinite(c[2])]
        xh = pick(cands, pose_conditioning) if cands else None
        if xh is None:
            raise InputError(
                f"rod {rod} cannot reach the platform from the arms (base_radius {Rb}, "
                f"platform_radius {Rp}, arm {arm}): no regular home pose"
            )
        names = "base_radius/platform_radius/arm/rod/spreads"
    else:
        xh = points(home_x, (6,), "home_x")
        names = "base_radius/platform_radius/arm/rod/spreads/home_x"
    Rm = rpy_matrix(*xh[3:])
    thetas = _rus_inverse(base, plane, arm, rod, xh[:3] + anchors @ Rm.T, "home_x")
    if pose_conditioning(xh) < 1e-6:
        raise InputError(f"{names} give a singular home pose {xh.tolist()}")
    b = TreeBuilder(name)
    b.add("platform_joint", "floating", "base", "platform")
    _arm_rod_legs(b, base, plane, arm, anchors)
    home = _floating_home(xh)
    home.update({f"theta_{i + 1}": float(t) for i, t in enumerate(thetas)})
    spec = Spec(
        closures=tuple(
            Closure(f"elbow_{n}", f"platform_anchor_{n}", "distance", rod) for n in range(1, 7)
        ),
        actuated=tuple(f"theta_{n}" for n in range(1, 7)),
        platform="platform",
        workspace=SPATIAL_WORKSPACE,
        home=home,
    )
    return finish(b.build(), spec, names)


# ---------------------------------------------------------------------------- 3-RPS


def three_rps(
    base_radius: float,
    platform_radius: float,
    *,
    angles: ArrayLike = (math.pi / 2, 7 * math.pi / 6, 11 * math.pi / 6),
    height: float | None = None,
    name: str = "3rps",
) -> Model:
    """The 3-RPS parallel manipulator: three revolute-prismatic-spherical legs, the prismatic
    joints actuated (``theta = leg lengths``), a platform with three freedoms.

    Leg i rises from base point ``base_radius (cos a_i, sin a_i, 0)`` on a revolute joint
    ``rev_i`` whose axis is tangent to the base circle there, so the leg swings in the
    vertical plane through the centre; its prismatic joint ``leg_i`` runs along the leg, and
    a ball joint (a ``3d`` point closure) joins its end to the platform point
    ``platform_radius (cos a_i, sin a_i, 0)``. The platform is free (a ``floating`` joint:
    ``x = [x, y, z, roll, pitch, yaw]``); its pose has three freedoms, the other three
    (parasitic motions) follow. The direct kinematics has 16 complex solutions for general
    leg lengths.

    Args:
        base_radius: radius of the base circle [m].
        platform_radius: radius of the platform circle [m].
        angles: (3,) polar angles ``a_i`` of the legs [rad], distinct modulo 2 pi.
        height: platform height at home [m] (level, centred): default ``base_radius``.
        name: robot name.

    Returns:
        The loaded model; ``home`` is the level platform at ``height``.

    Raises:
        InputError: a non-positive radius or height, or angles that are not three distinct
            values.
    """
    Rb = positive(base_radius, "base_radius")
    Rp = positive(platform_radius, "platform_radius")
    h = Rb if height is None else positive(height, "height")
    a = points(angles, (3,), "angles")
    gaps = np.abs((a[:, None] - a[None, :] + math.pi) % (2 * math.pi) - math.pi)
    if np.any(gaps[~np.eye(3, dtype=bool)] < 1e-6):
        raise InputError(f"angles must be three distinct values modulo 2 pi, got {a.tolist()}")
    b = TreeBuilder(name)
    b.add("platform_joint", "floating", "base", "platform")
    home = _floating_home(np.array([0.0, 0.0, h, 0.0, 0.0, 0.0]))
    closures = []
    for i, ai in enumerate(a):
        n = i + 1
        radial = np.array([math.cos(ai), math.sin(ai), 0.0])
        tangent = np.array([-math.sin(ai), math.cos(ai), 0.0])
        b.add(f"rev_{n}", "revolute", "base", f"swing_{n}", xyz=list(Rb * radial),
              axis=list(tangent), limits=(-math.pi, math.pi))  # fmt: skip
        b.add(f"leg_{n}", "prismatic", f"swing_{n}", f"leg_{n}_end", limits=(0.0, 1e3))
        b.add(f"platform_anchor_{n}_joint", "fixed", "platform", f"platform_anchor_{n}",
              xyz=list(Rp * radial))  # fmt: skip
        # the leg (along the swing's z) turned about the tangent towards -radial
        home[f"rev_{n}"] = math.atan2(Rp - Rb, h)
        home[f"leg_{n}"] = math.hypot(Rp - Rb, h)
        closures.append(Closure(f"leg_{n}_end", f"platform_anchor_{n}", "3d"))
    spec = Spec(
        closures=tuple(closures),
        actuated=tuple(f"leg_{n}" for n in range(1, 4)),
        platform="platform",
        workspace=SPATIAL_WORKSPACE,
        home=home,
    )
    return finish(b.build(), spec, "base_radius/platform_radius/angles/height")
