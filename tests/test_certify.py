"""Interval replay and Krawczyk certificates (scdk_sym.algebraic.interval, .certify).

References are independent of the code under test: systems built around known roots ``r``
(every term carries a factor ``x - r``, so ``f(r) = 0`` exactly in binary64), CasADi's own
float evaluation, numpy/math for the elementary operations, and the paper's example solved
by ``sc.solve``.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from factories import MODELS, SEED_THETA0, SEED_X1, shipped
from flint import arb, ctx

import scdk_sym as sc
from scdk_sym.algebraic import (
    certify_all,
    certify_configuration_sets,
    certify_configurations,
    certify_sets,
    certify_solution,
    closure_function,
    interval_function,
    krawczyk,
)
from scdk_sym.algebraic.interval import balls
from scdk_sym.errors import InputError, IntervalError

EPS = float(np.finfo(float).eps)


def _sq(v):
    return v**2  # CasADi records it as its sq operation


def _random_system(rng: np.random.Generator, n: int) -> tuple[ca.Function, np.ndarray]:
    """A square system with the known regular root r: A (x - r) + quadratic and trig terms."""
    r = rng.uniform(-2, 2, n)
    A = rng.normal(size=(n, n)) + n * np.eye(n)
    x = ca.SX.sym("x", n)
    u = x - r  # exactly 0 at x = r
    rows = []
    for i in range(n):
        j, k = rng.integers(0, n, 2)
        b = rng.normal(size=7)
        rows.append(
            ca.dot(A[i], u)
            + b[0] * u[j] * u[k]
            + b[1] * ca.sin(u[j]) * ca.cos(x[k])
            + b[2] * (ca.exp(u[k]) - 1) * ca.atan2(x[j], 2 + _sq(x[k]))
            + b[3] * ca.tan(u[j]) * u[k] ** 3
            + b[4] * (ca.sqrt(1 + _sq(u[k])) - 1)
            + b[5] * ca.log(1 + _sq(u[j])) / (2 + ca.cos(x[j]))
            + b[6] * (ca.power(1 + _sq(u[j]), 1.5) - 1) * ca.fabs(x[k])
        )
    return ca.Function("f", [x], [ca.vertcat(*rows)]), r


# ------------------------------------------------------------------ (1) known roots


@pytest.mark.parametrize("n", [1, 2, 3, 6])
def test_random_systems_with_known_roots_are_proven_around_the_root(n):
    rng = np.random.default_rng(100 + n)
    for _ in range(4):
        f, r = _random_system(rng, n)
        x = r + rng.uniform(-1e-9, 1e-9, n)  # an approximate zero, as a solver returns it
        c = krawczyk(f, x)
        assert c.proven, c.reason
        assert c.contains(r)
        assert c.radius <= 1e-6
        assert np.all(c.domain[:, 0] <= r) and np.all(r <= c.domain[:, 1])


def test_a_rough_point_gets_a_wide_uniqueness_box_and_a_tight_enclosure():
    rng = np.random.default_rng(5)
    f, r = _random_system(rng, 3)
    x = r + rng.choice([-1, 1], 3) * 1e-4
    rough = krawczyk(f, x, tighten=0)
    tight = krawczyk(f, x)
    assert rough.proven and tight.proven, (rough.reason, tight.reason)
    assert tight.contains(r) and rough.contains(r)
    assert tight.radius <= 1e-13 < 1e-9 <= rough.radius
    assert np.all(tight.domain[:, 0] < r - 1e-4) and np.all(r + 1e-4 < tight.domain[:, 1])


def test_a_parameter_box_is_certified_for_every_parameter_in_it():
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p")
    f = ca.Function("f", [x, p], [ca.vertcat(x[0] ** 2 + x[1] ** 2 - p, x[0] - 2 * x[1])])
    root = np.array([2.0, 1.0]) / math.sqrt(5)  # the zero at p = 1 with x0 = 2 x1 > 0
    thin = krawczyk(f, root, [1.0])
    wide = krawczyk(f, root, [[1 - 1e-6, 1 + 1e-6]])
    assert thin.proven and wide.proven, (thin.reason, wide.reason)
    assert wide.radius > 1e-7 > thin.radius  # the zero moves by ~ 2e-7 over the box
    for q in (1 - 1e-6, 1 + 1e-6):
        assert wide.contains(np.array([2.0, 1.0]) * math.sqrt(q / 5))


# ------------------------------------------------------------------ (2) model solutions


@pytest.fixture(scope="module")
def seed():
    """The paper's example (models/planar_hexa) solved on both branches."""
    model = shipped("planar_hexa")
    start = model.inverse_kinematics(SEED_X1)
    return model, {b: sc.solve(model, SEED_THETA0, start=start, branch=b) for b in BRANCHES}


