"""Assembly modes: every real direct-kinematics solution, against independent references.

References written here from first principles, sharing no code with the package:

* Delta: intersection of three spheres (radius = rod) centred at the elbows shifted by the
  platform anchors.
* planar 3-RPR (and the seed 3-RRR, a 3-RPR between its elbows and the platform): the
  univariate polynomial in ``t = tan(phi / 2)`` obtained by solving the two differences of
  the leg equations for the position (Cramer) and substituting into the first.
* 6-6 Stewart-Gough: exhaustive random-start Levenberg-Marquardt on the leg equations
  (thousands of starts, vectorised numpy), deduplicated.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from factories import needs_compiler, shipped
from numpy.polynomial import Polynomial
from stewart import (
    DIETMAIER_BASE,
    DIETMAIER_LENGTHS,
    DIETMAIER_PLATFORM,
    random_platform,
    stewart_reference,
)

import scdk_sym as sc
from scdk_sym.errors import InputError, NotAssembledError
from scdk_sym.solvers.modes import explore


def curve_modes(*args, **kwargs):
    """The real-curve search (``method=\"curves\"``), which this module tests."""
    return sc.assembly_modes(*args, method="curves", **kwargs)


# ---------------------------------------------------------------------------- references


def rot2(phi: float) -> np.ndarray:
    return np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])


def rpr_reference(A: np.ndarray, C: np.ndarray, rho: np.ndarray) -> list[np.ndarray]:
    """All real poses (x, y, phi) of a 3-RPR: |p + R(phi) C_i - A_i| = rho_i, i = 1..3.

    With D = 1 + t^2 and D R = [[1 - t^2, -2t], [2t, 1 - t^2]], the differences (leg i minus
    leg 1, i = 2, 3) are linear in p: M(t) p = r(t) with polynomial entries. Cramer gives
    p = N / det M; leg 1 times D det M^2 is a polynomial in t whose real roots contain every
    solution (phi = pi is checked apart). Each root is polished by Newton on the three leg
    equations and kept if they hold to 1e-9.
    """
    t = Polynomial([0.0, 1.0])
    one = Polynomial([1.0])
    D = one + t * t
    DR = [[one - t * t, -2 * t], [2 * t, one - t * t]]

    def rotated(b):
        return [DR[0][0] * b[0] + DR[0][1] * b[1], DR[1][0] * b[0] + DR[1][1] * b[1]]

    def dot(u, v):
        return u[0] * v[0] + u[1] * v[1]

    rows, rhs = [], []
    for i in (1, 2):
        Rd = rotated(C[i] - C[0])
        rows.append([2 * (Rd[k] - D * (A[i][k] - A[0][k])) for k in range(2)])
        norms = C[i] @ C[i] + A[i] @ A[i] - C[0] @ C[0] - A[0] @ A[0]
        rhs.append(
            D * (rho[i] ** 2 - rho[0] ** 2)
            - (D * norms - 2 * dot(A[i], rotated(C[i])) + 2 * dot(A[0], rotated(C[0])))
        )
    det = rows[0][0] * rows[1][1] - rows[0][1] * rows[1][0]
    N = [rows[1][1] * rhs[0] - rows[0][1] * rhs[1], rows[0][0] * rhs[1] - rows[1][0] * rhs[0]]
    RC1 = rotated(C[0])
    poly = (
        D * dot(N, N)
        + 2 * det * dot(N, [RC1[k] - D * A[0][k] for k in range(2)])
        + det * det * (D * (C[0] @ C[0] + A[0] @ A[0] - rho[0] ** 2) - 2 * dot(A[0], RC1))
    )
    phis = [2 * np.arctan(r.real) for r in poly.roots() if abs(r.imag) <= 1e-6 * max(1, abs(r))]
    sols: list[np.ndarray] = []
    for phi in [*phis, np.pi]:
        R = rot2(phi)
        M = np.array([2 * (R @ (C[i] - C[0]) - (A[i] - A[0])) for i in (1, 2)])
        if abs(np.linalg.det(M)) < 1e-12:
            continue
        r = [
            rho[i] ** 2
            - rho[0] ** 2
            - np.sum((R @ C[i] - A[i]) ** 2)
            + np.sum((R @ C[0] - A[0]) ** 2)
            for i in (1, 2)
        ]
        x = np.append(np.linalg.solve(M, r), phi)
        for _ in range(20):
            R, dR = rot2(x[2]), rot2(x[2] + np.pi / 2)
            d = x[:2] + C @ R.T - A
            F = np.sum(d * d, axis=1) - rho**2
            J = np.column_stack([2 * d, 2 * np.sum(d * (C @ dR.T), axis=1)])
            x = x - np.linalg.solve(J, F)
        if np.max(np.abs(np.linalg.norm(x[:2] + C @ rot2(x[2]).T - A, axis=1) - rho)) < 1e-9:
            x[2] = np.angle(np.exp(1j * x[2]))
            if not any(pose_distance(x, s) < 1e-7 for s in sols):
                sols.append(x)
    return sols


