"""Homotopy engine: tracker, endgame, monodromy + trace test, cache, query solve.

References are independent of the engine: Bezout counts, numpy.roots of a univariate
elimination, a random-start real Newton on the quadrics, and for the 6-6 platform the
random-start Levenberg-Marquardt of tests/stewart.py. The full 6-6 monodromy from one random
point (minutes in numpy) runs with ``SCDK_SLOW=1``; the default suite obtains the 6-6
start system by tracking Dietmaier's 40 real postures to a random complex parameter point and
certifies it with the trace test.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from polynomial_systems import Quadrics, QuarticPair, StewartGough, quaternions, rotation_numerator
from stewart import (
    DIETMAIER_BASE,
    DIETMAIER_LENGTHS,
    DIETMAIER_PLATFORM,
    random_platform,
    stewart_reference,
)

from scdk_sym.algebraic import (
    ENGINE_VERSION,
    PolynomialSystem,
    StartSystem,
    monodromy_solve,
    solve_homotopy,
    start_system,
    trace_test,
)
from scdk_sym.algebraic.distinct import dedup, pair_distances, pairs_apart
from scdk_sym.algebraic.homotopy import solve_homotopies, track_parameter_homotopy
from scdk_sym.algebraic.parameter_homotopy import ParameterHomotopy
from scdk_sym.algebraic.paths.continuation import DONE, STEP_LIMIT, TrackerOptions, track
from scdk_sym.errors import HomotopyError, InputError, ScdkError


def _residual(system, z, p):
    P = np.broadcast_to(np.asarray(p, dtype=complex), (len(z), system.n_params))
    return np.abs(system.evaluate(np.asarray(z, dtype=complex), P)[0]).max(axis=1)


def _real_newton_reference(system, p, starts, seed):
    """Real solutions by Newton from uniform random real starts in [-3, 3]^n (independent)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-3, 3, size=(starts, system.n)).astype(complex)
    P = np.broadcast_to(np.asarray(p, dtype=complex), (starts, system.n_params))
    for _ in range(60):
        G, J, _ = system.evaluate(x, P)
        with np.errstate(all="ignore"):
            ok = np.abs(np.linalg.det(J.real)) > 1e-12
            dx = np.zeros_like(x)
            dx[ok] = np.linalg.solve(J.real[ok], G.real[ok][..., None])[..., 0]
        x = x - np.clip(dx.real, -1, 1)
    good = np.isfinite(x).all(axis=1) & (_residual(system, x, p) < 1e-12)
    sols: list[np.ndarray] = []
    for r in x[good].real:
        if not any(np.abs(r - s).max() < 1e-7 for s in sols):
            sols.append(r)
    return np.array(sols)


def _same_sets(a, b, tol):
    if len(a) != len(b):
        return False
    return all(np.abs(b - r).max(axis=1).min() < tol for r in a)


# ------------------------------------------------------------------------------------ tracker
def _sqrt_homotopy(z, t, idx):
    """H = z^2 - (1 + 3 t) per path (two components, independent): z(t) = +-sqrt(1 + 3 t)."""
    H = z * z - (1.0 + 3.0 * t)[:, None]
    Hz = np.zeros((len(z), 2, 2), dtype=complex)
    Hz[:, 0, 0], Hz[:, 1, 1] = 2 * z[:, 0], 2 * z[:, 1]
    return H, Hz, np.full(z.shape, -3.0 + 0j)


def _straight(tau, idx):
    return tau + 0j, np.ones_like(tau, dtype=complex)


def test_tracker_follows_a_closed_form_path():
    z0 = np.array([[1.0, -1.0], [-1.0, 1.0]], dtype=complex)
    out = track(_sqrt_homotopy, _straight, z0, np.arange(2), np.zeros(2), np.ones(2))
    assert (out.status == DONE).all() and np.allclose(out.tau, 1.0)
    assert np.abs(out.z - np.array([[2, -2], [-2, 2]])).max() < 1e-12
    assert (out.accepted <= out.steps).all() and out.steps.max() < 100


def test_tracker_loops_are_bounded():
    z0 = np.array([[1.0, -1.0]], dtype=complex)
    opts = TrackerOptions(max_steps=3, h0=1e-3)
    out = track(
        _sqrt_homotopy, _straight, z0, np.zeros(1, dtype=int), np.zeros(1), np.ones(1), opts
    )
    assert out.status[0] == STEP_LIMIT and out.steps[0] == 3 and 0 < out.tau[0] < 1


