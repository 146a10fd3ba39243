"""Certified assembly modes (``sc.assembly_modes``, method "homotopy") against independent
references: the 3-RPR's univariate polynomial and the seed robot as a 3-RPR between its
elbows (tests/test_modes.py), the Delta's three-sphere intersection (closed form), random-start
Levenberg-Marquardt on 6-6 platforms (tests/stewart.py) and Gepetto's ``robot_delta`` in
Pinocchio (tests/gepetto_reference.py).

Every start system here is computed in a fresh cache directory, so the times include the
monodromy of each model. CI time (``pytest tests/test_modes_certified.py
tests/test_rootbound.py``): 41 s in one run on the 2 shared cores, load average 5 (the seed
robot's monodromy stops when its 6 roots reach the root bound). The 6-6 platforms and
``robot_delta`` run only with ``SCDK_SLOW=1`` (``SCDK_SLOW=1 pytest
tests/test_modes_certified.py -k "dietmaier or random_6_6"``: 73-103 s per platform, 4 passed;
``-k robot_delta``: 76 s for its four tests, start system (complete by its root bound after 7
loops) and Pinocchio reference included, load average 6.3 on the 2 cores).
"""

from __future__ import annotations

import os
import time
from functools import cache

import numpy as np
import pytest
from factories import shipped
from stewart import (
    DIETMAIER_BASE,
    DIETMAIER_LENGTHS,
    DIETMAIER_PLATFORM,
    random_platform,
    stewart_reference,
)
from test_modes import (
    assert_same_stewart_poses,
    assert_verified_distinct_sorted,
    delta_reference,
    pose_distance,
    rpr_geometries_with_six,
    rpr_reference,
)

import scdk_sym as sc
from scdk_sym.results import AssemblyModes

#: A 6-6 monodromy takes about a minute.
SLOW = pytest.mark.slow
#: Largest closure residual of a returned solution [model length unit].
RESIDUAL = 1e-9


@pytest.fixture(autouse=True, scope="module")
def fresh_cache(tmp_path_factory):
    """Start systems in a fresh cache: each test computes what it certifies."""
    old = os.environ.get("SCDK_CACHE_DIR")
    os.environ["SCDK_CACHE_DIR"] = str(tmp_path_factory.mktemp("cache"))
    yield
    if old is None:
        os.environ.pop("SCDK_CACHE_DIR")
    else:
        os.environ["SCDK_CACHE_DIR"] = old


def assert_certified(model, sols: AssemblyModes, root_count: int | None = None) -> None:
    assert isinstance(sols, AssemblyModes) and sols.method == "homotopy"
    assert sols.certified, sols.report
    assert sols.report.startswith("certified complete")
    if root_count is not None:
        assert sols.root_count == root_count
    assert len(sols.certificates) == len(sols)
    for cfg, cert in zip(sols, sols.certificates, strict=True):
        assert cert.proven, cert.reason
        assert cfg.residual <= RESIDUAL
        assert model.residual(cfg.y, cfg.theta) <= RESIDUAL
    assert_verified_distinct_sorted(model, list(sols))


# ---------------------------------------------------------------------------- planar


def test_seed_robot_both_solutions_certified():
    """At theta = (1.210588, 0.878435, 2.99292) the curve search found none; the seed robot
    is a 3-RPR between its elbows, whose sextic gives the reference."""
    g = sc.builders.seed_geometry()
    model = shipped("planar_hexa")
    theta = np.array([1.210588, 0.878435, 2.99292])
    elbows = g["base_points"] + g["arm"] * np.c_[np.cos(theta), np.sin(theta)]
    ref = rpr_reference(elbows, g["platform_points"], np.full(3, g["rod"]))
    assert len(ref) == 2
    sols = sc.assembly_modes(model, theta)
    assert len(sols) == 2
    for s in ref:
        assert min(pose_distance(c.x, s) for c in sols) < 1e-8
    assert_certified(model, sols, root_count=6)
    # a second query reuses the start system held by the model
    t0 = time.perf_counter()
    again = sc.assembly_modes(model, theta)
    assert time.perf_counter() - t0 < 5.0
    assert again.certified and len(again) == len(sols)
    assert all(np.array_equal(a.y, b.y) for a, b in zip(again, sols, strict=True))


