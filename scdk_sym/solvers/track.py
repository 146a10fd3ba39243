"""Direct kinematics along a sequence of joint readings, preserving the continuity of motion.

A controller reads the actuated joints ``theta_0, theta_1, ...`` and needs the platform pose
at each. Warm-started Newton converges to the solution nearest to the previous one; through
a direct-kinematic singularity (a fold: two solutions meet and leave) that is the mirror
solution, and the tracked pose turns back while the robot goes on. Near a fold both
solutions lie ahead of the previous one along the singularity-consistent (SC) solution curve,
the continuing one often as the SECOND crossing of ``s = 1`` (``s`` overshoots, turns on the
singular manifold and comes back), so :func:`track` collects the candidate solutions and
judges them against the predicted motion, and refuses to guess when the readings are too
coarse to tell them apart.

The judging rule
----------------
Both backends apply this rule with the same constants (:mod:`scdk_sym.follower.track_rule`,
which :mod:`scdk_sym.codegen.generate` writes into the generated tracker) and the same kernels:
``backend="cvodes"`` (this module) follows the SC curve with CVODES
(:func:`~scdk_sym.solvers.sc.trace`), ``backend="c"`` with the follower's RK4
predictor-corrector steps (:mod:`scdk_sym.follower.kernels`, code-generated) in the generated C
tracker (``scdk_sym/codegen/c/tracker_rule.c.in``; the tracker's header states the same rule).
Only the way the curve is followed differs; the prediction, the cheap step, the Newton
correctors, the choice and the refusal are the same computation.

*Notation.* Sample ``k`` is ``(y_k, theta_k)``; every ``y`` is written in the local chart
centred on ``y_k`` (floating joints: Rodrigues parameters relative to the rotation of ``y_k``,
see :mod:`scdk_sym.model.chart`; other coordinates as they are). ``|v|`` is the max norm over
the coordinates of ``y`` [model length unit, rad], ``|v|_2`` the Euclidean norm; ``tol`` the
model's residual tolerance; ``det_k = det J_p(y_k, theta_k)``; ``dtheta = theta - theta_k``
for the new reading ``theta``. The motion increments ``d_j = y_j - y_(j-1)`` (each in the
chart of ``y_(j-1)``) count from the first sample or the last repeated reading: ``n`` of
them are known, at most 3.

R0. *Rest.* A reading equal to ``theta_k`` (every component) gives ``y_(k+1) = y_k`` and sets
    ``n = 0`` (the robot stood still; its motion starts anew). The start configuration is not
    a sample: ``n = 0`` after the first sample.
R1. *Prediction.* With ``lin = |d_k - d_(k-1)|`` (``n >= 2``, else 0) and ``quad = |d_k - 2
    d_(k-1) + d_(k-2)|`` (``n = 3``, else 0), the extrapolation is quadratic, ``D = 2 d_k -
    d_(k-1)``, if ``n = 3`` and ``quad <= lin`` (it did better at the last sample) or ``n = 2``
    and ``lin <= SMOOTH |d_k|``; else linear, ``D = d_k``. Then ``y_pred = y_k + D``, the
    predicted step ``L = |D|``, the accuracy ``E`` = ``quad`` or ``lin`` (of the extrapolation
    used: its error at the last sample; 0 if unknown) and the arc-length scale ``ell =
    sqrt(|dtheta|_2^2 + |D|_2^2)``. Without a known motion (``n = 0``): ``y_pred = y_k``, ``L``
    unknown (infinite), ``E = 0``, and ``ell = 1 / |t_s|`` with ``t`` the unit tangent of the
    curve at ``(y_k, 0)`` in the metric ``|dy|_2^2 + (|dtheta|_2 ds)^2``, clamped to
    ``[|dtheta|_2, 1e3 max(1, length scale)]``.
R2. *Cheap continuation.* First (``n >= 1``) ``y_f``: Newton from ``y_pred``, ``g`` and
    ``J_p`` evaluated at every iterate (at most ``FAST_ITERATIONS`` times, each evaluation
    followed by its correction, the last one that after which ``max|g| <= 1e-3 tol`` at the
    iterate). It is the answer, without any other candidate, if every evaluation was finite
    with ``J_p`` regular, ``max|g| <= tol`` at the last iterate, Newton moved ``y_pred`` by
    at most ``0.05 |y_f - y_k| + 10 tol`` (the extrapolated motion was as accurate as the RK4
    point below must be) and by at most ``ACCEPT L + 10 tol``, ``y_f`` lies within ``0.05
    |y_f - y_k| + 10 tol`` of the Euler point ``y_e = y_k + J_p^-1 J_s dtheta`` (``J_p``, ``J_s``
    and the chart of the last evaluation of ``J_p`` at sample ``k``, ``y_e`` moved into the
    chart of ``y_k``: ``y_f`` is the continuation of ``y_k``, not a root the prediction happened
    to lie next to), ``d = det J_p`` at the last
    iterate (kept as the sample's ``det``) and ``det J_p`` at ``y_pred`` (the first) have the
    non-zero sign of ``det_k``, ``2 det_k - det_(k-1)`` has that sign and ``|d| >= |det_k -
    d|``: the conditions of the cheap continuation below, checked at ``y_f``. Else ``y_c``:
    one RK4 step of ``dy/ds = J_p^-1 J_s dtheta`` from ``s = 0`` to 1, then Newton
    (``NEWTON_CALLS`` calls of the 2-iteration kernel, stopping once ``max|g| <= 1e-3 tol``).
    *Valid* if finite, ``max|g| <= tol`` and Newton moved the RK4 point by at most ``0.05
    |y_c - y_k| + 10 tol``. It is the answer, without any other candidate, if valid and ``det
    J_p(y_c, theta)`` has the non-zero sign of ``det_k``, and: with ``n >= 1``, ``|y_c -
    y_pred| <= ACCEPT L + 10 tol``, ``2 det_k - det_(k-1)`` has that sign, ``|det J_p(y_c)|
    >= |det_k - det J_p(y_c)|`` and ``det J_p(y_pred, theta)`` has that sign (nothing hints
    at a crossing of ``det J_p = 0`` between the samples or within the next step; ``y_c`` is
    *regular* if all but the first of these hold); with ``n = 0``, its fold partner (see R3),
    polished, is not a solution other than ``y_c`` within ``MARGIN |y_c - y_k| + 10 tol`` of
    ``y_k``.
R3. *Candidates* (R2 not taken), in this order: ``y_c`` if valid; Newton from ``y_pred``; the
    *fold partner* of each of these two that was kept; the first ``HITS_PER_DIRECTION``
    crossings of ``s = 1`` of the SC curve from ``(y_k, 0)`` in each direction (convergent,
    ``s`` increasing, first) met within arc length ``BUDGET ell``. Each is polished (Newton,
    ``PREDICTED_CALLS`` calls, stopping once ``max|g| <= 1e-3 tol``), its revolute angles moved
    by multiples of ``2 pi`` to within ``pi`` of ``y_k``, and kept if ``max|g| <= tol`` and it
    lies farther than ``10 tol`` from every kept one. The fold partner of a root ``r`` is the
    other root of the quadratic normal form of a fold there (near a fold, the mirror
    solution, however close): with ``J = J_p(r, theta)``, ``v`` from ``PARTNER_ITERATIONS``
    steps ``v <- (J^T J)^-1 v / |.|_2`` of inverse iteration from ``v = (1, ..., 1) /
    sqrt(m)``, ``sigma = |J v|_2``, ``u = J v / sigma`` and the curvature ``c = u . (J_p(r + h
    v) - J_p(r - h v)) v / (2 h)``, ``h = PARTNER_STEP max(1, length scale)``, it is ``r - (2
    sigma / c) v``, and none if that lies farther than ``PARTNER_REACH max(1, length scale)``
    from ``r`` (or is not finite). The *miss* of a candidate is ``e = |y - y_pred|``: ``c1``
    has the least, ``e1`` (the first of equal ones), ``c2`` the least of the others, ``e2``.
R4. *Choice and decidability.* The answer is ``c1`` if either there is no ``c2`` or ``e2 >
    MARGIN max(e1, E) + 10 tol`` (the runner-up is clearly less consistent with the
    prediction, given its accuracy), and either ``e1 <= ACCEPT L + 10 tol`` (``c1`` agrees with
    the predicted motion) or ``c1`` is ``y_c`` and ``y_c`` is regular (a poorly predicted
    motion where nothing hints at a singularity). Otherwise the readings are too coarse to
    decide: status ``ERR_UNDECIDABLE``, raised as :class:`~scdk_sym.errors.TrackError` naming
    the sample, ``theta`` and the workspace ``x`` of ``c1`` and ``c2``. No candidate:
    ``ERR_NO_SOLUTION``.
R5. The answer must have ``max|g| <= tol`` (else ``ERR_VERIFY``); the chart is re-centred on
    it. The finished track is verified again, sample by sample, on every closure row.

When the true solution is among the candidates, a choice by R4 is wrong only if it misses the
prediction by more than ``e2 > MARGIN max(e1, E)``: ``MARGIN`` times more than the best
candidate and than the prediction's own error at the last sample. Near-ties are refused,
never broken. Without a known motion (the first two samples, and the first after a rest) the
prediction is "no motion": the solution nearest to the previous sample is taken only if the
next one is ``MARGIN`` times farther, and a step that crosses a fold so deeply that the mirror
solution lies that much nearer than the true one cannot be told from a small step; keep the
first samples of a track away from the singular manifold.

*Crossings* (:func:`crossings`, both backends, after the track): wherever ``det J_p`` has
opposite signs at consecutive samples (the start and the first sample included: ``index =
-1``), the sign change is bisected along the motion between them (see :func:`locate`); ``s``
is the fraction of the way from sample ``index`` to ``index + 1``, and the kind is "fold".
A motion that crosses the singular manifold and comes back between two readings does not
count.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..backends import resolve
from ..codegen.status import TrackerStatus as _S  # the status codes shared with the C tracker
from ..errors import InputError, PathError, TrackError
from ..follower.geometry import periodic
from ..follower.track_rule import (  # the rule's constants (stated above)
    ACCEPT,
    BUDGET,
    FAST_ITERATIONS,
    HITS_PER_DIRECTION,
    MARGIN,
    NEWTON_CALLS,
    PARTNER_ITERATIONS,
    PARTNER_REACH,
    PARTNER_STEP,
    PREDICTED_CALLS,
    SMOOTH,
)
from ..kernels.fastcall import Buffered, model_calls
from ..model.rotations import gibbs, gibbs_product, rot_exp
from ..products import TRACK_KERNELS
from ..results import Configuration, Crossing, TrackResult
from ..robot import Model
from .background import without_waiting
from .sc import null_direction, trace, validate_start

OK, OK_PATH, OK_PREDICTED = _S.OK, _S.OK_PATH, _S.OK_PREDICTED  # codegen.status.TrackerStatus
ERR_NO_SOLUTION, ERR_VERIFY, ERR_UNDECIDABLE = _S.ERR_NO_SOLUTION, _S.ERR_VERIFY, _S.ERR_UNDECIDABLE


def _thetas(model: Model, thetas) -> np.ndarray:
    try:
        arr = np.asarray(thetas, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"thetas must be an (N, {model.k}) array of numbers") from exc
    if arr.ndim != 2 or arr.shape[1] != model.k or arr.shape[0] < 1:
        raise InputError(
            f"thetas must have shape (N, {model.k}) (columns {', '.join(model.actuated)}), "
            f"got {arr.shape}"
        )
    bad = np.nonzero(~np.all(np.isfinite(arr), axis=1))[0]
    if bad.size:
        raise InputError(f"thetas row {int(bad[0])} is not finite: {arr[bad[0]].tolist()}")
    return arr


def track(
    model: Model,
    thetas: Sequence[Sequence[float]] | np.ndarray,
    start: Configuration | None = None,
    backend: str = "cvodes",
) -> TrackResult:
    """Direct kinematics along joint readings, following the motion through singularities.

    Every reading is judged by the rule of this module's docstring (the same in both
    backends): the first sample is reached from ``start`` on the convergent branch, and each
    following one is the candidate solution that continues the predicted motion (an
    extrapolation of the last samples, readings at a steady rate), provided no other candidate
    is about as consistent with the prediction; otherwise :class:`~scdk_sym.errors.TrackError`
    is raised instead of a guess.

    Args:
        model: the model.
        thetas: (N, k) actuated joint readings [rad or model length unit], in time order.
        start: assembled configuration the robot starts from (default ``model.home``).
        backend: a name of :mod:`scdk_sym.backends` that track offers: "cvodes" (curves
            followed with CVODES via CasADi, default), "c" (the generated-C tracker, one call
            for the whole sequence) or "auto" (c when a C compiler is found).

    Returns:
        A :class:`~scdk_sym.results.TrackResult`: ``x`` (N, n), ``y`` (N, m), ``residual``
        (N,), and the singular-manifold crossings of :func:`crossings`.

    Raises:
        InputError: bad shapes, non-finite readings or a backend track does not offer.
        NotAssembledError: ``start`` is not assembled.
        TrackError: at a sample the readings are too coarse to decide between two candidate
            solutions (``status = ERR_UNDECIDABLE``, ``candidates`` their workspace x), no
            solution was met (``ERR_NO_SOLUTION``: the readings leave the reachable set or
            jump too far), or a sample failed its verification.
    """
    backend = without_waiting(
        model,
        resolve(backend, "track"),
        lambda built: track(model, model.home.theta[None], model.home, backend=built),
    )
    if len(model.stages) > 1:  # a leg's knee, then its ankle (each leg in turn): one each
        from .blocks import track_blocks

        readings = _thetas(model, thetas)
        return track_blocks(
            model, model.stages, readings, validate_start(model, start), track, backend=backend
        )
    if backend == "c":
        from .track_c import track_c

        return track_c(model, thetas, start)
    thetas = _thetas(model, thetas)
    start = validate_start(model, start)
    tracker = _Tracker(model, start)
    ys, dets = [], []
    for i, theta in enumerate(thetas):
        tracker.step(theta, i)
        if i == 0:
            tracker.n = 0  # the start is not a sample: the motion is extrapolated from here on
        ys.append(tracker.canonical())
        dets.append(tracker.det)
    y_can = np.array(ys)
    configs = [model.configuration(y, th) for y, th in zip(y_can, thetas, strict=True)]
    residual = np.array([c.residual for c in configs])
    verify_samples(model, residual, thetas)
    return TrackResult(
        x=np.array([c.x for c in configs]),
        y=y_can,
        theta=thetas,
        residual=residual,
        crossings=crossings(model, start, y_can, thetas, np.array(dets)),
        status="converged",
        backend="cvodes",
    )


# ---------------------------------------------------------------------------- the rule


@dataclass(frozen=True)
class _Kernels:
    """The C tracker's kernels (the same SX Functions it is generated from), zero-copy."""

    predict: Buffered
    newton: Buffered
    closure: Buffered
    recentre: Buffered


