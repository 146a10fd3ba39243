"""The curve follower: one implementation of following a solution curve of the closures.

For a line ``theta(s) = theta1 + s dtheta`` in joint space the solutions of
``g(y, theta(s)) = 0`` form curves in ``q = (y, s)``. :func:`follow` walks such a curve from
an assembled point along the oriented singularity-consistent tangent (see
:mod:`scdk_sym.follower.kernels`) and reports what it meets:

- **level crossings** (``s`` passes a level, e.g. ``s = 1``: a direct-kinematics solution at
  ``theta(1)``), finished by Newton at fixed ``theta`` from a cubic Hermite guess and
  verified;
- **folds** (``s`` turns: ``t_s`` and ``det J_p`` change sign together), located by Newton on
  ``[g; t_s] = 0``;
- **bifurcations** (two branches cross: ``H' = [J_p, -j_s]`` drops rank because the left null
  vector of ``J_p`` is one of ``J_s`` too, ``det J_p`` changes sign while ``t_s`` does not),
  stepped over one at a time at fixed ``s`` from the extrapolation of the incoming branch
  (Newton at fixed ``theta``: the walk continues the incoming branch even where the other one
  has nearly the same tangent) or, failing that, along the incoming tangent with a corrector
  on the plane normal to it, and located by bisection of ``det J_p``. Where ``H'`` nearly
  drops rank only because the line is tangent to the singular surface, the point is a fold.

Two predictors produce the samples, judged by the same rules:

- ``"rk4"``: ``STEPS`` explicit steps of arc length ``h`` per call (RK4 along the tangent field,
  Newton corrections on the plane normal to the tangent), accepted one by one;
- ``"cvodes"``: CasADi's CVODES integrating the stabilised SC ODE over ``GRID`` samples of arc
  length ``h`` (:mod:`scdk_sym.follower.cvodes`), accepted as a whole.

Step control: a rejected step halves ``h`` (a quarter where an event needs resolution: a
level crossing and a fold in one step, a turning point that could hide two crossings of a
level, a finish that left the curve, a turn of ``s`` without a sign change of ``det J_p``); a
smooth chunk grows it by 1.6. When ``h`` has shrunk ``STALL_HALVINGS`` times in a row (calls
rejected in whole or in part) the follower tries to step over (a bifurcation, where no
tangent field is smooth); failing that the walk ends ``stalled``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..interrupts import check
from ..kernels.fastcall import model_calls
from ..results import Crossing, PathSamples
from .geometry import features, in_chart, local_features, periodic
from .kernels import follower_calls

if TYPE_CHECKING:
    from ..robot import Model

#: A predictor-corrector step is accepted when its first correction is below this fraction of
#: the step, its last below NEWTON_TOL model sizes, and the tangent turned by < acos(MIN_COS).
MAX_PREDICTOR_ERROR = 0.1
NEWTON_TOL = 1e-7
MIN_COS = 0.97
#: Accepted steps whose first correction is below SMOOTH_CORRECTION of the step and whose
#: tangent turned by < acos(SMOOTH_COS) are smooth: the next step grows by GROW.
SMOOTH_CORRECTION = 0.02
SMOOTH_COS = 0.95
GROW = 1.6
#: Intervals of a step on which the cubic Hermite of s is checked for a crossing of a level.
FINE = 64
#: A CVODES chunk is accepted when its end tangent is within acos(CHUNK_COS) of its start's.
CHUNK_COS = 0.8
#: Rejections in a row (each halving the step) before stepping over.
STALL_HALVINGS = 6
#: Bound on the follower's loop iterations, in accepted-step budgets (a guard: each iteration
#: advances, shrinks the step or stops, so it is never reached on a curve it can follow).
LOOP_FACTOR = 10
#: A stepped-over point must continue the incoming tangent within acos(STEP_OVER_COS).
STEP_OVER_COS = 0.9
#: Lengths of the straight step-over, in units of the last good step, tried in turn.
STEP_OVER_FACTORS = (2.0, 8.0, 32.0, 128.0, 0.5)
#: A step-over past a level of ``s`` is at most this many last good steps long.
SHORT_OVER = 2.0
#: det J_p changing sign without a turn of s is a bifurcation where H' = [J_p, -j_s] has
#: sigma_min / sigma_max below this (else the step jumped across a fold and is refined) ...
BIFURCATION_RANK = 1e-3
#: ... and the left null vector w of J_p there is one of J_s too, |w^T J_s| / |J_s| below this
#: (the singularity does not depend on the actuators). Where only w^T J_s dtheta vanishes the
#: line grazes the singular surface: two folds close together, not two branches crossing.
STRUCTURAL = 1e-4
#: Largest initial step [model sizes].
FIRST_STEP = 0.01
#: Rejected steps after which a walk ends as stalled.
MAX_REJECTED = 200
#: Rejections after which a walk on CVODES continues on the explicit predictor.
CVODES_REJECTIONS = 16
#: Calls of the explicit predictor after a CVODES chunk it had to take over.
BACKUP_CALLS = 4
#: The orientation chart is re-centred when a Rodrigues parameter exceeds this (~53 deg).
RECENTRE = 0.5
#: Rodrigues parameters of the chart stay below this (127 deg) inside one call.
CHART_LIMIT = 2.0
PREDICTORS = ("rk4", "cvodes")


@dataclass(frozen=True)
class Line:
    """A line in joint space, ``theta(s) = theta1 + s dtheta``.

    Attributes:
        theta1: (k,) actuated values at ``s = 0`` [rad or model length unit].
        dtheta: (k,) direction; ``theta(1) = theta1 + dtheta``.
    """

    theta1: np.ndarray
    dtheta: np.ndarray

    def at(self, s: float) -> np.ndarray:
        return self.theta1 + s * self.dtheta


@dataclass(frozen=True)
class Hit:
    """A crossing of a level of ``s`` (a solution at ``theta(level)``).

    Attributes:
        y: (m,) canonical unknowns of the verified solution.
        level: the level of ``s``.
        arc: arc length from the start at which it was met.
        crossings: number of singular points (folds and bifurcations) met before it.
        arriving: +1 if ``s`` was increasing through the level, -1 if decreasing.
    """

    y: np.ndarray
    level: float
    arc: float
    crossings: int
    arriving: float


@dataclass
class Walk:
    """What :func:`follow` met along one curve.

    Attributes:
        hits: level crossings, in order of arc length.
        singular: folds and bifurcations (``Crossing`` with ``s`` on the line), in order.
        singular_arcs: arc length of each.
        det0: ``det J_p`` at the start.
        arc: arc length followed (metric ``|dy|^2 + (|dtheta| ds)^2``).
        steps: accepted steps (samples).
        rejected: rejected steps or chunks.
        step_overs: bifurcations stepped over after a stall.
        closed: the curve came back to its start.
        reversed: ... but backwards (the walk jumped between nearly touching branches).
        repeated: a hit or a fold was met a second time (it went round a loop it jumped onto).
        timed_out: stopped by the deadline.
        stalled: stopped because the step could not be continued (nor stepped over).
        s_range: (min, max) of ``s`` met.
        path: the sampled curve when recorded.
        end: (q local, tangent, chart) of the last accepted point.
    """

    hits: list[Hit] = field(default_factory=list)
    singular: list[Crossing] = field(default_factory=list)
    singular_arcs: list[float] = field(default_factory=list)
    det0: float = 0.0
    arc: float = 0.0
    steps: int = 0
    rejected: int = 0
    step_overs: int = 0
    closed: bool = False
    reversed: bool = False
    repeated: bool = False
    timed_out: bool = False
    stalled: bool = False
    s_range: tuple[float, float] = (0.0, 0.0)
    path: PathSamples | None = field(default=None, repr=False)
    end: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False)


def null_direction(Jp: np.ndarray, js: np.ndarray) -> np.ndarray:
    """Unit vector along nu = [adj(J_p) j_s; det J_p] (generalised cross product of H's rows)."""
    H = np.hstack([Jp, -js[:, None]])
    _, _, Vt = np.linalg.svd(H)
    t = Vt[-1]
    if np.linalg.det(np.vstack([H, t])) < 0:
        t = -t
    return t


# ---------------------------------------------------------------------------- predictors


@dataclass
class _Chunk:
    Q: np.ndarray  # (m+1, n+1) samples, the first the current point
    T: np.ndarray  # (m+1, n+1) unit tangents
    D: np.ndarray  # (n+1,) det J_p
    ok: int  # accepted steps (leading)
    smooth: bool  # every accepted step well inside the tolerances: the step may grow
    partial: bool = False  # some steps of the call were rejected


class _RK4:
    """Explicit predictor-corrector steps (:class:`~scdk_sym.follower.kernels.FollowerKernels`)."""

    def __init__(self, model, kern, p, weight, scale, min_cos=MIN_COS):
        self.model, self.kern, self.p, self.scale = model, kern, p, scale
        self.min_cos = min_cos
        self.m = model.m
        self.rot_idx = [i for idx in model.chart.rotations for i in idx]

    def advance(self, q, t, h, c, det) -> _Chunk:
        m = self.m
        X, info, J = (np.array(a) for a in self.kern.steps(np.concatenate([q, t]), h, self.p, c))
        good = (
            np.all(np.isfinite(X), axis=0)
            & (info[0] <= MAX_PREDICTOR_ERROR * h)
            & (info[1] <= NEWTON_TOL * self.scale)
            & (info[2] >= self.min_cos)
        )
        if self.rot_idx:
            good &= np.max(np.abs(X[self.rot_idx]), axis=0) <= CHART_LIMIT
        n_ok = int(np.argmin(good)) if not good.all() else good.size
        Q = np.hstack([q[:, None], X[: m + 1, :n_ok]])
        T = np.hstack([t[:, None], X[m + 1 :, :n_ok]])
        D = np.concatenate([[det], _dets(J[:, :n_ok], m)])
        smooth = bool(
            n_ok == good.size
            and info[0].max() < SMOOTH_CORRECTION * h
            and info[2].min() > SMOOTH_COS
        )
        return _Chunk(Q, T, D, n_ok, smooth, n_ok < good.size)


class _Cvodes:
    """CVODES chunks of the stabilised SC field (:mod:`scdk_sym.follower.cvodes`)."""

    def __init__(self, model, eng, line, w):
        from .cvodes import GAIN

        self.model, self.eng, self.line, self.w, self.gain = model, eng, line, w, GAIN
        self.m = model.m
        self.rot_idx = [i for idx in model.chart.rotations for i in idx]

    def advance(self, q, t, h, c, det) -> _Chunk:
        from .cvodes import GRID

        m = self.m
        p = np.concatenate([self.line.theta1, self.line.dtheta, t, [GRID * h, self.gain]])
        try:
            X = self.eng.integrate(q, np.concatenate([p, c]))
        except RuntimeError:
            check()  # CasADi reports an interrupt as a RuntimeError: not a failed chunk
            X = np.full((m + 1, GRID), np.nan)
        Q = np.hstack([q[:, None], X])
        bad = _Chunk(Q[:, :1], t[:, None], np.array([det]), 0, False)
        if not np.all(np.isfinite(Q)):
            return bad
        if self.rot_idx and np.max(np.abs(Q[self.rot_idx])) > CHART_LIMIT:
            return bad
        T, Jv, _ = self.eng.probe_samples(Q, p, c)
        te = T[:, -1]
        cosine = float(te[:-1] @ t[:-1] + self.w**2 * te[-1] * t[-1])
        if not cosine >= CHUNK_COS:
            return bad
        D = np.concatenate([[det], _dets(Jv[:, 1:], m)])
        T[:, 0] = t
        return _Chunk(Q, T, D, GRID, cosine > 0.995)


def _dets(J: np.ndarray, m: int) -> np.ndarray:
    """det of column-major vec(J_p) columns (m*m, N) -> (N,)."""
    if J.shape[1] == 0:
        return np.zeros(0)
    return np.linalg.det(J.T.reshape(-1, m, m).transpose(0, 2, 1))


# ---------------------------------------------------------------------------- the walk


def _hermite(u: np.ndarray) -> np.ndarray:
    """Cubic Hermite basis (h00, h10, h01, h11) at the fractions ``u`` of a step."""
    u2, u3 = u * u, u * u * u
    return np.array([2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2])


_FINE = np.linspace(0.0, 1.0, FINE + 1)
_BASIS = _hermite(_FINE)


def _hidden_pair(sa: float, sb: float, ta: float, tb: float, h: float, level: float) -> bool:
    """Whether a turning point of s inside a step crosses the level twice between samples."""
    a, b = sa - level, sb - level
    if ta * tb >= 0 or a * b <= 0:
        return False
    s = np.array([a, h * ta, b, h * tb]) @ _BASIS
    return bool(np.any(s * a <= 0))


def follow(
    model: Model,
    line: Line,
    y_start: np.ndarray,
    s_start: float,
    direction: float,
    *,
    predictor: str = "rk4",
    backend: str = "cvodes",
    levels: tuple[float, ...] = (1.0,),
    max_hits: int | float = math.inf,
    max_singular: int | float = math.inf,
    max_arc: float | None = None,
    max_steps: int = 20000,
    deadline: float = math.inf,
    step: float | None = None,
    record: bool = False,
    stop_when_closed: bool = True,
    tangent: np.ndarray | None = None,
    chart: np.ndarray | None = None,
    locate: bool = True,
    min_cos: float = MIN_COS,
) -> Walk:
    """Follow the solution curve of ``g(y, line.at(s)) = 0`` from ``(y_start, s_start)``.

    The walk is a loop of predictor calls: each call's accepted samples are judged segment
    by segment (folds, bifurcations, level crossings), taken up to the first segment that
    needs a smaller step, and the step adapted; where the step keeps shrinking the follower
    steps over the point (see the module documentation).

    Args:
        model: the model.
        line: the line in joint space.
        y_start: (m,) canonical unknowns of an assembled point of the curve (or local ones
            with ``chart``).
        s_start: its path parameter.
        direction: +1 to follow ``nu = [adj(J_p) j_s; det J_p]`` (``s' = det J_p``), -1 for
            ``-nu``; ignored when ``tangent`` is given.
        predictor: "rk4" (explicit predictor-corrector) or "cvodes" (the SC ODE by CVODES).
        backend: kernels, "cvodes" (SX) or "compiled" (generated C); see
            :mod:`scdk_sym.backends`.
        levels: levels of ``s`` whose crossings are reported (and finished at
            ``line.at(level)``).
        max_hits: stop after this many level crossings.
        max_singular: stop after this many singular points (folds and bifurcations).
        max_arc: arc-length budget (default: 60 arc lengths per unit of ``s`` at the start
            plus 20 model sizes).
        max_steps: stop after this many accepted steps.
        deadline: ``time.perf_counter()`` value at which to stop.
        step: initial arc length per step (default: a sixteenth of the arc per unit ``s``, at
            most ``FIRST_STEP`` model sizes).
        record: keep the sampled curve in ``walk.path``.
        stop_when_closed: stop when the curve comes back to its start.
        tangent: (m+1,) initial tangent orientation (instead of ``direction``).
        chart: chart of ``y_start`` when it is given in local coordinates.
        locate: locate folds by Newton (else: interpolated between the samples, their ``x``
            not computed, for searches that only count them).
        min_cos: an explicit step is accepted only if the tangent turned by less than
            ``acos(min_cos)`` (small turns keep two nearby crossing branches apart; a search
            that only collects solutions may take larger ones).

    Returns:
        A :class:`Walk`.

    Raises:
        InputError: unknown predictor or backend.
    """
    if predictor not in PREDICTORS:
        raise InputError(f"unknown predictor {predictor!r}; predictors: {', '.join(PREDICTORS)}")
    rules = _Rules(levels, max_hits, max_singular, max_steps, deadline, record,
                   stop_when_closed, locate)  # fmt: skip
    walker = _Walker(model, line, rules, follower_calls(model, backend))
    walker.start(y_start, s_start, direction, tangent, chart)
    walker.choose_steps(predictor, backend, max_arc, step, min_cos)
    return walker.run(direction)


@dataclass(frozen=True)
class _Rules:
    """What a walk reports and when it stops (the options of :func:`follow`)."""

    levels: tuple[float, ...]
    max_hits: int | float
    max_singular: int | float
    max_steps: int
    deadline: float
    record: bool
    stop_when_closed: bool
    locate: bool


#: What a step of the walk tells its loop.
_GO, _STOP = False, True


class _Walker:
    """The state of one walk of :func:`follow` and its steps (each a method of <= 60 lines).

    State: the current point ``q = (y local, s)`` in chart ``c``, its unit tangent ``t`` and
    ``det J_p``; the step ``h`` with its bounds and the count of halvings in a row; the last
    accepted points ``hist`` (for extrapolation); what was met (``out``, a :class:`Walk`).
    """

    def __init__(self, model: Model, line: Line, rules: _Rules, kern) -> None:
        self.model, self.line, self.o, self.kern = model, line, rules, kern
        self.m = model.m
        self.scale = max(1.0, float(model.length_scale))
        self.tol = float(model.tolerance)
        self.dtheta = np.asarray(line.dtheta, float)
        self.p = np.concatenate([np.asarray(line.theta1, float), self.dtheta])
        w2 = float(self.dtheta @ self.dtheta)
        self.w = math.sqrt(w2)
        self.weight = np.append(np.ones(self.m), w2)
        self.rots = model.chart.rotations
        self.rot_idx = [i for idx in self.rots for i in idx]
        self.per = periodic(model)

    # ------------------------------------------------------------------------------ set-up

    def start(self, y_start, s_start: float, direction: float, tangent, chart) -> None:
        """The start point in its chart, its oriented unit tangent and ``det J_p``."""
        model, m = self.model, self.m
        if chart is None:
            y_loc, c = model.chart.to_local(y_start)
        else:
            y_loc, c = np.array(y_start, dtype=float), np.array(chart, dtype=float)
        q = np.append(y_loc, float(s_start))
        if tangent is None:
            Jp, Js = (np.array(a) for a in model_calls(model).jac(y_loc, self.line.at(s_start), c))
            v0 = direction * null_direction(Jp, Js @ self.dtheta)
        else:
            v0 = np.asarray(tangent, float)
        t_raw, J0 = self.kern.tangent(q, v0, self.p, c)
        self.q, self.c, self.t = q, c, np.array(t_raw).ravel()
        self.det = float(_dets(np.array(J0), m)[0])
        self.out = Walk(det0=self.det)
        self.q_first, self.c_first, self.t_first = q.copy(), c.copy(), self.t.copy()
        self.left = False  # the walk has left its start (for the closure test)
        self.s_lo = self.s_hi = float(q[-1])
        self.f_hits = np.zeros((0, 0))
        self.f_folds: list[tuple[np.ndarray, float]] = []
        self.rec: dict[str, list] = {"q": [], "c": [], "det": [], "arc": []}
        if self.o.record:
            _record(self.rec, q, c, self.det, 0.0)
        self.skip_level_at_start = True
        self.hist = [q.copy()]  # the last accepted points (same chart), for extrapolation

    def choose_steps(self, predictor: str, backend: str, max_arc, step, min_cos: float) -> None:
        """The predictors, the arc budget and the step bounds, from the start's arc per ``s``."""
        scale, w = self.scale, self.w
        ell0 = min(1.0 / max(abs(self.t[-1]) * w, 1e-6) * w, 1e3 * scale) if w > 0 else scale
        ell0 = max(ell0, 1e-9 * scale)
        self.budget = 60.0 * ell0 + 20.0 * scale if max_arc is None else float(max_arc)
        rk4 = _RK4(self.model, self.kern, self.p, self.weight, scale, min_cos)
        self.pred: _RK4 | _Cvodes
        self.backup: _RK4 | None
        if predictor == "rk4":
            self.pred, self.backup = rk4, None
            self.h_max = 0.5 * scale
        else:
            from .cvodes import GRID, engine

            self.pred = _Cvodes(self.model, engine(self.model, backend), self.line, w)
            self.backup = rk4
            self.h_max = 2.0 * ell0 / GRID
        self.h = min(ell0 / 16, FIRST_STEP * scale) if step is None else float(step)
        self.h_min = 1e-12 * max(ell0, 1e-6 * scale)
        self.h_first = self.h_good = self.h
        self.halvings = 0
        self.reject_limit = MAX_REJECTED
        self.backup_left = 0

    # ------------------------------------------------------------------------------ the loop

    def run(self, direction: float) -> Walk:
        """Predict, judge and take steps until a stop rule holds; the walk's report."""
        out, o = self.out, self.o
        turns = 0  # loop iterations: every one either advances, shrinks h or stops
        while out.arc < self.budget and out.steps < o.max_steps:
            turns += 1
            if turns > LOOP_FACTOR * o.max_steps:
                out.stalled = True
                break
            if self.halvings >= STALL_HALVINGS or self.h < self.h_min:
                if self.backup is not None:
                    self._explicit_from_here()
                    continue
                if self._step_over_stall() is _STOP:
                    break
                continue
            if out.rejected > self.reject_limit:
                out.stalled = True
                break
            if time.perf_counter() > o.deadline:
                out.timed_out = True
                break
            ch = self._advance()
            if ch.ok == 0:
                out.rejected += 1
                self.halvings += 1
                self.h /= 2
                continue
            if self._take(ch) is _STOP:
                break
        out.s_range = (self.s_lo, self.s_hi)
        out.end = (self.q, self.t, self.c)
        if o.record and self.rec["q"]:
            out.path = _samples(self.model, self.line, self.rec, direction)
        return out

    def _explicit_from_here(self) -> None:
        """CVODES creeps (its error control, not the curve, may be at fault): explicit steps
        from here; only their stall is a point to step over."""
        assert self.backup is not None
        self.pred, self.backup = self.backup, None
        self.h, self.halvings = max(self.h_good, self.h_first), 0
        self.reject_limit = max(self.reject_limit, self.out.rejected + CVODES_REJECTIONS)

    def _advance(self) -> _Chunk:
        """One predictor call from the current point (the explicit one where CVODES fails)."""
        q, t, h, c, det = self.q, self.t, self.h, self.c, self.det
        if self.backup is not None and self.out.rejected >= CVODES_REJECTIONS:
            self.pred, self.backup = self.backup, None  # CVODES keeps failing here: explicit
            self.h, self.halvings = max(h, self.h_first), 0  # steps from now on
            self.reject_limit = self.out.rejected + CVODES_REJECTIONS
            h = self.h
        if self.backup is not None and self.backup_left > 0:
            self.backup_left -= 1
            return self.backup.advance(q, t, h, c, det)
        ch = self.pred.advance(q, t, h, c, det)
        if ch.ok == 0 and self.backup is not None:
            # CVODES could not integrate this stretch (e.g. next to two crossing branches,
            # where no smooth field exists): the explicit predictor-corrector takes over for
            # the next few calls
            ch = self.backup.advance(q, t, h, c, det)
            self.backup_left = BACKUP_CALLS if ch.ok else 0
        return ch

    def _take(self, ch: _Chunk) -> bool:
        """Judge a chunk's samples, take them up to the first event that needs a smaller
        step (or a step over a bifurcation), adapt the step; ``_STOP`` when a rule says so."""
        refine_at, replaced, last = self._judge(ch)
        used = last if refine_at is None else refine_at
        if replaced is not None:
            used = replaced[0]
        if self.o.stop_when_closed and used > 0:
            self._check_closed(ch, used)
        if used > 0:
            self._accept(ch, used)
        if replaced is not None:
            self._jump_to(replaced)
        self.t = self.t / math.sqrt(float(self.weight @ (self.t * self.t)))
        out = self.out
        if out.closed or out.repeated or len(out.hits) >= self.o.max_hits:
            return _STOP
        if len(out.singular) >= self.o.max_singular:
            return _STOP
        self._recentre()
        self._adapt_step(ch, refine_at, replaced, used, last)
        return _GO

    def _adapt_step(self, ch: _Chunk, refine_at, replaced, used: int, last: int) -> None:
        """A quarter step to resolve an event, half after a partial call, else grow."""
        if refine_at is not None:
            self.h /= 4
            self.out.rejected += 1
            if self.backup is not None:
                self.backup_left = BACKUP_CALLS  # resolve the event with the explicit steps
        elif ch.partial and replaced is None:
            self.h /= 2
            self.out.rejected += 1
            self.halvings += 1
        else:
            self.halvings = 0
            self.h_good = self.h
            if ch.smooth:
                self.h = min(GROW * self.h, self.h_max)
        if replaced is not None or (used == last and not ch.partial):
            self.halvings = 0

    # ------------------------------------------------------------------------ judging a chunk

    def _judge(self, ch: _Chunk) -> tuple[int | None, tuple | None, int]:
        """Walk the accepted segments in order; stop at the first that needs a smaller step
        (``refine_at``) or is replaced by a step over a bifurcation (``replaced``); ``last``:
        the samples to take when neither (fewer when the hits are complete).

        Only segments where ``s`` turns, ``det J_p`` changes sign or a level is crossed can
        act: a rule acting on other segments must add its condition to :func:`_eventful`.
        """
        full = len(self.out.hits) >= self.o.max_hits
        for j in _eventful(ch.Q, ch.T, ch.D, ch.ok, self.o.levels, full):
            verdict, replaced = self._segment(ch, j)
            if verdict == "refine":
                return j, None, ch.ok
            if verdict == "replace":
                return None, replaced, ch.ok
            if verdict == "full":
                return None, None, j + 1
        return None, None, ch.ok

    def _segment(self, ch: _Chunk, j: int) -> tuple[str, tuple | None]:
        """The events of segment ``j``: "go", "refine", "replace" (with the replacement
        ``(j, q, t, det)``) or "full" (the hits are complete)."""
        Q, T, D, h = ch.Q, ch.T, ch.D, self.h
        can_refine = h / 4 >= self.h_min
        before_segment = len(self.out.singular)
        turn = T[-1, j] * T[-1, j + 1] < 0
        flip = D[j] * D[j + 1] < 0
        at_start = self.skip_level_at_start and j == 0
        crossing_levels = _levels_passed(self.o.levels, float(Q[-1, j]), float(Q[-1, j + 1]),
                                         at_start)  # fmt: skip
        hidden = any(
            _hidden_pair(Q[-1, j], Q[-1, j + 1], T[-1, j], T[-1, j + 1], h, L)
            for L in self.o.levels
        )
        # leaving a level and turning back through it within one step
        hidden |= bool(turn and at_start and Q[-1, 0] in self.o.levels)
        if turn and not flip and can_refine:
            # s turned while det J_p kept its sign: not a fold (there both change sign
            # together) but a step that jumped onto a nearby branch (e.g. across the gap
            # where the line grazes the singular surface); smaller steps stay on the curve
            return "refine", None
        if (hidden or (crossing_levels and turn)) and can_refine:
            return "refine", None
        if flip and not turn:
            verdict, replaced = self._flip_without_turn(ch, j)
            if verdict != "go":
                return verdict, replaced
        if turn:
            verdict, replaced = self._turn(ch, j)
            if verdict != "go":
                return verdict, replaced
        return self._levels_crossed(ch, j, crossing_levels, before_segment), None

    def _flip_without_turn(self, ch: _Chunk, j: int) -> tuple[str, tuple | None]:
        """``det J_p`` changed sign without a turn of ``s``: two branches crossing (``H'``
        drops rank at the point) or a step that jumped across a fold (then ``H'`` keeps its
        rank, and smaller steps show the turn); first at fixed ``s`` on the incoming branch
        (which also locates the point on it), else straight."""
        Q, T, D, h, c = ch.Q, ch.T, ch.D, self.h, self.c
        model, kern, line, p, weight = self.model, self.kern, self.line, self.p, self.weight
        past = [*self.hist, *(Q[:, i] for i in range(1, j + 1))][-3:]
        got = _step_over_in_s(model, kern, line, p, weight, past, T[:, j], c, D[j],
                              self.o.levels, self.tol)  # fmt: skip
        if got is not None and _is_bifurcation(model, got[4], self.dtheta):
            self._add_singular(got[4], self.out.arc + h * (j + 0.5))
            return "replace", (j, got[0], got[1], got[2])
        seg = Q[:, j + 1] - Q[:, j]
        length = float(math.sqrt(weight @ (seg * seg)))
        replaced = None
        q_str = _straight(kern, p, Q[:, j], T[:, j], length, c, self.tol)
        if q_str is not None and _wdist(weight, q_str, Q[:, j + 1]) > 0.05 * length:
            t_str, det_str = _tangent(kern, q_str, T[:, j], p, c, self.m)
            replaced = (j, q_str, t_str, det_str)
        q_b = replaced[1] if replaced is not None else Q[:, j + 1]
        cr = _locate_bifurcation(model, kern, line, p, weight, Q[:, j], q_b, c, D[j])
        if not _is_bifurcation(model, cr, self.dtheta) and h / 4 >= self.h_min:
            return "refine", None
        self._add_singular(cr, self.out.arc + h * (j + 0.5))
        return ("replace", replaced) if replaced is not None else ("go", None)

    def _turn(self, ch: _Chunk, j: int) -> tuple[str, tuple | None]:
        """``s`` turned on segment ``j``: a fold, located (or interpolated) and recorded; or,
        where two branches cross there, a step straight over the point."""
        Q, T, D, h, c = ch.Q, ch.T, ch.D, self.h, self.c
        model, kern, line, p, weight = self.model, self.kern, self.line, self.p, self.weight
        locate, can_refine = self.o.locate, h / 4 >= self.h_min
        if locate:
            cr = _locate_fold(model, kern, line, p, Q[:, j], Q[:, j + 1], T[:, j], T[:, j + 1],
                              c)  # fmt: skip
        else:
            cr = _interpolated_fold(model, line, Q[:, j], Q[:, j + 1], T[:, j], T[:, j + 1], c)
        if locate and _is_bifurcation(model, cr, self.dtheta):
            # not a fold: two branches cross there and the predictor swung onto the other
            # one; step straight over the point from the sample before it
            seg = Q[:, j + 1] - Q[:, j]
            length = float(math.sqrt(weight @ (seg * seg)))
            stepped = _step_over(model, kern, p, weight, Q[:, j], T[:, j], c, D[j], length,
                                 self.tol)  # fmt: skip
            if stepped is not None:
                q_new, t_new, det_new, _len = stepped
                if det_new * D[j] < 0:
                    cr = _locate_bifurcation(model, kern, line, p, weight, Q[:, j], q_new, c,
                                             D[j])  # fmt: skip
                    self._add_singular(cr, self.out.arc + h * (j + 0.5))
                return "replace", (j, q_new, t_new, det_new)
            if can_refine:
                return "refine", None
        if locate and can_refine and _turns_beyond(self.o.levels, Q[-1, j], Q[-1, j + 1], cr.s):
            # the located fold lies past a level both samples are short of: the step hid two
            # crossings of it (too close to the fold for the interpolation to show); smaller
            # steps put a sample between them
            return "refine", None
        f = np.append(features(model, cr.y)[0], cr.s * self.w)
        arc = self.out.arc + h * j
        for f_old, a_old in self.f_folds:
            if np.max(np.abs(f_old - f)) < 2 * h + 1e-6 * self.scale and arc - a_old > 4 * h:
                self.out.repeated = True
        self.f_folds.append((f, arc))
        self._add_singular(cr, self.out.arc + h * (j + 0.5))
        return "go", None

    def _levels_crossed(self, ch: _Chunk, j: int, crossing_levels, before: int) -> str:
        """Finish each level crossed on segment ``j`` (a hit), or ask for a smaller step."""
        Q, T, h = ch.Q, ch.T, self.h
        for L in crossing_levels:
            y_hit = _finish(self.model, self.kern, self.line, Q[:, j], Q[:, j + 1], T[:, j],
                            T[:, j + 1], h, L, self.c, self.tol)  # fmt: skip
            if y_hit is None:
                if h / 4 >= self.h_min:
                    return "refine"
                continue
            self._add_hit(y_hit, L, self.out.arc + h * (j + 0.5), before, Q[-1, j], Q[-1, j + 1])
            if len(self.out.hits) >= self.o.max_hits:
                break
        return "full" if len(self.out.hits) >= self.o.max_hits else "go"

    def _add_singular(self, cr: Crossing, arc: float) -> None:
        self.out.singular.append(cr)
        self.out.singular_arcs.append(arc)

    def _add_hit(self, y_hit, level, arc: float, before: int, s_a, s_b) -> None:
        """Record the solution ``y_hit`` (chart ``c``) at ``s = level``, met at arc length
        ``arc`` on a stretch from ``s_a`` to ``s_b`` whose singular points start at index
        ``before`` (a solution met before marks the walk repeated instead)."""
        f_hit = local_features(self.model, y_hit, self.c)[None]
        f_hits = self.f_hits
        if f_hits.size and np.min(np.max(np.abs(f_hits - f_hit), axis=1)) <= 1e-6 * self.scale:
            self.out.repeated = True
            return
        self.f_hits = np.vstack([f_hits, f_hit]) if f_hits.size else f_hit
        crossings = _met_before(self.out.singular, before, float(s_a), float(level))
        arriving = 1.0 if s_b > s_a else -1.0
        y = self.model.chart.to_canonical(y_hit, self.c)
        self.out.hits.append(Hit(y, float(level), arc, crossings, arriving))

    # -------------------------------------------------------------------- taking the samples

    def _check_closed(self, ch: _Chunk, used: int) -> None:
        """Whether the accepted path came back to the start point (in the current chart)."""
        q_ref = in_chart(self.q_first, self.c_first, self.c, self.rots)
        if q_ref is None:
            return
        weight, h = self.weight, self.h
        Qu = ch.Q[:, : used + 1]
        Dq = Qu - q_ref[:, None]
        if self.per.size:
            Dq[self.per] = (Dq[self.per] + math.pi) % (2 * math.pi) - math.pi
        E = np.diff(Qu, axis=1)
        tau = np.clip(-(weight @ (Dq[:, :-1] * E)) / np.maximum(weight @ (E * E), 1e-300), 0, 1)
        P = Dq[:, :-1] + tau * E
        dist = np.sqrt(weight @ (P * P))
        if not self.left:
            self.left = bool(np.any(dist > 3 * h))
        elif np.any(dist < 0.1 * h):
            jj = int(np.argmin(dist))
            self.out.closed = True
            self.out.reversed = bool(weight @ (ch.T[:, jj + 1] * self.t_first) < 0)

    def _accept(self, ch: _Chunk, used: int) -> None:
        """Take the chunk's first ``used`` samples."""
        Q, out, h = ch.Q, self.out, self.h
        self.skip_level_at_start = False
        self.s_lo = min(self.s_lo, float(Q[-1, : used + 1].min()))
        self.s_hi = max(self.s_hi, float(Q[-1, : used + 1].max()))
        if self.o.record:
            for j in range(1, used + 1):
                _record(self.rec, Q[:, j], self.c, float(ch.D[j]), out.arc + h * j)
        out.steps += used
        out.arc += h * used
        self.hist = [*self.hist, *(Q[:, i].copy() for i in range(1, used + 1))][-3:]
        self.q, self.t, self.det = Q[:, used].copy(), ch.T[:, used].copy(), float(ch.D[used])

    def _jump_to(self, replaced: tuple) -> None:
        """Take the point that replaces a segment's end (a step over a bifurcation)."""
        _j, q_new, t_new, det_new = replaced
        length = float(math.sqrt(self.weight @ ((q_new - self.q) ** 2)))
        self._moved_to(q_new, t_new, det_new, length)

    def _moved_to(self, q_new, t_new, det_new: float, length: float) -> None:
        self.q, self.t, self.det = q_new, t_new, det_new
        self.hist = [*self.hist[-2:], self.q.copy()]
        self.out.arc += length
        self.out.steps += 1
        self.skip_level_at_start = False
        if self.o.record:
            _record(self.rec, self.q, self.c, self.det, self.out.arc)

    def _recentre(self) -> None:
        """A new orientation chart when a rotation's Rodrigues parameters grew large."""
        if self.rots and np.max(np.abs(self.q[self.rot_idx])) > RECENTRE:
            y_new, self.c = self.model.chart.recentre(self.q[:-1], self.c)
            self.q = np.append(y_new, self.q[-1])
            self.hist = [self.q.copy()]
            self.t = np.array(self.kern.tangent(self.q, self.t, self.p, self.c)[0]).ravel()

    # -------------------------------------------------------------------------- stepping over

    def _step_over_stall(self) -> bool:
        """The step keeps shrinking (next to crossing branches no tangent field is smooth and
        the predictors creep towards the point): step over it, finishing every level the step
        passes (a solution it skipped would be lost, or a later one taken for the first)."""
        stepped, cr = self._try_step_over()
        out, q = self.out, self.q
        finished: list[tuple[float, np.ndarray | None]] = []
        if stepped is not None:
            q_new, t_new, det_new, length = stepped[:4]
            passed = _levels_passed(self.o.levels, float(q[-1]), float(q_new[-1]),
                                    self.skip_level_at_start)  # fmt: skip
            finished = [
                (L, _finish(self.model, self.kern, self.line, q, q_new, self.t, t_new, length,
                            L, self.c, self.tol))
                for L in passed
            ]  # fmt: skip
        if stepped is None or any(y_hit is None for _L, y_hit in finished):
            # nothing to step over (a tight turn of a smooth curve, e.g. next to a point
            # where two branches nearly cross, or a tight fold), or a step-over passing a
            # level with no solution on its chord (it jumped between such branches): smaller
            # steps follow the curve; halve on, down to h_min, else stalled
            if self.h / 2 >= self.h_min:
                self.halvings = 0
                self.h /= 2
                return _GO
            out.stalled = True
            return _STOP
        out.step_overs += 1
        before = len(out.singular)
        if cr is not None:
            self._add_singular(cr, out.arc + 0.5 * length)
        for L, y_hit in finished:
            if len(out.hits) < self.o.max_hits:
                self._add_hit(y_hit, L, out.arc + 0.5 * length, before, q[-1], q_new[-1])
        self._moved_to(q_new, t_new, det_new, length)
        self.h, self.halvings = self.h_good, 0
        self.reject_limit = max(self.reject_limit, out.rejected + CVODES_REJECTIONS)
        if out.repeated or len(out.hits) >= self.o.max_hits:
            return _STOP
        return _STOP if len(out.singular) >= self.o.max_singular else _GO

    def _try_step_over(self) -> tuple[tuple | None, Crossing | None]:
        """A step over the point ahead: at fixed ``s`` first, else straight (only short
        straight steps may pass a level of ``s``)."""
        model, kern, line, p, weight = self.model, self.kern, self.line, self.p, self.weight
        stepped = _step_over_in_s(model, kern, line, p, weight, self.hist, self.t, self.c,
                                  self.det, self.o.levels, self.tol)  # fmt: skip
        if stepped is not None:
            return stepped, stepped[4]
        args = (model, kern, line, p, weight, self.q, self.t, self.c, self.det, self.h_good,
                self.tol)  # fmt: skip
        stepped, cr = _step_over_located(*args, STEP_OVER_FACTORS)
        if (
            stepped is not None
            and stepped[3] > SHORT_OVER * self.h_good
            and _levels_passed(self.o.levels, float(self.q[-1]), float(stepped[0][-1]), False)
        ):
            # a long step-over past a level cannot be finished there reliably
            short = tuple(f for f in STEP_OVER_FACTORS if f <= SHORT_OVER)
            stepped, cr = _step_over_located(*args, short)
        return stepped, cr


def _turns_beyond(levels, s_a: float, s_b: float, s_turn: float) -> bool:
    """Whether ``s`` turning at ``s_turn`` between samples at ``s_a`` and ``s_b`` passes a level
    that neither sample reaches (it crosses it twice inside the step)."""
    return any((s_a - L) * (s_turn - L) < 0 and (s_b - L) * (s_turn - L) < 0 for L in levels)


def _levels_passed(levels, s_a: float, s_b: float, leaving: bool) -> list[float]:
    """The levels of ``s`` a step from ``s_a`` to ``s_b`` passes or reaches (none for a step
    that keeps ``s``); with ``leaving``, not the one ``s_a`` sits on (the walk's start)."""
    return [
        L
        for L in levels
        if (s_a - L) * (s_b - L) <= 0 and s_a != s_b and not (leaving and s_a == L)
    ]


def _eventful(Q, T, D, n: int, levels, stop: bool) -> range | list[int]:
    """The segments ``j`` (of samples ``j`` and ``j + 1``, ``j < n``) of a chunk on which
    something may happen: ``s`` turns (``t_s`` changes sign), ``det J_p`` changes sign, or
    ``s`` meets a level; every segment when ``stop`` (the walk has its hits already). The
    same products and comparisons as the walk makes per segment, for all segments at once."""
    if stop or n == 0:
        return range(n)
    s, ts, det = Q[-1, : n + 1], T[-1, : n + 1], D[: n + 1]
    event = (ts[:-1] * ts[1:] < 0) | (det[:-1] * det[1:] < 0)
    for L in levels:
        event |= (s[:-1] - L) * (s[1:] - L) <= 0
    return np.flatnonzero(event).tolist()


def _record(rec, q, c, det, arc) -> None:
    rec["q"].append(np.array(q, dtype=float))
    rec["c"].append(np.array(c, dtype=float))
    rec["det"].append(float(det))
    rec["arc"].append(float(arc))


def _samples(model, line: Line, rec: dict, direction: float) -> PathSamples:
    Q = np.array(rec["q"])
    Y = np.array([model.chart.to_canonical(r[:-1], cc) for r, cc in zip(Q, rec["c"], strict=True)])
    X = []
    for r, cc in zip(Q, rec["c"], strict=True):
        X.append(np.array(model_calls(model).pose(r[:-1], line.at(r[-1]), cc)[1]).ravel())
    det = np.array(rec["det"])
    return PathSamples(
        s=Q[:, -1], y=Y, x=np.array(X), det_jp=det, sdot=direction * det, arc=np.array(rec["arc"])
    )


def _wdist(weight, a, b) -> float:
    d = a - b
    return float(math.sqrt(weight @ (d * d)))


def _tangent(kern, q, v, p, c, m) -> tuple[np.ndarray, float]:
    t, J = kern.tangent(q, v, p, c)
    return np.array(t).ravel(), float(_dets(np.array(J), m)[0])


def _straight(kern, p, q, t, length, c, tol) -> np.ndarray | None:
    """The curve point on the plane normal to ``t`` at ``length`` along it (None if Newton
    did not converge there or moved off by more than half the length)."""
    q_pred = q + length * t
    q_new, res = kern.plane(q_pred, t, p, c)
    q_new = np.array(q_new).ravel()
    if not (np.all(np.isfinite(q_new)) and float(res) <= 0.1 * tol):
        return None
    if float(np.max(np.abs(q_new - q_pred))) > 0.5 * length:
        return None
    return q_new


def _step_over(model, kern, p, weight, q, t, c, det, h_good, tol, factors=None):
    """Step over a point the predictors cannot pass (a bifurcation): straight along ``t`` with
    a corrector on the plane normal to it, at ``factors`` (default
    :data:`STEP_OVER_FACTORS`) times ``h_good`` in turn; the new point must continue the
    incoming tangent. Returns (q, t, det, length) or None."""
    m = model.m
    for f in STEP_OVER_FACTORS if factors is None else factors:
        length = f * h_good
        q_new = _straight(kern, p, q, t, length, c, tol)
        if q_new is None:
            continue
        t_new, det_new = _tangent(kern, q_new, t, p, c, m)
        if not np.all(np.isfinite(t_new)):
            continue
        if float(weight @ (t_new * t)) >= STEP_OVER_COS:
            return q_new, t_new, det_new, _wdist(weight, q_new, q)
    return None


def _step_over_located(model, kern, line, p, weight, q, t, c, det, h_good, tol, factors):
    """:func:`_step_over` at ``factors`` times ``h_good``, with the crossing located where
    ``det J_p`` changed sign: ``((q, t, det, length), crossing or None)``, or ``(None, None)``
    if no step-over continues the tangent or the sign change is not on its chord."""
    got = _step_over(model, kern, p, weight, q, t, c, det, h_good, tol, factors)
    if got is None or got[2] * det > 0:
        return got, None
    at = _locate_bifurcation(model, kern, line, p, weight, q, got[0], c, det)
    lo, hi = sorted((float(q[-1]), float(got[0][-1])))
    if not lo - 1e-9 <= at.s <= hi + 1e-9:
        return None, None  # det J_p changed sign off the chord: no crossing located
    return got, at


#: Steps in s of the step-over at fixed s (:func:`_step_over_in_s`): the first is this
#: fraction of the last step's, each next one twice the previous.
S_STEP_FIRST = 0.5
S_STEP_TRIES = 24


def _step_over_in_s(model, kern, line, p, weight, hist, t, c, det, levels, tol):
    """Step over a point where two branches cross at fixed ``s``: past it, the solution of
    ``g(y, theta(s)) = 0`` nearest to the extrapolation of the incoming branch.

    At a bifurcation ``s`` keeps increasing (or decreasing) along the incoming branch, so ``s``
    parametrises it; the quadratic in ``s`` through its last three accepted points continues
    it to second order, while the other branch leaves along another direction: Newton at
    fixed ``theta`` from the extrapolation stays on the incoming branch (the way a
    continuation in the actuated joints with a secant predictor moves the robot), even where
    the two branches have nearly the same tangent (there the tangent itself is ill-conditioned
    and is not used). Steps in ``s`` grow from half the last one until ``det J_p`` has changed
    sign (one crossing passed), without passing a level of ``levels``.

    Args:
        hist: the last accepted points ``q = (y, s)`` of the walk, the current one last.

    Returns:
        (q, t, det, length, crossing) or None (fewer than three points, ``s`` not monotone
        over them, Newton strayed, or no sign change within ``S_STEP_TRIES`` steps).
    """
    m = model.m
    if len(hist) < 3:
        return None
    P = np.array(hist[-3:])
    q = P[-1]
    S = P[:, -1] - q[-1]
    ds0 = float(S[2] - S[1])
    if not ((S[1] - S[0]) * ds0 > 0 and ds0 * float(t[-1]) > 0):
        return None

    # Lagrange quadratic through the three points, in s relative to the current one
    def extrapolate(ds):
        w = [
            (ds - S[1]) * (ds - S[2]) / ((S[0] - S[1]) * (S[0] - S[2])),
            (ds - S[0]) * (ds - S[2]) / ((S[1] - S[0]) * (S[1] - S[2])),
            (ds - S[0]) * (ds - S[1]) / ((S[2] - S[0]) * (S[2] - S[1])),
        ]
        return w[0] * P[0, :m] + w[1] * P[1, :m] + w[2] * P[2, :m]

    def solve_at(ds):
        y_pred = extrapolate(ds)
        y, res = kern.polish(y_pred, line.at(float(q[-1] + ds)), c)
        y = np.array(y).ravel()
        if not (np.all(np.isfinite(y)) and float(res) <= 0.1 * tol):
            return None
        move = float(np.linalg.norm(y - y_pred))
        if move > 0.5 * float(np.linalg.norm(y_pred - q[:m])) + 10 * tol:
            return None  # Newton went elsewhere (e.g. s turns ahead: no solution near)
        q_new = np.append(y, q[-1] + ds)
        t_new, det_new = _tangent(kern, q_new, t, p, c, m)
        return q_new, t_new, det_new

    ds = S_STEP_FIRST * ds0
    for _ in range(S_STEP_TRIES):
        s_new = float(q[-1] + ds)
        if any((L - q[-1]) * (L - s_new) < 0 for L in levels):
            return None
        got = solve_at(ds)
        if got is None:
            return None
        q_new, t_new, det_new = got
        if det_new * det < 0:
            if not (np.all(np.isfinite(t_new)) and t_new[-1] * ds0 > 0):
                return None
            # the crossing: bisection of det J_p in s on the same extrapolated branch
            lo, hi, y_mid = 0.0, ds, q_new[:m]
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                got_mid = solve_at(mid)
                if got_mid is None:
                    break
                y_mid = got_mid[0][:m]
                if got_mid[2] * det > 0:
                    lo = mid
                else:
                    hi = mid
                if abs(hi - lo) <= 1e-12 * max(1.0, abs(float(q[-1]))):
                    break
            s_cr = float(q[-1] + 0.5 * (lo + hi))
            cfg = model.configuration(y_mid, line.at(s_cr), c)
            cr = Crossing(s_cr, cfg.x, cfg.y, cfg.theta, kind="bifurcation")
            return q_new, t_new, det_new, _wdist(weight, q_new, q), cr
        ds *= 2.0
    return None


def _locate_bifurcation(model, kern, line, p, weight, qa, qb, c, det_a) -> Crossing:
    """Where ``det J_p`` vanishes between two points of one branch: bisection on points of the
    curve (the chord's points corrected on planes normal to it)."""
    m = model.m
    d = qb - qa
    d = d / math.sqrt(float(weight @ (d * d)) + 1e-300)
    lo, hi = 0.0, 1.0
    best = 0.5 * (qa + qb)
    for _ in range(24):
        mid = 0.5 * (lo + hi)
        q_mid, _res = kern.plane(qa + mid * (qb - qa), d, p, c)
        q_mid = np.array(q_mid).ravel()
        if not np.all(np.isfinite(q_mid)):
            break
        best = q_mid
        _t, det_mid = _tangent(kern, q_mid, d, p, c, m)
        if det_mid * det_a > 0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-7:
            break
    theta = line.at(float(best[-1]))
    cfg = model.configuration(best[:m], theta, c)
    return Crossing(float(best[-1]), cfg.x, cfg.y, cfg.theta, kind="bifurcation")


def _locate_fold(model, kern, line, p, qa, qb, ta, tb, c) -> Crossing:
    """The turning point of ``s`` between two samples (Newton on ``[g; t_s] = 0`` from the
    point where the interpolated ``t_s`` vanishes; that point itself if Newton strays)."""
    m = model.m
    alpha = ta[-1] / (ta[-1] - tb[-1])
    q0 = qa + alpha * (qb - qa)
    q1 = np.array(kern.fold(q0, ta, p, c)).ravel()
    seg = float(np.linalg.norm(qb - qa))
    if not np.all(np.isfinite(q1)) or float(np.linalg.norm(q1 - q0)) > 2 * seg + 1e-12:
        q1 = q0
    cfg = model.configuration(q1[:m], line.at(float(q1[-1])), c)
    return Crossing(float(q1[-1]), cfg.x, cfg.y, cfg.theta, kind="fold")


def _interpolated_fold(model, line, qa, qb, ta, tb, c) -> Crossing:
    """The turning point of ``s`` interpolated between two samples (``x`` left empty)."""
    m = model.m
    alpha = ta[-1] / (ta[-1] - tb[-1])
    q = qa + alpha * (qb - qa)
    theta = line.at(float(q[-1]))
    return Crossing(float(q[-1]), np.zeros(0), model.chart.to_canonical(q[:m], c), theta)


def _finish(model, kern, line, qa, qb, ta, tb, h, level, c, tol) -> np.ndarray | None:
    """The solution at ``s = level`` between two samples (cubic Hermite guess + Newton at
    ``line.at(level)``), in chart ``c``; None if Newton failed or strayed."""
    m = model.m
    if qa[-1] == level:
        return np.array(qa[:m])
    s = np.array([qa[-1] - level, h * ta[-1], qb[-1] - level, h * tb[-1]]) @ _BASIS
    j = np.nonzero(s[:-1] * s[1:] <= 0)[0]
    u = 0.5
    if j.size:
        i = j[0]
        u = _FINE[i] + (_FINE[i + 1] - _FINE[i]) * s[i] / (s[i] - s[i + 1] + 1e-300)
    H = _hermite(np.array([u]))[:, 0]
    y_guess = H[0] * qa[:m] + H[1] * h * ta[:m] + H[2] * qb[:m] + H[3] * h * tb[:m]
    y, res = kern.polish(y_guess, line.at(level), c)
    y = np.array(y).ravel()
    if not (np.all(np.isfinite(y)) and float(res) <= 0.1 * tol):
        return None
    seg = float(np.linalg.norm(qb[:m] - qa[:m]))
    if float(np.linalg.norm(y - y_guess)) > 3 * seg + 10 * tol:
        return None
    return y


def _is_bifurcation(model, cr: Crossing, dtheta: np.ndarray) -> bool:
    """Whether two solution branches cross at a singular point: H' = [J_p, -J_s dtheta /
    |dtheta|] drops rank (sigma_min / sigma_max < ``BIFURCATION_RANK``) for every line, i.e.
    the left null vector w of J_p annihilates J_s (|w^T J_s| / |J_s| < ``STRUCTURAL``).

    Where only ``w^T J_s dtheta`` vanishes the line is tangent to the singular surface: a
    fold (or two folds close together where the line grazes it), on which ``det J_p`` keeps
    the sign of the side the curve is on; stepping across would land on the other sheet.
    """
    y, c = model.chart.to_local(cr.y)
    Jp, Js = (np.array(a) for a in model_calls(model).jac(y, cr.theta, c))
    js = Js @ dtheta / max(float(np.linalg.norm(dtheta)), 1e-300)
    S = np.linalg.svd(np.hstack([Jp, -js[:, None]]), compute_uv=False)
    if not S[-1] < BIFURCATION_RANK * S[0]:
        return False
    w = np.linalg.svd(Jp)[0][:, -1]
    return bool(np.linalg.norm(w @ Js) < STRUCTURAL * max(float(np.linalg.norm(Js)), 1e-300))


def _met_before(singular: list[Crossing], first: int, s_a: float, level: float) -> int:
    """Singular points met before a level crossing in a segment starting at ``s = s_a``: all
    of the earlier segments, and of this one those between ``s_a`` and the level."""
    n = first
    for cr in singular[first:]:
        if (cr.s - s_a) * (level - cr.s) >= 0:
            n += 1
    return n
