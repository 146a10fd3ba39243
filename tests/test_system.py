"""Symbolic kinematics: Jacobians against finite differences, placements against Pinocchio."""

import numpy as np
import pytest
from factories import SEED_THETA0, SEED_X1, hexapod, seed_models

from scdk_sym.solvers.solve import solve
from scdk_sym.verify.pinocchio import closure_residuals, placement_error


def _models():
    return [*seed_models(), hexapod()]


def _random_point(model, rng):
    y = model.home.y + rng.normal(scale=0.2, size=model.m)
    theta = model.home.theta + rng.normal(scale=0.2, size=model.k)
    return y, theta


@pytest.mark.parametrize("model", _models(), ids=lambda m: m.name)
def test_jacobians_match_central_differences(model):
    rng = np.random.default_rng(11)
    kern = model.kernels
    h = 1e-6
    for _ in range(10):
        y, theta = _random_point(model, rng)
        y, c = model.chart.to_local(y)
        Jp, Js = (np.array(a) for a in kern.jac(y, theta, c))
        fd_p = np.column_stack(
            [
                (
                    np.array(kern.g(y + h * e, theta, c)) - np.array(kern.g(y - h * e, theta, c))
                ).ravel()
                / (2 * h)
                for e in np.eye(model.m)
            ]
        )
        fd_s = -np.column_stack(
            [
                (
                    np.array(kern.g(y, theta + h * e, c)) - np.array(kern.g(y, theta - h * e, c))
                ).ravel()
                / (2 * h)
                for e in np.eye(model.k)
            ]
        )
        scale = 1 + np.abs(Jp).max()
        np.testing.assert_allclose(Jp, fd_p, atol=1e-7 * scale)
        np.testing.assert_allclose(Js, fd_s, atol=1e-7 * scale)


@pytest.mark.parametrize("model", _models(), ids=lambda m: m.name)
def test_every_link_placement_matches_pinocchio(model):
    rng = np.random.default_rng(12)
    errors = [placement_error(model, *_random_point(model, rng)) for _ in range(20)]
    assert max(errors) < 1e-12 * max(1.0, model.length_scale)


@pytest.mark.parametrize("model", seed_models(), ids=lambda m: m.name)
def test_solutions_close_the_loops_for_pinocchio(model):
    start = model.inverse_kinematics(SEED_X1)
    for branch in ("convergent", "divergent"):
        res = solve(model, SEED_THETA0, start=start, branch=branch)
        assert closure_residuals(model, res.joints).max() < 1e-10


def test_hexapod_solutions_close_the_loops_for_pinocchio():
    model = hexapod()
    rng = np.random.default_rng(13)
    for _ in range(5):
        x = np.r_[
            rng.uniform(-0.05, 0.05, 2), 0.6 + rng.uniform(-0.05, 0.05), rng.uniform(-0.2, 0.2, 3)
        ]
        target = model.inverse_kinematics(x)
        res = solve(model, target.theta, start=model.home)
        np.testing.assert_allclose(res.x, x, atol=1e-9)
        assert closure_residuals(model, res.joints).max() < 1e-12
