"""Certified assembly modes of mechanisms outside the shipped zoo, with their known root counts.

Each set must be certified complete with the mechanism's known number of complex solutions,
and its real solutions must equal an independent reference at the same joint values:

- the 3-RPS (``sc.builders.three_rps``): 16, against random-start Levenberg-Marquardt on its
  own six pose equations (each anchor on its leg's plane, at its leg's length);
- the 6-3 and the 3-3 (octahedral) Stewart-Gough platforms: 16 each, against the 6-6
  random-start reference of ``tests/stewart.py``;
- a spatial RSSR four-bar (a crank, a rocker on a skew axis, an S-S coupler): 2, against
  the closed form of its rocker angle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from stewart import lm_poses, rotations, stewart_reference
from test_modes import assert_same_stewart_poses

import scdk_sym as sc
from scdk_sym.builders.common import finish
from scdk_sym.model.spec import Closure, Spec
from scdk_sym.model.urdf import TreeBuilder


def ring(radius: float, degrees) -> np.ndarray:
    """Points on a horizontal circle at the given polar angles [deg] -> (n, 3) [m]."""
    a = np.radians(degrees)
    return np.c_[radius * np.cos(a), radius * np.sin(a), np.zeros(len(a))]


# ---------------------------------------------------------------------------- 3-RPS


def rps_reference(Rb: float, Rp: float, angles, lengths, starts: int, seed: int):
    """Real platform poses (p, R) of the 3-RPS by random-start LM on its pose equations:
    t_i . (P_i - A_i) = 0 (the anchor on the vertical plane of leg i) and
    (|P_i - A_i|^2 - L_i^2) / 2 = 0, with P_i = p + R B_i; dedup to 1e-7."""
    a = np.asarray(angles, dtype=float)
    radial = np.c_[np.cos(a), np.sin(a), np.zeros(3)]
    tangent = np.c_[-np.sin(a), np.cos(a), np.zeros(3)]
    A, B, L = Rb * radial, Rp * radial, np.asarray(lengths, dtype=float)
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(starts, 4))
    w = 2.0 * np.arccos(np.clip(np.abs(q[:, 0]) / np.linalg.norm(q, axis=1), 0, 1))
    axis = q[:, 1:] / np.maximum(np.linalg.norm(q[:, 1:], axis=1), 1e-300)[:, None]
    R = rotations(axis * w[:, None])
    p = rng.uniform(-2.0, 2.0, size=(starts, 3)) * (Rb + L.max())

    def residual(p, R):
        d = p[:, None, :] + np.einsum("nij,kj->nki", R, B) - A[None]  # (N, 3, 3)
        plane = np.einsum("nki,ki->nk", d, tangent)
        length = 0.5 * (np.sum(d * d, axis=2) - L**2)
        return np.concatenate([plane, length], axis=1), d

    def jacobian(R, d):
        arm = np.einsum("nij,kj->nki", R, B)  # d P_i / d omega = -[arm]x
        jp = np.concatenate([np.broadcast_to(tangent, d.shape), d], axis=1)
        jw_plane = np.cross(arm, np.broadcast_to(tangent, d.shape))
        jw_len = np.cross(arm, d)
        return np.concatenate([jp, np.concatenate([jw_plane, jw_len], axis=1)], axis=2)

    p, R, r = lm_poses(residual, jacobian, p, R, iterations=80, singular=1e-12)
    found: list[tuple[np.ndarray, np.ndarray]] = []
    for i in np.flatnonzero(np.abs(r).max(axis=1) < 1e-11):
        if all(max(np.abs(p[i] - q).max(), np.abs(R[i] - S).max()) > 1e-7 for q, S in found):
            found.append((p[i].copy(), R[i].copy()))
    return found


@pytest.mark.parametrize("lengths", [(1.1, 1.2, 1.15), (1.3, 0.9, 1.1)])
def test_three_rps_certified_with_16_roots_and_the_reference_real_set(lengths):
    angles = np.radians([90.0, 210.0, 330.0])
    m = sc.builders.three_rps(1.0, 0.5, angles=angles)
    sols = sc.assembly_modes(m, lengths)
    assert sols.certified, sols.report
    assert sols.root_count == 16
    reference = rps_reference(1.0, 0.5, angles, lengths, starts=3000, seed=1)
    assert len(reference) >= 2
    assert_same_stewart_poses(sols, reference, tol=1e-7)


def test_three_rps_bad_inputs_are_refused_in_one_line():
    with pytest.raises(sc.ScdkError, match="distinct"):
        sc.builders.three_rps(1.0, 0.5, angles=(0.0, 0.0, 2.0))
    with pytest.raises(sc.ScdkError, match="base_radius"):
        sc.builders.three_rps(-1.0, 0.5)


# ---------------------------------------------------------------------------- 6-3 and 3-3


def six_three() -> tuple[np.ndarray, np.ndarray]:
    """A 6-3 platform: six base points, each pair of legs meeting at a platform point."""
    A = ring(1.0, [-20, 20, 100, 140, 220, 260])
    B = ring(0.5, [0, 120, 240])[[0, 1, 1, 2, 2, 0]]
    return A, B


def three_three() -> tuple[np.ndarray, np.ndarray]:
    """An octahedral 3-3 platform: legs meet in pairs at three base and three platform
    points."""
    A = ring(1.0, [0, 120, 240])[[0, 0, 1, 1, 2, 2]]
    B = ring(0.5, [60, 180, 300])[[0, 2, 0, 1, 1, 2]]
    return A, B


@pytest.mark.parametrize("geometry", [six_three, three_three], ids=["6-3", "3-3"])
def test_special_stewart_platforms_certified_with_16_roots(geometry):
    A, B = geometry()
    m = sc.builders.stewart_gough(A, B)
    lengths = m.home.theta * (1 + 0.01 * np.random.default_rng(4).normal(size=6))
    sols = sc.assembly_modes(m, lengths)
    assert sols.certified, sols.report
    assert sols.root_count == 16
    reference = stewart_reference(A, B, lengths, 4000, 2)
    assert len(reference) >= 2
    assert_same_stewart_poses(sols, reference, tol=1e-7)


# ---------------------------------------------------------------------------- RSSR


#: Crank length, rocker length, rocker axis position (d, 0, e), its tilt [rad] and the
#: assembled home angles [rad] of the spatial four-bar.
RSSR = {"a": 0.3, "b": 0.5, "d": 1.0, "e": 0.2, "tilt": 0.6, "crank": 0.4, "rocker": 1.9}


def rssr_model() -> sc.Model:
    """A spatial RSSR four-bar: the actuated crank turns about z at the origin, the rocker
    about a skew axis through (d, 0, e); an S-S coupler of fixed length joins their tips."""
    g = RSSR
    axis = (0.0, math.sin(g["tilt"]), math.cos(g["tilt"]))
    b = TreeBuilder("rssr")
    b.add("crank", "revolute", "base", "crank_link", limits=(-math.pi, math.pi))
    b.add("crank_tip_joint", "fixed", "crank_link", "crank_tip", xyz=(g["a"], 0.0, 0.0))
    b.add("rocker", "revolute", "base", "rocker_link", xyz=(g["d"], 0.0, g["e"]), axis=axis,
          limits=(-math.pi, math.pi))  # fmt: skip
    b.add("rocker_tip_joint", "fixed", "rocker_link", "rocker_tip", xyz=(g["b"], 0.0, 0.0))
    C = rssr_crank_tip(g["crank"])
    length = float(np.linalg.norm(C - rssr_rocker_tip(g["rocker"])))
    spec = Spec(
        closures=(Closure("crank_tip", "rocker_tip", "distance", length),),
        actuated=("crank",),
        platform="rocker_tip",
        workspace=("x", "y", "z"),
        home={"crank": g["crank"], "rocker": g["rocker"]},
    )
    return finish(b.build(), spec, "rssr")


def rssr_crank_tip(theta: float) -> np.ndarray:
    return RSSR["a"] * np.array([math.cos(theta), math.sin(theta), 0.0])


def rssr_rocker_tip(phi: float) -> np.ndarray:
    g = RSSR
    w = np.array([0.0, math.cos(g["tilt"]), -math.sin(g["tilt"])])  # axis x (1, 0, 0)
    return np.array([g["d"], 0.0, g["e"]]) + g["b"] * (
        math.cos(phi) * np.array([1.0, 0.0, 0.0]) + math.sin(phi) * w
    )


def rssr_reference(theta: float, length: float) -> list[float]:
    """Rocker angles closing the coupler: A cos(phi) + B sin(phi) = K, in closed form."""
    g = RSSR
    c = rssr_crank_tip(theta) - np.array([g["d"], 0.0, g["e"]])
    w = np.array([0.0, math.cos(g["tilt"]), -math.sin(g["tilt"])])
    A, B = 2 * g["b"] * c[0], 2 * g["b"] * float(c @ w)
    K = float(c @ c) + g["b"] ** 2 - length**2
    r = math.hypot(A, B)
    if abs(K) > r:
        return []
    base, half = math.atan2(B, A), math.acos(K / r)
    return [base - half, base + half]


@pytest.mark.parametrize("theta", [0.4, 1.5, -2.0])
def test_rssr_four_bar_certified_with_2_roots_and_its_closed_form(theta):
    m = rssr_model()
    assert m.m == 1 and m.k == 1
    sols = sc.assembly_modes(m, [theta])
    assert sols.certified, sols.report
    assert sols.root_count == 2
    length = m.spec.closures[0].length
    reference = rssr_reference(theta, float(length))
    got = sorted(cfg.joints["rocker"] for cfg in sols)
    assert len(got) == len(reference)
    for phi in reference:
        diff = [abs((g - phi + math.pi) % (2 * math.pi) - math.pi) for g in got]
        assert min(diff) < 1e-9
