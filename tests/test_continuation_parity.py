"""The C path tracker against the numpy tracker, LM references and certificates (6-6).

The start system of Dietmaier's platform (40 real postures, all of its complex solutions) is
made here without monodromy: the 40 LM postures are tracked from the real leg lengths to a
random complex parameter point with offsets, and the set passes the trace test of the frames'
placements. Queries are seeded leg lengths of random reachable poses.
"""

from __future__ import annotations

import numpy as np
import pytest
from stewart import (
    DIETMAIER_BASE,
    DIETMAIER_LENGTHS,
    DIETMAIER_PLATFORM,
    stewart_reference,
)
from test_modes import assert_same_stewart_poses

import scdk_sym as sc
from scdk_sym.algebraic import algebraic_form, homotopy, trace_test
from scdk_sym.algebraic.certify.krawczyk_c import source_dir as interval_source_dir
from scdk_sym.algebraic.clibrary import _cpu_flags
from scdk_sym.algebraic.homotopy import scaled_cond, track_parameter_homotopy
from scdk_sym.algebraic.monodromy import StartSystem
from scdk_sym.algebraic.parameter_homotopy import ParameterHomotopy
from scdk_sym.algebraic.paths.continuation import DONE, TrackerOptions, track
from scdk_sym.algebraic.paths.continuation_c import CTracker, c_tracker, source_dir, tracker_library
from scdk_sym.algebraic.scaled import scaled_form
from scdk_sym.errors import InputError
from scdk_sym.kernels.compile import LU_HEADER, run_compiler
from scdk_sym.kernels.lanes import lane_source
from scdk_sym.model.chart import rot_exp, rot_log
from scdk_sym.products import START_SYSTEM
from scdk_sym.solvers import start_system as hm

#: Largest relative difference of a C endpoint from the numpy one.
ENDPOINT_TOL = 1e-9


def query_lengths(seed: int) -> np.ndarray:
    """Leg lengths of a random pose near Dietmaier's first LM posture (seeded)."""
    rng = np.random.default_rng(seed)
    p = np.array([0.2, -0.1, 0.9]) + 0.1 * rng.normal(size=3)
    R = rot_exp(0.3 * rng.normal(size=3))
    return np.linalg.norm(p + DIETMAIER_PLATFORM @ R.T - DIETMAIER_BASE, axis=1)


@pytest.fixture(scope="module")
def dietmaier():
    """(model, scaled form, certified start system) of Dietmaier's platform."""
    model = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    form = scaled_form(algebraic_form(model, "compiled"))
    ref = stewart_reference(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS, 4000, 0)
    assert len(ref) == 40
    z = np.array([form.form.from_model(np.r_[p, rot_log(R)]) for p, R in ref], dtype=complex)
    G, _, _ = form.evaluate(z, form.params(DIETMAIER_LENGTHS))
    assert np.abs(G).max() < 1e-9  # the postures are solutions of the form
    rng = np.random.default_rng(21)
    p_real = form.params(DIETMAIER_LENGTHS)
    p_star = p_real + 0.2 * (rng.normal(size=6) + 1j * rng.normal(size=6))
    b_star = np.where(form.offset_rows, 0.3 * (rng.normal(size=8) + 1j * rng.normal(size=8)), 0)
    hom = ParameterHomotopy(form, p_real[None], p_star[None], np.zeros((1, 8)), b_star[None], [1])
    ends = track_parameter_homotopy(form, z, hom, np.zeros(40, dtype=int), endgame=False)
    assert (ends.status == "success").all()
    residual = trace_test(
        form, ends.z, p_star, b_star, rng, trace_map=hm.frame_trace_map(form, p_star)
    )
    start = StartSystem(p_star, b_star, ends.z, 40, residual, residual <= hm.TRACE_TOL, 0, 21)
    assert start.trace_passed, residual
    return model, form, start


