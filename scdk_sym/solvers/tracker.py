"""The tracking rule applied to one reading (rules R0-R4 of :mod:`scdk_sym.solvers.track`).

:class:`Tracker` keeps the motion that led to the last sample and judges each new reading:
the rest (R0), the prediction (R1), the cheap continuation (R2), the candidates (R3) and the
choice or the refusal (R4, :func:`choose`). The numerics at the sample are those of
:class:`~scdk_sym.solvers.tracker_numerics.TrackerNumerics`; the candidates met along the
SC curve come from :func:`~scdk_sym.solvers.trace.trace`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..codegen.status import TrackerStatus
from ..errors import PathError, TrackError
from ..follower.tangent import null_direction
from ..follower.track_rule import (  # the rule's constants (stated in solvers.track)
    ACCEPT,
    BUDGET,
    HITS_PER_DIRECTION,
    MARGIN,
    NEWTON_CALLS,
    SMOOTH,
)
from ..results import Configuration
from ..robot import Model
from .trace import trace
from .track_errors import no_solution_error, undecidable_error
from .tracker_numerics import SampleJacobian, TrackerNumerics, inf_norm, sign_of


class Tracker(TrackerNumerics):
    """State of the rule: the last sample in its own chart and the motion that led to it.

    Args:
        model: the model.
        start: the assembled configuration the track starts from.
    """

    def __init__(self, model: Model, start: Configuration):
        super().__init__(model, start)
        self.det_prev = self.det
        self.d: list[np.ndarray] = []  # motion increments, most recent first
        self.n = 0

    # -- one reading
    def step(self, theta: np.ndarray, index: int) -> int:
        dtheta = theta - self.theta
        w = float(np.linalg.norm(dtheta))
        if w == 0.0:  # R0
            self.n = 0
            return TrackerStatus.OK
        pred = self._prediction(w)
        y, det, code = self._fast(theta, pred)
        if y is None:
            y, det, code = self._cheap(theta, pred)
        if y is None:
            y, code = self._path(theta, dtheta, w, pred, index)
            det = 0.0
        self._commit(y, theta, det)
        return code

    def _prediction(self, w: float):
        if self.n == 0:
            return None
        d = self.d
        lin = inf_norm(d[0] - d[1]) if self.n >= 2 else 0.0  # what linear missed at the last sample
        if self.n >= 3:  # the extrapolation that did better at the last sample
            qua = inf_norm(d[0] - 2.0 * d[1] + d[2])
            quad = qua <= lin
        else:
            qua, quad = 0.0, self.n == 2 and lin <= SMOOTH * inf_norm(d[0])
        D = 2.0 * d[0] - d[1] if quad else d[0]
        E = qua if quad else lin
        ell = math.sqrt(w * w + float(D @ D))
        return _Prediction(self.y + D, inf_norm(D), E, ell)

    def _fast(self, theta, pred):
        """R2: the fast continuation, (y_f, det J_p there, OK) if taken, else (None, 0, 0)."""
        s0 = sign_of(self.det)
        if pred is None or s0 == 0:
            return None, 0.0, 0
        y, res, d0, d1 = self._newton_lu(pred.y, theta)
        if y is None or not res <= self.tol:
            return None, 0.0, 0
        moved = inf_norm(y - pred.y)
        if not moved <= 0.05 * inf_norm(y - self.y) + 10.0 * self.tol:
            return None, 0.0, 0
        if not moved <= ACCEPT * pred.step + 10.0 * self.tol:
            return None, 0.0, 0
        e = self._euler(theta)
        if e is None or not inf_norm(y - e) <= 0.05 * inf_norm(y - self.y) + 10.0 * self.tol:
            return None, 0.0, 0
        if sign_of(d1) != s0 or sign_of(d0) != s0:
            return None, 0.0, 0
        if sign_of(2.0 * self.det - self.det_prev) != s0:
            return None, 0.0, 0
        if abs(d1) < abs(self.det - d1):
            return None, 0.0, 0
        return y, d1, TrackerStatus.OK

    def _cheap(self, theta, pred):
        """R2: (y_c, det J_p there, OK) if taken, else (None, 0, 0); keeps a valid y_c."""
        self.y_cheap, self.cheap_regular = None, False
        y1 = self.K.predict(self.y, self.theta, theta - self.theta, self.c)[0].copy()
        if not np.all(np.isfinite(y1)):
            return None, 0.0, 0
        y, res, moved = self._newton(y1, theta, NEWTON_CALLS)
        if y is None or not res <= self.tol:
            return None, 0.0, 0
        if not moved <= 0.05 * inf_norm(y - self.y) + 10.0 * self.tol:
            return None, 0.0, 0
        self.y_cheap = y
        d1 = self._det(y, theta, keep=True)
        s0 = sign_of(self.det)
        if sign_of(d1) == 0 or sign_of(d1) != s0:
            return None, 0.0, 0
        if pred is None:  # no fold partner about as near to y_k
            yp = self._partner(y, theta)
            yp = self._polish(yp, theta) if yp is not None else None
            if (
                yp is not None
                and inf_norm(yp - y) > 10.0 * self.tol
                and not inf_norm(yp - self.y) > MARGIN * inf_norm(y - self.y) + 10.0 * self.tol
            ):
                return None, 0.0, 0
        else:
            agree = inf_norm(y - pred.y) <= ACCEPT * pred.step + 10.0 * self.tol
            if sign_of(2.0 * self.det - self.det_prev) != s0:
                return None, 0.0, 0
            if abs(d1) < abs(self.det - d1):
                return None, 0.0, 0
            if sign_of(self._det(pred.y, theta)) != s0:
                return None, 0.0, 0
            self.cheap_regular = True  # nothing hints at a singularity
            if not agree:
                return None, 0.0, 0
        return y, d1, TrackerStatus.OK

    def _ell0(self, theta, w: float) -> tuple[float, float]:
        """(arc length per unit s at y_k, clamped; the convergent direction relative to nu)."""
        _, Jp, Js = self.K.closure(self.y, self.theta, self.c)
        m = self.m
        Jp = Jp.reshape(m, m, order="F")
        Js = Js.reshape(m, self.model.k, order="F")
        nu = null_direction(Jp, Js @ (theta - self.theta))
        t_s = abs(nu[-1]) / math.sqrt(float(nu[:-1] @ nu[:-1]) + (w * nu[-1]) ** 2)
        ell = 1.0 / max(t_s, 1e-12)
        ell = max(min(ell, 1e3 * self.scale), w)
        return ell, (1.0 if nu[-1] > 0 else -1.0)

    def _hits(self, theta, direction: float, max_hits: int, budget: float) -> list[np.ndarray]:
        prev = self.model.configuration(self.canonical(), self.theta)
        try:
            tr = trace(self.model, theta, prev, direction, max_hits=max_hits, max_arc=budget)
        except PathError:
            return []
        return [self.local(h.y) for h in tr.hits[:max_hits] if h.arc < budget]

    def _path(self, theta, dtheta, w, pred, index):
        ell0, conv = self._ell0(theta, w)
        if pred is None:  # no motion known: y_pred = y_k, the step unknown
            pred = _Prediction(self.y.copy(), math.inf, 0.0, ell0)
        budget = BUDGET * pred.ell
        cands: list[tuple[np.ndarray, int]] = []

        def add(y, code):
            y = self._polish(y, theta)
            if y is None:
                return
            if any(inf_norm(y - yc) <= 10.0 * self.tol for yc, _ in cands):
                return
            cands.append((y, code))

        cheap_idx = -1
        if self.y_cheap is not None:
            add(self.y_cheap, TrackerStatus.OK_PATH)
            cheap_idx = 0 if cands else -1
        add(pred.y, TrackerStatus.OK_PREDICTED)
        for yc, _ in list(cands):  # the other solution of a fold next to them, if any
            y = self._partner(yc, theta)
            if y is not None:
                add(y, TrackerStatus.OK_PREDICTED)
        for direction in (conv, -conv):
            for y in self._hits(theta, direction, HITS_PER_DIRECTION, budget):
                add(y, TrackerStatus.OK_PATH)
        if not cands:
            raise self._no_solution(theta, index)
        miss = [inf_norm(y - pred.y) for y, _ in cands]
        regular = cheap_idx if self.cheap_regular else -1
        order, taken = choose(miss, pred.step, pred.accuracy, self.tol, regular)
        if taken:
            return cands[order[0]]
        shown = [cands[i][0] for i in order[:2]]
        raise self._undecidable(theta, index, shown, miss, order, pred)

    def _x(self, y, theta) -> np.ndarray:
        return self.model.configuration(y, theta, self.c).x

    def _no_solution(self, theta, index) -> TrackError:
        return no_solution_error(index, theta)

    def _undecidable(self, theta, index, shown, miss, order, pred) -> TrackError:
        xs = [self._x(y, theta) for y in shown]
        return undecidable_error(index, theta, xs, [miss[i] for i in order[:2]], pred.accuracy,
                                 pred.step)  # fmt: skip

    def _commit(self, y, theta, det) -> None:
        self.d = [y - self.y, *self.d[:2]]
        self.n = min(self.n + 1, 3)
        self.theta = np.array(theta, dtype=float)
        at = np.array(y, dtype=float)  # J_p, J_s of the taken step (R2) were evaluated here
        self.y, self.c = self._recentre(y, self.c)
        self.det_prev = self.det
        if det == 0.0:  # evaluated at the sample, in its own chart
            det = self._det(self.y, self.theta, keep=True)
            at = self.y.copy()
        self.det = det
        self.jac = SampleJacobian(*self.jac_next, at) if self.jac_next else None
        self.jac_next = None


def choose(
    miss: Sequence[float], step: float, accuracy: float, tol: float, regular: int = -1
) -> tuple[list[int], bool]:
    """R4: the candidates best first and whether the best one is the answer.

    Args:
        miss: each candidate's miss ``e`` of the prediction (max norm).
        step: the predicted step ``L`` (``inf`` without a known motion).
        accuracy: the prediction's accuracy ``E``.
        tol: the model's residual tolerance.
        regular: index of the cheap continuation ``y_c`` when it is regular (R2), else -1.

    Returns:
        The candidate indices by increasing miss (the first of equal ones first: ``c1``,
        ``c2``, ...) and whether ``c1`` is taken (else the readings are too coarse to decide).
    """
    order = sorted(range(len(miss)), key=lambda i: miss[i])
    e1 = miss[order[0]]
    e2 = miss[order[1]] if len(order) > 1 else math.inf
    agrees = e1 <= ACCEPT * step + 10.0 * tol or order[0] == regular
    return order, bool(agrees and e2 > MARGIN * max(e1, accuracy) + 10.0 * tol)


@dataclass(frozen=True)
class _Prediction:
    """R1's prediction of the next sample."""

    y: np.ndarray  # predicted configuration (chart of the current sample)
    step: float  # L = |D|
    accuracy: float  # E
    ell: float  # arc-length scale of the step