def pose_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Max difference of two planar poses (x, y, phi), phi modulo 2 pi."""
    return max(
        float(np.max(np.abs(a[:2] - b[:2]))), abs(float(np.angle(np.exp(1j * (a[2] - b[2])))))
    )


def delta_reference(R: float, r: float, arm: float, rod: float, theta: np.ndarray) -> list:
    """Platform positions of a Delta at arm angles theta: three spheres of radius rod.

    Arm i turns about the horizontal axis tangent to the base circle at polar angle -90, 30,
    150 deg; theta = 0 points it outwards, positive turns it down. The platform centre p is
    at distance rod from each sphere centre elbow_i - r e_i.
    """
    polar = np.radians([-90.0, 30.0, 150.0])
    e = np.column_stack([np.cos(polar), np.sin(polar), np.zeros(3)])
    down = np.array([0.0, 0.0, 1.0])
    elbows = R * e + arm * (np.cos(theta)[:, None] * e - np.sin(theta)[:, None] * down)
    S = elbows - r * e
    M = 2 * (S[1:] - S[0])  # |p - S_i|^2 - |p - S_1|^2 = 0, i = 2, 3: linear in p
    rhs = np.sum(S[1:] ** 2, axis=1) - S[0] @ S[0]
    n = np.cross(S[1] - S[0], S[2] - S[0])
    p0 = np.linalg.lstsq(M, rhs, rcond=None)[0]
    w = p0 - S[0]
    a, b, c = n @ n, 2 * n @ w, w @ w - rod**2  # |p0 + lam n - S_1|^2 = rod^2
    disc = b * b - 4 * a * c
    if disc < 0:
        return []
    return [
        p0 + lam * n for lam in ((-b - np.sqrt(disc)) / (2 * a), (-b + np.sqrt(disc)) / (2 * a))
    ]


# ---------------------------------------------------------------------------- helpers


def assert_same_stewart_poses(found, reference, tol=1e-6):
    poses = [(c.platform_pose[:3, 3], c.platform_pose[:3, :3]) for c in found]
    for p, R in reference:
        assert min(max(np.abs(p - q).max(), np.abs(R - S).max()) for q, S in poses) < tol
    assert len(found) == len(reference)


def assert_verified_distinct_sorted(model, sols):
    for c in sols:
        assert c.residual <= model.tolerance
        assert model.residual(c.y, c.theta) <= model.tolerance
    X = np.array([c.x for c in sols])
    for i in range(len(X)):
        for j in range(i):
            assert np.abs(sols[i].platform_pose - sols[j].platform_pose).max() > 1e-6
    keys = [tuple(np.round(x, 8)) for x in X]
    assert keys == sorted(keys)


@cache
def rpr_geometries_with_six() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """3-RPR geometries with leg lengths of six real assembly modes (seeded search)."""
    rng = np.random.default_rng(0)
    out = []
    while len(out) < 2:
        A, C, rho = (
            rng.uniform(-1, 1, (3, 2)),
            rng.uniform(-0.6, 0.6, (3, 2)),
            rng.uniform(0.3, 1.5, 3),
        )
        if len(rpr_reference(A, C, rho)) == 6:
            out.append((A, C, rho))
    return out


# ---------------------------------------------------------------------------- Delta


def test_delta_finds_both_sphere_intersections():
    R, r, arm, rod = 0.2, 0.05, 0.25, 0.5
    model = sc.builders.delta(R, r, arm, rod)
    rng = np.random.default_rng(3)
    for _ in range(4):
        theta = model.home.theta + rng.uniform(-0.6, 0.6, 3)
        ref = delta_reference(R, r, arm, rod, theta)
        assert len(ref) == 2
        sols = curve_modes(model, theta, seed=1)
        assert len(sols) == 2
        for p in ref:
            assert min(np.abs(c.x - p).max() for c in sols) < 1e-9
        assert_verified_distinct_sorted(model, sols)


def test_delta_out_of_reach_gives_no_solution():
    R, r, arm, rod = 0.2, 0.05, 0.25, 0.5
    model = sc.builders.delta(R, r, arm, rod)
    rng = np.random.default_rng(0)
    theta = rng.uniform(-np.pi, np.pi, 3)
    while delta_reference(R, r, arm, rod, theta):  # arm angles the rods cannot close
        theta = rng.uniform(-np.pi, np.pi, 3)
    search = explore(model, theta, seed=0)
    assert search.solutions == []
    assert search.complete


# ---------------------------------------------------------------------------- 3-RPR


def test_rpr_reference_agrees_with_brute_force_newton():
    A, C, rho = rpr_geometries_with_six()[0]
    ref = rpr_reference(A, C, rho)
    rng = np.random.default_rng(1)
    found: list[np.ndarray] = []
    for _ in range(800):
        x = np.array([*rng.uniform(-3, 3, 2), rng.uniform(-np.pi, np.pi)])
        for _ in range(40):
            R, dR = rot2(x[2]), rot2(x[2] + np.pi / 2)
            d = x[:2] + C @ R.T - A
            J = np.column_stack([2 * d, 2 * np.sum(d * (C @ dR.T), axis=1)])
            if abs(np.linalg.det(J)) < 1e-12:
                break
            x = x - np.linalg.solve(J, np.sum(d * d, axis=1) - rho**2)
        d = x[:2] + C @ rot2(x[2]).T - A
        closed = np.all(np.isfinite(x)) and np.max(np.abs(np.linalg.norm(d, axis=1) - rho)) < 1e-10
        if closed and not any(pose_distance(x, s) < 1e-7 for s in found):
            found.append(x)
    assert len(ref) == len(found) == 6
    for s in ref:
        assert min(pose_distance(s, f) for f in found) < 1e-8


@pytest.mark.parametrize("case", [0, 1])
def test_rpr_six_real_solutions(case):
    A, C, rho = rpr_geometries_with_six()[case]
    model = sc.builders.planar_3rpr(A, C)
    sols = curve_modes(model, rho, seed=case)
    ref = rpr_reference(A, C, rho)
    assert len(ref) == 6
    assert len(sols) == 6
    for s in ref:
        assert min(pose_distance(c.x, s) for c in sols) < 1e-8
    assert_verified_distinct_sorted(model, sols)


def test_rpr_random_geometries_every_count():
    rng = np.random.default_rng(7)
    counts = set()
    for _ in range(10):
        A, C, rho = (
            rng.uniform(-1, 1, (3, 2)),
            rng.uniform(-0.6, 0.6, (3, 2)),
            rng.uniform(0.3, 1.5, 3),
        )
        ref = rpr_reference(A, C, rho)
        sols = curve_modes(sc.builders.planar_3rpr(A, C), rho)
        assert len(sols) == len(ref)
        for s in ref:
            assert min(pose_distance(c.x, s) for c in sols) < 1e-8
        counts.add(len(ref))
    assert {0, 2, 4} <= counts  # the sample exercises empty, small and larger sets


@pytest.mark.parametrize("name", ["planar_hexa", "planar_hexa_reduced"])
def test_seed_robot_is_a_3rpr_between_its_elbows(name):
    """The paper's example: its two solutions (phi = 0.2074, 0.9999) are all there is."""
    g = sc.builders.seed_geometry()
    model = shipped(name)
    theta = np.array([1.292, -0.802, -2.896])
    elbows = g["base_points"] + g["arm"] * np.c_[np.cos(theta), np.sin(theta)]
    ref = rpr_reference(elbows, g["platform_points"], np.full(3, g["rod"]))
    sols = curve_modes(model, theta)
    assert len(ref) == len(sols) == 2
    for s in ref:
        assert min(pose_distance(c.x, s) for c in sols) < 1e-8
    assert sorted(round(float(c.x[2]), 4) for c in sols) == [0.2075, 0.9999]