def test_seed_robot_two_solutions_next_to_a_singular_surface_certified():
    """theta0 1e-5 rad from the singular surface: the two real solutions lie 1.3e-5 cm apart
    (a merge of nearby endpoints dropped one and still said "complete"). Reference,
    independent of the homotopy: the closed-form closure and finite-difference det signs of
    tests/references.py at each returned solution, and both solutions of the straight-path
    solver's two branches."""
    from references import reference

    ref, model = reference("planar_hexa"), shipped("planar_hexa")
    theta = np.array([1.3076296916771795, -0.9677712680963285, -3.113399801611976])
    sols = sc.assembly_modes(model, theta)
    assert len(sols) == 2, sols.report
    assert_certified(model, sols, root_count=6)
    u = [ref.coords(c) for c in sols]
    for v in u:
        assert np.abs(ref.closure(v, theta)).max() <= 1e-9
    assert 1e-6 < ref.distance(u[0], u[1]) < 1e-4
    assert ref.det_sign(u[0], theta) == -ref.det_sign(u[1], theta) != 0
    for branch in ("convergent", "divergent"):
        res = sc.solve(model, theta, branch=branch)
        assert min(ref.distance(ref.coords(res), v) for v in u) <= 1e-9


def test_rpr_six_real_solutions_certified():
    A, C, rho = rpr_geometries_with_six()[0]
    model = sc.builders.planar_3rpr(A, C)
    ref = rpr_reference(A, C, rho)
    assert len(ref) == 6
    sols = sc.assembly_modes(model, rho)
    assert len(sols) == 6
    for s in ref:
        assert min(pose_distance(c.x, s) for c in sols) < 1e-8
    assert_certified(model, sols, root_count=6)
    # other leg lengths, the same start system: 0, 2 or 4 real ones, each the sextic's
    rng = np.random.default_rng(3)
    for _ in range(3):
        rho2 = rho * (1 + 0.3 * rng.uniform(-1, 1, 3))
        ref2 = rpr_reference(A, C, rho2)
        sols2 = sc.assembly_modes(model, rho2)
        assert len(sols2) == len(ref2)
        for s in ref2:
            assert min(pose_distance(c.x, s) for c in sols2) < 1e-8
        assert_certified(model, sols2, root_count=6)


def test_delta_both_sphere_intersections_certified():
    R, r, arm, rod = 0.2, 0.05, 0.25, 0.5
    model = sc.builders.delta(R, r, arm, rod)
    rng = np.random.default_rng(3)
    for _ in range(3):
        theta = model.home.theta + rng.uniform(-0.6, 0.6, 3)
        ref = delta_reference(R, r, arm, rod, theta)
        assert len(ref) == 2
        sols = sc.assembly_modes(model, theta)
        assert len(sols) == 2
        for p in ref:
            assert min(np.abs(c.x - p).max() for c in sols) < 1e-9
        assert_certified(model, sols, root_count=2)
    # out of reach: proven empty
    theta = rng.uniform(-np.pi, np.pi, 3)
    while delta_reference(R, r, arm, rod, theta):
        theta = rng.uniform(-np.pi, np.pi, 3)
    sols = sc.assembly_modes(model, theta)
    assert len(sols) == 0 and sols.certified and sols.root_count == 2


