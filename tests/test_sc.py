"""The singularity-consistent solver on the paper's example (scdk_sym.solvers.solve)."""

import numpy as np
import pytest
from factories import SEED_THETA0, SEED_X1, compiler_missing, seed_models, shipped

from scdk_sym.errors import InputError, NotAssembledError, PathError, ScdkError
from scdk_sym.results import Configuration
from scdk_sym.solvers.solve import solve
from scdk_sym.solvers.trace import trace


@pytest.fixture(scope="module", params=["planar_hexa", "planar_hexa_reduced"])
def seed(request):
    model = shipped(request.param)
    return model, model.inverse_kinematics(SEED_X1)


def test_convergent_branch_reproduces_the_paper(seed):
    model, start = seed
    res = solve(model, SEED_THETA0, start=start, branch="convergent")
    # the paper: x3 = [0, 0, 0.207] (0.207376); theta0 is rounded to 3 decimals
    assert abs(res.x[2] - 0.2074) < 1.5e-3
    assert abs(res.x[0]) < 5e-3 and abs(res.x[1]) < 5e-3
    assert res.crossings == ()
    assert res.residual <= 1e-8 and res.status == "converged" and res.branch == "convergent"
    np.testing.assert_array_equal(res.theta, SEED_THETA0)


def test_divergent_branch_crosses_the_singular_manifold_once(seed):
    model, start = seed
    res = solve(model, SEED_THETA0, start=start, branch="divergent")
    # the paper: x0 = [0, 0, 1.000], crossing at x = y = 0, phi = 0.575360
    assert abs(res.x[2] - 0.9999) < 1.5e-3
    assert abs(res.x[0]) < 5e-3 and abs(res.x[1]) < 5e-3
    assert len(res.crossings) == 1 and res.residual <= 1e-8
    assert abs(res.crossings[0].x[2] - 0.5754) < 2e-3


def test_divergent_answer_names_its_strategy_and_every_strategy_is_a_way(seed):
    """The paper's example is answered by the first way, the paper's divergent path; the
    declared strategies and the search's ways are the same list (no undeclared way)."""
    from scdk_sym.solvers.divergent import DIVERGENT_STRATEGIES, _DivergentSearch

    model, start = seed
    res = solve(model, SEED_THETA0, start=start, branch="divergent")
    conv = solve(model, SEED_THETA0, start=start, branch="convergent")
    assert res.strategy == "paper" and conv.strategy == ""
    assert res.to_dict()["strategy"] == "paper" and "strategy" not in conv.to_dict()
    names = [s.name for s in DIVERGENT_STRATEGIES]
    ways = sorted(n[4:] for n in vars(_DivergentSearch) if n.startswith("way_"))
    assert len(set(names)) == len(names) == 6
    assert sorted(n.replace("-", "_") for n in names) == ways


def test_crossing_is_on_the_singular_manifold(seed):
    model, start = seed
    res = solve(model, SEED_THETA0, start=start, branch="divergent")
    cr = res.crossings[0]
    y, c = model.chart.to_local(cr.y)
    Jp, Js = (np.array(a) for a in model.kernels.jac(y, cr.theta, c))
    # s reported consistently with theta(s) = theta1 + s (theta0 - theta1)
    np.testing.assert_allclose(
        cr.theta, start.theta + cr.s * (SEED_THETA0 - start.theta), atol=1e-12
    )
    assert model.residual(cr.y, cr.theta) < 1e-10
    # det J_p vanishes there (relative to its size along the path): sigma_min / sigma_max
    sv = np.linalg.svd(Jp, compute_uv=False)
    assert sv[-1] / sv[0] < 1e-9
    # det J_p changes sign exactly once along the sampled path
    flips = np.count_nonzero(np.diff(np.sign(res.path.det_jp)) != 0)
    assert flips == 1