def _kernels(model: Model) -> _Kernels:
    def build() -> _Kernels:
        from ..codegen.kernels import build_tracker_kernels

        kern = build_tracker_kernels(model.symbolic, model.chart.rotations, "scdk")
        return _Kernels(
            Buffered(kern.predict), Buffered(kern.newton), Buffered(kern.closure),
            Buffered(kern.recentre),
        )  # fmt: skip

    return model.products.get(TRACK_KERNELS, build)


TWO_PI = 2.0 * math.pi


def _sign(v: float) -> int:
    return (v > 0) - (v < 0)


def _inf(v: np.ndarray) -> float:
    return float(np.max(np.abs(v))) if v.size else 0.0


class _Tracker:
    """State of the rule: the last sample in its own chart and the motion that led to it."""

    def __init__(self, model: Model, start: Configuration):
        self.model = model
        self.K = _kernels(model)
        self.m = model.m
        self.tol = float(model.tolerance)
        self.per = periodic(model)
        self.scale = max(1.0, float(model.length_scale))
        y, c = model.chart.to_local(start.y)
        self.y, self.c = self._recentre(y, c)
        self.theta = np.array(start.theta, dtype=float)
        self.jac_next: tuple[np.ndarray, np.ndarray] | None = None
        self.det = self._det(self.y, self.theta, keep=True)
        self.jac: _Jacobian | None = None  # J_p, J_s of the last evaluation at the sample (R2)
        if self.jac_next is not None:
            self.jac = _Jacobian(*self.jac_next, self.y.copy())
        self.det_prev = self.det
        self.d: list[np.ndarray] = []  # motion increments, most recent first
        self.n = 0

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
        return y, res, _inf(y - y0)

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
                res, d1 = _inf(g), float(np.linalg.det(Jp))
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
        if not _inf(y - r) <= PARTNER_REACH * self.scale:
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

    # -- one reading
    def step(self, theta: np.ndarray, index: int) -> int:
        dtheta = theta - self.theta
        w = float(np.linalg.norm(dtheta))
        if w == 0.0:  # R0
            self.n = 0
            return OK
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
        lin = _inf(d[0] - d[1]) if self.n >= 2 else 0.0  # what linear missed at the last sample
        if self.n >= 3:  # the extrapolation that did better at the last sample
            qua = _inf(d[0] - 2.0 * d[1] + d[2])
            quad = qua <= lin
        else:
            qua, quad = 0.0, self.n == 2 and lin <= SMOOTH * _inf(d[0])
        D = 2.0 * d[0] - d[1] if quad else d[0]
        E = qua if quad else lin
        ell = math.sqrt(w * w + float(D @ D))
        return _Prediction(self.y + D, _inf(D), E, ell)

    def _fast(self, theta, pred):
        """R2: the fast continuation, (y_f, det J_p there, OK) if taken, else (None, 0, 0)."""
        s0 = _sign(self.det)
        if pred is None or s0 == 0:
            return None, 0.0, 0
        y, res, d0, d1 = self._newton_lu(pred.y, theta)
        if y is None or not res <= self.tol:
            return None, 0.0, 0
        moved = _inf(y - pred.y)
        if not moved <= 0.05 * _inf(y - self.y) + 10.0 * self.tol:
            return None, 0.0, 0
        if not moved <= ACCEPT * pred.step + 10.0 * self.tol:
            return None, 0.0, 0
        e = self._euler(theta)
        if e is None or not _inf(y - e) <= 0.05 * _inf(y - self.y) + 10.0 * self.tol:
            return None, 0.0, 0
        if _sign(d1) != s0 or _sign(d0) != s0:
            return None, 0.0, 0
        if _sign(2.0 * self.det - self.det_prev) != s0:
            return None, 0.0, 0
        if abs(d1) < abs(self.det - d1):
            return None, 0.0, 0
        return y, d1, OK

    def _cheap(self, theta, pred):
        """R2: (y_c, det J_p there, OK) if taken, else (None, 0, 0); keeps a valid y_c."""
        self.y_cheap, self.cheap_regular = None, False
        y1 = self.K.predict(self.y, self.theta, theta - self.theta, self.c)[0].copy()
        if not np.all(np.isfinite(y1)):
            return None, 0.0, 0
        y, res, moved = self._newton(y1, theta, NEWTON_CALLS)
        if y is None or not res <= self.tol:
            return None, 0.0, 0
        if not moved <= 0.05 * _inf(y - self.y) + 10.0 * self.tol:
            return None, 0.0, 0
        self.y_cheap = y
        d1 = self._det(y, theta, keep=True)
        s0 = _sign(self.det)
        if _sign(d1) == 0 or _sign(d1) != s0:
            return None, 0.0, 0
        if pred is None:  # no fold partner about as near to y_k
            yp = self._partner(y, theta)
            yp = self._polish(yp, theta) if yp is not None else None
            if (
                yp is not None
                and _inf(yp - y) > 10.0 * self.tol
                and not _inf(yp - self.y) > MARGIN * _inf(y - self.y) + 10.0 * self.tol
            ):
                return None, 0.0, 0
        else:
            agree = _inf(y - pred.y) <= ACCEPT * pred.step + 10.0 * self.tol
            if _sign(2.0 * self.det - self.det_prev) != s0:
                return None, 0.0, 0
            if abs(d1) < abs(self.det - d1):
                return None, 0.0, 0
            if _sign(self._det(pred.y, theta)) != s0:
                return None, 0.0, 0
            self.cheap_regular = True  # nothing hints at a singularity
            if not agree:
                return None, 0.0, 0
        return y, d1, OK

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
            if any(_inf(y - yc) <= 10.0 * self.tol for yc, _ in cands):
                return
            cands.append((y, code))

        cheap_idx = -1
        if self.y_cheap is not None:
            add(self.y_cheap, OK_PATH)
            cheap_idx = 0 if cands else -1
        add(pred.y, OK_PREDICTED)
        for yc, _ in list(cands):  # the other solution of a fold next to them, if any
            y = self._partner(yc, theta)
            if y is not None:
                add(y, OK_PREDICTED)
        for direction in (conv, -conv):
            for y in self._hits(theta, direction, HITS_PER_DIRECTION, budget):
                add(y, OK_PATH)
        if not cands:
            raise self._no_solution(theta, index)
        miss = [_inf(y - pred.y) for y, _ in cands]
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
        self.jac = _Jacobian(*self.jac_next, at) if self.jac_next else None
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
class _Jacobian:
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