def test_result_is_a_sequence_and_curves_are_never_certified():
    R, r, arm, rod = 0.2, 0.05, 0.25, 0.5
    model = sc.builders.delta(R, r, arm, rod)
    theta = model.home.theta + 0.1
    sols = sc.assembly_modes(model, theta)
    assert len(sols) == 2 and list(sols) == [sols[0], sols[1]] and sols[-1] is sols[1]
    assert len(sols[:1]) == 1 and [c.x.tolist() for c in reversed(sols)] == [
        sols[1].x.tolist(),
        sols[0].x.tolist(),
    ]
    d = sols.to_dict()
    assert d["certified"] is True and d["root_count"] == 2 and d["count"] == 2
    assert all(s["certified"] is True for s in d["solutions"])
    curves = sc.assembly_modes(model, theta, method="curves", seed=1)
    assert not curves.certified and curves.report.startswith("not certified")
    assert curves.root_count == 0 and curves.method == "curves"
    for a, b in zip(curves, sols, strict=True):
        assert np.abs(a.x - b.x).max() < 1e-8
    with pytest.raises(sc.errors.InputError):
        sc.assembly_modes(model, theta, patience=3)  # a curve-search option
    with pytest.raises(sc.errors.InputError):
        sc.assembly_modes(model, theta, method="guess")


def test_architecturally_singular_3rpr_is_flagged_not_certified():
    """Base and platform congruent, equal legs: the platform translates on a circle (a real
    positive-dimensional solution set). Bounded work, a flag and a reason, no hang."""
    A = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, 0.8]])
    model = sc.builders.planar_3rpr(A, A)
    t0 = time.perf_counter()
    sols = sc.assembly_modes(model, [0.5, 0.5, 0.5])
    assert time.perf_counter() - t0 < 120.0
    assert not sols.certified
    assert sols.report.startswith("not certified: ") and len(sols.report.splitlines()) == 1
    assert "singular" in sols.report


def test_start_systems_are_stored_on_disk_proven_or_failed(monkeypatch):
    """A new model object (as in another process) reads the start system from disk: no
    monodromy; a failed one is stored with its reason and only ``rebuild`` recomputes it."""
    import scdk_sym.algebraic as algebraic
    from scdk_sym.kernels.cache import cache_dir

    R, r, arm, rod = 0.2, 0.05, 0.25, 0.5
    theta = sc.builders.delta(R, r, arm, rod).home.theta + np.array([0.1, -0.2, 0.05])
    ref = delta_reference(R, r, arm, rod, theta)
    assert len(ref) == 2
    first = sc.assembly_modes(sc.builders.delta(R, r, arm, rod), theta)
    assert first.certified, first.report
    assert "2 distinct regular roots = BKK root bound" in first.report  # two sphere meets
    calls: list[int] = []
    monodromy = algebraic.monodromy_solve

    def counted(*args, **kwargs):
        calls.append(1)
        return monodromy(*args, **kwargs)

    monkeypatch.setattr(algebraic, "monodromy_solve", counted)
    again = sc.assembly_modes(sc.builders.delta(R, r, arm, rod), theta)
    assert calls == [] and again.certified
    for p in ref:
        assert min(np.abs(c.x - p).max() for c in again) < 1e-9
    # no loop: one solution, below the root bound, no test runs; the failure is stored
    failed = sc.assembly_modes(sc.builders.delta(R, r, arm, rod), theta, seed=5, max_loops=0)
    assert calls == [1] and not failed.certified and failed.root_count == 1
    assert "no completeness test passed" in failed.report and "rebuild=True" in failed.report
    assert "BKK root bound 2" in failed.report
    assert list((cache_dir() / "homotopy").glob("*-s5-modes*.npz"))
    stored = sc.assembly_modes(sc.builders.delta(R, r, arm, rod), theta, seed=5)
    assert calls == [1] and not stored.certified and stored.report == failed.report
    rebuilt = sc.assembly_modes(sc.builders.delta(R, r, arm, rod), theta, seed=5, rebuild=True)
    assert calls == [1, 1] and rebuilt.certified, rebuilt.report
    for p in ref:
        assert min(np.abs(c.x - p).max() for c in rebuilt) < 1e-9
    after = sc.assembly_modes(sc.builders.delta(R, r, arm, rod), theta, seed=5)
    assert calls == [1, 1] and after.certified


