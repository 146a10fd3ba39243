"""Shared test factories (plain functions, cached: models are immutable)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np

import scdk_sym as sc

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
#: The paper's example (section 5): start pose, joint angles to solve.
SEED_X1 = np.array([0.0, 0.0, 0.4])
SEED_THETA0 = np.array([1.292, -0.802, -2.896])


@cache
def shipped(name: str) -> sc.Model:
    """A model of models/ (loaded once per test session)."""
    return sc.load_model(MODELS / name)


def seed_models() -> list[sc.Model]:
    """The paper's robot in both modelings: full chains and the reduced (x, y, phi) form."""
    return [shipped("planar_hexa"), shipped("planar_hexa_reduced")]


@cache
def hexapod() -> sc.Model:
    """A general 6-6 Stewart-Gough platform (SI units) built in memory."""
    ang_b = np.radians([0, 120, 240]).repeat(2) + np.radians([-12, 12] * 3)
    ang_p = np.radians([60, 180, 300]).repeat(2) + np.radians([-20, 20] * 3)
    ang_p = np.roll(ang_p, 1)
    A = np.c_[0.5 * np.cos(ang_b), 0.5 * np.sin(ang_b), np.zeros(6)]
    B = np.c_[0.3 * np.cos(ang_p), 0.3 * np.sin(ang_p), np.zeros(6)]
    return sc.builders.stewart_gough(A, B, home_x=[0, 0, 0.6, 0, 0, 0])


def compiler_missing() -> str | None:
    """Why compile tests must be skipped (no usable C compiler, as the package finds it), or
    ``None`` when a compiler is there."""
    from scdk_sym.errors import BuildError
    from scdk_sym.kernels.compile import compiler_command

    try:
        compiler_command()
    except BuildError as exc:
        return f"no C compiler: {exc}"
    return None


def needs_compiler():
    """A ``skipif`` mark for tests that compile C (the reason says what is missing)."""
    import pytest

    reason = compiler_missing()
    return pytest.mark.skipif(reason is not None, reason=reason or "")