# ----------------------------------------------------------------------------------- quadrics
@pytest.fixture(scope="module")
def quadrics():
    system = Quadrics(3, seed=3)
    return system, monodromy_solve(system, seed=0, progress=False)


def test_protocol_is_satisfied():
    assert isinstance(Quadrics(2, 0), PolynomialSystem)
    assert isinstance(StewartGough(DIETMAIER_BASE, DIETMAIER_PLATFORM), PolynomialSystem)


def test_quadrics_monodromy_finds_bezout_count_and_passes_trace(quadrics):
    system, start = quadrics
    assert start.root_count == 2**3 == len(start.solutions)
    assert start.trace_passed and start.trace_residual < 1e-8
    F = system.evaluate(start.solutions, np.tile(start.p, (8, 1)))[0] + start.b
    assert np.abs(F).max() < 1e-10
    # distinct solutions
    d = np.abs(start.solutions[:, None] - start.solutions[None]).max(axis=2)
    assert (d + np.eye(8) * 1e9).min() > 1e-6


def test_trace_test_rejects_incomplete_sets(quadrics):
    system, start = quadrics
    rng = np.random.default_rng(11)
    for keep in (7, 4, 1):
        assert trace_test(system, start.solutions[:keep], start.p, start.b, rng) > 1e-4


def test_monodromy_stops_when_its_test_passes_and_says_why_it_failed():
    system = Quadrics(3, seed=3)
    rng = np.random.default_rng(11)
    residuals: list[float] = []

    def counted(sols, p, b):
        residuals.append(trace_test(system, sols, p, b, rng))
        return residuals[-1]

    start = monodromy_solve(system, seed=0, progress=False, max_loops=40, test=counted)
    # the first stable count is the Bezout number 2^3: one test, passed, no further loop
    assert start.root_count == 8 and start.trace_passed and start.reason == ""
    assert len(residuals) == 1 and residuals[0] < 1e-8 and start.trace_residual == residuals[0]
    assert start.loops < 40

    def short(sols, p, b):  # the trace of the set without its first point
        residuals.append(trace_test(system, sols[1:], p, b, rng))
        return residuals[-1]

    residuals.clear()
    failed = monodromy_solve(system, seed=0, progress=False, max_loops=12, test=short)
    assert failed.loops == 12 and not failed.trace_passed and len(residuals) >= 1
    assert min(residuals) > 1e-4
    assert failed.reason.startswith("trace test failed") and "12 monodromy loops" in failed.reason


def test_monodromy_out_of_its_budget_returns_what_it_found_and_says_so():
    """No loop starts once the CPU budget is spent: with none, the start point alone, not
    certified, the reason naming the budget; with ample time the same seed finds all 8."""
    system = Quadrics(3, seed=3)
    spent = monodromy_solve(system, seed=0, progress=False, budget=0.0)
    assert spent.loops == 0 and spent.root_count == 1 and not spent.trace_passed
    assert spent.reason.startswith("out of time (0 s of CPU) after 0 monodromy loops")
    ample = monodromy_solve(system, seed=0, progress=False, budget=600.0)
    assert ample.trace_passed and ample.root_count == 2**3


def test_quadrics_real_solutions_match_random_start_newton(quadrics):
    system, start = quadrics
    p0 = np.random.default_rng(5).normal(size=3)
    res = solve_homotopy(system, start, p0, seed=1)
    assert res.complete and (res.status == "success").all()
    assert _residual(system, res.endpoints, p0).max() < 1e-10
    ref = _real_newton_reference(system, p0, starts=3000, seed=2)
    assert len(ref) >= 2  # the reference sees real roots at this p0
    assert _same_sets(res.real_solutions, ref, 1e-8)