@dataclass(frozen=True)
class _Prediction:
    y: np.ndarray  # predicted configuration (chart of the current sample)
    step: float  # L = |D|
    accuracy: float  # E
    ell: float  # arc-length scale of the step


def no_solution_error(index: int, theta: np.ndarray) -> TrackError:
    """The :class:`TrackError` of a sample where no solution was met (status -5)."""
    return TrackError(
        f"sample {index}: no solution at theta={np.asarray(theta).tolist()} was met from the "
        "previous sample along the solution curve (the readings leave the reachable set or jump "
        "too far)",
        index, ERR_NO_SOLUTION, theta=theta,
    )  # fmt: skip


def undecidable_error(index: int, theta, xs, miss, accuracy: float, step: float) -> TrackError:
    """The :class:`TrackError` of a sample the rule refuses to decide (status -9, rule R4).

    Args:
        index: the sample.
        theta: (k,) its reading.
        xs: workspace coordinates of the best candidate and the runner-up (if any).
        miss: their misses of the predicted configuration (max norm).
        accuracy: the accuracy of the prediction ``E``.
        step: the predicted step ``L``.
    """
    e1 = float(miss[0])
    if not math.isfinite(step):
        why = (
            f"no motion is known to predict from, and their distances {e1:.3g} and "
            f"{float(miss[1]):.3g} from the previous sample are within a factor {MARGIN:g}"
        )
    elif len(xs) < 2 or e1 > ACCEPT * step:
        why = f"the best misses the predicted motion by {e1:.3g} > {ACCEPT:g} x step {step:.3g}"
    else:
        why = (
            f"their misses {e1:.3g} and {float(miss[1]):.3g} of the predicted motion (accuracy "
            f"{accuracy:.3g}) are within a factor {MARGIN:g}"
        )
    listed = " and ".join(str(np.round(np.asarray(x, float), 6).tolist()) for x in xs)
    return TrackError(
        f"sample {index}: the readings are too coarse to decide between candidate solutions "
        f"x = {listed} at theta={np.asarray(theta).tolist()}: {why}",
        index, ERR_UNDECIDABLE, theta=theta, candidates=xs,
    )  # fmt: skip