BRANCHES = ("convergent", "divergent")


def test_both_branches_of_the_papers_example_are_proven_distinct(seed):
    model, res = seed
    ys = [res[b].y for b in BRANCHES]
    for y in ys:
        c = certify_solution(model, y, SEED_THETA0)
        assert c.proven, c.reason
        assert c.radius <= 1e-9 and c.contains(y)
    s = certify_all(closure_function(model), ys, SEED_THETA0)
    assert s.proven and s.count == 2 and not s.overlaps, s.reason


def test_stewart_gough_solutions_from_inverse_kinematics_are_proven():
    model = shipped("stewart_gough")
    rng = np.random.default_rng(7)
    for _ in range(2):
        pose = model.home.x + np.r_[rng.uniform(-0.03, 0.03, 3), rng.uniform(-0.1, 0.1, 3)]
        cfg = model.inverse_kinematics(pose)
        y, chart = model.chart.to_local(cfg.y)
        c = krawczyk(closure_function(model), y, np.r_[cfg.theta, chart])
        assert c.proven, c.reason
        assert c.radius <= 1e-9 and c.contains(y)
        assert certify_solution(model, cfg.y, cfg.theta).proven


# ------------------------------------------------------------------ (3) far from any zero


def test_points_far_from_any_zero_are_not_proven(seed):
    x = ca.SX.sym("x", 2)
    no_zero = ca.Function("f", [x], [ca.vertcat(_sq(x[0]) + _sq(x[1]) + 1, x[0] - x[1])])
    c = krawczyk(no_zero, [0.3, 0.3])
    assert not c.proven and "contract" in c.reason
    model, res = seed
    c = certify_solution(model, res["convergent"].y + 0.3, SEED_THETA0)
    assert not c.proven and c.reason and c.tries >= 1


# ------------------------------------------------------------------ (4) singular zeros


def test_double_roots_are_not_proven():
    x = ca.SX.sym("x")
    square = ca.Function("f", [x], [x**2])
    for x0 in (0.0, 1e-7):
        c = krawczyk(square, [x0])
        assert not c.proven and ("singular" in c.reason or "contract" in c.reason), c.reason
    z = ca.SX.sym("z", 2)  # the unit circle tangent to the line y = 1 at (0, 1)
    tangent = ca.Function("t", [z], [ca.vertcat(_sq(z[0]) + _sq(z[1]) - 1, z[1] - 1)])
    for z0 in ([0.0, 1.0], [1e-6, 1.0]):
        c = krawczyk(tangent, z0)
        assert not c.proven, c.reason


def test_the_singular_configuration_of_the_papers_example_is_not_proven(seed):
    model, res = seed
    fold = res["divergent"].crossings[0]
    c = certify_solution(model, fold.y, fold.theta)
    assert not c.proven and "singular" in c.reason, c.reason


# ------------------------------------------------------------------ (5) nearby roots


def test_two_nearby_roots_get_disjoint_boxes():
    a, b = 0.5, 0.5 + 1e-7
    x = ca.SX.sym("x", 2)
    f = ca.Function("f", [x], [ca.vertcat((x[0] - a) * (x[0] - b), x[1] - ca.sin(x[0]))])
    xs = [[a, math.sin(a)], [b, math.sin(b)]]
    s = certify_all(f, xs)
    assert s.proven and s.count == 2 and not s.overlaps, s.reason
    first, second = s.certificates
    assert first.box[0, 1] < second.box[0, 0]
    twice = certify_all(f, [xs[0], xs[1], np.add(xs[0], 1e-12)])
    assert not twice.proven and twice.count == 2 and twice.duplicates == ((0, 2),), twice.reason
    assert "counted twice" in twice.reason


