"""Both trackers (``backend="cvodes"`` and ``backend="c"``) judge readings by one rule.

The ground truth is a platform motion chosen first; the joint readings are its closed-form
inverse kinematics. On every path each backend must either follow the commanded motion (max
|x - x_commanded| <= 1e-6) or raise :class:`TrackError`; never deviate silently. When both
follow, their poses agree to 1e-9 and their crossing records (det J_p sign changes between
samples) are identical; when one refuses, the other refuses at the same sample. Singular
crossings are checked against a closed-form singularity condition of each mechanism.
"""

from __future__ import annotations

import numpy as np
import pytest
import stewart
from factories import MODELS, needs_compiler, shipped
from stewart import fold_path

from scdk_sym.codegen import library as clib
from scdk_sym.errors import TrackError
from scdk_sym.follower import track_rule as constants
from scdk_sym.model.rotations import rpy_matrix
from scdk_sym.solvers import track as rule
from scdk_sym.solvers.track import track

pytestmark = needs_compiler()

BACKENDS = ("cvodes", "c")
FOLLOW = 1e-6  # a backend follows the motion when max |x - x_commanded| stays below this
SAME = 1e-9  # the two backends agree to this (poses, crossing s and x, relative)

# ---------------------------------------------------------------- closed-form references

ARM = ROD = 7.0  # the seed robot (models/planar_hexa, cm): 3-RRR, arm = rod = 7
_A = np.radians([-30.0, -150.0, 90.0])
BASE = 20.0 / np.sqrt(3.0) * np.c_[np.cos(_A), np.sin(_A)]  # base vertices, side 20
PLATFORM_RADIUS = 10.0 / np.sqrt(3.0)  # platform side 10


def seed_legs(x):
    """(platform vertices C (3, 2), elbows E (3, 2), theta (3,)) of the seed robot at pose
    x = (x, y, phi), working mode theta_i = atan2(d) - acos((|d|^2 + arm^2 - rod^2) /
    (2 arm |d|)) with d = C_i - A_i."""
    C = np.asarray(x[:2]) + PLATFORM_RADIUS * np.c_[np.cos(_A + x[2]), np.sin(_A + x[2])]
    d = C - BASE
    r = np.linalg.norm(d, axis=1)
    theta = np.arctan2(d[:, 1], d[:, 0]) - np.arccos((r**2 + ARM**2 - ROD**2) / (2 * ARM * r))
    E = BASE + ARM * np.c_[np.cos(theta), np.sin(theta)]
    return C, E, theta


def seed_thetas(X):
    return np.array([seed_legs(x)[2] for x in X])


def seed_singularity(x) -> float:
    """det of the rods' line coordinates [u_i, (C_i - P) x u_i]: zero where the three rods
    are concurrent or parallel (the direct-kinematic singularity of a 3-RRR)."""
    C, E, _ = seed_legs(x)
    u = (C - E) / ROD
    arm = C - np.asarray(x[:2])
    return float(np.linalg.det(np.c_[u, arm[:, 0] * u[:, 1] - arm[:, 1] * u[:, 0]]))


HEXAPOD_A, HEXAPOD_B = stewart.anchors(MODELS / "stewart_gough")


def hexapod_thetas(X):
    return stewart.leg_lengths(X, HEXAPOD_A, HEXAPOD_B)


def hexapod_singularity(x) -> float:
    """det of the 6-6 platform's leg Jacobian [u_i, (R b_i) x u_i] (u_i unit leg vectors)."""
    Rb = HEXAPOD_B @ rpy_matrix(*x[3:]).T
    d = x[:3] + Rb - HEXAPOD_A
    u = d / np.linalg.norm(d, axis=1)[:, None]
    return float(np.linalg.det(np.hstack([u, np.cross(Rb, u)])))


# ---------------------------------------------------------------- paths