def test_homotopies_to_several_targets_at_once_equal_one_at_a_time(quadrics):
    """Three targets reached from three root sets in one batch: each result is the one
    homotopy's from its set, bit for bit, and the real roots are a random-start Newton's."""
    system, start = quadrics
    rng = np.random.default_rng(8)
    p1 = rng.normal(size=3)
    roots = solve_homotopy(system, start, p1, seed=1).endpoints
    P_from = np.stack([p1, p1 + 0.01, p1 - 0.02]).astype(complex)
    sets = [roots]
    for p in P_from[1:]:  # the complete set at each of the other starting points
        near = replace(start, p=P_from[0], b=0 * start.b, solutions=roots)
        sets.append(solve_homotopy(system, near, p, attempts=1).endpoints)
    targets = P_from.real + rng.normal(scale=0.1, size=(3, 3))
    gamma = np.exp(0.7j)
    batch = solve_homotopies(system, P_from, np.stack(sets), targets, gamma=gamma)
    for p_from, z, p0, got in zip(P_from, sets, targets, batch, strict=True):
        one = solve_homotopy(system, replace(start, p=p_from, b=0 * start.b, solutions=z), p0,
                             attempts=1, gamma=gamma)  # fmt: skip
        assert (got.status == one.status).all() and got.gamma == one.gamma
        np.testing.assert_array_equal(got.endpoints, one.endpoints)
        np.testing.assert_array_equal(got.real_solutions, one.real_solutions)
        assert got.complete and (got.steps == one.steps).all()
    ref = _real_newton_reference(system, targets[0], starts=3000, seed=2)
    assert _same_sets(batch[0].real_solutions, ref, 1e-8)


def test_two_paths_at_one_regular_endpoint_fail(quadrics):
    """A start system listing a solution twice: both copies reach one regular endpoint, which
    only a path jump can produce; they are reported failed and the result is not complete."""
    system, start = quadrics
    twice = StartSystem(
        start.p, start.b, np.vstack([start.solutions, start.solutions[:1]]), 9, 0.0, True, 0, 0
    )
    res = solve_homotopy(system, twice, np.ones(3), attempts=1)
    assert list(np.flatnonzero(res.status == "failed")) == [0, 8]
    assert not res.complete and (res.status[1:8] == "success").all()


# ------------------------------------------------------------------------- quartic pair
@pytest.fixture(scope="module")
def quartic():
    system = QuarticPair()
    return system, monodromy_solve(system, seed=3, progress=False)


def test_quartic_real_roots_match_numpy_roots(quartic):
    system, start = quartic
    assert start.root_count == 4 and start.trace_passed
    rng = np.random.default_rng(8)
    checked = 0
    for _ in range(3):
        p0 = rng.normal(size=6)
        res = solve_homotopy(system, start, p0, seed=2)
        roots = np.roots(QuarticPair.univariate(p0))
        xr = np.sort(roots[np.abs(roots.imag) < 1e-9].real)
        assert res.complete
        assert np.allclose(np.sort(res.real_solutions[:, 0]), xr, atol=1e-9, rtol=0)
        assert np.allclose(res.real_solutions[:, 1], res.real_solutions[:, 0] ** 2 + p0[0])
        checked += len(xr)
    assert checked > 0


def test_endgame_double_root_has_winding_two(quartic):
    system, start = quartic
    # (x - 1)^2 (x + 2)(x - 3): a double real root at x = 1
    coeffs = np.polymul(np.polymul([1, -1], [1, -1]), np.polymul([1, 2], [1, -3]))
    p0 = QuarticPair.params_for(coeffs)
    res = solve_homotopy(system, start, p0, seed=4)
    assert res.complete
    sing = res.status == "singular"
    assert sing.sum() == 2 and (res.winding[sing] == 2).all()
    assert np.abs(res.endpoints[sing, 0] - 1.0).max() < 1e-6
    assert np.allclose(np.sort(res.real_solutions[:, 0]), [-2, 1, 3], atol=1e-6)


def test_endgame_path_to_infinity(quartic):
    system, start = quartic
    # p5 = 0: the quartic drops to the cubic (x + 1)(x - 0.5)(x - 2), one root at infinity
    coeffs = np.concatenate([[0.0], np.polymul(np.polymul([1, 1], [1, -0.5]), [1, -2])])
    p0 = QuarticPair.params_for(coeffs)
    res = solve_homotopy(system, start, p0, seed=5)
    assert res.complete
    assert (res.status == "at_infinity").sum() == 1 and (res.status == "success").sum() == 3
    assert np.allclose(np.sort(res.real_solutions[:, 0]), [-1, 0.5, 2], atol=1e-9)