# ------------------------------------------------------------------ (6) replay = float evaluation


@pytest.mark.parametrize("name", sorted(p.name for p in MODELS.iterdir() if p.is_dir()))
def test_replay_of_every_shipped_closure_system_matches_casadi(name):
    model = shipped(name)
    s = model.symbolic
    g = ca.Function("g", [s.y, s.theta, s.c], [s.g, s.J_p])
    replay = interval_function(g)
    rng = np.random.default_rng(3)
    for _ in range(5):
        args = [
            rng.normal(0, 0.5, model.m),
            model.home.theta + rng.normal(0, 0.1, model.k),
            rng.normal(size=s.c.numel()),  # any numbers: the chart enters polynomially
        ]
        ref = [np.array(v).ravel(order="F") for v in g(*args)]
        ref[1] = np.array(ca.densify(g(*args)[1])).ravel(order="F")
        got = replay(*(balls(a) for a in args))
        for values, balls_ in zip(ref, got, strict=True):
            mid = np.array([float(b.mid()) for b in balls_])
            assert np.all(np.abs(mid - values) <= 1e-12 * (1 + np.abs(values)))
            for v, ball in zip(values, balls_, strict=True):
                # the ball holds the exact value; the float value carries its own rounding
                # (measured: outside the ball by < 1 ulp for 11 of 2920 values)
                slack = arb(0, 4 * EPS * (1 + abs(v)))
                assert (ball + slack).contains(arb(v)), (v, ball)


_OPS = {
    "add": (lambda a, b: a + b, lambda a, b: a + b),
    "sub": (lambda a, b: a - b, lambda a, b: a - b),
    "mul": (lambda a, b: a * b, lambda a, b: a * b),
    "div": (lambda a, b: a / b, lambda a, b: a / b),
    "atan2": (ca.atan2, math.atan2),
    "fmin": (ca.fmin, min),
    "fmax": (ca.fmax, max),
    "hypot": (ca.hypot, math.hypot),
    "pow": (lambda a, b: ca.fabs(a) ** b, lambda a, b: abs(a) ** b),
    "integer pow": (lambda a, b: a ** ca.floor(b), lambda a, b: a ** math.floor(b)),
    "neg": (lambda a, b: -a, lambda a, b: -a),
    "sq": (lambda a, b: _sq(a), lambda a, b: a * a),
    "cube": (lambda a, b: a**3, lambda a, b: a**3),
    "inverse cube": (lambda a, b: a**-3, lambda a, b: a**-3),
    "real power": (lambda a, b: ca.fabs(a) ** 2.5, lambda a, b: abs(a) ** 2.5),
    "twice": (lambda a, b: 2 * a, lambda a, b: 2 * a),
    "inv": (lambda a, b: 1 / a, lambda a, b: 1 / a),
    "sqrt": (lambda a, b: ca.sqrt(ca.fabs(a)), lambda a, b: math.sqrt(abs(a))),
    "sin": (lambda a, b: ca.sin(a), lambda a, b: math.sin(a)),
    "cos": (lambda a, b: ca.cos(a), lambda a, b: math.cos(a)),
    "tan": (lambda a, b: ca.tan(a), lambda a, b: math.tan(a)),
    "exp": (lambda a, b: ca.exp(a), lambda a, b: math.exp(a)),
    "log": (lambda a, b: ca.log(ca.fabs(a)), lambda a, b: math.log(abs(a))),
    "fabs": (lambda a, b: ca.fabs(a), lambda a, b: abs(a)),
    "asin": (lambda a, b: ca.asin(a / 4), lambda a, b: math.asin(a / 4)),
    "tanh": (lambda a, b: ca.tanh(a), lambda a, b: math.tanh(a)),
    "if_else": (lambda a, b: ca.if_else(a < b, a, b * b), lambda a, b: a if a < b else b * b),
    "logic": (
        lambda a, b: ca.if_else(ca.logic_or(ca.logic_and(a <= b, a != b), a == b), a, -b),
        lambda a, b: a if (a <= b and a != b) or a == b else -b,
    ),
}


