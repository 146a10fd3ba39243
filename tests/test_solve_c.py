"""The convergent solve in one call of the generated C follower (scdk_sym.solvers.solve_c)."""

import numpy as np
import pytest
from factories import SEED_THETA0, SEED_X1, needs_compiler, shipped

import scdk_sym as sc
from scdk_sym.codegen import library as clib
from scdk_sym.errors import PathError

pytestmark = needs_compiler()


def compare(model, start, targets):
    """solve(backend="c") against the CVODES solve (fast=False) at each target; returns the
    raw C statuses."""
    lib = clib.tracker_library(model)
    y1, c1 = model.chart.to_local(start.y)
    statuses = []
    for theta0 in targets:
        statuses.append(lib.solve_convergent(y1, c1, start.theta, theta0).status)
        try:
            ref = sc.solve(model, theta0, start=start, fast=False, record_path=False)
        except sc.ScdkError as exc:
            with pytest.raises(type(exc)):
                sc.solve(model, theta0, start=start, backend="c")
            continue
        res = sc.solve(model, theta0, start=start, backend="c")
        assert_same_answer(model, res, ref, "convergent")
    return statuses


def assert_same_answer(model, res, ref, branch: str, whole_crossings: bool = False) -> None:
    """``res`` equals ``ref``: x and y to 1e-9, status, b, branch, the crossings' kinds and
    their s (to 1e-6; with ``whole_crossings`` to 1e-9, with index, x, y and theta)."""
    np.testing.assert_allclose(res.x, ref.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.y, ref.y, rtol=0, atol=1e-9)
    assert res.residual <= model.tolerance and res.status == ref.status
    assert res.b == ref.b and res.branch == branch
    assert [c.kind for c in res.crossings] == [c.kind for c in ref.crossings]
    for a, b in zip(res.crossings, ref.crossings, strict=True):
        if not whole_crossings:
            assert a.s == pytest.approx(b.s, abs=1e-6)
            continue
        assert a.s == pytest.approx(b.s, abs=1e-9) and a.index == b.index
        for name in ("x", "y", "theta"):
            np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-9)


def test_seed_robot_equals_the_cvodes_solve():
    model = shipped("planar_hexa")
    start = model.inverse_kinematics(SEED_X1)
    rng = np.random.default_rng(21)
    targets = [SEED_THETA0, *(SEED_THETA0 + rng.normal(scale=0.05, size=(15, 3)))]
    statuses = compare(model, start, targets)
    assert statuses[0] == clib.OK_PATH  # the paper's example is solved in C
    assert statuses.count(clib.OK_PATH) >= 10, statuses


def test_hexapod_equals_the_cvodes_solve():
    model = shipped("stewart_gough")
    rng = np.random.default_rng(22)
    targets = model.home.theta + rng.normal(scale=0.01, size=(10, 6))  # m
    statuses = compare(model, model.home, targets)
    assert statuses.count(clib.OK_PATH) >= 8, statuses


def test_other_branches_and_refusals_fall_back():
    model = shipped("planar_hexa")
    start = model.inverse_kinematics(SEED_X1)
    # an explicit b and an explicit arc budget are solved by the compiled solve
    for kw in ({"b": -1.0}, {"b": 1.0}, {"branch": "divergent", "max_arc": 50.0}):
        res = sc.solve(model, SEED_THETA0, start=start, backend="c", record_path=False, **kw)
        ref = sc.solve(model, SEED_THETA0, start=start, backend="compiled", record_path=False,
                       **kw)  # fmt: skip
        np.testing.assert_allclose(res.x, ref.x, rtol=0, atol=1e-12)
        assert res.b == ref.b and len(res.crossings) == len(ref.crossings)
        # the hand-over is reported, never silent
        assert (res.backend, ref.backend, ref.fallback) == ("compiled", "compiled", "")
        word = "b is solved" if "b" in kw else "max_arc"
        assert res.fallback.startswith("backend 'c' handed over to 'compiled'") and word in (
            res.fallback
        )
        assert res.to_dict()["fallback"] == res.fallback
    assert res.x[2] == pytest.approx(0.9999, abs=1e-4) and len(res.crossings) == 1
    own = sc.solve(model, SEED_THETA0, start=start, backend="c", record_path=False)
    assert (own.backend, own.fallback) == ("c", "") and "fallback" not in own.to_dict()
    cv = sc.solve(model, SEED_THETA0, start=start, record_path=False)
    assert (cv.backend, cv.to_dict()["backend"]) == ("cvodes", "cvodes")
    # behind the start on the line: the convergent curve turns at a fold before any s = 1
    # crossing, so the C call refuses and the fallback says what the reference says
    lib = clib.tracker_library(model)
    y1, c1 = model.chart.to_local(start.y)
    behind = start.theta - (SEED_THETA0 - start.theta)
    out = lib.solve_convergent(y1, c1, start.theta, behind)
    assert out.status == clib.ERR_SINGULAR_PATH and np.all(np.isnan(out.x))
    with pytest.raises(PathError):
        sc.solve(model, behind, start=start, fast=False)
    with pytest.raises(PathError):
        sc.solve(model, behind, start=start, backend="c")
    moved = lib.solve_convergent(y1 + 0.01, c1, start.theta, SEED_THETA0)
    assert moved.status == clib.ERR_NOT_ASSEMBLED and np.all(np.isnan(moved.y))
    moved = lib.solve_divergent(y1 + 0.01, c1, start.theta, SEED_THETA0)
    assert moved.status == clib.ERR_NOT_ASSEMBLED and np.isnan(moved.fold_s)


