"""Round trips pose -> inverse kinematics -> SC direct kinematics on every shipped builder model,
checked against Pinocchio and against references written here from first principles.

For each model, ``N_POSES`` random poses are drawn (seeded) in a box around home; the actuated
values come from ``model.inverse_kinematics``, the start from the inverse kinematics of a pose
near the target, and ``sc.solve(..., branch="convergent")`` must return the pose. Independent
references (not calling the package): leg-length / rod-length equations for every model, the
three-sphere intersection of the Delta (both solutions), the circle intersection of the
five-bar (both solutions) and the classical reduction of the 3-RPR to one polynomial in
``t = tan(phi / 2)`` (every real root).
"""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest

import scdk_sym as sc
from scdk_sym.solvers.solve import solve
from scdk_sym.verify.pinocchio import closure_residuals, placement_error

MODELS = Path(__file__).resolve().parents[1] / "models"
N_POSES = 200
#: Max pose error of a round trip [m, and rotation-matrix entries].
POSE_TOL = 1e-9
#: Max closure residual of a solution [m].
RESIDUAL_TOL = 1e-12

#: name -> (seed, half-widths of the sampling box around home, in workspace coordinates)
BOXES = {
    "stewart_gough": (11, [0.06, 0.06, 0.06, 0.2, 0.2, 0.35]),
    "planar_3rpr": (12, [0.06, 0.06, 0.25]),
    "delta": (13, [0.06, 0.06, 0.03]),
    "hexa": (14, [0.04, 0.04, 0.04, 0.15, 0.15, 0.3]),
    "five_bar": (15, [0.08, 0.06]),
}


# ---------------------------------------------------------------------------- first principles


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def pose_matrix(workspace: tuple[str, ...], x: np.ndarray) -> np.ndarray:
    """4x4 placement of workspace coordinates (URDF rpy: R = Rz(yaw) Ry(pitch) Rx(roll))."""
    v = dict(zip(workspace, x, strict=True))
    T = np.eye(4)
    T[:3, 3] = [v.get("x", 0.0), v.get("y", 0.0), v.get("z", 0.0)]
    if "phi" in v:
        T[:3, :3] = rot_z(v["phi"])
    elif "yaw" in v:
        T[:3, :3] = rot_z(v["yaw"]) @ rot_y(v["pitch"]) @ rot_x(v["roll"])
    return T


def anchors(model: sc.Model, prefix: str) -> np.ndarray:
    """(n, 3) origins of the fixed frames ``<prefix>_<i>`` in their parent link (from the URDF)."""
    out = []
    i = 1
    while True:
        joints = [j for j in model.tree.joints if j.child == f"{prefix}_{i}"]
        if not joints:
            return np.array(out)
        out.append(joints[0].origin[:3, 3])
        i += 1


def arm_pivots(model: sc.Model) -> tuple[np.ndarray, np.ndarray]:
    """Pivot positions (n, 3) and polar plane angles (n,) of the actuated arms."""
    pivots, planes = [], []
    for name in model.actuated:
        o = model.tree.joint(name).origin
        pivots.append(o[:3, 3])
        planes.append(math.atan2(o[1, 0], o[0, 0]))
    return np.array(pivots), np.array(planes)


def spatial_elbows(pivots, planes, arm: float, theta: np.ndarray) -> np.ndarray:
    """Elbows of arms turning down from the horizontal outward direction by theta [rad]."""
    radial = np.column_stack([np.cos(planes), np.sin(planes), np.zeros(len(planes))])
    return pivots + arm * (np.cos(theta)[:, None] * radial - np.sin(theta)[:, None] * [0, 0, 1])


def arm_length(model: sc.Model) -> float:
    return float(np.linalg.norm(model.tree.joint("elbow_1_joint").origin[:3, 3]))


def rod_length(model: sc.Model) -> np.ndarray:
    return np.array([c.length for c in model.closures])


