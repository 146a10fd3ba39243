"""Tracking through direct-kinematic singularities: continuity against inverse-kinematics truth.

The ground truth is a platform motion chosen first; the joint readings are its inverse
kinematics. Along a motion that crosses the singular manifold, the readings fold back (the
joint path turns round), and the solution nearest to the previous one is the mirror
configuration: warm-started Newton jumps to it, the SC tracker must not.
"""

from __future__ import annotations

import numpy as np
import pytest
from factories import hexapod, shipped

import scdk_sym as sc
from scdk_sym.errors import InputError, NotAssembledError
from scdk_sym.model.rotations import rot_exp

SINGULAR_PHI = 0.575360  # the paper's singular configuration of the seed robot (x = y = 0)


def newton_tracker(model: sc.Model, thetas: np.ndarray, start: sc.Configuration) -> np.ndarray:
    """Plain warm-started Newton on g(y, theta) = 0 from the previous solution: poses (N, 4, 4)."""
    y = np.array(start.y, dtype=float)
    poses = [start.platform_pose]
    for theta in thetas[1:]:
        y = _newton_root(model, y, theta, strict=False)
        poses.append(model.configuration(y, theta).platform_pose)
    return np.array(poses)


def jumps(poses: np.ndarray, truth: np.ndarray, tol: float = 1e-6) -> int:
    """Samples whose pose differs from the truth (a branch jump and what follows it)."""
    return int(np.sum(np.max(np.abs(poses - truth), axis=(1, 2)) > tol))


def seed_path(model: sc.Model, count: int):
    """The seed robot turning its platform phi = 0.40 -> 1.00 at x = y = 0 (through 0.5754)."""
    phis = np.linspace(0.40, 1.00, count)
    truth = [model.inverse_kinematics([0.0, 0.0, phi]) for phi in phis]
    return phis, np.array([c.theta for c in truth]), truth


@pytest.mark.parametrize("count", [13, 27, 61])
def test_seed_robot_through_its_singularity_without_branch_jumps(count):
    model = shipped("planar_hexa")
    phis, thetas, truth = seed_path(model, count)
    poses_true = np.array([c.platform_pose for c in truth])
    # the readings fold back at the singular manifold: the joint path turns round there
    steps = np.diff(thetas, axis=0)
    assert np.any(np.sum(steps[:-1] * steps[1:], axis=1) < 0)

    result = sc.track(model, thetas, start=truth[0])
    tracked = [
        model.configuration(y, t).platform_pose for y, t in zip(result.y, thetas, strict=True)
    ]
    assert jumps(np.array(tracked), poses_true) == 0
    assert np.max(np.abs(result.x - np.array([c.x for c in truth]))) < 1e-9
    assert np.all(result.residual <= model.tolerance)
    # one crossing, between the samples on either side of the singular configuration
    assert len(result.crossings) == 1
    crossing = result.crossings[0]
    before = int(np.nonzero(phis < SINGULAR_PHI)[0][-1])
    assert crossing.index == before
    assert abs(crossing.x[2] - SINGULAR_PHI) < 1e-3
    assert np.max(np.abs(crossing.x[:2])) < 1e-6

    # warm-started Newton on the same readings jumps back to the mirror branch
    assert jumps(newton_tracker(model, thetas, truth[0]), poses_true) >= 1


def test_reduced_seed_model_tracks_the_same_motion():
    model = shipped("planar_hexa_reduced")
    phis, thetas, truth = seed_path(model, 21)
    result = sc.track(model, thetas, start=truth[0])
    assert np.max(np.abs(result.x[:, 2] - phis)) < 1e-9
    assert [c.index for c in result.crossings] == [int(np.nonzero(phis < SINGULAR_PHI)[0][-1])]
    poses_true = np.array([c.platform_pose for c in truth])
    assert jumps(newton_tracker(model, thetas, truth[0]), poses_true) >= 1