def seed_line(n):
    """The seed robot turning its platform phi = 0.40 -> 1.00 at x = y = 0 (through 0.5754)."""
    phis = np.linspace(0.40, 1.00, n)
    return np.c_[0 * phis, 0 * phis, phis]


def seed_loop(n):
    """A closed loop of the seed robot's platform (cm, rad) that crosses its singular surface
    four times: a circle of radius 0.5 cm while phi swings twice between 0.25 and 0.85."""
    t = np.linspace(0.0, 1.0, n)
    w = 2 * np.pi * t
    return np.c_[0.5 * np.sin(w), 0.5 * (1 - np.cos(w)), 0.55 + 0.3 * np.sin(2 * w - 0.9)]


def random_path(rng, x0, amplitude, n):
    """A smooth random pose path from x0: three sines per coordinate (seeded)."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    X = np.tile(np.asarray(x0, float), (n, 1))
    for f in (0.5, 1.0, 1.5):
        a = amplitude * rng.uniform(-1, 1, len(x0))
        phase = rng.uniform(0, 2 * np.pi, len(x0))
        X += a * (np.sin(2 * np.pi * f * t + phase) - np.sin(phase))
    return X


def seed_reachable(X) -> bool:
    """Every rod clear of full stretch (90%) and of the base vertex (2 cm)."""
    r = np.array([np.linalg.norm(seed_legs(x)[0] - BASE, axis=1) for x in X])
    return bool(r.max() < 0.9 * (ARM + ROD) and r.min() > 2.0)


# ---------------------------------------------------------------- the two backends


def outcomes(model, thetas, start, X):
    """backend -> ("follow", TrackResult) or ("raise", TrackError); asserts no silent deviation,
    neither in a finished track nor in the samples before a refusal."""
    out = {}
    for backend in BACKENDS:
        try:
            res = track(model, thetas, start=start, backend=backend)
        except TrackError as err:
            assert err.status == rule.ERR_UNDECIDABLE, (backend, str(err))
            out[backend] = ("raise", err)
            if err.index > 0:
                before = track(model, thetas[: err.index], start=start, backend=backend)
                error = float(np.max(np.abs(before.x - X[: err.index])))
                assert error <= FOLLOW, f"{backend} deviates before refusing, by {error:.3g}"
            continue
        error = float(np.max(np.abs(res.x - X)))
        assert error <= FOLLOW, f"{backend} deviates silently from the motion by {error:.3g}"
        assert np.all(res.residual <= model.tolerance)
        out[backend] = ("follow", res)
    return out


def assert_same_decisions(out):
    (kind_a, a), (kind_b, b) = out["cvodes"], out["c"]
    assert kind_a == kind_b, f"cvodes: {kind_a}, c: {kind_b}"
    if kind_a == "raise":
        assert a.index == b.index and a.status == b.status
        assert len(a.candidates) == len(b.candidates)
        for xa, xb in zip(a.candidates, b.candidates, strict=True):
            np.testing.assert_allclose(xa, xb, rtol=0, atol=SAME)
        return
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=SAME)
    assert [(c.index, c.kind) for c in a.crossings] == [(c.index, c.kind) for c in b.crossings]
    for ca, cb in zip(a.crossings, b.crossings, strict=True):
        assert abs(ca.s - cb.s) <= SAME * max(1.0, abs(ca.s))
        np.testing.assert_allclose(ca.x, cb.x, rtol=SAME, atol=SAME)


def sign_changes(values) -> list[int]:
    v = np.sign(values)
    return [int(i) for i in np.flatnonzero(v[:-1] * v[1:] < 0)]


def assert_crossings_on_the_singular_surface(res, X, singularity):
    """Crossing records where the commanded motion crosses the singular surface, located on it."""
    dets = [singularity(x) for x in X]
    assert [c.index for c in res.crossings] == sign_changes(dets)
    typical = float(np.median(np.abs(dets)))
    for c in res.crossings:
        assert c.kind == "fold" and 0.0 <= c.s <= 1.0
        assert abs(singularity(c.x)) < 1e-6 * typical
        lo, hi = X[c.index], X[c.index + 1]  # between the samples it is recorded between
        assert np.all(c.x >= np.minimum(lo, hi) - 1e-3) and np.all(c.x <= np.maximum(lo, hi) + 1e-3)


# ---------------------------------------------------------------- fixed paths


@pytest.fixture(scope="module")
def hexapod():
    return shipped("stewart_gough")


@pytest.fixture(scope="module")
def seed():
    return shipped("planar_hexa")


@pytest.mark.parametrize("every", [1, 10, 20])  # 399, 40 and 20 samples
def test_hexapod_fold_path_both_backends_follow_alike(hexapod, every):
    X = fold_path(hexapod.home.x, 400)
    thetas = hexapod_thetas(X)
    start = hexapod.inverse_kinematics(X[0])
    out = outcomes(hexapod, thetas[1::every], start, X[1::every])
    assert_same_decisions(out)
    assert out["c"][0] == "follow"  # the path is fine enough at every one of these samplings
    res = out["cvodes"][1]
    assert len(res.crossings) == 1 and abs(res.crossings[0].x[5] - 1.5707) < 1e-3
    assert_crossings_on_the_singular_surface(res, X[1::every], hexapod_singularity)


@pytest.mark.parametrize("count", [13, 27, 61, 200])
def test_seed_line_through_the_fold_both_backends_follow_alike(seed, count):
    X = seed_line(count)
    out = outcomes(seed, seed_thetas(X), seed.inverse_kinematics(X[0]), X)
    assert_same_decisions(out)
    assert out["c"][0] == "follow"
    res = out["cvodes"][1]
    assert_crossings_on_the_singular_surface(res, X, seed_singularity)
    assert len(res.crossings) == 1
    assert abs(res.crossings[0].x[2] - 0.575360) < 1e-5  # the paper's singular configuration
    assert np.max(np.abs(res.crossings[0].x[:2])) < 1e-9  # on the commanded motion x = y = 0


@pytest.mark.parametrize(("count", "expected"), [(13, "raise"), (27, "raise"), (61, "follow"),
                                                 (200, "follow")])  # fmt: skip
def test_seed_closed_loop_crossing_four_times(seed, count, expected):
    X = seed_loop(count)
    np.testing.assert_allclose(X[-1], X[0], rtol=0, atol=1e-12)
    thetas = seed_thetas(X)
    flips = sign_changes([seed_singularity(x) for x in X])
    assert len(flips) == 4
    out = outcomes(seed, thetas, seed.inverse_kinematics(X[0]), X)
    assert_same_decisions(out)
    kind, value = out["cvodes"]
    assert kind == expected
    if kind == "follow":
        assert_crossings_on_the_singular_surface(value, X, seed_singularity)
        np.testing.assert_allclose(value.x[-1], value.x[0], rtol=0, atol=FOLLOW)  # closed
    else:
        # refused next to a crossing of the commanded motion; the commanded pose is one of the
        # two candidates it could not tell apart
        assert min(abs(value.index - f) for f in flips) <= 1
        assert len(value.candidates) == 2
        assert min(np.max(np.abs(x - X[value.index])) for x in value.candidates) < FOLLOW
        np.testing.assert_array_equal(value.theta, thetas[value.index])
        assert f"sample {value.index}:" in str(value) and "too coarse" in str(value)


# ---------------------------------------------------------------- random paths


def random_cases():
    """20 seed-robot paths (phi from 0.4-0.6, the singular 0.5754 among them) and 12 hexapod
    paths (yaw from 1.35-1.6, the singular 90 deg among them), 40-150 samples each, seeded."""
    rng = np.random.default_rng(0)
    seed, hexapod = shipped("planar_hexa"), shipped("stewart_gough")
    cases = []
    while len(cases) < 20:
        n = int(rng.integers(40, 150))
        x0 = np.array([0.0, 0.0, rng.uniform(0.4, 0.6)])
        X = random_path(rng, x0, np.array([0.3, 0.3, 0.15]), n)
        if seed_reachable(X):
            cases.append((seed, seed_thetas(X), seed.inverse_kinematics(X[0]), X))
    for _ in range(12):
        n = int(rng.integers(40, 150))
        x0 = hexapod.home.x + np.array([0, 0, 0, 0, 0, rng.uniform(1.35, 1.6)])
        X = random_path(rng, x0, np.array([0.02, 0.02, 0.02, 0.05, 0.05, 0.12]), n)
        cases.append((hexapod, hexapod_thetas(X)[1:], hexapod.inverse_kinematics(X[0]), X[1:]))
    return cases


def test_random_paths_never_deviate_silently_and_both_backends_decide_alike():
    followed = crossed = 0
    for model, thetas, start, X in random_cases():
        out = outcomes(model, thetas, start, X)  # asserts: no silent deviation in either
        assert_same_decisions(out)
        kind, res = out["c"]
        if kind == "follow":
            followed += 1
            crossed += bool(res.crossings)
            singularity = hexapod_singularity if model.k == 6 else seed_singularity
            assert [c.index for c in res.crossings] == sign_changes([singularity(x) for x in X])
    # not vacuous: most paths are followed, many of them through singularities
    assert followed >= 22 and crossed >= 8, (followed, crossed)


# ---------------------------------------------------------------- one rule, one vocabulary


def test_generated_defaults_are_the_rule_constants(hexapod):
    opt = clib.tracker_library(hexapod).default_options()
    assert (opt.accept, opt.margin, opt.arc_budget, opt.max_steps, opt.order) == (
        constants.ACCEPT, constants.MARGIN, constants.BUDGET, constants.MAX_STEPS, 2,
    )  # fmt: skip
    assert clib.ERR_UNDECIDABLE == rule.ERR_UNDECIDABLE == -9 and -9 in clib.STATUS
    assert (clib.ERR_NO_SOLUTION, clib.ERR_VERIFY) == (rule.ERR_NO_SOLUTION, rule.ERR_VERIFY)


def test_the_c_header_states_the_rule(tmp_path, hexapod):
    from scdk_sym.codegen.generate import generate

    header = generate(hexapod, tmp_path).tracker_h.read_text()
    for clause in ("R0 Rest", "R1 Prediction", "R2 Cheap", "R3 Candidates", "R4 The answer is c1",
                   "R5 The answer must"):  # fmt: skip
        assert clause in header
    assert "#define SCDK_ERR_UNDECIDABLE (-9)" in header and "scdk_refusal" in header


def test_refusal_in_the_c_tracker_keeps_the_state_and_names_both_candidates(seed):
    X = seed_loop(13)
    thetas = seed_thetas(X)
    start = seed.inverse_kinematics(X[0])
    y0, c0 = seed.chart.to_local(start.y)
    out = clib.tracker_library(seed).track(y0, c0, start.theta, thetas)
    # the loop crosses the singular surface in its first step, before any motion is known
    assert out.status == clib.ERR_UNDECIDABLE and out.failed == 1
    assert out.codes[0] == clib.OK
    assert list(out.codes[1:3]) == [clib.ERR_UNDECIDABLE, clib.ERR_STATE]
    assert np.all(np.isnan(out.x[1:])) and np.isinf(out.refusal.step)
    r = out.refusal
    assert r.x.shape == (2, 3) and r.y.shape == (2, seed.m)
    assert r.miss[0] <= r.miss[1] <= constants.MARGIN * max(r.miss[0], r.accuracy)
    np.testing.assert_array_equal(r.theta, thetas[1])
    # each candidate is an assembled configuration at the reading, with the reported pose
    for y, x in zip(r.y, r.x, strict=True):
        cfg = seed.configuration(y, thetas[1], r.c)
        assert cfg.residual <= seed.tolerance
        np.testing.assert_allclose(cfg.x, x, rtol=0, atol=1e-12)
