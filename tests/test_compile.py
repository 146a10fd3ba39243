"""Compiled kernels (scdk_sym.kernels.compile) against the CasADi SX Functions."""

from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
from factories import MODELS, SEED_THETA0, hexapod, needs_compiler, shipped

import scdk_sym as sc
from scdk_sym.errors import BuildError
from scdk_sym.kernels import compile as comp
from scdk_sym.kernels.cache import cache_dir

pytestmark = needs_compiler()


@pytest.mark.parametrize(
    "make", [lambda: shipped("planar_hexa"), hexapod], ids=["planar", "hexapod"]
)
def test_compiled_kernels_equal_the_sx_functions(make):
    """Near home (y, theta, chart), other inputs random: far from the closures the warm
    kernel's Newton iterations overflow, where inlined and called closures differ in NaN."""
    model = make()
    sx = model.kernels
    c_k = comp.compiled_kernels(model)
    rng = np.random.default_rng(3)
    y, c = model.chart.to_local(model.home.y)
    near = {"y": y, "y1": y, "theta": model.home.theta, "theta1": model.home.theta}
    near.update(theta0=model.home.theta, c=c, q=np.r_[y, 0.5])
    for f in fields(sx):
        f_sx, f_c = getattr(sx, f.name), getattr(c_k, f.name)
        assert f_c.n_in() == f_sx.n_in() and f_c.n_out() == f_sx.n_out()
        for _ in range(3):
            args = [
                near[name] + rng.normal(scale=0.03, size=np.shape(near[name]))
                if name in near
                else rng.normal(scale=0.3, size=f_sx.size_in(i))
                for i, name in enumerate(f_sx.name_in())
            ]
            for a, b in zip(f_sx.call(args), f_c.call(args), strict=True):
                a, b = np.array(a), np.array(b)
                size = np.abs(a[np.isfinite(a)]).max(initial=0.0)
                np.testing.assert_allclose(b, a, rtol=1e-10, atol=1e-10 * (1 + size))
    for name in (name for group in comp.KERNEL_GROUPS for name in group):
        assert getattr(c_k, name).class_name() == "External"  # compiled, not the SX Function
    # cached: the library exists under the model's key (kernels built again: the same key)
    path = comp._build_library(model).path
    assert path == comp.compiled_library(model).path
    assert path.parent == cache_dir() and path.exists()
    assert path.name.endswith(f"_{comp.compiler_tag()}.so")


def test_compiled_field_integrates_as_the_sx_one_without_its_jacobian():
    """No Jacobian of the field is compiled: CVODES's functional iteration never evaluates the
    one CasADi builds (by finite differences) and the chunk equals the SX engine's."""
    from scdk_sym.follower.cvodes import engine

    model = shipped("planar_hexa")
    y, c = model.chart.to_local(model.home.y)
    rng = np.random.default_rng(7)
    for _ in range(3):
        dtheta = rng.normal(scale=0.1, size=model.k)
        v = np.r_[np.zeros(model.m), 1.0]
        p = np.r_[model.home.theta, dtheta, v, 0.05 / np.linalg.norm(dtheta), 5.0, c]
        chunks = []
        for backend in ("cvodes", "compiled"):
            integ = engine(model, backend).integrator.function
            chunks.append(np.array(integ(x0=np.r_[y, 0.0], p=p)["xf"]))
            assert integ.stats()["n_call_jacF"] == 0 and integ.stats()["nfevals"] > 0
        assert np.ptp(chunks[0][-1]) > 1e-3  # s moved along the chunk
        np.testing.assert_allclose(chunks[1], chunks[0], rtol=1e-12, atol=1e-12)


