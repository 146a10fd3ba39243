"""``sc.solve_many``: every row the single solve's answer, bit for bit, failures in their rows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from factories import needs_compiler

import scdk_sym as sc
from scdk_sym.errors import InputError, ScdkError

MODELS = Path(__file__).resolve().parents[1] / "models"

pytestmark = needs_compiler()


def readings(model: sc.Model, start: sc.Configuration, seed: int, count: int, spread: float):
    """(count, k) seeded readings around the start's [rad or model length unit]."""
    rng = np.random.default_rng(seed)
    return start.theta + rng.uniform(-spread, spread, (count, model.k))


@pytest.mark.parametrize(
    ("name", "x", "spread"),
    [("planar_hexa", [0.0, 0.0, 0.4], 0.8), ("stewart_gough", None, 0.08)],
)
def test_every_row_is_the_single_solve_s_answer(name, x, spread):
    model = sc.load_model(MODELS / name)
    start = model.inverse_kinematics(x) if x is not None else model.home
    thetas = readings(model, start, 5, 40, spread)
    batch = sc.solve_many(model, thetas, start)
    solved = failed = 0
    for i, theta in enumerate(thetas):
        try:
            res = sc.solve(model, theta, start, backend="c", record_path=False)
        except ScdkError as exc:
            assert batch.status[i] == "failed" and type(batch.errors[i]) is type(exc)
            assert np.isnan(batch.y[i]).all()
            failed += 1
            continue
        solved += 1
        np.testing.assert_array_equal(batch.y[i], res.y)
        np.testing.assert_array_equal(batch.x[i], res.x)
        assert batch.residual[i] == res.residual <= model.tolerance
        assert batch.status[i] == res.status
        assert (i in batch.handed_over) == bool(res.fallback)
    assert solved >= 20  # the readings mostly lie in reach
    assert batch.ok == (failed == 0)


def test_divergent_rows_and_other_backends_loop_the_single_solve():
    model = sc.load_model(MODELS / "planar_hexa")
    start = model.inverse_kinematics([0.0, 0.0, 0.4])
    thetas = readings(model, start, 9, 4, 0.1)
    batch = sc.solve_many(model, thetas, start, "divergent", backend="compiled")
    solved = 0
    for i, theta in enumerate(thetas):
        try:
            res = sc.solve(model, theta, start, "divergent", backend="compiled", record_path=False)
        except ScdkError as exc:
            assert batch.status[i] == "failed" and type(batch.errors[i]) is type(exc)
            continue
        solved += 1
        np.testing.assert_array_equal(batch.y[i], res.y)
        assert batch.status[i] == res.status
    assert solved >= 2


def test_bad_readings_and_options_are_refused_with_the_row():
    model = sc.load_model(MODELS / "planar_hexa")
    with pytest.raises(InputError, match=r"thetas must be \(N, 3\) rows"):
        sc.solve_many(model, np.zeros((2, 2)))
    bad = np.zeros((3, 3))
    bad[1, 2] = np.nan
    with pytest.raises(InputError, match=r"thetas\[1\]"):
        sc.solve_many(model, bad)
    with pytest.raises(InputError, match="unknown backend 'gpu'"):
        sc.solve_many(model, np.zeros((1, 3)), backend="gpu")
    with pytest.raises(InputError, match="branch must be"):
        sc.solve_many(model, np.zeros((1, 3)), branch="both")