@pytest.mark.parametrize("op", sorted(_OPS))
def test_each_operation_encloses_its_values_over_a_ball(op):
    sym, ref = _OPS[op]
    a, b = ca.SX.sym("a"), ca.SX.sym("b")
    f = interval_function(ca.Function("f", [a, b], [sym(a, b)]))
    rng = np.random.default_rng(11)
    for _ in range(20):
        centre = rng.uniform(0.2, 3, 2) * rng.choice([-1, 1], 2)
        out = f(*([arb(c, 1e-3)] for c in centre))[0][0]
        for _ in range(5):
            point = centre + rng.uniform(-1e-3, 1e-3, 2)
            assert out.contains(arb(ref(*point))), (op, point, out)
        assert out.rad() < 1e3 * 1e-3 * (1 + abs(out.mid()))  # bounded, not a blow-up


def test_undecided_comparisons_enclose_both_branches():
    a, b = ca.SX.sym("a"), ca.SX.sym("b")
    f = interval_function(ca.Function("f", [a, b], [ca.if_else(a < b, a, 3 - b)]))
    out = f([arb(1, 0.1)], [arb(1)])[0][0]  # a < b undecided over a in [0.9, 1.1]
    assert all(out.contains(arb(v)) for v in (0.9, 0.95, 2.0))
    decided = f([arb(0.5, 0.1)], [arb(1)])[0][0]
    assert decided.contains(arb(0.5)) and not decided.contains(arb(2.0))


def test_unsupported_operations_are_named():
    a = ca.SX.sym("a")
    with pytest.raises(IntervalError, match="copysign") as err:
        interval_function(ca.Function("f", [a], [ca.copysign(a, 1.0)]))
    assert err.value.operation == "copysign"


def test_wrong_inputs_are_refused():
    x = ca.SX.sym("x", 2)
    f = ca.Function("f", [x], [x[0]])
    with pytest.raises(InputError, match="not square"):
        krawczyk(f, [0.0, 0.0])
    g = ca.Function("g", [x], [x])
    with pytest.raises(InputError, match="x must be 2"):
        krawczyk(g, [0.0])
    assert krawczyk(g, np.array([0.0, 0.0], dtype=complex)).proven  # real values, complex dtype
    with pytest.raises(InputError, match="imaginary"):
        krawczyk(g, [1j, 0.0])


def test_the_assembly_modes_of_the_hexapod_are_proven_distinct_in_one_chart():
    model = shipped("stewart_gough")
    theta = model.home.theta
    ys = [cfg.y for cfg in sc.assembly_modes(model, theta)]
    s = certify_configurations(model, ys, theta)
    assert s.proven and s.count == len(ys) >= 2, s.reason
    again = certify_configurations(model, [*ys, ys[1] + 1e-10], theta)
    assert not again.proven and again.count == len(ys)
    assert again.duplicates == ((1, len(ys)),), again.reason
    half_turn = np.array(ys[0])
    half_turn[list(model.chart.rotations[0])] = [math.pi, 0.0, 0.0]  # about x, from identity
    with pytest.raises(InputError, match="half turn"):
        certify_configurations(model, [half_turn], theta, np.eye(3).ravel())


def test_sets_at_several_points_certified_at_once_equal_one_set_at_a_time():
    """The modes of the hexapod at three leg vectors, certified in one call: the boxes and
    verdicts of three separate calls (the points' parameters differ: each box is its own
    point's)."""
    model = shipped("stewart_gough")
    rng = np.random.default_rng(3)
    sets = []
    for _ in range(3):
        theta = model.home.theta * (1 + 0.01 * rng.normal(size=model.k))
        ys = np.array([cfg.y for cfg in sc.assembly_modes(model, theta)])
        sets.append((ys, theta, None))
    together = certify_configuration_sets(model, sets)
    for (ys, theta, _), got in zip(sets, together, strict=True):
        one = certify_configurations(model, ys, theta)
        assert got.proven and got.count == one.count == len(ys) >= 2
        assert got.reason == one.reason
        for a, b in zip(got.certificates, one.certificates, strict=True):
            np.testing.assert_array_equal(a.box, b.box)
            assert a.radius <= 1e-9 * (1 + np.abs(a.x).max())
    with pytest.raises(InputError, match="one parameter vector per set"):
        certify_sets(closure_function(model), [sets[0][0]], [])


