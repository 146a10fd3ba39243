"""The numerics of the tracking rule at the last sample (its rules R2 and R3).

The rule is stated in :mod:`scdk_sym.solvers.track`. :class:`TrackerNumerics` holds the
last sample ``y_k`` in the local chart centred on it (see :mod:`scdk_sym.model.chart`) and
computes there what the rule asks for: ``det J_p``, the Newton correctors, the Euler point
``y_k + J_p^-1 J_s dtheta``, a candidate polished and its revolute angles moved next to
``y_k``, and the fold partner of a root. The kernels are the C tracker's own
(:class:`TrackKernels`), so both backends compute the same values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..follower.geometry import periodic
from ..follower.track_rule import (  # the rule's constants (stated in solvers.track)
    FAST_ITERATIONS,
    PARTNER_ITERATIONS,
    PARTNER_REACH,
    PARTNER_STEP,
    PREDICTED_CALLS,
)
from ..kernels.fastcall import Buffered
from ..model.rotations import gibbs, gibbs_product, rot_exp
from ..products import TRACK_KERNELS
from ..results import Configuration
from ..robot import Model


@dataclass(frozen=True)
class TrackKernels:
    """The C tracker's kernels (the same SX Functions it is generated from), zero-copy."""

    predict: Buffered
    newton: Buffered
    closure: Buffered
    recentre: Buffered


def track_kernels(model: Model) -> TrackKernels:
    """The tracker's kernels of ``model`` (built once per model: ``TRACK_KERNELS``)."""

    def build() -> TrackKernels:
        from ..kernels.tracker_functions import build_tracker_kernels

        kern = build_tracker_kernels(model.symbolic, model.chart.rotations, "scdk")
        return TrackKernels(
            Buffered(kern.predict), Buffered(kern.newton), Buffered(kern.closure),
            Buffered(kern.recentre),
        )  # fmt: skip

    return model.products.get(TRACK_KERNELS, build)


#: A full turn [rad].
TWO_PI = 2.0 * math.pi


def sign_of(v: float) -> int:
    """The sign of ``v``: -1, 0 or 1."""
    return (v > 0) - (v < 0)


def inf_norm(v: np.ndarray) -> float:
    """The max norm ``|v|`` (0 for an empty vector)."""
    return float(np.max(np.abs(v))) if v.size else 0.0


@dataclass(frozen=True)
class SampleJacobian:
    """J_p and J_s of the last evaluation at a sample, and the sample in that evaluation's
    chart."""

    jp: np.ndarray  # (m, m)
    js: np.ndarray  # (m, k)
    at: np.ndarray  # (m,) the sample, in the chart of the evaluation


def euler_point(y: np.ndarray, at: np.ndarray, delta: np.ndarray, rotations) -> np.ndarray:
    """``y + delta`` with ``delta`` an increment at ``at`` in another chart, moved into the chart
    centred on ``y`` (R2's Euler point).

    ``at`` is ``y`` in the chart the increment was computed in (its rotation coordinates are
    Gibbs parameters ``a``, zero when it is ``y``'s own chart); the rotation coordinates of
    ``y`` are 0. Each rotation ``cayley(a + delta_r)`` of that chart is, in the chart of ``y``,
    ``cayley(-a) cayley(a + delta_r)``, whose Gibbs parameters are ``gibbs_product(-a, b)``
    with ``b = a + delta_r``; the other coordinates are ``y + delta``.

    Args:
        y: (m,) the sample in its own chart [model length unit, rad].
        at: (m,) the sample in the chart of the increment.
        delta: (m,) the increment.
        rotations: index triples of the rotation coordinates (:attr:`Chart.rotations`).

    Returns:
        (m,) the point in the chart of ``y``.
    """
    e = y + delta
    for idx in rotations:
        ii = list(idx)
        a = at[ii]
        b = a + delta[ii]
        e[ii] = gibbs_product(-a, b)
    return e