def compare_divergent(model, start, targets):
    """solve(branch="divergent", backend="c") against the compiled solve at each target: the
    same answer (1e-9) and the same crossings (kind, s, x, y, theta, index); where the C call
    itself solved, its raw answer and fold too. Returns the raw C statuses."""
    lib = clib.tracker_library(model)
    y1, c1 = model.chart.to_local(start.y)
    kw = {"start": start, "branch": "divergent", "record_path": False}
    statuses = []
    for theta0 in targets:
        out = lib.solve_divergent(y1, c1, start.theta, theta0)
        statuses.append(out.status)
        try:
            ref = sc.solve(model, theta0, backend="compiled", **kw)
        except sc.ScdkError as exc:
            assert out.status != clib.OK_PATH, theta0
            with pytest.raises(type(exc)):
                sc.solve(model, theta0, backend="c", **kw)
            continue
        res = sc.solve(model, theta0, backend="c", **kw)
        assert_same_answer(model, res, ref, "divergent", whole_crossings=True)
        if out.status == clib.OK_PATH:
            np.testing.assert_allclose(out.x, ref.x, rtol=0, atol=1e-9)
            assert out.det * ref.b > 0 and out.residual <= model.tolerance
            assert len(ref.crossings) == 1 and ref.crossings[0].kind == "fold"
            assert out.fold_s == pytest.approx(ref.crossings[0].s, abs=1e-9)
            np.testing.assert_allclose(out.fold_x, ref.crossings[0].x, rtol=0, atol=1e-9)
    return statuses


def test_divergent_seed_example_is_one_c_call():
    model = shipped("planar_hexa")
    start = model.inverse_kinematics(SEED_X1)
    assert compare_divergent(model, start, [SEED_THETA0]) == [clib.OK_PATH]
    res = sc.solve(model, SEED_THETA0, start=start, branch="divergent", backend="c",
                   record_path=False)  # fmt: skip
    conv = sc.solve(model, SEED_THETA0, start=start, backend="c", record_path=False)
    # the paper's divergent answer, across the fold the path turns at behind the start
    assert res.x[2] == pytest.approx(0.9999, abs=1e-4) and res.b == -conv.b
    assert [c.kind for c in res.crossings] == ["fold"]
    assert res.crossings[0].s == pytest.approx(-0.2782, abs=1e-4)


def test_divergent_seed_robot_equals_the_compiled_solve():
    model = shipped("planar_hexa")
    start = model.inverse_kinematics(SEED_X1)
    rng = np.random.default_rng(31)
    targets = SEED_THETA0 + rng.normal(scale=0.5, size=(16, 3))
    statuses = compare_divergent(model, start, targets)
    assert statuses.count(clib.OK_PATH) >= 6, statuses
    # the paths the C walk does not decide (e.g. s = -1 reached before a fold) fall back
    assert statuses.count(clib.ERR_SINGULAR_PATH) >= 3, statuses


def test_divergent_3rpr_equals_the_compiled_solve():
    model = shipped("planar_3rpr")
    rng = np.random.default_rng(32)
    targets = model.home.theta + rng.normal(scale=0.1, size=(16, 3))
    statuses = compare_divergent(model, model.home, targets)
    assert statuses.count(clib.OK_PATH) >= 2, statuses


def test_divergent_hexapod_equals_the_compiled_solve():
    # a floating platform (the answer and the fold in the start's chart); the first two paths
    # meet more singular points after the fold: the C call refuses, the compiled solve decides
    model = shipped("stewart_gough")
    rng = np.random.default_rng(7)
    targets = model.home.theta + rng.normal(scale=0.3, size=(3, 6))  # m
    statuses = compare_divergent(model, model.home, targets)
    assert statuses == [clib.ERR_SINGULAR_PATH, clib.ERR_SINGULAR_PATH, clib.OK_PATH]


def test_repeated_solves_from_several_starts_equal_the_raw_call_bit_for_bit():
    """The C solve bound to its start: solves alternating between starts (home, another, an
    equal copy of it), and from two threads at once, each equal to the binding's own call at
    that start, bit for bit."""
    import threading

    model = shipped("planar_hexa")
    lib = clib.tracker_library(model)
    other = model.inverse_kinematics(SEED_X1)
    copy = sc.Configuration(other.theta, other.y, other.x, other.platform_pose,
                            other.joints, other.residual)  # fmt: skip
    rng = np.random.default_rng(3)
    steps = 0.02 * rng.normal(size=(4, 3))

    def raw(start, theta0):
        y1, c1 = model.chart.to_local(start.y)
        out = lib.solve_convergent(y1, c1, start.theta, theta0)
        return model.chart.to_canonical(out.y, out.c)

    for start in (other, model.home, copy, other, None, copy):
        at = model.home if start is None else start
        for theta0 in at.theta + steps:
            res = sc.solve(model, theta0, start, backend="c", record_path=False)
            np.testing.assert_array_equal(res.y, raw(at, theta0))
            assert res.backend == "c" and not res.fallback
    targets = list(other.theta + steps)
    answers: dict[int, list[np.ndarray]] = {}

    def run(i, start):
        answers[i] = [sc.solve(model, t, start, backend="c", record_path=False).y
                      for t in targets * 25]  # fmt: skip

    threads = [threading.Thread(target=run, args=(i, s)) for i, s in enumerate((other, other))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in (0, 1):
        for theta0, y in zip(targets * 25, answers[i], strict=True):
            np.testing.assert_array_equal(y, raw(other, theta0))
