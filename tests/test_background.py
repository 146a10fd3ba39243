"""``backend="auto"`` does not wait on a compiler: the first calls answer with CVODES while the
compiled products are built in the background, later calls use them, with the same answers
(each checked against the paper's values and the explicit backends)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from factories import needs_compiler

import scdk_sym as sc
from scdk_sym.solvers import background

MODELS = Path(__file__).resolve().parents[1] / "models"
THETA0 = [1.292, -0.802, -2.896]

pytestmark = needs_compiler()


def test_auto_answers_with_cvodes_while_the_c_backend_builds_then_uses_it(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    monkeypatch.setenv("SCDK_CACHE_DIR", str(tmp_path / "cache"))  # nothing built yet
    monkeypatch.delenv("SCDK_AUTO_WAITS", raising=False)
    model = sc.load_model(MODELS / "planar_hexa")
    start = model.inverse_kinematics([0.0, 0.0, 0.4])
    first = sc.solve(model, THETA0, start=start, backend="auto", record_path=False)
    assert first.backend == "cvodes"
    again = sc.track(model, [THETA0], start=start, backend="auto")
    assert again.backend in ("cvodes", "c")  # cvodes unless the build is already done
    err = capsys.readouterr().err
    assert err.count("in the background") == 1  # said once per model
    assert background.wait(model, timeout=600)
    assert background.ready(model, "c")
    later = sc.solve(model, THETA0, start=start, backend="auto", record_path=False)
    assert later.backend == "c" and not later.fallback
    # the same answer as CVODES, and the paper's (phi = 0.2074 on the convergent branch)
    np.testing.assert_allclose(later.x, first.x, rtol=0, atol=1e-9)
    assert later.x[2] == pytest.approx(0.2074, abs=5e-4)
    assert sc.track(model, [THETA0], start=start, backend="auto").backend == "c"
    # built into the cache: a new model object of the same files (the next run of a
    # script) finds the library through the cache's index, and auto uses it at once
    fresh = sc.load_model(MODELS / "planar_hexa")
    assert sc.solve(fresh, THETA0, start=start, backend="auto", record_path=False).backend == "c"
    assert "in the background" not in capsys.readouterr().err


def test_an_explicit_backend_and_scdk_auto_waits_still_wait(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("SCDK_CACHE_DIR", str(tmp_path / "cache"))
    model = sc.load_model(MODELS / "planar_hexa")
    start = model.inverse_kinematics([0.0, 0.0, 0.4])
    explicit = sc.solve(model, THETA0, start=start, backend="c", record_path=False)
    assert explicit.backend == "c"
    monkeypatch.setenv("SCDK_AUTO_WAITS", "1")
    other = sc.load_model(MODELS / "planar_hexa")
    assert sc.solve(other, THETA0, start=start, backend="auto", record_path=False).backend == "c"