def test_an_mx_function_is_expanded_and_inputs_are_checked():
    x = ca.MX.sym("x", 2)
    f = ca.Function("f", [x], [ca.vertcat(ca.sin(x[0]) * x[1], x[0] - x[1] ** 2)])
    replay = interval_function(f)
    assert replay.function.is_a("SXFunction")
    got = replay(balls([0.5, -1.5]))[0]
    want = np.array(f([0.5, -1.5])).ravel()
    assert all((g + arb(0, 4 * EPS)).contains(arb(w)) for g, w in zip(got, want, strict=True))
    assert interval_function(f) is replay  # translated once
    with pytest.raises(InputError, match="has 2 entries"):
        replay(balls([0.5]))


@pytest.mark.parametrize("prec", [30, 120])
def test_certificates_hold_at_other_arb_precisions(prec):
    rng = np.random.default_rng(9)
    f, r = _random_system(rng, 3)
    old = ctx.prec
    try:
        ctx.prec = prec
        c = krawczyk(f, r + 1e-9)
    finally:
        ctx.prec = old
    assert c.proven and c.contains(r), c.reason
    assert c.radius <= (1e-6 if prec < 53 else 1e-14)


def test_configuration_sets_at_once_equal_set_by_set():
    """certify_configuration_sets of several Stewart-Gough sets (rotations in a common chart
    per set, given or not): bit for bit the sets certified one at a time (the loop of
    ``_local`` and ``certify_sets``), and sets whose boxes are disjoint said so by the
    comparison of all sets at once as by the pairwise one."""
    from scdk_sym.algebraic.certify import configurations as cm
    from scdk_sym.algebraic.certify.disjoint import certificate_set

    model = shipped("stewart_gough")
    rng = np.random.default_rng(2)
    sets = []
    for _ in range(6):
        theta = model.home.theta * (1 + 0.02 * rng.normal(size=model.k))
        modes = sc.assembly_modes(model, theta)
        ys = np.vstack([s.y for s in modes])[: int(rng.integers(1, len(modes) + 1))]
        c = None if rng.random() < 0.5 else model.chart.to_local(ys[-1])[1]
        sets.append((ys, theta, c))
    at_once = cm.certify_configuration_sets(model, sets)
    for (ys, theta, c), got in zip(sets, at_once, strict=True):
        local, q = cm._local(model, ys, theta, c)
        want = cm.certify_sets(cm.closure_function(model), [local], [q])[0]
        assert got.reason == want.reason and got.count == want.count
        assert got.overlaps == want.overlaps and got.duplicates == want.duplicates
        for a, b in zip(got.certificates, want.certificates, strict=True):
            assert a.box.tobytes() == b.box.tobytes() and a.x.tobytes() == b.x.tobytes()
        plain = certificate_set(got.certificates)  # every pair compared again
        assert plain.reason == got.reason and plain.overlaps == got.overlaps


def test_first_coordinate_screen_agrees_with_the_pairwise_box_test():
    """``_apart_in_first`` (a sort of the first coordinates) says "pairwise disjoint" only for
    sets whose every pair is apart in the first coordinate, checked pair by pair; sets where
    only the first coordinates are tested must include touching ends and NaN bounds."""
    from scdk_sym.algebraic.certify.disjoint import _apart_in_first

    rng = np.random.default_rng(11)
    seen = {True: 0, False: 0}
    for trial in range(400):
        P = int(rng.integers(0, 12))
        lo = rng.uniform(0, 1, P).round(int(rng.integers(1, 4)))  # ties and touching ends
        hi = lo + rng.choice([0.0, 0.001, 0.01, 0.2], P)
        first = np.stack([lo, hi], axis=1)
        if trial % 37 == 0 and P:
            first[rng.integers(P), rng.integers(2)] = np.nan
        # independent reference: every pair, [a, b] and [c, d] meet when a <= d and c <= b
        apart = (
            all(
                not (first[i, 0] <= first[j, 1] and first[j, 0] <= first[i, 1])
                for i in range(P)
                for j in range(i + 1, P)
            )
            and not np.isnan(first).any()
        )
        assert _apart_in_first(first) == (apart or P < 2), first
        seen[apart] += 1
    assert min(seen.values()) > 50  # both answers exercised