def test_both_modelings_give_the_same_solutions():
    full, reduced = seed_models()
    for branch in ("convergent", "divergent"):
        a = solve(full, SEED_THETA0, start=full.inverse_kinematics(SEED_X1), branch=branch)
        b = solve(reduced, SEED_THETA0, start=reduced.inverse_kinematics(SEED_X1), branch=branch)
        np.testing.assert_allclose(a.x, b.x, atol=1e-10)
        np.testing.assert_allclose(a.platform_pose, b.platform_pose, atol=1e-10)
        assert len(a.crossings) == len(b.crossings)
        for ca_, cb in zip(a.crossings, b.crossings, strict=True):
            np.testing.assert_allclose(ca_.x, cb.x, atol=1e-8)


def test_branch_names_follow_the_sign_of_b_det_jp():
    # the paper's b = +0.5 is the convergent branch of the reduced model; in the full-chain
    # model det J_p has the opposite sign at the start, so b = +0.5 is the divergent branch
    full, reduced = seed_models()
    r = solve(reduced, SEED_THETA0, start=reduced.inverse_kinematics(SEED_X1), b=0.5)
    f = solve(full, SEED_THETA0, start=full.inverse_kinematics(SEED_X1), b=0.5)
    assert {r.branch, f.branch} == {"convergent", "divergent"}
    assert abs(r.x[2] - f.x[2]) > 0.5


def test_path_samples_follow_the_paper_figures(seed):
    model, start = seed
    res = solve(model, SEED_THETA0, start=start, branch="divergent")
    p = res.path
    assert p.s.shape == p.det_jp.shape == p.sdot.shape and p.x.shape == (len(p.s), 3)
    # phase plot: s' < 0 first (divergent), = 0 on the manifold, > 0 afterwards (Fig. 6)
    assert p.sdot[0] < 0 < p.sdot[-1]
    assert np.all(np.diff(p.arc) > 0)
    # each sample lies on the solution curve
    worst = max(
        model.residual(y, start.theta + s * (SEED_THETA0 - start.theta))
        for y, s in zip(p.y, p.s, strict=True)
    )
    assert worst < 1e-7


@pytest.mark.parametrize("backend", ["cvodes", "compiled"])
def test_fast_path_and_backends_agree_with_the_full_path(backend):
    if backend == "compiled" and compiler_missing():
        pytest.skip(compiler_missing())
    model = shipped("planar_hexa_reduced")
    rng = np.random.default_rng(5)
    for _ in range(10):
        x = np.r_[rng.uniform(-1, 1, 2), rng.uniform(-0.2, 0.3)]
        target = model.inverse_kinematics(x)
        near = model.inverse_kinematics(x + rng.normal(scale=0.02, size=3))
        fast = solve(model, target.theta, start=near, backend=backend, record_path=False)
        full = solve(model, target.theta, start=near, backend=backend, record_path=True)
        np.testing.assert_allclose(fast.x, x, atol=1e-10)
        np.testing.assert_allclose(full.x, x, atol=1e-10)


def test_start_already_at_theta0_returns_it():
    model = shipped("planar_hexa")
    res = solve(model, model.home.theta)
    np.testing.assert_allclose(res.x, model.home.x, atol=1e-14)
    assert res.crossings == ()


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"theta0": [1.0, 2.0]}, InputError, "must have 3 values, got 2"),
        ({"theta0": [1.0, float("nan"), 2.0]}, InputError, "finite"),
        ({"theta0": "abc"}, InputError, "must be 3 numbers"),
        ({"branch": "sideways"}, InputError, "unknown branch 'sideways'; branches: convergent"),
        ({"b": 0.0}, InputError, "non-zero"),
        ({"backend": "gpu"}, InputError, "'gpu' is not offered by solve; backends: auto, c, comp"),
        ({"start": "home"}, InputError, "start must be a Configuration"),
    ],
)
def test_bad_input_is_refused(kwargs, error, message):
    model = shipped("planar_hexa")
    args = {"theta0": SEED_THETA0, **kwargs}
    with pytest.raises(error, match=message):
        solve(model, **args)


def test_start_that_is_not_assembled_is_refused():
    model = shipped("planar_hexa")
    home = model.home
    bad = Configuration(home.theta, home.y + 0.1, home.x, home.platform_pose, home.joints)
    with pytest.raises(NotAssembledError, match="start configuration is not assembled"):
        solve(model, SEED_THETA0, start=bad)


