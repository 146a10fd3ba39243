"""Kernels built for C on a large model (``loops``: solves in loops, MX Functions of calls, the
fold and ``dJ_p`` in their compact forms) against the written-out SX kernels: the same
mathematics, to rounding, in a fraction of the generated C."""

from __future__ import annotations

import tempfile
import warnings
from dataclasses import fields
from functools import cache
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from factories import needs_compiler, shipped

import scdk_sym as sc
from scdk_sym.errors import ModelWarning
from scdk_sym.follower.calls import build_follower_kernels
from scdk_sym.kernels import compile as comp
from scdk_sym.kernels.curve import WRITTEN_SOLVE_MAX, closure_function, compact, loop_solver
from scdk_sym.kernels.functions import build_kernels

LEG = Path(__file__).resolve().parent / "fixtures" / "gepetto" / "digit_like"


@cache
def leg() -> sc.Model:
    """A leg of 18 unknowns (its bordered system 19 x 19: solved in loops)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        return sc.load_model(LEG).blocks[0]


def arguments(model: sc.Model, rng: np.random.Generator, tangent: ca.Function) -> dict:
    """Seeded arguments of every kernel near the model's home (small motions: the warm
    kernel's Newton polish converges)."""
    y, c = model.chart.to_local(model.home.y)
    theta, m, k = model.home.theta, model.m, model.k
    dtheta = 0.01 * rng.normal(size=k)
    q = np.r_[y + 1e-3 * rng.normal(size=m), 0.3]
    p = np.r_[theta, dtheta]
    t = np.array(tangent(q, np.r_[np.zeros(m), 1.0], p, c)[0]).ravel()
    field_p = np.r_[p, t, 0.1, 5.0]
    return {
        "field": (q, field_p, c),
        "probe": (q, field_p, c),
        "warm": (q[:m], theta, theta + dtheta, c),
        "steps": (np.r_[q, t], 0.01, p, c),
        "step": (np.r_[q, t], 0.01, p, c),
        "tangent": (q, t, p, c),
        "plane": (q, t, p, c),
        "polish": (q[:m], theta, c),
        "newton": (q[:m], theta, c),
        "predict": (q[:m], theta, dtheta, c),
        "singular": (q[:m], theta, c),
    }


def assert_close(expected, got, name: str, rtol: float = 1e-11) -> None:
    for a, b in zip(expected, got, strict=True):
        a, b = np.array(a, dtype=float), np.array(b, dtype=float)
        assert np.all(np.isfinite(a)), name
        np.testing.assert_allclose(b, a, rtol=0, atol=rtol * (1 + np.abs(a).max()), err_msg=name)


def test_compact_kernels_compute_what_the_written_ones_do():
    model = leg()
    sym = model.symbolic
    assert compact(sym, loops=True) and not compact(sym, loops=False)
    closure = closure_function(sym)
    written = (build_kernels(sym), build_follower_kernels(sym, inline=True))
    built = (
        build_kernels(sym, closure=closure, loops=True),
        build_follower_kernels(sym, inline=False, closure=closure, solver_calls=False, loops=True),
    )
    rng = np.random.default_rng(17)
    for _ in range(3):
        args = arguments(model, rng, written[1].tangent)
        for ref, new in zip(written, built, strict=True):
            for f in fields(ref):
                if f.name not in args:
                    continue
                kernel = getattr(new, f.name)
                assert kernel.is_a("MXFunction"), f.name
                call = list(args[f.name])
                assert_close(getattr(ref, f.name).call(call), kernel.call(call), f.name)


def inner(f: ca.Function, name: str) -> ca.Function:
    return next(g for g in f.find_functions() if g.name() == name)


def test_the_fold_newton_step_by_the_adjoint_is_the_derivative_of_the_bordered_solve():
    """One Newton step on ``[g; t_hat_s]``: its Jacobian's last row by the adjoint of the
    bordered solve (compact) against CasADi's derivative of the written-out solve."""
    model = leg()
    sym = model.symbolic
    closure = closure_function(sym)
    steps = [
        inner(build_follower_kernels(sym, inline=False, closure=closure, **kw).fold, "scdk_fold1")
        for kw in ({}, {"solver_calls": False, "loops": True})
    ]
    rng = np.random.default_rng(5)
    y, c = model.chart.to_local(model.home.y)
    m, k = model.m, model.k
    for _ in range(3):
        p = np.r_[model.home.theta, 0.05 * rng.normal(size=k)]
        q = np.r_[y + 1e-3 * rng.normal(size=m), 0.3]
        v = np.r_[rng.normal(size=m), 1.0]
        ref, new = (np.array(f(q, v, p, c)).ravel() for f in steps)
        np.testing.assert_allclose(new, ref, rtol=0, atol=1e-10 * np.abs(ref - q).max())