def leg_equations(name: str, model: sc.Model, theta: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Residuals [m] of the mechanism's defining equations at actuated values and pose T."""
    p, R = T[:3, 3], T[:3, :3]
    if name in ("stewart_gough", "planar_3rpr"):
        a = anchors(model, "base_anchor")
        b = anchors(model, "platform_anchor")
        return np.linalg.norm(p + b @ R.T - a, axis=1) - theta
    if name in ("delta", "hexa"):
        pivots, planes = arm_pivots(model)
        E = spatial_elbows(pivots, planes, arm_length(model), theta)
        b = anchors(model, "platform_anchor")
        return np.linalg.norm(p + b @ R.T - E, axis=1) - rod_length(model)
    if name == "five_bar":
        pivots, _ = arm_pivots(model)
        arm = arm_length(model)
        E = pivots[:, :2] + arm * np.column_stack([np.cos(theta), np.sin(theta)])
        return np.linalg.norm(p[:2] - E, axis=1) - rod_length(model)
    raise AssertionError(name)


# ---------------------------------------------------------------------------- round trips


@cache
def model(name: str) -> sc.Model:
    return sc.load_model(MODELS / name)


@cache
def round_trips(name: str) -> list[tuple[np.ndarray, np.ndarray, sc.SolveResult]]:
    """(target x, its actuated values, the DK result) for N_POSES random poses."""
    m = model(name)
    seed, box = BOXES[name]
    rng = np.random.default_rng(seed)
    box = np.array(box)
    out = []
    for _ in range(N_POSES):
        x = m.home.x + rng.uniform(-1.0, 1.0, box.size) * box
        target = m.inverse_kinematics(x)
        start = m.inverse_kinematics(x + rng.uniform(-0.02, 0.02, box.size) * box)
        res = solve(m, target.theta, start=start, branch="convergent", record_path=False)
        out.append((x, target.theta, res))
    return out


def pose_error(T: np.ndarray, T_ref: np.ndarray) -> float:
    return float(np.abs(T - T_ref).max())


NAMES = list(BOXES)


@pytest.mark.parametrize("name", NAMES)
def test_round_trip_returns_the_pose(name: str) -> None:
    m = model(name)
    trips = round_trips(name)
    assert len(trips) >= 200
    errors = [pose_error(r.platform_pose, pose_matrix(m.workspace, x)) for x, _, r in trips]
    assert max(errors) <= POSE_TOL, (name, max(errors))
    assert all(r.branch == "convergent" and not r.crossings for _, _, r in trips)


@pytest.mark.parametrize("name", NAMES)
def test_round_trip_satisfies_first_principles(name: str) -> None:
    m = model(name)
    worst = 0.0
    for x, theta, r in round_trips(name):
        np.testing.assert_array_equal(r.theta, theta)
        worst = max(worst, np.abs(leg_equations(name, m, theta, pose_matrix(m.workspace, x))).max())
        worst = max(worst, np.abs(leg_equations(name, m, theta, r.platform_pose)).max())
    assert worst <= RESIDUAL_TOL, worst


@pytest.mark.parametrize("name", NAMES)
def test_round_trip_pinocchio_closures(name: str) -> None:
    m = model(name)
    worst = max(closure_residuals(m, r.joints).max() for _, _, r in round_trips(name))
    assert worst <= RESIDUAL_TOL, worst


@pytest.mark.parametrize("name", NAMES)
def test_symbolic_placements_match_pinocchio(name: str) -> None:
    m = model(name)
    trips = round_trips(name)[:25]
    worst = max(placement_error(m, r.y, r.theta) for _, _, r in trips)
    assert worst <= 1e-12, worst
    assert placement_error(m, m.home.y, m.home.theta) <= 1e-12


# ---------------------------------------------------------------------------- references


def sphere_intersections(centres: np.ndarray, radius: float) -> list[np.ndarray]:
    """Both points at distance ``radius`` from three centres (empty if none)."""
    c1, c2, c3 = centres
    # 2 (c_i - c_1) . P = |c_i|^2 - |c_1|^2, i = 2, 3: a line P0 + s n
    A = 2 * np.array([c2 - c1, c3 - c1])
    rhs = np.array([c2 @ c2 - c1 @ c1, c3 @ c3 - c1 @ c1])
    P0 = np.linalg.lstsq(A, rhs, rcond=None)[0]
    n = np.cross(c2 - c1, c3 - c1)
    n /= np.linalg.norm(n)
    # |P0 + s n - c1|^2 = radius^2
    d = P0 - c1
    b, c = 2 * n @ d, d @ d - radius**2
    disc = b * b - 4 * c
    if disc < 0:
        return []
    return [P0 + s * n for s in ((-b - math.sqrt(disc)) / 2, (-b + math.sqrt(disc)) / 2)]


def test_delta_matches_three_sphere_intersection() -> None:
    m = model("delta")
    pivots, planes = arm_pivots(m)
    b = anchors(m, "platform_anchor")
    arm, rod = arm_length(m), rod_length(m)[0]
    worst_ours, worst_other = 0.0, np.inf
    for _, theta, r in round_trips("delta"):
        # platform origin P: |P + b_i - E_i| = rod, spheres about E_i - b_i
        sols = sphere_intersections(spatial_elbows(pivots, planes, arm, theta) - b, rod)
        assert len(sols) == 2
        dists = [np.linalg.norm(r.x - s) for s in sols]
        i = int(np.argmin(dists))
        worst_ours = max(worst_ours, dists[i])
        worst_other = min(worst_other, dists[1 - i])
        # ours is the lower one (the working assembly mode of home: platform below the elbows)
        assert sols[i][2] < sols[1 - i][2]
    assert worst_ours <= POSE_TOL, worst_ours
    assert worst_other > 1e-3  # the two solutions are distinct: the match is not by chance


def circle_intersections(c1, c2, r1: float, r2: float) -> list[np.ndarray]:
    d = float(np.linalg.norm(c2 - c1))
    a = (d * d + r1 * r1 - r2 * r2) / (2 * d)
    h2 = r1 * r1 - a * a
    if h2 < 0:
        return []
    u = (c2 - c1) / d
    mid = c1 + a * u
    perp = np.array([-u[1], u[0]])
    return [mid + math.sqrt(h2) * perp, mid - math.sqrt(h2) * perp]


def test_five_bar_matches_circle_intersection() -> None:
    m = model("five_bar")
    pivots, _ = arm_pivots(m)
    arm = arm_length(m)
    rods = rod_length(m)
    worst_ours, worst_other = 0.0, np.inf
    for _, theta, r in round_trips("five_bar"):
        E = pivots[:, :2] + arm * np.column_stack([np.cos(theta), np.sin(theta)])
        sols = circle_intersections(E[0], E[1], rods[0], rods[1])
        assert len(sols) == 2
        dists = [np.linalg.norm(r.x - s) for s in sols]
        i = int(np.argmin(dists))
        worst_ours = max(worst_ours, dists[i])
        worst_other = min(worst_other, dists[1 - i])
        # ours is on the left of E1 -> E2 (the assembly mode of home, above the elbows)
        e = E[1] - E[0]
        assert e[0] * (r.x[1] - E[0, 1]) - e[1] * (r.x[0] - E[0, 0]) > 0
    assert worst_ours <= POSE_TOL, worst_ours
    assert worst_other > 1e-3


P = np.polynomial.polynomial


def _trig(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """alpha + beta cos(phi) + gamma sin(phi), times (1 + t^2), as a polynomial in t."""
    return P.polyadd(P.polyadd(alpha * np.array([1, 0, 1.0]), beta * np.array([1, 0, -1.0])),
                     gamma * np.array([0, 2.0]))  # fmt: skip


def rpr_solutions(a: np.ndarray, c: np.ndarray, rho: np.ndarray) -> list[np.ndarray]:
    """Every real assembly [x, y, phi] of a 3-RPR with base pivots a (3, 2), platform pivots c
    (3, 2) in the platform frame and leg lengths rho (3,).

    With e_i = R(phi) c_i - a_i, the differences of the leg equations
    ``|p + e_i|^2 = rho_i^2`` are linear in p: ``M(phi) p = v(phi)``; p = adj(M) v / det M in
    the first equation gives one polynomial in ``t = tan(phi / 2)``, of degree 12 here (the
    factor (1 + t^2)^3 of the classical sextic is kept), whose real roots are the solutions.
    """

    def e_coeffs(i):  # e_i = (Rc_i - a_i): components as (alpha, beta, gamma)
        cx, cy = c[i]
        return [(-a[i, 0], cx, -cy), (-a[i, 1], cy, cx)]

    def sq_coeffs(i):  # |e_i|^2 = |c_i|^2 + |a_i|^2 - 2 a_i . R c_i
        ax, ay = a[i]
        cx, cy = c[i]
        return (c[i] @ c[i] + a[i] @ a[i], -2 * (ax * cx + ay * cy), -2 * (ay * cx - ax * cy))

    M = [[None, None], [None, None]]
    v = [None, None]
    for row, i in enumerate((1, 2)):
        for col in range(2):
            ai, a1 = e_coeffs(i)[col], e_coeffs(0)[col]
            M[row][col] = _trig(*(2 * (p - q) for p, q in zip(ai, a1, strict=True)))
        si, s1 = sq_coeffs(i), sq_coeffs(0)
        const = -(si[0] - s1[0]) + rho[i] ** 2 - rho[0] ** 2
        v[row] = _trig(const, -(si[1] - s1[1]), -(si[2] - s1[2]))
    D = P.polysub(P.polymul(M[0][0], M[1][1]), P.polymul(M[0][1], M[1][0]))
    N = [
        P.polysub(P.polymul(M[1][1], v[0]), P.polymul(M[0][1], v[1])),
        P.polysub(P.polymul(M[0][0], v[1]), P.polymul(M[1][0], v[0])),
    ]
    w = np.array([1, 0, 1.0])
    e1 = [_trig(*k) for k in e_coeffs(0)]
    comps = [P.polyadd(P.polymul(w, N[k]), P.polymul(D, e1[k])) for k in range(2)]
    poly = P.polysub(
        P.polyadd(P.polymul(comps[0], comps[0]), P.polymul(comps[1], comps[1])),
        rho[0] ** 2 * P.polymul(P.polymul(D, D), P.polymul(w, w)),
    )
    poly = P.polytrim(poly / np.abs(poly).max(), 1e-14)
    roots = P.polyroots(poly)
    phis = [2 * math.atan(t.real) for t in roots if abs(t.imag) <= 1e-7 * (1 + abs(t))]
    if len(poly) < 13:  # degree dropped: a root at t = infinity (phi = pi)
        phis.append(math.pi)
    out = []
    for phi in phis:
        R = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
        e = c @ R.T - a
        A = 2 * np.array([e[1] - e[0], e[2] - e[0]])
        rhs = -np.array([e[k] @ e[k] - e[0] @ e[0] - rho[k] ** 2 + rho[0] ** 2 for k in (1, 2)])
        try:
            p = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError:
            continue
        z = np.array([*p, phi])
        for _ in range(6):  # Newton polish on the three leg equations
            R = np.array([[math.cos(z[2]), -math.sin(z[2])], [math.sin(z[2]), math.cos(z[2])]])
            d = z[:2] + c @ R.T - a
            F = np.sum(d * d, axis=1) - rho**2
            dR = np.array([[-math.sin(z[2]), -math.cos(z[2])], [math.cos(z[2]), -math.sin(z[2])]])
            J = np.column_stack([2 * d, 2 * np.sum(d * (c @ dR.T), axis=1)])
            try:
                z = z - np.linalg.solve(J, F)
            except np.linalg.LinAlgError:
                break
        R = np.array([[math.cos(z[2]), -math.sin(z[2])], [math.sin(z[2]), math.cos(z[2])]])
        if np.abs(np.linalg.norm(z[:2] + c @ R.T - a, axis=1) - rho).max() < 1e-10:
            z[2] = math.atan2(math.sin(z[2]), math.cos(z[2]))
            if all(np.abs(z - s).max() > 1e-8 for s in out):
                out.append(z)
    return out


def test_rpr_reference_finds_a_known_assembly() -> None:
    # a pose chosen here: the reference must return it among its solutions
    a = np.array([[0.0, 0.0], [1.0, 0.0], [0.4, 0.9]])
    c = np.array([[0.0, 0.0], [0.3, 0.0], [0.1, 0.25]])
    rng = np.random.default_rng(5)
    for _ in range(20):
        z = np.array([*rng.uniform(0.1, 0.6, 2), rng.uniform(-math.pi, math.pi)])
        R = np.array([[math.cos(z[2]), -math.sin(z[2])], [math.sin(z[2]), math.cos(z[2])]])
        rho = np.linalg.norm(z[:2] + c @ R.T - a, axis=1)
        sols = rpr_solutions(a, c, rho)
        assert min(np.abs(s - z).max() for s in sols) < 1e-9
        assert len(sols) in (2, 4, 6)


def test_rpr_dk_is_a_root_of_the_polynomial() -> None:
    m = model("planar_3rpr")
    a = anchors(m, "base_anchor")[:, :2]
    c = anchors(m, "platform_anchor")[:, :2]
    worst, counts = 0.0, set()
    for _, theta, r in round_trips("planar_3rpr"):
        sols = rpr_solutions(a, c, theta)
        counts.add(len(sols))
        d = [np.abs(np.r_[r.x[:2] - s[:2], math.remainder(r.x[2] - s[2], 2 * math.pi)]).max()
             for s in sols]  # fmt: skip
        worst = max(worst, min(d))
    assert worst <= POSE_TOL, worst
    assert max(counts) >= 2  # other assembly modes exist: membership is a real check


def test_rpr_every_real_root_is_reached_from_a_start_near_it() -> None:
    m = model("planar_3rpr")
    a = anchors(m, "base_anchor")[:, :2]
    c = anchors(m, "platform_anchor")[:, :2]
    rng = np.random.default_rng(8)
    for _ in range(200):  # leg lengths with four real assembly modes
        z = np.array([*rng.uniform(-0.5, 1.5, 2), rng.uniform(-math.pi, math.pi)])
        R = np.array([[math.cos(z[2]), -math.sin(z[2])], [math.sin(z[2]), math.cos(z[2])]])
        rho = np.linalg.norm(z[:2] + c @ R.T - a, axis=1)
        sols = rpr_solutions(a, c, rho)
        if len(sols) >= 4:
            break
    assert len(sols) >= 4
    for s in sols:
        start = m.inverse_kinematics(s + np.array([1e-3, -1e-3, 2e-3]))
        res = solve(m, rho, start=start, record_path=False)
        d = np.r_[res.x[:2] - s[:2], math.remainder(res.x[2] - s[2], 2 * math.pi)]
        assert np.abs(d).max() <= POSE_TOL, (s, res.x)