def test_unreachable_theta_raises_a_path_error():
    # arms pointing radially outwards: the elbows are too far apart for the platform
    model = shipped("planar_hexa")
    with pytest.raises(PathError, match="did not reach s = 1") as info:
        solve(model, [-0.5236, -2.618, 1.5708], start=model.inverse_kinematics(SEED_X1))
    assert isinstance(info.value, ScdkError)


# ---------------------------------------------------------------------------- divergent


@pytest.mark.parametrize("name", ["delta", "hexa", "five_bar", "stewart_gough", "planar_3rpr"])
def test_divergent_near_home_returns_another_verified_solution(name):
    """Revolute actuators wrap around and the straight line never folds: the divergent branch
    crosses the nearest singular surface instead (checked by the independent closures)."""
    from references import reference

    model = shipped(name)
    theta0 = model.home.theta + 0.02
    conv = solve(model, theta0, branch="convergent")
    div = solve(model, theta0, branch="divergent")
    ref = reference(name)
    for res in (conv, div):
        assert np.max(np.abs(ref.closure(ref.coords(res), theta0))) < 1e-9
    assert ref.distance(ref.coords(conv), ref.coords(div)) > 1e-3
    assert len(div.crossings) >= 1 and div.branch == "divergent"
    # an odd number of crossings: det d(closure)/dx has opposite signs at the two answers
    s_conv = ref.det_sign(ref.coords(conv), theta0)
    s_div = ref.det_sign(ref.coords(div), theta0)
    assert s_conv * s_div == -1


def test_divergent_at_the_start_theta_is_the_mirror_solution():
    from test_modes import rpr_reference

    model = shipped("planar_hexa")
    home = model.home
    res = solve(model, home.theta, branch="divergent")
    # the 3-RRR at fixed arms is a 3-RPR with legs of the rod length from the elbows
    a = np.radians([-30.0, -150.0, 90.0])
    base = (20 / np.sqrt(3)) * np.c_[np.cos(a), np.sin(a)]
    plat = (10 / np.sqrt(3)) * np.c_[np.cos(a), np.sin(a)]
    elbows = base + 7.0 * np.c_[np.cos(home.theta), np.sin(home.theta)]
    sols = rpr_reference(elbows, plat, np.full(3, 7.0))
    assert min(np.abs(s - res.x).max() for s in sols) < 1e-8
    assert np.abs(res.x - home.x).max() > 0.1 and len(res.crossings) == 1


def test_divergent_returns_dietmaiers_posture_across_a_near_singular_surface():
    """From 2 mm / 5 mrad off each of the 40 postures, one branch returns the posture.

    All 200 starts. The hardest (posture 18, offset 4) starts within det J_p ~ 1e-6 of a
    singular surface that the straight line grazes: the curve turns back at once (a fold on
    which H' = [J_p, -j_s] nearly drops rank, not two branches crossing) and the posture is
    on the start's side, reached on the convergent branch along a line bent away from it."""
    from stewart import (
        DIETMAIER_BASE,
        DIETMAIER_LENGTHS,
        DIETMAIER_PLATFORM,
        rotations,
        stewart_reference,
    )

    import scdk_sym as sc

    ref = stewart_reference(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS, 3000, seed=5)
    assert len(ref) == 40
    model = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    rng = np.random.default_rng(11)
    missed = []
    for i, (p, R) in enumerate(ref):
        for j in range(5):
            dp, dw = rng.normal(size=3), rng.normal(size=3)
            R1 = rotations((0.005 * dw / np.linalg.norm(dw))[None])[0] @ R
            rpy = [
                np.arctan2(R1[2, 1], R1[2, 2]),
                np.arcsin(-R1[2, 0]),
                np.arctan2(R1[1, 0], R1[0, 0]),
            ]
            start = model.inverse_kinematics(np.r_[p + 0.002 * dp / np.linalg.norm(dp), rpy])
            found = False
            for branch in ("convergent", "divergent"):
                try:
                    res = solve(model, DIETMAIER_LENGTHS, start=start, branch=branch,
                                record_path=False)  # fmt: skip
                except ScdkError:
                    continue
                T = res.platform_pose
                if np.abs(T[:3, 3] - p).max() < 1e-6 and np.abs(T[:3, :3] - R).max() < 1e-6:
                    found = True
                    break
            if not found:
                missed.append((i, j))
    assert not missed, missed


