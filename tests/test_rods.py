"""Rods between ball joints (scdk_sym.robot.rods): found where the URDF has them, their length
as the URDF's offsets give it, and a distance model's solution lifted back to the model."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import scdk_sym as sc
from scdk_sym.robot.rods import distance_model, find_rods, lift, seat

GEPETTO = Path(__file__).resolve().parent / "fixtures" / "gepetto"
MODELS = Path(__file__).resolve().parent.parent / "models"


def load(name: str) -> sc.Model:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.load_model(GEPETTO / name)


def half_rods(m: sc.Model, closure: int) -> float:
    """The rod's length as the URDF writes it: each half runs from its ball's centre straight
    to the weld's frame, so the length is the sum of the two frames' offsets."""
    c = m.closures[closure]
    return sum(float(np.linalg.norm(m.tree.parent_joint(f).origin[:3, 3]))
               for f in (c.frame_a, c.frame_b))  # fmt: skip


def test_digit_like_has_a_rod_per_loop_of_the_urdf_length() -> None:
    m = load("digit_like")
    rods = find_rods(m)
    assert [r.closure for r in rods] == [0, 1, 2]
    for r in rods:
        assert abs(r.length - half_rods(m, r.closure)) < 1e-9
        assert len(r.joints) == 6  # two revolute triples (one spin locked)


@pytest.mark.parametrize("name", ["stewart_gough", "delta", "planar_3rpr", "five_bar"])
def test_the_zoo_has_no_rods_between_balls(name: str) -> None:
    assert find_rods(sc.load_model(MODELS / name)) == ()


def test_a_configuration_lifts_back_from_its_distance_model() -> None:
    """A configuration away from home, solved by the model, projected to the distance model's
    unknowns and lifted back: the same links' placements; seated near itself: itself."""
    m = load("digit_like")
    ankle = m.stages[1]
    rods = find_rods(ankle)
    reduced = distance_model(ankle, rods)
    assert reduced is not None and reduced.m == 2 and reduced.k == ankle.k
    theta = ankle.home.theta + np.array([0.1, -0.05, 0.08, 0.1, -0.2, 0.15, 0.0])
    res = sc.solve(ankle, theta)
    y_red = res.y[[ankle.unknowns.index(n) for n in reduced.unknowns]]
    # the distance model's rows vanish there (each rod keeps its length)
    assert reduced.residual(y_red, theta) < 1e-12
    y = lift(ankle, rods, reduced, y_red, theta)
    assert y is not None and ankle.residual(y, theta) < 1e-10
    a = ankle.placements(ankle.configuration(res.y, theta))
    b = ankle.placements(ankle.configuration(y, theta))
    for link in ("foot", "foot_part", "crank", "crank_2"):
        assert np.abs(a[link] - b[link]).max() < 1e-10
    again = seat(ankle, rods, y, theta, res.y)
    assert again is not None and np.abs(again - res.y).max() < 1e-9