def _legs(A: np.ndarray, B: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Leg lengths of a 6-6 platform at pose y = (position, rotation vector)."""
    return np.linalg.norm(y[:3] + B @ rot_exp(y[3:]).T - A, axis=1)


def _leg_jacobian_det(A, B, y) -> float:
    """det of the 6x6 platform Jacobian [u_i, (R b_i) x u_i] (u_i unit leg vectors)."""
    Rb = B @ rot_exp(y[3:]).T
    d = y[:3] + Rb - A
    u = d / np.linalg.norm(d, axis=1)[:, None]
    return float(np.linalg.det(np.hstack([u, np.cross(Rb, u)])))


@pytest.mark.parametrize("count", [17, 33])
def test_hexapod_through_its_twist_singularity(count):
    """A 6-6 platform moved straight through the singular manifold (turned about z)."""
    model = hexapod()
    ang_b = np.radians([0, 120, 240]).repeat(2) + np.radians([-12, 12] * 3)
    ang_p = np.roll(np.radians([60, 180, 300]).repeat(2) + np.radians([-20, 20] * 3), 1)
    A = np.c_[0.5 * np.cos(ang_b), 0.5 * np.sin(ang_b), np.zeros(6)]
    B = np.c_[0.3 * np.cos(ang_p), 0.3 * np.sin(ang_p), np.zeros(6)]
    assert np.allclose(_legs(A, B, model.home.y), model.home.theta, atol=1e-12)
    # bisection on the twist angle for the singular configuration
    lo, hi = 1.0, 2.0
    level = np.array([0.0, 0.0, 0.6, 0.0, 0.0, 0.0])
    twist = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    assert (
        _leg_jacobian_det(A, B, level + lo * twist) * _leg_jacobian_det(A, B, level + hi * twist)
        < 0
    )
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        same = _leg_jacobian_det(A, B, level + mid * twist) * _leg_jacobian_det(
            A, B, level + lo * twist
        )
        lo, hi = (mid, hi) if same > 0 else (lo, mid)
    singular = level + lo * twist
    direction = np.array([0.02, -0.03, 0.05, 0.3, -0.2, 1.0])
    direction /= np.linalg.norm(direction)
    t = np.linspace(-0.3, 0.3, count) + 0.0123
    Y = singular + t[:, None] * direction
    thetas = np.array([_legs(A, B, y) for y in Y])
    truth = np.array(
        [model.configuration(y, th).platform_pose for y, th in zip(Y, thetas, strict=True)]
    )
    start = model.configuration(Y[0], thetas[0])

    result = sc.track(model, thetas, start=start)
    poses = np.array(
        [model.configuration(y, th).platform_pose for y, th in zip(result.y, thetas, strict=True)]
    )
    assert jumps(poses, truth) == 0
    assert len(result.crossings) == 1
    assert result.crossings[0].index == int(np.nonzero(t < 0)[0][-1])
    assert abs(_leg_jacobian_det(A, B, result.crossings[0].y)) < 1e-3 * abs(
        _leg_jacobian_det(A, B, Y[0])
    )
    assert jumps(newton_tracker(model, thetas, start), truth) >= 1


def test_regular_motion_matches_newton_and_truth():
    model = shipped("planar_hexa")
    phis = np.linspace(0.15, 0.45, 16)
    truth = [model.inverse_kinematics([0.01 * p, -0.02 * p, p]) for p in phis]
    thetas = np.array([c.theta for c in truth])
    result = sc.track(model, thetas, start=truth[0])
    assert result.crossings == ()
    assert result.backend == "cvodes"
    assert np.max(np.abs(result.x - np.array([c.x for c in truth]))) < 1e-9
    newton = newton_tracker(model, thetas, truth[0])
    assert jumps(newton, np.array([c.platform_pose for c in truth])) == 0


@pytest.mark.parametrize("count", [27, 61])
def test_fast_continuation_on_regular_samples_never_across_the_fold(monkeypatch, count):
    """R2's Newton from the prediction answers the regular samples where the Euler step from
    the previous sample is accurate, never where it is not, and never the reading where the
    motion crosses the singular manifold (the inverse-kinematics truth)."""
    from scdk_sym.solvers import tracker as rule

    model = shipped("planar_hexa")
    phis, thetas, truth = seed_path(model, count)
    taken: list[bool] = []
    fast = rule.Tracker._fast

    def record(self, theta, pred):
        out = fast(self, theta, pred)
        taken.append(out[0] is not None)
        return out

    monkeypatch.setattr(rule.Tracker, "_fast", record)
    result = sc.track(model, thetas, start=truth[0])
    # sample 0 is the start's reading (R0: no call); taken[i - 1] is sample i
    assert len(taken) == count - 1
    assert np.max(np.abs(result.x - np.array([c.x for c in truth]))) < 1e-9
    across = int(np.nonzero(phis > SINGULAR_PHI)[0][0])  # first sample past the singularity
    assert not taken[across - 1]
    assert not taken[0]  # sample 1: no motion known yet, no prediction to start from
    # the Euler step's miss of the truth, relative to the step: y_e = y_(i-1) + J_p^-1 J_s
    # dtheta at the true previous sample (a model without floating joints: one chart)
    ys = np.array([c.y for c in truth])
    euler = np.full(count, np.inf)
    for i in range(1, count):
        Jp, Js = (np.array(J) for J in model.kernels.jac(ys[i - 1], thetas[i - 1], []))
        y_e = ys[i - 1] + np.linalg.solve(Jp, Js @ (thetas[i] - thetas[i - 1]))
        euler[i] = np.max(np.abs(ys[i] - y_e)) / np.max(np.abs(ys[i] - ys[i - 1]))
    # elsewhere, away from the fold, the fast continuation answers where that miss is below
    # the 5 % R2 allows (with a margin for the chart and the sample's Newton residual)
    far = [i for i in range(2, count) if abs(phis[i] - SINGULAR_PHI) > 0.1 and euler[i] < 0.04]
    assert len(far) >= count // 4 and all(taken[i - 1] for i in far)
    assert not any(taken[i - 1] for i in range(2, count) if euler[i] > 0.06)


def test_first_sample_solved_from_start_and_standing_still():
    model = shipped("planar_hexa")
    a = model.inverse_kinematics([0.0, 0.0, 0.30])
    b = model.inverse_kinematics([0.0, 0.0, 0.35])
    thetas = np.array([b.theta, b.theta, b.theta, a.theta])
    result = sc.track(model, thetas, start=a)  # the first reading differs from the start
    assert np.max(np.abs(result.x[:3] - b.x)) < 1e-9
    assert np.max(np.abs(result.x[3] - a.x)) < 1e-9
    assert result.y.shape == (4, model.m)
    assert result.theta.shape == (4, model.k)


def test_bad_readings_and_backends():
    model = shipped("planar_hexa")
    ok = np.tile(model.home.theta, (3, 1))
    with pytest.raises(InputError, match=r"shape \(N, 3\)"):
        sc.track(model, ok[:, :2])
    with pytest.raises(InputError, match="row 1"):
        sc.track(model, np.vstack([ok[0], [np.nan, 0.0, 0.0], ok[2]]))
    with pytest.raises(InputError, match="backends: auto, c, cvodes"):
        sc.track(model, ok, backend="euler")
    home = model.home
    broken = sc.Configuration(home.theta, home.y + 0.2, home.x, home.platform_pose, home.joints)
    with pytest.raises(NotAssembledError):
        sc.track(model, ok, start=broken)


def test_c_backend_is_dispatched_to_track_c(monkeypatch):
    import scdk_sym.solvers.track as track_module

    calls = []

    def fake(model, thetas, start):
        calls.append((model, np.asarray(thetas), start))
        return "from track_c"

    monkeypatch.setattr(track_module, "track_c", fake)
    model = shipped("planar_hexa")
    thetas = np.tile(model.home.theta, (2, 1))
    assert sc.track(model, thetas, start=model.home, backend="c") == "from track_c"
    assert calls[0][0] is model and calls[0][2] is model.home
    assert np.array_equal(calls[0][1], thetas)


def test_the_choice_rule_orders_by_miss_and_refuses_near_ties():
    """R4 on its own: the best candidate is the least miss (the first of equal ones), taken
    only when the runner-up misses MARGIN times more and the best agrees with the motion."""
    from scdk_sym.follower.track_rule import ACCEPT, MARGIN
    from scdk_sym.solvers.tracker import choose

    tol = 1e-12
    # clearly nearer and within ACCEPT of the step: taken, wherever it is in the list
    for miss in ([0.01, 0.5], [0.5, 0.01], [0.5, 0.3, 0.01]):
        order, taken = choose(miss, 0.1, 0.0, tol)
        assert order[0] == int(np.argmin(miss)) and taken
    assert choose([0.01, 0.5, 0.3], 0.1, 0.0, tol)[0] == [0, 2, 1]
    # equal misses: the first listed is c1, and the tie is refused, never broken
    assert choose([0.3, 0.1, 0.1], 0.5, 0.0, tol) == ([1, 2, 0], False)
    assert choose([0.1, 0.1], 0.5, 0.0, tol) == ([0, 1], False)
    # a near tie (runner-up within MARGIN) is refused
    assert choose([0.01, 0.9 * MARGIN * 0.01], 0.1, 0.0, tol)[1] is False
    # the prediction's own error widens the margin
    assert choose([0.01, 0.05], 0.1, 0.0, tol)[1] is True
    assert choose([0.01, 0.05], 0.1, 0.02, tol)[1] is False
    # the best must agree with the predicted step, unless it is the regular cheap step
    assert choose([0.1, 1.0], 0.1 / ACCEPT * 0.9, 0.0, tol)[1] is False
    assert choose([0.1, 1.0], 0.1 / ACCEPT * 0.9, 0.0, tol, regular=0)[1] is True
    assert choose([0.1, 1.0], 0.1 / ACCEPT * 0.9, 0.0, tol, regular=1)[1] is False
    # no motion known (infinite step): nearest to the previous sample, if clearly nearest
    assert choose([0.2, 0.01], np.inf, 0.0, tol) == ([1, 0], True)
    assert choose([0.7], 0.1, 0.0, tol) == ([0], False)


def _newton_root(
    model: sc.Model, y: np.ndarray, theta: np.ndarray, strict: bool = True
) -> np.ndarray:
    """Plain Newton on g(y, theta) = 0 from canonical y: a root to 1e-13 (``strict``: else an
    AssertionError), or the 50th iterate."""
    for _ in range(50):
        y_loc, c = model.chart.to_local(y)
        g = np.array(model.kernels.g(y_loc, theta, c)).ravel()
        Jp = np.array(model.kernels.jac(y_loc, theta, c)[0])
        y = model.chart.to_canonical(y_loc - np.linalg.solve(Jp, g), c)
        if np.max(np.abs(g)) < 1e-13:
            return y
    if strict:
        raise AssertionError("Newton did not converge")
    return y


def test_fast_continuation_never_takes_another_root_next_to_the_prediction():
    """A prediction lying on another root with the sign of det J_p (a poorly extrapolated
    motion) must not be taken by R2's Newton from y_pred: the fast step is tied to y_k by the
    Euler point, the rule falls through, and R4 refuses (the prediction is as inaccurate as
    the step). A prediction next to the continuation is taken, and equals the continuation
    (Newton along the reading's homotopy in 50 steps, independent of the tracker)."""
    from scdk_sym.errors import TrackError
    from scdk_sym.solvers import tracker as rule
    from scdk_sym.solvers.track import ERR_UNDECIDABLE, OK

    model = hexapod()
    theta_k = model.home.theta
    # two roots at theta_k with det J_p of one sign (home and the platform turned over)
    y_k = _newton_root(model, np.array([0.286, 0.0, -0.4, 0.0, 1.465, 0.0]), theta_k)
    other = _newton_root(model, model.home.y, theta_k)
    rng = np.random.default_rng(7)
    theta = theta_k + 2e-3 * rng.uniform(-1.0, 1.0, model.k)
    # the continuation of y_k and the other root, at the new reading
    cont = y_k.copy()
    for s in np.linspace(0.0, 1.0, 51)[1:]:
        cont = _newton_root(model, cont, theta_k + s * (theta - theta_k))
    jump = _newton_root(model, other, theta)
    assert np.max(np.abs(jump - cont)) > 0.5  # far apart: taking one for the other is a jump

    def tracker():
        t = rule.Tracker(model, model.configuration(y_k, theta_k))
        t.n, t.d = 1, [np.zeros(model.m)]
        return t

    t = tracker()
    assert np.sign(t._det(t.local(jump), theta)) == np.sign(t.det) != 0
    step = rule.inf_norm(t.local(jump) - t.y)
    on_other = rule._Prediction(t.local(jump), step, step, step)
    assert t._fast(theta, on_other)[0] is None
    t._prediction = lambda w: on_other
    with pytest.raises(TrackError) as err:
        t.step(theta, 5)
    assert err.value.status == ERR_UNDECIDABLE and err.value.index == 5
    # a prediction next to the continuation is taken: it is the continuation
    t = tracker()
    near = t.local(cont) + 1e-6 * rng.uniform(-1.0, 1.0, model.m)
    pred = rule._Prediction(near, rule.inf_norm(near - t.y), 0.0, 1.0)
    y, det, code = t._fast(theta, pred)
    assert y is not None and code == OK
    np.testing.assert_allclose(model.chart.to_canonical(y, t.c), cont, rtol=0, atol=1e-10)


def test_a_start_next_to_a_fold_with_a_far_partner_guess_is_tracked_on_both_backends():
    """Gepetto's 5bar_linkage started 0.005 sigma_max from a fold where the fold's curvature
    about vanishes (the normal form put the "partner" 1e8 away; Newton from there came back to
    the root, 1e-8 off, and the rule saw two candidates at one distance and refused): every
    sample equals the commanded configuration (walked on the closure manifold by Pinocchio's
    closures, tests/references.py) within the fuzz's tolerance, on both backends."""
    from references import TRACK_TOL, draw_tracks, run_tracks

    track = draw_tracks("5bar_linkage", 20, 0, 100)[5]
    assert track.kind == "singular"
    outcomes = run_tracks([track])
    assert [(o.backend, o.status) for o in outcomes] == [("cvodes", "ok"), ("c", "ok")]
    assert max(o.error for o in outcomes) <= TRACK_TOL