def test_a_grazed_fold_is_a_fold_and_the_convergent_branch_bends_past_it():
    """Dietmaier's posture 18 from its hardest start (the 5th seeded offset): the straight line
    grazes a singular surface at once (the start has det J_p ~ 1e-6). The follower must report
    that turn as a fold (H' = [J_p, -j_s] nearly drops rank only because the line is tangent
    to the surface: the left null vector of J_p is not one of J_s, which a crossing of two
    branches needs), and the convergent branch must return the posture itself (it is on the
    start's side: det J_p > 0 there as at the start) with no singular point crossed."""
    from stewart import (
        DIETMAIER_BASE,
        DIETMAIER_LENGTHS,
        DIETMAIER_PLATFORM,
        rotations,
        stewart_reference,
    )

    import scdk_sym as sc
    from scdk_sym.follower.surface import grazes

    ref = stewart_reference(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS, 3000, seed=5)
    model = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    rng = np.random.default_rng(11)  # the offsets of the 200-start test, in its order
    for _ in range(18 * 5 + 4):
        rng.normal(size=3), rng.normal(size=3)
    dp, dw = rng.normal(size=3), rng.normal(size=3)
    p, R = ref[18]
    R1 = rotations((0.005 * dw / np.linalg.norm(dw))[None])[0] @ R
    rpy = [np.arctan2(R1[2, 1], R1[2, 2]), np.arcsin(-R1[2, 0]), np.arctan2(R1[1, 0], R1[0, 0])]
    start = model.inverse_kinematics(np.r_[p + 0.002 * dp / np.linalg.norm(dp), rpy])
    theta0 = np.asarray(DIETMAIER_LENGTHS, float)
    y, c = model.chart.to_local(start.y)
    det0 = float(np.linalg.det(np.array(model.kernels.jac(y, start.theta, c)[0])))
    assert 0 < det0 < 1e-5  # the start is within det J_p ~ 1e-6 of the surface
    walk = trace(model, theta0, start, 1.0)
    first = walk.singular[0]
    assert first.kind == "fold" and abs(first.s) < 1e-4, walk.singular
    assert grazes(model, first, theta0 - start.theta)
    res = solve(model, theta0, start=start, branch="convergent")
    assert res.crossings == ()
    assert np.abs(res.platform_pose[:3, 3] - p).max() < 1e-9
    assert np.abs(res.platform_pose[:3, :3] - R).max() < 1e-9
    assert np.abs(res.theta - theta0).max() == 0.0


@pytest.mark.parametrize("name", ["planar_hexa", "planar_hexa_reduced"])
def test_warm_fast_path_reports_the_branch_sign_of_the_full_path(name, monkeypatch):
    """``b`` of a convergent solve is the sign of det J_p at the start (``b det J_p > 0``),
    whether the warm kernel answers or the path is integrated; the two modelings of the seed
    robot have opposite signs there (DESIGN section 2)."""
    import scdk_sym.solvers.convergent as sc_module

    model = shipped(name)
    start = model.inverse_kinematics(SEED_X1)
    theta0 = start.theta + np.array([0.01, -0.02, 0.015])
    y, c = model.chart.to_local(start.y)
    det = float(np.linalg.det(np.array(model.kernels.jac(y, start.theta, c)[0])))
    full = solve(model, theta0, start=start, record_path=True)
    assert full.b == (1.0 if det > 0 else -1.0) and full.b * det > 0

    def no_path(*args, **kwargs):
        raise AssertionError("the warm fast path should have answered")

    monkeypatch.setattr(sc_module, "along_line", no_path)
    fast = solve(model, theta0, start=start, record_path=False)
    assert fast.path is None and fast.branch == "convergent"
    assert fast.b == full.b
    np.testing.assert_allclose(fast.x, full.x, atol=1e-9)