def test_certified_only_tracks_no_path_of_an_unproven_start_system(monkeypatch):
    """``certified_only``: a start system that is not proven complete (no monodromy loop)
    returns at once, with no solution and the reason; without it the paths are tracked and
    the delta's one start root reaches one of its two real assemblies (a closed form)."""
    import scdk_sym.algebraic as algebraic

    R, r, arm, rod = 0.2, 0.05, 0.25, 0.5
    theta = sc.builders.delta(R, r, arm, rod).home.theta + np.array([0.1, -0.2, 0.05])
    ref = delta_reference(R, r, arm, rod, theta)
    tracked = sc.assembly_modes(
        sc.builders.delta(R, r, arm, rod), theta, seed=7, max_loops=0, cache=False
    )
    assert not tracked.certified and len(tracked) == 1
    assert min(np.abs(tracked[0].x - p).max() for p in ref) < 1e-9

    def no_tracking(*args, **kwargs):
        raise AssertionError("a path of an unproven start system was tracked")

    monkeypatch.setattr(algebraic, "solve_homotopy", no_tracking)
    skipped = sc.assembly_modes(
        sc.builders.delta(R, r, arm, rod), theta, seed=7, max_loops=0, cache=False,
        certified_only=True,
    )  # fmt: skip
    assert not skipped.certified and len(skipped) == 0 and skipped.root_count == 1
    assert skipped.report.startswith("not certified: start system not proven complete")
    assert skipped.report.endswith("its paths not tracked (certified_only)")


# ---------------------------------------------------------------------------- 6-6 (slow)


@SLOW
def test_dietmaier_40_real_of_40_certified():
    ref = stewart_reference(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS, 3000, seed=5)
    assert len(ref) == 40
    model = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    sols = sc.assembly_modes(model, DIETMAIER_LENGTHS)
    assert_same_stewart_poses(list(sols), ref)
    assert_certified(model, sols, root_count=40)


@SLOW
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_6_6_root_count_40_real_set_equals_reference(seed):
    A, B, L = random_platform(seed)
    model = sc.builders.stewart_gough(A, B)
    sols = sc.assembly_modes(model, L)
    ref = stewart_reference(A, B, L, 3000, seed)
    assert_same_stewart_poses(list(sols), ref)
    assert_certified(model, sols, root_count=40)


@SLOW
def test_a_6_6_start_system_short_of_40_roots_is_never_certified():
    # random platform #16 (38 finite roots, two at infinity: tests/test_homotopy.py): its
    # monodromy stops at 38 roots, and a rational fit of the trace on a
    # circle of the pencil once passed on them; only a proof may certify
    A, B, L = random_platform(16)
    model = sc.builders.stewart_gough(A, B)
    sols = sc.assembly_modes(model, L)
    assert sols.root_count == 40 or not sols.certified, sols.report
    ref = stewart_reference(A, B, L, 3000, 16)
    if sols.certified:
        assert_same_stewart_poses(list(sols), ref)


# ---------------------------------------------------------------------------- robot_delta


@cache
def robot_delta_case(theta: tuple[float, float]):
    from gepetto_reference import FIXTURE, reference

    model = sc.load_model(FIXTURE, frame="effector")
    ref = reference()
    expected = ref.assemblies(theta, ref.q_of(model.home.joints), starts=300, seed=11)
    return model, ref, expected, sc.assembly_modes(model, theta)


@SLOW
@pytest.mark.parametrize("theta", [(0.0, 0.0), (0.3, 0.4), (-0.4, 0.4)])
def test_robot_delta_eight_assemblies_each_certified(theta):
    """Two five-bar modes x (parallelogram or crossed) in each of two loops, from random-start
    LM in Pinocchio. The form has 64 complex roots: 2 per circle-circle closure (three loops)
    times 2 per rotation row (sin = 0 also at a half turn, a root that is no closure)."""
    from gepetto_reference import wrap

    model, ref, expected, sols = robot_delta_case(theta)
    assert len(expected) == 8
    assert len(sols) == 8, sols.report
    for q in expected:
        best = min(
            max(abs(float(wrap(c.joints[n] - q[ref.index[n]]))) for n in model.unknowns)
            for c in sols
        )
        assert best < 1e-6
    assert sols.root_count == 64
    assert len(sols.certificates) == 8
    for cfg, cert in zip(sols, sols.certificates, strict=True):
        assert cert.proven, cert.reason
        assert model.residual(cfg.y, cfg.theta) <= RESIDUAL
    assert_verified_distinct_sorted(model, list(sols))