def test_sources_compile_with_every_warning_as_error(dietmaier, tmp_path):
    _, form, _ = dietmaier
    src = source_dir()
    flags = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", f"-I{LU_HEADER.parent}"]
    # both include the package's one LU (scdk_lu.h); the tracker with a generated evaluation
    run_compiler(
        [*flags, "-c", interval_source_dir() / "krawczyk.c", "-o", tmp_path / "krawczyk.o"]
    )
    (tmp_path / "scdk_eval.c").write_text(lane_source(form.form.G_pairs, "scdk_eval"))
    sizes = [f"-DSCDK_N={form.n}", f"-DSCDK_K={form.n_params}", "-DSCDK_LANES=4",
             '-DSCDK_EVAL_FILE="scdk_eval.c"', f"-I{tmp_path}"]  # fmt: skip
    run_compiler([*flags, *sizes, "-c", src / "continuation.c", "-o", tmp_path / "continuation.o"])
    for stem in ("krawczyk", "continuation"):
        assert (tmp_path / f"{stem}.o").stat().st_size > 0
    assert tracker_library(form.form).exists()


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("third", [True, False])
def test_c_tracker_steps_like_the_numpy_tracker(dietmaier, seed, third):
    """Raw tracker on t in [0, 0.99]: same statuses, same end points, same step counts, with
    the third Newton iteration and without (and the tighter predictor target it needs)."""
    _, form, start = dietmaier
    rng = np.random.default_rng(seed)
    gamma = np.exp(2j * np.pi * rng.uniform())
    p0 = form.params(query_lengths(seed))
    hom = ParameterHomotopy(form, start.p[None], p0[None], start.b[None], np.zeros((1, 8)), [gamma])
    M = len(start.solutions)
    idx, tau0, tau1 = np.zeros(M, dtype=int), np.zeros(M), np.full(M, 0.99)
    options = TrackerOptions() if third else TrackerOptions(third=False, eta=1e-5, trust=1e-3)
    py = track(hom, lambda tau, i: (tau + 0j, np.ones_like(tau, dtype=complex)),
               start.solutions, idx, tau0, tau1, options)  # fmt: skip
    c = c_tracker(form, "c")(hom, start.solutions, idx, tau0, tau1, options)
    np.testing.assert_array_equal(c.status, py.status)
    scale = 1.0 + np.abs(py.z).max(axis=1)
    assert (np.abs(c.z - py.z).max(axis=1) / scale).max() <= ENDPOINT_TOL
    np.testing.assert_allclose(c.tau, py.tau, rtol=0, atol=1e-12)
    # the step sequences only part on a rounding-level tie of an acceptance test
    assert np.mean(c.steps == py.steps) >= 0.9
    assert abs(int(c.steps.sum()) - int(py.steps.sum())) <= 0.02 * py.steps.sum()


def test_the_lane_width_and_instruction_set_change_no_value(dietmaier):
    """The tracker built 4 lanes wide on the baseline instruction set, with AVX2, and 8 wide
    with AVX-512 (where the processor has them) tracks 40 paths of Dietmaier's homotopy (to
    t = 1, near-singular ends included) to the same bits: endpoints, times, steps, step
    sizes and statuses."""
    _, form, start = dietmaier
    cpu = _cpu_flags()
    builds = [((), 4)]
    if "avx2" in cpu:
        builds.append((("-mavx2",), 4))
    if "avx512f" in cpu:
        builds.append((("-mavx2", "-mavx512f"), 8))
    p0 = form.params(DIETMAIER_LENGTHS)
    hom = ParameterHomotopy(form, start.p[None], p0[None], start.b[None], np.zeros((1, 8)), [1])
    M = len(start.solutions)
    outs = []
    for flags, width in builds:
        tracker = CTracker(form.form, tracker_library(form.form, flags, width))
        outs.append(tracker.track(hom, start.solutions, np.zeros(M, dtype=int), np.zeros(M),
                                  np.ones(M), np.asarray(form.weights)))  # fmt: skip
    assert (outs[0].status == DONE).sum() >= 38  # the paths arrive
    for other in outs[1:]:
        for name in ("z", "tau", "h", "status", "steps", "accepted"):
            np.testing.assert_array_equal(getattr(other, name), getattr(outs[0], name))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_c_and_numpy_queries_reach_the_same_roots(dietmaier, seed):
    from scdk_sym.algebraic import solve_homotopy

    _, form, start = dietmaier
    p0 = form.params(query_lengths(seed))
    res = {t: solve_homotopy(form, start, p0, seed=seed, tracker=t) for t in ("c", "python")}
    c, py = res["c"], res["python"]
    np.testing.assert_array_equal(c.status, py.status)
    ok = py.status == "success"
    assert ok.sum() >= 38
    scale = 1.0 + np.abs(py.endpoints[ok]).max(axis=1)
    assert (np.abs(c.endpoints[ok] - py.endpoints[ok]).max(axis=1) / scale).max() <= ENDPOINT_TOL
    assert c.real_solutions.shape == py.real_solutions.shape
    np.testing.assert_allclose(c.real_solutions, py.real_solutions, rtol=0, atol=ENDPOINT_TOL)


