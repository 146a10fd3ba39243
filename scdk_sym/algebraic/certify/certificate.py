"""What a Krawczyk test proves: the certificate of one point, and of a set of points."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ...results import frozen_array


@dataclass(frozen=True)
class Certificate:
    """The outcome of a Krawczyk test around one approximate solution.

    Attributes:
        proven: ``K(X)`` lies in the interior of ``X``: ``domain`` holds exactly one zero of
            ``f(., p)`` (for every ``p`` in the parameter box), and it lies in ``box``.
        box: (n, 2) ``[lo, hi]`` per unknown, rounded outward to binary64: the enclosure
            ``K(X)`` of the zero (tightened) when proven; the last box ``X`` tried otherwise
            (NaN when none was built).
        domain: (n, 2) the box ``X`` rounded inward: no other zero lies in it (NaN when not
            proven).
        radius: largest half-width of ``box`` (in the units of ``x``; inf when unbounded).
        reason: one line: what was proven, or why not.
        x: (n,) the centre ``m`` of the boxes (the point given).
        tries: boxes ``X`` tried.
    """

    proven: bool
    box: np.ndarray
    domain: np.ndarray
    radius: float
    reason: str
    x: np.ndarray
    tries: int = 0

    def __post_init__(self) -> None:
        for name in ("box", "domain", "x"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))

    def contains(self, point: ArrayLike) -> bool:
        """Whether ``point`` (n,) lies in ``box``."""
        q = np.asarray(point, dtype=float)
        return bool(np.all((self.box[:, 0] <= q) & (q <= self.box[:, 1])))


@dataclass(frozen=True)
class CertificateSet:
    """Certificates of several solutions of one system, and whether they are distinct.

    Attributes:
        certificates: one per solution given, in order.
        overlaps: pairs ``(i, j)``, ``i < j``, of proven certificates whose boxes intersect:
            possibly one zero counted twice.
        duplicates: the overlapping pairs proven to be one zero (one box lies in the other's
            ``domain``, where the zero is unique).
        count: distinct real zeros proven: the connected components of the overlap graph of
            the proven boxes (exact when every overlap is a duplicate, a lower bound else).
        reason: one-line summary.
    """

    certificates: tuple[Certificate, ...]
    overlaps: tuple[tuple[int, int], ...]
    duplicates: tuple[tuple[int, int], ...]
    count: int
    reason: str

    @property
    def proven(self) -> bool:
        """Every solution proven and every pair of boxes disjoint: ``count`` distinct zeros."""
        return all(c.proven for c in self.certificates) and not self.overlaps