def test_a_small_model_generates_the_same_c_either_way():
    """Below :data:`WRITTEN_SOLVE_MAX`, kernels built for C are the written-out ones: the same
    generated C, byte for byte."""
    model = shipped("stewart_gough")
    sym = model.symbolic
    assert model.m + 1 <= WRITTEN_SOLVE_MAX and not compact(sym, loops=True)
    texts = []
    for loops in (False, True):
        closure = closure_function(sym)
        kern = build_kernels(sym, closure=closure, loops=loops)
        follower = build_follower_kernels(
            sym, inline=False, closure=closure, solver_calls=False, loops=loops
        )
        with tempfile.TemporaryDirectory() as tmp:
            sources, _ = comp.write_c_parts([kern.warm, kern.field, follower.steps], "k", Path(tmp))
            texts.append([s.read_text() for s in sources])
    assert texts[0] == texts[1]


def test_the_loop_solver_fails_as_the_symbolic_one_on_a_singular_matrix():
    """No rank test: a singular matrix gives the divisions by zero the symbolic solve gives,
    never a silent zero."""
    n = WRITTEN_SOLVE_MAX + 2
    A = np.random.default_rng(2).normal(size=(n, n))
    A[:, 3] = A[:, 2]
    x = np.array(loop_solver(ca.Sparsity.dense(n, n))(A, np.ones(n))).ravel()
    assert not np.all(np.isfinite(x)) or np.abs(x).max() > 1e10
    good = A + np.eye(n)
    good[:, 3] += 1.0
    rhs = np.c_[np.ones(n), np.arange(n)]
    x = np.array(loop_solver(ca.Sparsity.dense(n, n), 2)(good, rhs))
    np.testing.assert_allclose(x, np.linalg.solve(good, rhs), rtol=1e-12)


@needs_compiler()
def test_the_compiled_library_of_a_leg_is_small_and_computes_the_same(tmp_path, monkeypatch):
    """The compiled backend's library of an 18-unknown leg: a few tens of thousands of lines
    of C (the closure Function twice, where written-out solves and their derivatives made
    hundreds of thousands), its kernels equal to the Functions they were generated from."""
    monkeypatch.setenv("SCDK_CACHE_DIR", str(tmp_path))
    model = leg()
    lib = comp._build_library(model)
    assert lib.path.parent == tmp_path and lib.path.exists()
    by_name = {f.name: getattr(lib.kernels, f.name) for f in fields(lib.kernels)}
    by_name.update({f.name: getattr(lib.follower, f.name) for f in fields(lib.follower)})
    groups = [[by_name[n] for n in group] for group in comp.LIBRARY_GROUPS]
    with tempfile.TemporaryDirectory() as tmp:
        sources, _ = comp.write_c_parts(groups, "k", Path(tmp))
        lines = sum(len(s.read_text().splitlines()) for s in sources)
    assert lines < 70_000, lines
    rng = np.random.default_rng(23)
    args = arguments(model, rng, lib.follower.tangent)
    for name, call in args.items():
        if name in ("newton", "predict"):
            continue
        compiled = ca.external(by_name[name].name(), str(lib.path))
        assert_close(by_name[name].call(list(call)), compiled.call(list(call)), name, 1e-12)


@needs_compiler()
@pytest.mark.parametrize("branch", ["convergent", "divergent"])
def test_solves_of_the_leg_compiled_equal_those_of_the_virtual_machine(branch):
    model = leg()
    theta = model.home.theta + 0.05
    ours = sc.solve(model, theta, branch=branch, backend="compiled")
    ref = sc.solve(model, theta, branch=branch)
    np.testing.assert_allclose(ours.y, ref.y, rtol=0, atol=1e-9)