@SLOW
def test_robot_delta_set_certified_complete():
    """No trace test passes on robot_delta's 64 roots (solutions escape to infinity on the
    circle charts); their count equals the form's BKK root bound, which proves it."""
    model, _ref, _expected, sols = robot_delta_case((0.0, 0.0))
    assert_certified(model, sols, root_count=64)
    assert "64 distinct regular roots = BKK root bound" in sols.report


def test_root_bound_certificate_rejects_an_incomplete_or_degenerate_set():
    """The seed robot's start system is complete by its root bound (6, the 3-RPR sextic's
    degree); without one root, or with one root replaced by a near copy of another, the
    count check fails."""
    from scdk_sym.algebraic import algebraic_form
    from scdk_sym.algebraic.rootbound import root_bound
    from scdk_sym.algebraic.scaled import scaled_form
    from scdk_sym.solvers.start_system import complete_by_bound, model_start_system

    form = scaled_form(algebraic_form(shipped("planar_hexa")))
    start = model_start_system(form, 0)
    assert start.trace_passed and start.root_count == 6
    bound = root_bound(form, start.p, budget=60.0).bound  # the pipeline's budget is 2 s
    assert bound == 6
    z, p, b = start.solutions, start.p, start.b
    ok, note = complete_by_bound(form, z, p, b, bound)
    assert ok and note == "6 distinct regular roots = BKK root bound"
    ok, note = complete_by_bound(form, z[1:], p, b, bound)
    assert not ok and note == "5 roots found, root bound 6"
    rng = np.random.default_rng(0)
    near = z.copy()
    near[0] = z[1] + 1e-9 * (rng.normal(size=z.shape[1]) + 1j * rng.normal(size=z.shape[1]))
    ok, note = complete_by_bound(form, near, p, b, bound)
    assert not ok and "apart" in note
    # a point that is no root
    off = z.copy()
    off[0] = z[0] + 0.3
    ok, note = complete_by_bound(form, off, p, b, bound)
    assert not ok and "do not refine" in note


# ---------------------------------------------------------------- special 6-6 geometry


def test_shipped_stewart_gough_is_certified_with_its_own_root_count():
    """Planar base and platform, three-fold symmetric anchors: not the generic 40 roots. The
    start system's count equals a random-start complex Newton's at the same parameters, the
    real set a random-start LM's; the offset trace test does not pass here, the pencil's does."""
    from roots import newton_roots

    from scdk_sym.algebraic import algebraic_form
    from scdk_sym.algebraic.scaled import scaled_form
    from scdk_sym.backends import resolve
    from scdk_sym.solvers.start_system import model_start_system

    model = shipped("stewart_gough")
    theta = np.array([0.66, 0.63, 0.65, 0.62, 0.64, 0.66])
    sols = sc.assembly_modes(model, theta)
    assert_certified(model, sols)
    assert "trace test on the curve of an offset line" in sols.report
    form = scaled_form(algebraic_form(model, resolve("auto", "modes")))
    start = model_start_system(form, 0)
    roots = newton_roots(form, start.p, 3000, 80, np.random.default_rng(3), b=start.b)
    assert len(roots) == sols.root_count == 28
    A = np.array([model.placement(model.home, f"base_anchor_{i}")[:3, 3] for i in range(1, 7)])
    P0 = model.placement(model.home, "platform")
    B = np.array(
        [
            np.linalg.solve(P0, model.placement(model.home, f"platform_anchor_{i}"))[:3, 3]
            for i in range(1, 7)
        ]
    )
    ref = stewart_reference(A, B, theta, 4000, seed=2)
    assert len(ref) == 8
    assert_same_stewart_poses(list(sols), ref)