def test_compiled_follower_kernels_equal_the_sx_functions():
    """The curve follower's compiled kernels (closure calls; the plane, the fold and the
    singular kernel at -O0) against its SX Functions near the fold that the seed example's
    divergent path crosses, to 1e-13 relative (the same operations; the order of a few sums
    may differ)."""
    from scdk_sym.follower.calls import COMPILED_GROUPS, follower_kernels

    model = shipped("planar_hexa")
    start = model.inverse_kinematics([0.0, 0.0, 0.4])
    fold = sc.solve(model, SEED_THETA0, start=start, branch="divergent").crossings[0]
    assert fold.kind == "fold"
    sx, c_k = follower_kernels(model), follower_kernels(model, "compiled")
    y, c = model.chart.to_local(fold.y)
    rng = np.random.default_rng(11)
    for _ in range(3):
        dtheta = rng.normal(scale=0.05, size=model.k)
        p = np.r_[fold.theta - 0.5 * dtheta, dtheta]
        q = np.r_[y + rng.normal(scale=1e-3, size=model.m), 0.5]
        t = np.array(sx.tangent(q, np.r_[np.zeros(model.m), 1.0], p, c)[0]).ravel()
        args = {
            "steps": (np.r_[q, t], 0.01, p, c),
            "step": (np.r_[q, t], 0.01, p, c),
            "tangent": (q, t, p, c),
            "plane": (q, t, p, c),
            "fold": (q, t, p, c),
            "polish": (q[:-1], fold.theta, c),
            "singular": (q[:-1], fold.theta, c),
        }
        for name in (name for group in COMPILED_GROUPS for name in group):
            assert getattr(c_k, name).class_name() == "External"
            expected, got = (getattr(k, name).call(list(args[name])) for k in (sx, c_k))
            for a, b in zip(expected, got, strict=True):
                a, b = np.array(a), np.array(b)
                assert np.all(np.isfinite(a))
                np.testing.assert_allclose(b, a, rtol=1e-13, atol=1e-13 * (1 + np.abs(a).max()))
        # the fold kernel converged onto the fold crossed by the solve
        q_fold = np.array(c_k.fold(*args["fold"])).ravel()
        np.testing.assert_allclose(q_fold[:-1], y, atol=1e-8)


def test_missing_compiler_is_a_build_error(monkeypatch):
    monkeypatch.setenv("CC", "")
    monkeypatch.setattr(comp.shutil, "which", lambda name: None)
    with pytest.raises(BuildError, match="no C compiler found"):
        comp.compiler()