class TrackerNumerics:
    """The last sample in its own chart, and the computations of the rule there.

    Args:
        model: the model.
        start: the assembled configuration the track starts from (the first sample's
            predecessor).
    """

    def __init__(self, model: Model, start: Configuration):
        self.model = model
        self.K = track_kernels(model)
        self.m = model.m
        self.tol = float(model.tolerance)
        self.per = periodic(model)
        self.scale = max(1.0, float(model.length_scale))
        y, c = model.chart.to_local(start.y)
        self.y, self.c = self._recentre(y, c)
        self.theta = np.array(start.theta, dtype=float)
        self.jac_next: tuple[np.ndarray, np.ndarray] | None = None
        self.det = self._det(self.y, self.theta, keep=True)
        self.jac: SampleJacobian | None = None  # J_p, J_s of the last evaluation at the sample (R2)
        if self.jac_next is not None:
            self.jac = SampleJacobian(*self.jac_next, self.y.copy())

    # -- kernels
    def _det(self, y, theta, keep: bool = False) -> float:
        """det J_p at (y, theta); keep: J_p and J_s there become ``jac_next`` (None if J_p is
        not finite or singular)."""
        _, Jp, Js = self.K.closure(y, theta, self.c)
        if keep:
            self.jac_next = None
        if not np.all(np.isfinite(Jp)):
            return math.nan
        Jp = Jp.reshape(self.m, self.m, order="F")
        det = float(np.linalg.det(Jp))
        if keep and det != 0.0 and np.all(np.isfinite(Js)):
            self.jac_next = (Jp.copy(), Js.reshape(self.m, -1, order="F").copy())
        return det

    def _recentre(self, y, c):
        if not self.model.chart.rotations:
            return np.array(y, dtype=float), np.array(c, dtype=float)
        y0, c0 = self.K.recentre(y, c)
        return y0.copy(), c0.copy()

    def _newton(self, y, theta, calls: int) -> tuple[np.ndarray | None, float, float]:
        """Newton from y: (y, max|g|, how far it moved); y None if it diverged."""
        y0 = np.array(y, dtype=float)
        y = y0
        res = math.nan
        for _ in range(calls):
            yn, r, _ = self.K.newton(y, theta, self.c)
            if not (np.all(np.isfinite(yn)) and math.isfinite(r[0])):
                return None, math.nan, math.nan
            y, res = yn.copy(), float(r[0])
            if res <= 1e-3 * self.tol:
                break
        return y, res, inf_norm(y - y0)

    def _newton_lu(self, y, theta) -> tuple[np.ndarray | None, float, float, float]:
        """R2: Newton from y with g and J_p evaluated at every iterate, at most
        ``FAST_ITERATIONS`` times: every evaluation is followed by the Newton correction, and the
        iteration stops after the first one at which max|g| <= 1e-3 tol. Returns (y, max|g| at
        the last iterate, det J_p at the start, det J_p at the last iterate); y None if an
        evaluation was not finite or J_p singular. J_p and J_s of the last evaluation become
        ``jac_next`` (the sample's, if y is taken)."""
        m = self.m
        y = np.array(y, dtype=float)
        res = d0 = d1 = math.nan
        self.jac_next = None
        for it in range(FAST_ITERATIONS):
            g, Jp, Js = self.K.closure(y, theta, self.c)
            Jp = Jp.reshape(m, m, order="F")
            with np.errstate(all="ignore"):
                res, d1 = inf_norm(g), float(np.linalg.det(Jp))
            if not (math.isfinite(res) and math.isfinite(d1)) or d1 == 0.0:
                return None, math.nan, math.nan, math.nan
            if it == 0:
                d0 = d1
            y = y - np.linalg.solve(Jp, g)
            if res <= 1e-3 * self.tol:
                break
        if np.all(np.isfinite(Js)):
            self.jac_next = (Jp.copy(), Js.reshape(m, -1, order="F").copy())
        return y, res, d0, d1

    def _euler(self, theta) -> np.ndarray | None:
        """R2: the Euler point ``y_k + J_p^-1 J_s (theta - theta_k)`` of the continuation of
        y_k, from J_p and J_s of the last evaluation at sample k, in the chart of y_k (None if
        they are not known)."""
        jac = self.jac
        if jac is None:
            return None
        try:
            with np.errstate(all="ignore"):
                delta = np.linalg.solve(jac.jp, jac.js @ (theta - self.theta))
        except np.linalg.LinAlgError:
            return None
        return euler_point(self.y, jac.at, delta, self.model.chart.rotations)

    def _polish(self, y, theta) -> np.ndarray | None:
        """R3: a candidate polished, its revolute angles within pi of y_k (None: not a
        solution)."""
        y, res, _ = self._newton(y, theta, PREDICTED_CALLS)
        if y is None or not res <= self.tol:
            return None
        per = self.per
        y[per] -= TWO_PI * np.floor((y[per] - self.y[per]) / TWO_PI + 0.5)
        return y

    def _partner(self, r, theta) -> np.ndarray | None:
        """R3: the other root of the fold's quadratic normal form at the root r (None if J_p
        is singular there)."""
        m = self.m
        K, c = self.K, self.c

        def jac(y):
            return K.closure(y, theta, c)[1].reshape(m, m, order="F").copy()

        with np.errstate(all="ignore"):
            J = jac(r)
            if not np.all(np.isfinite(J)):
                return None
            v = np.full(m, 1.0 / math.sqrt(m))
            try:
                for _ in range(PARTNER_ITERATIONS):  # inverse iteration: smallest singular pair
                    x = np.linalg.solve(J, np.linalg.solve(J.T, v))
                    v = x / float(np.linalg.norm(x))
            except np.linalg.LinAlgError:
                return None
            Jv = J @ v
            sigma = float(np.linalg.norm(Jv))
            h = PARTNER_STEP * self.scale
            curv = float((Jv / sigma) @ ((jac(r + h * v) - jac(r - h * v)) @ v)) / (2.0 * h)
            y = r - (2.0 * sigma / curv) * v
        if not inf_norm(y - r) <= PARTNER_REACH * self.scale:
            return None
        return y if np.all(np.isfinite(y)) else None

    def canonical(self) -> np.ndarray:
        return self.model.chart.to_canonical(self.y, self.c)

    def local(self, y_can: np.ndarray) -> np.ndarray:
        """Canonical unknowns -> coordinates in the chart of the current sample."""
        y = np.array(y_can, dtype=float)
        for i, idx in enumerate(self.model.chart.rotations):
            ii = list(idx)
            R_ref = self.c[9 * i : 9 * i + 9].reshape(3, 3, order="F")
            y[ii] = gibbs(R_ref.T @ rot_exp(y[ii]))
        return y