# ---------------------------------------------------------------------------- 6-6


def test_dietmaier_platform_has_40_real_assembly_modes():
    ref = stewart_reference(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS, 3000, seed=5)
    assert len(ref) == 40
    model = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    search = explore(model, DIETMAIER_LENGTHS, seed=0)
    assert search.complete
    assert_same_stewart_poses(search.solutions, ref)
    assert_verified_distinct_sorted(model, search.solutions)


@pytest.mark.parametrize(("platform", "count"), [(2, 6), (18, 10)])
def test_random_6_6_platforms_against_random_start_reference(platform, count):
    """Platforms whose modes below the base are reached by few solution curves."""
    A, B, lengths = random_platform(platform)
    ref = stewart_reference(A, B, lengths, 6000, seed=platform)
    assert len(ref) == count
    model = sc.builders.stewart_gough(A, B)
    for seed in (0, 1):
        sols = curve_modes(model, lengths, seed=seed)
        assert_same_stewart_poses(sols, ref)


# ---------------------------------------------------------------------------- options


@needs_compiler()
def test_deterministic_for_a_seed_and_backends_agree():
    A, C, rho = rpr_geometries_with_six()[0]
    model = sc.builders.planar_3rpr(A, C)
    a = curve_modes(model, rho, seed=4)
    b = curve_modes(model, rho, seed=4)
    assert [c.x.tolist() for c in a] == [c.x.tolist() for c in b]
    compiled = curve_modes(model, rho, seed=4, backend="compiled")
    assert len(compiled) == len(a)
    for c, d in zip(a, compiled, strict=True):
        assert np.abs(c.x - d.x).max() < 1e-9


