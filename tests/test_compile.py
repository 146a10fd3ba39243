"""Compiled kernels (scdk_sym.kernels.compile) against the CasADi SX Functions."""

from dataclasses import fields

import numpy as np
import pytest
from factories import MODELS, hexapod, needs_compiler, shipped

import scdk_sym as sc
from scdk_sym.errors import BuildError
from scdk_sym.kernels import compile as comp
from scdk_sym.kernels.cache import cache_dir

pytestmark = needs_compiler()


@pytest.mark.parametrize(
    "make", [lambda: shipped("planar_hexa"), hexapod], ids=["planar", "hexapod"]
)
def test_compiled_kernels_equal_the_sx_functions(make):
    model = make()
    sx = model.kernels
    c_k = comp.compiled_kernels(model)
    rng = np.random.default_rng(3)
    for f in fields(sx):
        f_sx, f_c = getattr(sx, f.name), getattr(c_k, f.name)
        assert f_c.n_in() == f_sx.n_in() and f_c.n_out() == f_sx.n_out()
        for _ in range(3):
            args = [rng.normal(scale=0.3, size=f_sx.size_in(i)) for i in range(f_sx.n_in())]
            for a, b in zip(f_sx.call(args), f_c.call(args), strict=True):
                a, b = np.array(a), np.array(b)
                size = np.abs(a[np.isfinite(a)]).max(initial=0.0)
                np.testing.assert_allclose(b, a, rtol=1e-10, atol=1e-10 * (1 + size))
    # cached: the library exists under the model's key and is reused
    assert (cache_dir() / f"kernels_{comp.cache_key(model)}.so").exists()


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
    assert len(list(tmp_path.glob("kernels_*.so"))) == 1
    rng = np.random.default_rng(5)
    args = [rng.normal(scale=0.3, size=model.kernels.g.size_in(i)) for i in range(3)]
    expected = np.array(model.kernels.g(*args))
    np.testing.assert_allclose(np.array(c_k.g(*args)), expected, rtol=1e-12, atol=1e-12)
