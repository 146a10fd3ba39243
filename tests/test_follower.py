"""The curve follower: folds, bifurcations, level crossings; both predictors decide alike.

References: the seed robot's paper values (section 5), the closed form of the flat
parallelogram of Gepetto's robot_delta (loop 1 is flat at mot1_rod2 = pi/12 and the
parallelogram branch keeps free1_rod3 = mot1_rod2), and the independent closures of
tests/references.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from factories import SEED_THETA0, SEED_X1, shipped
from references import reference

import scdk_sym as sc
from scdk_sym.follower.curve import follow
from scdk_sym.follower.nearest import nearest_singular
from scdk_sym.follower.options import FollowOptions
from scdk_sym.follower.walk import Line

GEPETTO = "tests/fixtures/gepetto/robot_delta"


def robot_delta() -> sc.Model:
    return sc.load_model(GEPETTO, frame="effector")


@pytest.mark.parametrize("predictor", ["rk4", "cvodes"])
def test_steps_straight_over_the_flat_parallelogram(predictor):
    """A bifurcation: det J_p changes sign, s does not turn; the walk keeps the branch."""
    model = robot_delta()
    theta0 = np.array([0.0, 0.4])
    home = model.home
    line = Line(home.theta, theta0 - home.theta)
    direction = -1.0 if home.y is not None else 1.0
    options = FollowOptions(predictor=predictor, max_hits=1, max_arc=5.0)
    walks = [follow(model, line, home.y, 0.0, d, options) for d in (direction, -direction)]
    walk = next(w for w in walks if w.hits)
    assert [c.kind for c in walk.singular[: walk.hits[0].crossings]] == ["bifurcation"]
    cr = walk.singular[0]
    assert abs(cr.theta[1] - math.pi / 12) < 1e-6
    joints = model.configuration(walk.hits[0].y, theta0).joints
    # the parallelogram branch: the rod angle equals the motor angle
    assert abs(joints["free1_rod3"] - joints["mot1_rod2"]) < 1e-9
    assert model.residual(walk.hits[0].y, theta0) < 1e-12


def test_both_predictors_meet_the_same_points():
    model = shipped("planar_hexa")
    start = model.inverse_kinematics(SEED_X1)
    line = Line(start.theta, SEED_THETA0 - start.theta)
    a, b = (
        follow(model, line, start.y, 0.0, 1.0, FollowOptions(predictor=p, max_hits=1))
        for p in ("rk4", "cvodes")
    )
    assert len(a.hits) == len(b.hits) == 1
    np.testing.assert_allclose(a.hits[0].y, b.hits[0].y, atol=1e-12)
    assert [c.kind for c in a.singular] == [c.kind for c in b.singular] == ["fold"]
    assert abs(a.singular[0].s - b.singular[0].s) < 1e-9
    np.testing.assert_allclose(a.singular[0].x, b.singular[0].x, atol=1e-8)
    # the paper's singular configuration and its phi = 0.5754 (printed to 4 digits)
    assert abs(a.singular[0].x[2] - 0.5754) < 5e-4


def test_theta0_on_the_singular_surface_returns_the_singular_solution():
    model = shipped("planar_hexa")
    start = model.inverse_kinematics(SEED_X1)
    fold = sc.solve(model, SEED_THETA0, start=start, branch="divergent").crossings[0]
    res = sc.solve(model, fold.theta, start=start, branch="convergent")
    assert res.status == "singular"
    assert model.residual(res.y, res.theta) <= model.tolerance
    # the fold's configuration (a double root: Newton converges only to about sqrt(eps))
    np.testing.assert_allclose(res.x, fold.x, atol=1e-5)
    ref = reference("planar_hexa")
    assert np.max(np.abs(ref.closure(ref.coords(res), res.theta))) < 1e-8


def test_nearest_singular_configuration_is_singular_and_assembled():
    ref = reference("stewart_gough")
    for name in ("planar_3rpr", "five_bar", "hexa", "stewart_gough"):
        model = shipped(name)
        sing = nearest_singular(model, model.home)
        assert sing is not None, name
        assert model.residual(sing.y, sing.theta) <= model.tolerance
        y, c = model.chart.to_local(sing.y)
        sv = np.linalg.svd(np.array(model.kernels.jac(y, sing.theta, c)[0]), compute_uv=False)
        assert sv[-1] / sv[0] < 1e-9, name
    # independently: the hexapod's closed-form leg Jacobian is singular there too
    model = shipped("stewart_gough")
    sing = nearest_singular(model, model.home)
    cfg = model.configuration(sing.y, sing.theta)
    assert abs(ref.det_ratio(ref.coords(cfg), cfg.theta)) < 1e-6


def test_a_turn_of_s_inside_one_step_is_refined_not_stepped_over():
    """Two crossings of s = 1 on either side of a fold, both within the first step."""
    from scdk_sym.follower.levels import hidden_pair as _hidden_pair

    # s goes 0.9 -> 0.9 over a step of length 1, rising then falling: above 1 in between
    assert _hidden_pair(0.9, 0.9, 1.0, -1.0, 1.0, 1.0) is True
    assert _hidden_pair(0.9, 0.9, 0.05, -0.05, 1.0, 1.0) is False  # the peak stays below 1
    assert _hidden_pair(0.9, 1.1, 1.0, 1.0, 1.0, 1.0) is False  # no turn: one plain crossing
    # the seed robot's fold (the paper's phi = 0.5754) put at s = 1.01 of a line from the start
    model = shipped("planar_hexa")
    start = model.inverse_kinematics(SEED_X1)
    fold = sc.solve(model, SEED_THETA0, start=start, branch="divergent").crossings[0]
    theta0 = start.theta + (fold.theta - start.theta) / 1.01
    line = Line(start.theta, theta0 - start.theta)
    options = FollowOptions(predictor="rk4", max_hits=2, step=0.5, max_arc=5.0)
    walks = [follow(model, line, start.y, 0.0, d, options) for d in (1.0, -1.0)]
    walk = max(walks, key=lambda w: len(w.hits))
    assert len(walk.hits) == 2
    a, b = (model.configuration(h.y, theta0) for h in walk.hits)
    assert max(a.residual, b.residual) <= model.tolerance
    # the two solutions on either side of the fold, close to it and distinct
    assert abs(a.x[2] - fold.x[2]) < 0.1 and abs(b.x[2] - fold.x[2]) < 0.1
    assert abs(a.x[2] - b.x[2]) > 1e-3
    assert (a.x[2] - fold.x[2]) * (b.x[2] - fold.x[2]) < 0


def test_a_divergent_solve_crosses_the_fold_met_along_an_actuator_s_axis():
    """Gepetto's cassie_like from a start next to the alignment of a ball's first and last
    axes: ``sigma_min`` has a non-singular valley there, where the descent and the aims stop;
    the ankle motor's own axis meets the rocker's dead point. The divergent answer closes on
    Pinocchio's closures (tests/references.py, independent of the package), lies on the
    other side (det J_p of the other sign there, by finite differences: one fold crossed) and
    is not the convergent answer."""
    from references import load, wrap

    from scdk_sym.follower.singular import across_axes

    ref, m = reference("cassie_like"), load("cassie_like")
    theta0 = np.array([-0.085697592194608, -0.1335822651020772, 0.08124339127909272,
                       -0.056610751424316805, -0.04642655816072152])  # fmt: skip
    start = m.configuration(
        [1.3801807275554443, 1.8426838244563737, -1.0642846620682762, 0.027231400294665694,
         -1.7095726078029219, -1.9960635668159585, 1.5128990050165185, -2.106476136323052,
         -0.8440374038954175, 2.362614753269431, 1.490033607370333, -2.716542432487526],
        [-0.08166822694954012, -0.1319852562364129, 0.07850248557564471,
         -0.05545356185931574, -0.046183629015455925],
    )  # fmt: skip
    assert nearest_singular(m, start) is None  # the valley: no singular point descended to
    other = across_axes(m, start)
    assert other is not None and other.crossing.kind == "fold"
    moved = np.flatnonzero(np.abs(other.crossing.theta - start.theta) > 1e-9)
    assert [m.actuated[i] for i in moved] == ["motor_ankle"]
    res = sc.solve(m, theta0, start=start, branch="divergent")
    conv = sc.solve(m, theta0, start=start, branch="convergent")
    u = ref.coords(res)
    assert float(np.abs(ref.closure(u, theta0)).max()) <= 1e-9
    s0 = ref.det_sign(ref.coords(start), start.theta)
    assert s0 * ref.det_sign(u, theta0) == -1 and len(res.crossings) == 1
    assert float(np.abs(wrap(res.y - conv.y)).max()) > 0.1


def test_singular_test_decides_as_the_singular_values_do():
    """``singular_jp``'s determinant bound never decides otherwise than the singular values:
    seeded matrices of sizes 1-10 with relative smallest singular values around the 1e-6
    threshold and far above it (1e-8 to 1, log-uniform), scaled by 1e-3 to 1e3."""
    from scdk_sym.follower.finish import singular_jp

    rng = np.random.default_rng(11)
    decided = {True: 0, False: 0}
    for _ in range(3000):
        n = int(rng.integers(1, 11))
        U, _r = np.linalg.qr(rng.standard_normal((n, n)))
        V, _r = np.linalg.qr(rng.standard_normal((n, n)))
        s = np.sort(rng.uniform(0.1, 1.0, n))[::-1]
        s[-1] = s[0] * 10.0 ** rng.uniform(-8, 0)
        J = 10.0 ** rng.uniform(-3, 3) * (U * s) @ V.T
        S = np.linalg.svd(J, compute_uv=False)
        want = not S[-1] > 1e-6 * S[0]
        assert singular_jp(J) == want, (n, S[-1] / S[0])
        decided[want] += 1
    assert min(decided.values()) > 250  # both answers were asked for