@pytest.mark.parametrize("seed", [0, 1])
def test_c_tracked_modes_equal_lm_and_stay_certified(dietmaier, seed, monkeypatch):
    """assembly_modes with the C tracker (default) and with numpy: the same certified set,
    equal to the random-start LM reference."""
    model, form, start = dietmaier
    model.products.put(START_SYSTEM, start, (form.backend, 0, hm.MAX_LOOPS))
    L = query_lengths(seed)
    ref = stewart_reference(DIETMAIER_BASE, DIETMAIER_PLATFORM, L, 3000, seed)
    assert len(ref) >= 1
    calls = []

    def counted(system, tracker="auto"):
        calls.append(tracker)
        return c_tracker(system, tracker)

    monkeypatch.setattr(homotopy, "c_tracker", counted)
    with_c = sc.assembly_modes(model, L)
    assert calls and set(calls) == {"auto"} and c_tracker(form, "auto") is not None  # C did track
    monkeypatch.setattr(homotopy, "c_tracker", lambda system, tracker="auto": None)
    with_numpy = sc.assembly_modes(model, L)
    assert with_c.certified and with_numpy.certified, (with_c.report, with_numpy.report)
    assert_same_stewart_poses(list(with_c), ref)
    assert_same_stewart_poses(list(with_numpy), ref)
    assert len(with_c) == len(with_numpy)


def test_tracker_choice_errors(dietmaier):
    from polynomial_systems import Quadrics  # a hand-written system, no algebraic form

    with pytest.raises(InputError, match="unknown tracker"):
        c_tracker(dietmaier[1], "fortran")
    with pytest.raises(InputError, match="algebraic form"):
        c_tracker(Quadrics(3, 0), "c")
    assert c_tracker(Quadrics(3, 0), "auto") is None


def test_c_newton_equals_the_numpy_newton(dietmaier):
    """Newton's method in C (lanes; 37 points: a short last group) against tracker.newton:
    the same iterates, update norms and Jacobians, to rounding."""
    from scdk_sym.algebraic.paths.continuation import newton

    _, form, start = dietmaier
    rng = np.random.default_rng(3)
    p0 = form.params(query_lengths(3))
    hom = ParameterHomotopy(form, start.p[None], p0[None], start.b[None], np.zeros((1, 8)), [1])
    z0 = start.solutions[:37] * (
        1 + 1e-5 * (rng.normal(size=(37, 8)) + 1j * rng.normal(size=(37, 8)))
    )
    idx, t = np.zeros(37, dtype=int), np.zeros(37)
    zc, nuc, hzc, bound = c_tracker(form, "c").newton(hom, z0, t, idx, 3)
    zp, nup = newton(hom, z0, t + 0j, idx, 3)
    _, hzp, _ = hom(zp, t + 0j, idx)
    scale = 1.0 + np.abs(zp).max(axis=1)
    assert (np.abs(zc - zp).max(axis=1) / scale).max() <= 1e-13
    assert nup[:, 0].min() > 1e-7  # the points did move
    np.testing.assert_allclose(nuc, nup, rtol=1e-6, atol=1e-15)
    np.testing.assert_allclose(hzc, hzp, rtol=1e-12, atol=1e-12 * np.abs(hzp).max())
    # the condition bound: above the SVD's condition number, within sqrt(n) * sqrt(n) of it
    cond = scaled_cond(hzp)
    assert np.all(bound >= cond * (1 - 1e-9)) and np.all(bound <= 8.0 * cond)
    # without the condition: the same iterates, no H_z and no bound
    zn, nun, hzn, bn = c_tracker(form, "c").newton(hom, z0, t, idx, 3, condition=False)
    np.testing.assert_array_equal(zn, zc)
    np.testing.assert_array_equal(nun, nuc)
    assert hzn is None and bn is None