# ------------------------------------------------------------------------ 6-6 platform
def _poses_match(system, real_z, reference, tol):
    poses = system.poses(real_z)
    if len(poses) != len(reference):
        return False
    for p, R in reference:
        err = [max(np.abs(p - q).max(), np.abs(R - S).max()) for q, S in poses]
        if min(err) > tol:
            return False
    return True


@pytest.fixture(scope="module")
def family_start():
    """Start system of the whole 6-6 family (anchors and legs as parameters) from Dietmaier's
    40 real postures (LM reference) tracked to a random complex parameter point."""
    system = StewartGough()  # anchors free: one start system for every 6-6 platform
    ref = stewart_reference(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS, 4000, 0)
    assert len(ref) == 40
    q = quaternions(np.array([R for _, R in ref]))
    q = q / (q @ system.chart)[:, None]
    z = np.c_[np.array([p for p, _ in ref]), q, 1.0 / np.sum(q * q, axis=1)]
    p_real = system.params(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS)
    rng = np.random.default_rng(21)
    # a generic complex point near the real one: shorter paths, still generic
    p_star = p_real + 0.2 * (rng.normal(size=42) + 1j * rng.normal(size=42))
    b_star = np.where(system.offset_rows, 0.3 * rng.normal(size=8) + 0.3j * rng.normal(size=8), 0)
    hom = ParameterHomotopy(
        system, p_real[None], p_star[None], np.zeros((1, 8)), b_star[None], [1.0]
    )
    ends = track_parameter_homotopy(system, z, hom, np.zeros(40, dtype=int), endgame=False)
    assert (ends.status == "success").all()
    residual = trace_test(system, ends.z, p_star, b_star, rng)
    return system, StartSystem(p_star, b_star, ends.z, 40, residual, residual < 1e-8, 0, 21)


def test_stewart_jacobians_match_finite_differences():
    rng = np.random.default_rng(3)
    for system in (StewartGough(DIETMAIER_BASE, DIETMAIER_PLATFORM), StewartGough()):
        z, p = system.random_point(rng)
        _, Gz, Gp = system.evaluate(z[None], p[None])
        h = 1e-6
        for k in range(system.n):
            e = np.eye(system.n)[k] * h
            fd = (
                system.evaluate((z + e)[None], p[None])[0]
                - system.evaluate((z - e)[None], p[None])[0]
            )
            assert np.abs(fd[0] / (2 * h) - Gz[0, :, k]).max() < 1e-6
        for k in range(system.n_params):
            e = np.eye(system.n_params)[k] * h
            fd = (
                system.evaluate(z[None], (p + e)[None])[0]
                - system.evaluate(z[None], (p - e)[None])[0]
            )
            assert np.abs(fd[0] / (2 * h) - Gp[0, :, k]).max() < 1e-6


def test_stewart_start_system_passes_trace_and_fails_without_one(family_start):
    system, start = family_start
    assert start.trace_passed, start.trace_residual
    rng = np.random.default_rng(4)
    assert trace_test(system, start.solutions[:39], start.p, start.b, rng) > 1e-4


def test_chart_coordinates_have_trace_poles(family_start):
    """The quaternion's affine chart escapes to infinity inside the pencil: the trace of z is
    not linear even for the complete set; translation and rotation entries are."""
    system, start = family_start
    rng = np.random.default_rng(4)
    assert trace_test(system, start.solutions, start.p, start.b, rng, trace_map=lambda z: z) > 1e-6


@pytest.mark.parametrize(("seed", "finite"), [(1, 40), (16, 38)])
def test_family_homotopy_counts_each_platforms_finite_roots(family_start, seed, finite):
    """The start system of the whole 6-6 family (40 roots, trace test passed) tracked to one
    platform at complex legs: every isolated root of that platform is an endpoint. Random
    platform #16 has 38 distinct finite roots, the other two paths diverge (its geometry is
    special: two roots at infinity), the count that the monodromy of its own form reaches
    from every seed and that ``assembly_modes`` reports for it, not certified."""
    system, start = family_start
    A, B, L = random_platform(seed)
    rng = np.random.default_rng(5)
    legs = L + 0.1 * (rng.normal(size=6) + 1j * rng.normal(size=6))
    hom = ParameterHomotopy(
        system,
        start.p[None],
        system.params(A, B, legs)[None],
        start.b[None],
        np.zeros((1, 8)),
        [np.exp(2j * np.pi * rng.uniform())],
    )
    with np.errstate(all="ignore"):  # the paths that go to infinity overflow on their way
        ends = track_parameter_homotopy(system, start.solutions, hom, np.zeros(40, dtype=int))
    assert int((ends.status == "success").sum()) == finite, list(ends.status)
    roots = ends.z[ends.status == "success"]
    G, _, _ = system.evaluate(roots, np.repeat(system.params(A, B, legs)[None], finite, 0))
    assert np.abs(G).max() < 1e-8
    assert len(dedup(roots, 1e-6)) == finite