# ---------------------------------------------------------------------------- crossings


def crossings(
    model: Model, start: Configuration, y: np.ndarray, thetas: np.ndarray, dets: np.ndarray
) -> tuple[Crossing, ...]:
    """Singular-manifold crossings of a finished track (the same for every backend).

    Args:
        model: the model.
        start: the configuration the track started from.
        y: (N, m) canonical unknowns of the samples.
        thetas: (N, k) readings.
        dets: (N,) ``det J_p`` at the samples (any chart: only the sign is used).

    Returns:
        One "fold" :class:`~scdk_sym.results.Crossing` wherever ``det J_p`` has opposite signs
        at consecutive samples (the start and the first sample included): ``index`` the
        sample before it (-1: between the start and sample 0), ``s`` the fraction of the way
        to the next sample, located by :func:`locate`.
    """
    dets = np.asarray(dets, dtype=float)
    if dets.size == 0:
        return ()
    y_loc0, c0 = model.chart.to_local(start.y)
    det0 = float(np.linalg.det(model_calls(model).jac(y_loc0, start.theta, c0)[0]))
    dd = np.concatenate([[det0], dets])
    changes = np.flatnonzero(np.sign(dd[:-1]) * np.sign(dd[1:]) < 0)
    if changes.size == 0:
        return ()
    ys = np.vstack([start.y, y])
    ths = np.vstack([start.theta, thetas])
    out = []
    for j in changes:
        out.append(locate(model, ys[j], ys[j + 1], ths[j], ths[j + 1], float(dd[j]), j - 1))
    return tuple(out)