def test_time_budget_stops_early_and_says_so():
    model = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    search = explore(model, DIETMAIER_LENGTHS, time_budget=0.05)
    assert not search.complete
    assert search.elapsed < 1.0
    assert len(search.solutions) < 40
    for c in search.solutions:
        assert c.residual <= model.tolerance


def test_progress_bar_on_stderr(capsys):
    pytest.importorskip("tqdm")
    A, C, rho = rpr_geometries_with_six()[1]
    curve_modes(sc.builders.planar_3rpr(A, C), rho, progress=True)
    assert "assembly modes" in capsys.readouterr().err


def test_bad_inputs_raise_package_errors():
    model = shipped("planar_3rpr")
    with pytest.raises(InputError, match="theta0"):
        curve_modes(model, [0.4, 0.5])
    with pytest.raises(InputError, match="finite"):
        curve_modes(model, [0.4, np.nan, 0.4])
    with pytest.raises(InputError, match="backends: auto, compiled, cvodes"):
        curve_modes(model, [0.4, 0.5, 0.4], backend="cuda")
    with pytest.raises(InputError, match="time_budget"):
        curve_modes(model, [0.4, 0.5, 0.4], time_budget=0)
    with pytest.raises(InputError, match="patience"):
        curve_modes(model, [0.4, 0.5, 0.4], patience=-1)
    broken = sc.Configuration(
        model.home.theta, model.home.y + 0.1, model.home.x, model.home.platform_pose, {}
    )
    with pytest.raises(NotAssembledError):
        curve_modes(model, [0.4, 0.5, 0.4], start=broken)


def test_images_of_one_configuration_keep_the_first_as_the_in_order_rule():
    """The rows kept by the all-pairs rule against the plain in-order loop (a row goes when a
    kept row lies within tol, max-norm, of it) on 2000 seeded cases with planted near-copies,
    chains and NaN entries."""
    from scdk_sym.solvers.mode_polish import _first_of_images

    def in_order(feats, tol):
        kept: list[int] = []
        for i in range(len(feats)):
            if kept and np.abs(feats[kept] - feats[i]).max(axis=1).min() <= tol:
                continue
            kept.append(i)
        return kept

    rng = np.random.default_rng(3)
    fired = 0  # cases where some row went
    for _ in range(2000):
        R, d, tol = int(rng.integers(0, 12)), int(rng.integers(1, 5)), 1e-6
        feats = rng.normal(size=(R, d))
        for _ in range(int(rng.integers(0, 4)) if R >= 2 else 0):
            i, j = rng.integers(0, R, 2)
            feats[j] = feats[i] + rng.choice([0.0, 0.5, 0.9, 1.5]) * tol * rng.choice([-1, 1], d)
        if R and rng.random() < 0.2:
            feats[rng.integers(0, R), rng.integers(0, d)] = np.nan
        want = in_order(feats, tol)
        assert _first_of_images(feats, tol) == want, feats
        fired += len(want) < R
    assert fired >= 300


def test_mode_orders_are_pythons_round_to_the_bit():
    """The batch sort keys of assembly modes against ``round(v, 8)`` entry by entry, bit for
    bit, on 300 seeded batches of values from 1e-9 to 1e4 (beyond the fast path's range),
    with entries within 1e-15 of a rounding tie, zeros of both signs, inf and NaN."""
    from scdk_sym.results import mode_orders

    rng = np.random.default_rng(3)
    for _ in range(300):
        N, n = rng.integers(1, 30), rng.integers(2, 14)
        v = rng.normal(size=(N, n)) * 10.0 ** rng.uniform(-9, 4, size=(N, n))
        ties = (rng.integers(-(10**9), 10**9, size=(N, n)) + 0.5) * 1e-8
        ties += rng.normal(size=(N, n)) * 1e-15
        pick = rng.uniform(size=(N, n)) < 0.1
        v[pick] = ties[pick]
        v.flat[rng.integers(v.size)] = rng.choice([0.0, -0.0, np.inf, np.nan, -1e-10])
        got = mode_orders(v[:, :1], v[:, 1:])
        for row, key in zip(v.tolist(), got, strict=True):
            want = np.array([round(x, 8) for x in row])
            assert np.array(key).tobytes() == want.tobytes()
