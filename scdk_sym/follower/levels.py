"""Levels of ``s`` along a walk: which a step passes or hides inside it, and the solution at a
level crossed (Newton at fixed ``theta`` from a cubic Hermite guess)."""

from __future__ import annotations

import numpy as np

from ..results import Crossing
from .context import WalkContext
from .follow_rule import FINE


def hermite(u: np.ndarray) -> np.ndarray:
    """Cubic Hermite basis (h00, h10, h01, h11) at the fractions ``u`` of a step."""
    u2, u3 = u * u, u * u * u
    return np.array([2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2])


#: The fractions of a step at which the cubic Hermite of ``s`` is checked, and its basis there.
_FINE = np.linspace(0.0, 1.0, FINE + 1)
_BASIS = hermite(_FINE)


def hidden_pair(sa: float, sb: float, ta: float, tb: float, h: float, level: float) -> bool:
    """Whether a turning point of s inside a step crosses the level twice between samples."""
    a, b = sa - level, sb - level
    if ta * tb >= 0 or a * b <= 0:
        return False
    s = np.array([a, h * ta, b, h * tb]) @ _BASIS
    return bool(np.any(s * a <= 0))


def turns_beyond(levels, s_a: float, s_b: float, s_turn: float) -> bool:
    """Whether ``s`` turning at ``s_turn`` between samples at ``s_a`` and ``s_b`` passes a level
    that neither sample reaches (it crosses it twice inside the step)."""
    return any((s_a - L) * (s_turn - L) < 0 and (s_b - L) * (s_turn - L) < 0 for L in levels)


def levels_passed(levels, s_a: float, s_b: float, leaving: bool) -> list[float]:
    """The levels of ``s`` a step from ``s_a`` to ``s_b`` passes or reaches (none for a step
    that keeps ``s``); with ``leaving``, not the one ``s_a`` sits on (the walk's start)."""
    return [
        L
        for L in levels
        if (s_a - L) * (s_b - L) <= 0 and s_a != s_b and not (leaving and s_a == L)
    ]


def met_before(singular: list[Crossing], first: int, s_a: float, level: float) -> int:
    """Singular points met before a level crossing in a segment starting at ``s = s_a``: all
    of the earlier segments, and of this one those between ``s_a`` and the level."""
    n = first
    for cr in singular[first:]:
        if (cr.s - s_a) * (level - cr.s) >= 0:
            n += 1
    return n


def solve_at_level(
    ctx: WalkContext, qa, qb, ta, tb, h: float, level: float, c
) -> np.ndarray | None:
    """The solution at ``s = level`` between two samples (cubic Hermite guess + Newton at
    ``line.at(level)``), in chart ``c``; None if Newton failed or strayed.

    Args:
        ctx: the walk.
        qa: (m+1,) the first sample ``(y local, s)``.
        qb: (m+1,) the second.
        ta: (m+1,) unit tangent at ``qa``.
        tb: (m+1,) unit tangent at ``qb``.
        h: arc length between them [model length unit].
        level: the level of ``s``.
        c: the chart of both.
    """
    m, tol = ctx.m, ctx.tol
    if qa[-1] == level:
        return np.array(qa[:m])
    s = np.array([qa[-1] - level, h * ta[-1], qb[-1] - level, h * tb[-1]]) @ _BASIS
    j = np.nonzero(s[:-1] * s[1:] <= 0)[0]
    u = 0.5
    if j.size:
        i = j[0]
        u = _FINE[i] + (_FINE[i + 1] - _FINE[i]) * s[i] / (s[i] - s[i + 1] + 1e-300)
    H = hermite(np.array([u]))[:, 0]
    y_guess = H[0] * qa[:m] + H[1] * h * ta[:m] + H[2] * qb[:m] + H[3] * h * tb[:m]
    y, res = ctx.kern.polish(y_guess, ctx.line.at(level), c)
    y = np.array(y).ravel()
    if not (np.all(np.isfinite(y)) and float(res) <= 0.1 * tol):
        return None
    seg = float(np.linalg.norm(qb[:m] - qa[:m]))
    if float(np.linalg.norm(y - y_guess)) > 3 * seg + 10 * tol:
        return None
    return y