#: Workspace coordinates that are angles (interpolated the short way round).
ANGLES = ("phi", "roll", "pitch", "yaw")


def locate(model: Model, ya, yb, tha, thb, da: float, index: int) -> Crossing:
    """The crossing between two samples: where ``det J_p`` vanishes between them.

    With as many workspace coordinates as actuators, the motion between the samples is
    interpolated linearly in the workspace coordinates ``x`` (angles the short way round)
    and each interpolated pose solved by inverse-kinematics Newton over ``(y, theta)`` (regular
    at direct-kinematic singularities) from the chord between the samples; otherwise the
    chord in ``(y, theta)`` is projected onto the closure manifold ``g = 0`` (minimum-norm
    Gauss-Newton over ``(y, theta)``). The sign change of ``det J_p`` along that path is
    bisected; ``s`` is the fraction of the way from the first sample.

    Args:
        model: the model.
        ya: (m,) canonical unknowns of the first sample.
        yb: (m,) those of the second.
        tha: (k,) the first reading.
        thb: (k,) the second.
        da: ``det J_p`` at the first sample (its sign).
        index: the first sample's index, kept in the record.
    """
    m = model.m
    kern = model.kernels
    calls = model_calls(model)  # the same values as kern's plain calls, without conversions
    ya_loc, c = model.chart.to_local(ya)
    yb_loc = np.array(yb, dtype=float)
    for i, rot in enumerate(model.chart.rotations):
        idx = list(rot)
        R_ref = c[9 * i : 9 * i + 9].reshape(3, 3, order="F")
        yb_loc[idx] = gibbs(R_ref.T @ rot_exp(np.asarray(yb)[idx]))
    za = np.concatenate([ya_loc, tha])
    zb = np.concatenate([yb_loc, thb])
    tol = 1e-3 * model.tolerance

    def det_at(z) -> float:
        return float(np.linalg.det(calls.jac(z[:m], z[m:], c)[0]))

    def chord(alpha):
        z = za + alpha * (zb - za)
        for _ in range(30):
            g = calls.g(z[:m], z[m:], c).ravel()
            if np.max(np.abs(g)) <= tol:
                return z
            Jp, Js = calls.jac(z[:m], z[m:], c)
            G = np.hstack([Jp, -Js])
            z = z - G.T @ np.linalg.solve(G @ G.T, g)
        return z

    path = chord
    if len(model.workspace) == model.k:
        xa = calls.pose(ya_loc, tha, c)[1].ravel()
        dx = calls.pose(yb_loc, thb, c)[1].ravel() - xa
        for i, name in enumerate(model.workspace):
            if name in ANGLES:
                dx[i] = (dx[i] + math.pi) % TWO_PI - math.pi

        def motion(alpha):
            T = model.target_pose(xa + alpha * dx)
            z = za + alpha * (zb - za)
            for _ in range(30):
                zn, res = kern.ik_step(z, T, c)
                z = np.array(zn).ravel()
                if not np.all(np.isfinite(z)):
                    break
                if float(res) <= tol:
                    return z
            raise np.linalg.LinAlgError("inverse kinematics did not converge")

        path = motion
    sign_lo = float(np.sign(da))
    ends = (sign_lo * det_at(za), sign_lo * det_at(zb))
    for attempt in (path, chord):
        try:
            with np.errstate(all="ignore"):
                lo, hi, z = _sign_change(attempt, lambda z: sign_lo * det_at(z), za, *ends)
        except np.linalg.LinAlgError:
            continue
        if np.all(np.isfinite(z)):
            break
    else:  # fall back on the chord (accurate to the sample spacing)
        lo = hi = 0.5
        z = za + 0.5 * (zb - za)
    cfg = model.configuration(z[:m], z[m:], c)
    return Crossing(0.5 * (lo + hi), cfg.x, cfg.y, cfg.theta, index, "fold")