def test_dietmaier_all_40_real_postures(family_start):
    system, start = family_start
    p0 = system.params(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS)
    res = solve_homotopy(system, start, p0, seed=0)
    assert res.complete and res.start_certified and (res.status == "success").all()
    ref = stewart_reference(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS, 4000, 0)
    assert len(res.real_solutions) == 40
    assert _poses_match(system, res.real_solutions, ref, 1e-8)


@pytest.mark.parametrize("seed", [1])
def test_random_platform_real_postures_match_reference(family_start, seed):
    system, start = family_start
    A, B, L = random_platform(seed)
    res = solve_homotopy(system, start, system.params(A, B, L), seed=seed)
    assert res.complete
    ref = stewart_reference(A, B, L, 3000, seed)
    assert len(ref) >= 1
    assert _poses_match(system, res.real_solutions, ref, 1e-8)


@pytest.mark.slow  # full 6-6 monodromy: minutes in numpy
def test_stewart_monodromy_from_one_point_finds_40():
    system = StewartGough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    start = monodromy_solve(system, seed=0, progress=False)
    assert start.root_count == 40 and start.trace_passed
    res = solve_homotopy(system, start, DIETMAIER_LENGTHS)
    ref = stewart_reference(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS, 4000, 0)
    assert _poses_match(system, res.real_solutions, ref, 1e-8)


# ---------------------------------------------------------------------- cache and errors
def test_start_system_is_cached(tmp_path, monkeypatch):
    monkeypatch.setenv("SCDK_CACHE_DIR", str(tmp_path))
    system = Quadrics(2, seed=9)
    first = start_system(system, seed=4, progress=False)
    files = list((tmp_path / "homotopy").glob("*.npz"))
    assert len(files) == 1 and f"-v{ENGINE_VERSION}-s4" in files[0].name
    assert system.content_hash() in files[0].name

    def no_monodromy(*args, **kwargs):
        raise AssertionError("monodromy ran although the start system is cached")

    monkeypatch.setattr("scdk_sym.algebraic.monodromy.monodromy_solve", no_monodromy)
    second = start_system(system, seed=4, progress=False)
    assert np.array_equal(first.solutions, second.solutions) and second.root_count == 4


def test_bad_inputs_raise_scdk_errors(quadrics):
    system, start = quadrics
    with pytest.raises(InputError):
        solve_homotopy(system, start, np.ones(2))
    with pytest.raises(InputError):
        solve_homotopy(system, start, [np.nan, 0, 0])
    with pytest.raises(HomotopyError):
        solve_homotopy(Quadrics(2, 0), start, np.ones(2))

    broken = Quadrics(2, 0)
    broken.offset_rows = np.array([True, False])  # random_point does not zero row 1
    with pytest.raises(ScdkError, match="structural"):
        monodromy_solve(broken, progress=False)


def test_rotation_numerator_is_rotation_times_norm():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(5, 4))
    R = rotation_numerator(q) / np.sum(q * q, axis=1)[:, None, None]
    assert np.allclose(R @ R.transpose(0, 2, 1), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0)
    back = quaternions(R)
    back *= np.sign(np.sum(back * q, axis=1))[:, None]
    assert np.allclose(back, q / np.linalg.norm(q, axis=1)[:, None], atol=1e-12)


