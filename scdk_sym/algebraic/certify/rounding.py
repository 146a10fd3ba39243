"""Binary64 bounds of Arb balls, rounded outward (enclosures) or inward (boxes inside)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from flint import arb, ctx


def down(a: arb) -> float:
    """Largest binary64 <= every point of ``a`` (``-inf`` if unbounded or NaN)."""
    if not a.is_finite():
        return -math.inf
    lo = a.lower()
    f = float(lo)
    return math.nextafter(f, -math.inf) if arb(f) > lo else f


def up(a: arb) -> float:
    """Smallest binary64 >= every point of ``a`` (``inf`` if unbounded or NaN)."""
    if not a.is_finite():
        return math.inf
    hi = a.upper()
    f = float(hi)
    return math.nextafter(f, math.inf) if arb(f) < hi else f


def inward(m: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(n, 2) binary64 bounds inside ``[m - r, m + r]`` (one ulp in from the nearest)."""
    return np.stack([np.nextafter(m - r, np.inf), np.nextafter(m + r, -np.inf)], axis=1)


def outward(balls: Sequence[arb]) -> np.ndarray:
    """(n, 2) binary64 bounds around the balls."""
    if ctx.prec <= 53 and all(b.is_finite() for b in balls):
        # midpoints (<= 53 bits) and radii (30 bits) are binary64 numbers: one rounding of
        # mid -/+ rad, undone by one step outward
        mid = np.array([float(b.mid()) for b in balls])
        rad = np.array([float(b.rad()) for b in balls])
        return np.stack([np.nextafter(mid - rad, -np.inf), np.nextafter(mid + rad, np.inf)], 1)
    return np.array([[down(b), up(b)] for b in balls])
