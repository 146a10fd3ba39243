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
(:func:`~scdk_sym.solvers.trace.trace`), ``backend="c"`` with the follower's RK4
predictor-corrector steps (:mod:`scdk_sym.follower.calls`, code-generated) in the generated C
tracker (``scdk_sym/solvers/tracker.c.in``; the tracker's header states the same rule).
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

*Crossings* (:func:`~scdk_sym.solvers.crossings.crossings`, both backends, after the
track): wherever ``det J_p`` has opposite signs at consecutive samples (the start and the
first sample included: ``index = -1``), the sign change is bisected along the motion between
them (see :func:`~scdk_sym.solvers.crossings.locate`); ``s`` is the fraction of the way from
sample ``index`` to ``index + 1``, and the kind is "fold".
A motion that crosses the singular manifold and comes back between two readings does not
count.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..backends import resolve
from ..codegen.status import TrackerStatus as _S  # the status codes shared with the C tracker
from ..errors import InputError
from ..results import Configuration, TrackResult
from ..robot import Model
from .background import without_waiting
from .blockwise import track_blocks
from .crossings import crossings
from .query import validate_start
from .track_c import track_c
from .track_errors import verify_samples
from .tracker import Tracker

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
        (N,), and the singular-manifold crossings of
        :func:`~scdk_sym.solvers.crossings.crossings`.

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
        readings = _thetas(model, thetas)
        return track_blocks(
            model, model.stages, readings, validate_start(model, start), track, backend=backend
        )
    if backend == "c":
        return track_c(model, thetas, start)
    thetas = _thetas(model, thetas)
    start = validate_start(model, start)
    tracker = Tracker(model, start)
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