@pytest.mark.parametrize("max_steps", [2000, 12, 25])
def test_one_split_call_tracks_and_refines_as_separate_calls(dietmaier, max_steps):
    """``track_split`` (each path to t = 0.99 and, from there, on to 1 in its lane, then
    Newton at t = 1 on the arrived ends) gives the bits of two ``track`` calls, the second
    from the first's reached times and step sizes, and of a ``newton`` call on the arrived
    ends: points at the split and at the end, statuses, times, step sizes, step counts,
    Newton iterates, update norms and condition bounds; with few allowed steps some paths
    stop in either part."""
    _, form, start = dietmaier
    ct = c_tracker(form, "c")
    M = len(start.solutions)
    idx = np.zeros(M, dtype=int)
    options = TrackerOptions(max_steps=max_steps)
    for gamma in (1.0, np.exp(2j * np.pi * 0.3)):
        p0 = form.params(DIETMAIER_LENGTHS)
        hom = ParameterHomotopy(form, start.p[None], p0[None], start.b[None], np.zeros((1, 8)),
                                [gamma])  # fmt: skip
        first = ct(hom, start.solutions, idx, np.zeros(M), np.full(M, 0.99), options)
        ok = np.flatnonzero(first.status == DONE)
        second = ct(hom, first.z[ok], idx[ok], first.tau[ok], np.ones(ok.size), options,
                    first.h[ok])  # fmt: skip
        arrived = ok[second.status == DONE]
        z, nu, _, bound = ct.newton(hom, second.z[second.status == DONE],
                                    np.ones(arrived.size), idx[arrived], 2)  # fmt: skip
        sp = ct.split(hom, start.solutions, idx, 0.99, options)
        np.testing.assert_array_equal(sp.reached, ok)
        np.testing.assert_array_equal(sp.z_split, first.z[ok])
        rest = np.setdiff1d(np.arange(M), ok)
        for name in ("z", "tau", "h", "status", "steps", "accepted"):
            got, one, two = getattr(sp.end, name), getattr(first, name), getattr(second, name)
            np.testing.assert_array_equal(got[rest], one[rest])
            want = two + (one[ok] if name in ("steps", "accepted") else 0)
            np.testing.assert_array_equal(got[ok], want)
        np.testing.assert_array_equal(sp.arrived, arrived)
        for got, want in ((sp.z_newton, z), (sp.nu, nu), (sp.bound, bound)):
            np.testing.assert_array_equal(got, want)
        if max_steps < 2000:
            assert 0 < ok.size < M or arrived.size < ok.size  # stops in a part
        else:
            assert arrived.size >= 38 and (sp.nu[:, -1] < 1e-10).sum() >= 38


def test_regular_from_the_split_calls_newton_decides_as_its_own_newton(dietmaier):
    """``_regular`` given the split call's Newton outcome (H_z recomputed only where the
    condition bound does not decide) gives the ends and verdicts of ``_regular`` making its
    own Newton steps, with ``cond_max`` set so that the bound leaves half the ends open (and
    the SVD of a recomputed H_z decides them)."""
    from scdk_sym.algebraic.homotopy import _regular

    _, form, start = dietmaier
    ct = c_tracker(form, "c")
    M = len(start.solutions)
    idx = np.zeros(M, dtype=int)
    p0 = form.params(DIETMAIER_LENGTHS)
    hom = ParameterHomotopy(form, start.p[None], p0[None], start.b[None], np.zeros((1, 8)), [1])
    sp = ct.split(hom, start.solutions, idx, 0.99)
    z_end, ix = sp.end.z[sp.arrived], idx[sp.arrived]
    for cond_max in (2.0 * np.median(sp.bound), 1e13):
        open_ = sp.bound > 0.5 * cond_max
        z1, ok1 = _regular(form, hom, z_end, ix, cond_max, ct, (sp.z_newton, sp.nu, sp.bound))
        z2, ok2 = _regular(form, hom, z_end, ix, cond_max, ct)
        np.testing.assert_array_equal(z1, z2)
        np.testing.assert_array_equal(ok1, ok2)
        if cond_max < 1e13:
            assert 5 <= open_.sum() <= M - 5 and ok1[open_].sum() > 0  # the SVD decided some