def test_dedup_keeps_the_first_of_each_cluster():
    """Clusters of near-copies (1e-10 apart, relative) of rows of very different sizes: one
    row per cluster, the first one, sorted lexicographically; a NaN row matches nothing."""
    from scdk_sym.algebraic.distinct import dedup

    rng = np.random.default_rng(7)
    centres = rng.normal(size=(6, 4)) * np.array([1e-3, 1.0, 1e3, 1.0])
    labels = rng.integers(0, 6, size=40)
    x = centres[labels] * (1 + 1e-10 * rng.normal(size=(40, 4)))
    x = np.vstack([x, np.full((1, 4), np.nan)])
    out = dedup(x, 1e-8)
    firsts = [int(np.flatnonzero(labels == c)[0]) for c in np.unique(labels)]
    expected = x[firsts]
    expected = np.vstack([expected[np.lexsort(expected.T[::-1])], x[-1:]])  # NaN sorts last
    assert out.shape == (len(firsts) + 1, 4)
    np.testing.assert_array_equal(out, expected)


@pytest.mark.parametrize("block", [1, 3, 256])
def test_dedup_matches_only_rows_it_kept(block):
    """A chain a ~ b ~ c with a and c apart: b goes (it matches a, kept), c stays (its only
    match, b, was dropped), whatever the block size of the distance computation."""
    tol = 1e-6
    a = np.array([0.0, 1.0])
    b = a + [0.8 * tol * (1 + 1.0), 0.0]  # within tol of a, relative to a's scale
    c = b + [0.8 * tol * (1 + 1.0), 0.0]  # within tol of b, 1.6 tol from a
    far = np.array([5.0, -2.0])
    x = np.vstack([a, far, b, c, far * (1 + 1e-9)])
    out = dedup(x, tol, block=block)
    expected = np.vstack([a, c, far])
    np.testing.assert_array_equal(out, expected[np.lexsort(expected.T[::-1])])


def test_path_jumps_fail_as_the_per_target_rule_says():
    """Two regular ends of one target within 1e-8 (relative) both fail: the batched rule
    against a plain loop over the targets, on 2000 seeded cases with planted near-copies."""
    from scdk_sym.algebraic.homotopy import _fail_jumps

    def per_target(out, status, idx):
        for d in set(idx.tolist()):
            ends = [i for i in range(len(idx)) if idx[i] == d and status[i] == "success"]
            hit = [i for i in ends if sum(
                np.abs(out[i] - out[j]).max() <= 1e-8 * (1.0 + np.abs(out[j]).max())
                for j in ends if j != i) > 0]  # fmt: skip
            for i in hit:
                status[i], out[i] = "failed", np.nan

    rng = np.random.default_rng(0)
    fired = 0  # cases where the rule failed some path
    for _ in range(2000):
        M, n = int(rng.integers(0, 20)), int(rng.integers(1, 4))
        idx = rng.integers(0, 4, M)
        out = rng.normal(size=(M, n)) * 10.0 ** rng.integers(-3, 4) + 1j * rng.normal(size=(M, n))
        for _ in range(int(rng.integers(0, 3)) if M >= 2 else 0):
            i, j = rng.integers(0, M, 2)
            out[j] = out[i] * (1 + rng.choice([0.0, 1e-9, 5e-9, 2e-8]))
            idx[j] = idx[i] if rng.uniform() < 0.7 else idx[j]
        status = rng.choice(np.array(["success", "singular", "failed"], dtype=object), M,
                            p=[0.8, 0.1, 0.1])  # fmt: skip
        want_out, want = out.copy(), status.copy()
        per_target(want_out, want, idx)
        fired += int((want == "failed").sum() > (status == "failed").sum())
        _fail_jumps(out, status, idx)
        assert list(status) == list(want)
        np.testing.assert_array_equal(out, want_out)
    assert fired >= 200


def test_dedup_groups_equals_dedup_of_each_group():
    """Groups of several sizes (empty, one row, planted near-copies, NaN rows) at once, bit
    for bit as dedup of each, on 300 seeded batches."""
    from scdk_sym.algebraic.distinct import dedup, dedup_groups

    rng = np.random.default_rng(11)
    merged = 0  # groups where some row went
    for _ in range(300):
        n, tol = int(rng.integers(1, 4)), 1e-8
        xs = []
        for _ in range(int(rng.integers(1, 8))):
            size = (int(rng.choice([0, 1, 2, 3, 3, 6])), n)
            x = rng.normal(size=size) * 10.0 ** rng.integers(-2, 3)
            for _ in range(int(rng.integers(0, 3)) if len(x) >= 2 else 0):
                i, j = rng.integers(0, len(x), 2)
                x[j] = x[i] * (1 + rng.choice([0.0, 5e-9, 2e-8]))
            if len(x) and rng.random() < 0.15:
                x[rng.integers(0, len(x))] = np.nan
            xs.append(x)
        got = dedup_groups(xs, tol, block=int(rng.choice([1, 50, 1 << 20])))
        for x, g in zip(xs, got, strict=True):
            want = dedup(x, tol)
            assert g.shape == want.shape and g.tobytes() == want.tobytes()
            merged += len(want) < len(x)
    assert merged >= 50