def test_first_compilation_is_announced_once_and_split_sources_compile(
    tmp_path, monkeypatch, capsys
):
    """A first compiled use prints one stderr line; the split library equals the SX kernels."""
    monkeypatch.setenv("SCDK_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(comp, "_announced", set())
    model = shipped("planar_3rpr")
    c_k = comp.compiled_kernels(model)
    comp.compiled_kernels(sc.load_model(MODELS / "planar_3rpr"))  # cached on disk: silent
    assert capsys.readouterr().err == f"compiling kernels for {model.name}...\n"
    assert len(list(tmp_path.glob("compiled_*.so"))) == 1
    rng = np.random.default_rng(5)
    args = [rng.normal(scale=0.3, size=model.kernels.g.size_in(i)) for i in range(3)]
    expected = np.array(model.kernels.g(*args))
    np.testing.assert_allclose(np.array(c_k.g(*args)), expected, rtol=1e-12, atol=1e-12)


# ---------------------------------------------------------------- on-disk keys cover their inputs


@pytest.fixture
def package_copy(tmp_path, monkeypatch):
    """A copy of the package sources the keys hash, with :data:`comp.PACKAGE_ROOT` on it."""
    import shutil

    root = tmp_path / "scdk_sym"
    shutil.copytree(comp.PACKAGE_ROOT, root, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(comp, "PACKAGE_ROOT", root)
    return root


SOURCES = [
    "model/rotations.py", "model/chart.py", "model/urdf.py", "symbolic/system.py",
    "symbolic/kinematics.py", "kernels/functions.py", "kernels/compile.py", "kernels/curve.py",
    "kernels/follower.py", "follower/calls.py",
]  # fmt: skip


@pytest.mark.parametrize("part", SOURCES)
def test_kernel_key_changes_with_each_source_it_is_built_from(package_copy, part):
    model = shipped("planar_hexa")
    before = comp.cache_key(model)
    assert before == comp.cache_key(model)  # deterministic
    with open(package_copy / part, "a") as f:
        f.write("\n# changed\n")
    assert comp.cache_key(model) != before


def test_kernel_key_changes_with_flags_casadi_model_and_reduction(monkeypatch):
    model = shipped("planar_hexa")
    key = comp.cache_key(model)
    other = shipped("planar_hexa_reduced")
    assert comp.cache_key(other) != key
    with monkeypatch.context() as mp:
        mp.setattr(comp, "CFLAGS", (*comp.CFLAGS, "-ffast-math"))
        assert comp.cache_key(model) != key
    with monkeypatch.context() as mp:
        mp.setattr(comp.ca, "__version__", "0.0.0", raising=False)
        assert comp.cache_key(model) != key
    with monkeypatch.context() as mp:  # the same files reduced to other rows
        mp.setattr(model, "rows", tuple(reversed(model.rows)))
        assert comp.cache_key(model) != key
    assert comp.cache_key(model) == key
    # the compiler enters the library names (not the kernel hash)
    tag = comp.compiler_tag()
    monkeypatch.setenv("CC", "clang")
    assert comp.compiler_tag() != tag
    assert comp.cache_key(model) == key


def test_generated_library_keys_change_with_flags_and_compiler(tmp_path, monkeypatch):
    import importlib

    gen = importlib.import_module("scdk_sym.codegen.generate")  # the module, not the function

    parts = [tmp_path / n for n in ("k.c", "k.h", "t.c", "t.h", "lu.h")]
    for i, p in enumerate(parts):
        p.write_text(f"/* {i} */\n")
    src = gen.GeneratedSources(tmp_path, "p", *parts, ())
    key = gen.source_key(src)
    parts[2].write_text("/* template changed */\n")
    changed = gen.source_key(src)
    assert changed != key
    parts[4].write_text("/* the elimination changed */\n")
    assert gen.source_key(src) not in (key, changed)
    changed = gen.source_key(src)
    monkeypatch.setattr(gen, "SHARED_FLAGS", (*gen.SHARED_FLAGS, "-O3"))
    flagged = gen.source_key(src)
    assert flagged != changed
    monkeypatch.setenv("CC", "clang")
    assert gen.source_key(src) != flagged


def test_unoptimised_sources_compile_at_O0_and_enter_the_key(tmp_path, monkeypatch):
    import importlib

    gen = importlib.import_module("scdk_sym.codegen.generate")
    calls = []
    monkeypatch.setattr(comp, "run_compiler", lambda args, cwd=None: calls.append(list(args)))
    a, b = tmp_path / "a.c", tmp_path / "b.c"
    a.write_text("int a(void) { return 1; }\n")
    b.write_text("int b(void) { return 2; }\n")
    comp.compile_parallel([a, b], tmp_path / "lib.so", ("-O1", "-fPIC"), unoptimised=[b])
    flags = {Path(c[c.index("-c") + 1]).name: c[: c.index("-c")] for c in calls if "-c" in c}
    assert flags == {"a.c": ["-O1", "-fPIC"], "b.c": ["-O1", "-fPIC", "-O0"]}
    parts = [tmp_path / n for n in ("k.c", "k.h", "t.c", "t.h", "lu.h")]
    for i, p in enumerate(parts):
        p.write_text(f"/* {i} */\n")
    src = gen.GeneratedSources(tmp_path, "p", *parts, (a, b))
    cold = gen.GeneratedSources(tmp_path, "p", *parts, (a, b), (b,))
    assert gen.source_key(src) != gen.source_key(cold)