def _sign_change(
    point: Callable[[float], np.ndarray],
    value: Callable[[np.ndarray], float],
    z0: np.ndarray,
    f_lo: float,
    f_hi: float,
    xtol: float = 1e-13,
    iterations: int = 60,
) -> tuple[float, float, np.ndarray]:
    """Where ``value(point(a))`` turns from positive to not positive for ``a`` in [0, 1]:
    false position with the Illinois rule (the bracket kept, superlinear), bisection where a
    value is not usable.

    Args:
        point: the path's point at the fraction ``a`` of the way.
        value: the function of a point (positive at ``point(0)``).
        z0: ``point(0)``.
        f_lo: its value at ``a = 0``.
        f_hi: its value at ``a = 1``.
        xtol: bracket width to reach.
        iterations: at most that many evaluations.

    Returns:
        ``(lo, hi, z)``: the final bracket and the point of the last evaluation.
    """
    lo, hi, side, z = 0.0, 1.0, 0, z0
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if f_lo > 0.0 and f_hi <= 0.0 and math.isfinite(f_lo) and math.isfinite(f_hi):
            cut = lo + (hi - lo) * f_lo / (f_lo - f_hi)
            if lo < cut < hi:
                mid = cut
        z = point(mid)
        f = value(z)
        if f > 0.0:
            lo, f_lo = mid, f
            f_hi = 0.5 * f_hi if side == 1 else f_hi
            side = 1
        else:
            hi, f_hi = mid, f
            f_lo = 0.5 * f_lo if side == -1 else f_lo
            side = -1
        if hi - lo < xtol:
            break
    return lo, hi, z


def verify_samples(model: Model, residual: np.ndarray, thetas: np.ndarray) -> None:
    """Raise TrackError at the first sample whose residual exceeds the model's tolerance.

    Args:
        model: the model.
        residual: (N,) max |closure row| per sample [model length unit].
        thetas: (N, k) the readings.
    """
    bad = np.flatnonzero(~(residual <= model.tolerance))
    if bad.size:
        i = int(bad[0])
        raise TrackError(
            f"sample {i} failed verification: residual {residual[i]:.3g} > "
            f"{model.tolerance:.1e} (theta={thetas[i].tolist()})",
            i, 0, float(residual[i]), theta=thetas[i],
        )  # fmt: skip