def test_pair_distances_answer_every_bound_test_as_the_full_matrix():
    """``pair_distances`` against the plain (G, M, M) max-modulus matrix on 500 seeded
    batches (complex, and their real parts) with repeated rows, rows a hair apart (1e-9 ..
    1e-7, along any coordinate and in the imaginary part only), NaN rows and bounds per
    column: ``<= bound`` is the same
    everywhere, every finite entry equals the plain value bit for bit, a NaN is a NaN or
    (a pair apart in its first coordinate) inf."""
    rng = np.random.default_rng(17)
    for _ in range(500):
        G, M, n = rng.integers(1, 5), rng.integers(2, 12), rng.integers(1, 6)
        z = rng.normal(size=(G, M, n)) + 1j * rng.normal(size=(G, M, n))
        for _ in range(rng.integers(0, 4)):
            g, i, j = rng.integers(G), rng.integers(M), rng.integers(M)
            z[g, i] = z[g, j]
            if rng.uniform() < 0.6:
                k = rng.integers(n)
                z[g, i, k] += 10.0 ** rng.uniform(-9, -7) * (1j if rng.uniform() < 0.5 else 1)
        if rng.uniform() < 0.2:
            z[rng.integers(G), rng.integers(M), rng.integers(n)] = np.nan
        for x in (z, np.ascontiguousarray(z.real)):  # complex, and real rows
            plain = np.abs(x[:, :, None] - x[:, None]).max(axis=3)
            bound = 1e-8 * (1.0 + np.abs(x).max(axis=2))[:, None, :]
            got = pair_distances(x, bound)
            np.testing.assert_array_equal(got <= bound, plain <= bound)
            finite = np.isfinite(got)
            np.testing.assert_array_equal(got[finite], plain[finite])
            # NaN where computed, else inf (a pair surely apart by its first coordinate)
            assert (np.isnan(got) <= np.isnan(plain)).all()
            nan = np.isnan(plain)
            assert np.isinf(got[nan]).sum() + np.isnan(got).sum() == nan.sum()


def test_pairs_apart_only_where_no_pair_is_within_the_bound():
    """``pairs_apart`` (sorted first coordinates) against the plain (G, M, M) matrix of
    first-coordinate gaps on 600 seeded batches with ties, gaps just above and below the
    bound, inf and NaN entries: it says "apart" only when every off-diagonal gap times
    ``1 - 4 eps`` exceeds the bound, and then the full distances are all above it too; it
    says "not apart" whenever some finite gap is at most the bound."""
    rng = np.random.default_rng(23)
    eps = np.finfo(float).eps
    answers = {True: 0, False: 0}
    for _ in range(600):
        G, M, n = rng.integers(1, 4), rng.integers(1, 10), rng.integers(1, 4)
        z = rng.normal(size=(G, M, n)) + 1j * rng.normal(size=(G, M, n))
        bound = float(10.0 ** rng.uniform(-3, 0))
        if M > 1 and rng.uniform() < 0.5:  # two first coordinates about the bound apart
            g, i, j = rng.integers(G), rng.integers(M), rng.integers(M)
            if i != j:
                z[g, i, 0] = z[g, j, 0].real + bound * rng.choice([0.0, 0.5, 1.0, 1.0 + 1e-15, 2.0])
        if rng.uniform() < 0.1:
            z[rng.integers(G), rng.integers(M), 0] = rng.choice([np.nan, np.inf])
        x = z[..., 0].real
        with np.errstate(invalid="ignore"):
            gap = np.abs(x[:, :, None] - x[:, None])
            off = ~np.eye(M, dtype=bool)
            want = bool((gap[:, off] * (1.0 - 4.0 * eps) > bound).all())
        got = pairs_apart(z, bound)
        assert got == want, (x, bound)
        if got:
            assert (pair_distances(z, bound)[:, off] > bound).all()
        answers[got] += 1
    assert min(answers.values()) > 100
