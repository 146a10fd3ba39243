"""All assembly modes: every real direct-kinematics solution, by following SC solution curves.

For a target ``theta0`` and a line ``theta(s) = theta1 + s (theta0 - theta1)`` in joint space,
the solutions of ``g(y, theta(s)) = 0`` form curves in ``q = (y, s)``; every point of them with
``s = 1`` is a direct-kinematics solution at ``theta0``. The curve through an assembled start
usually meets ``s = 1`` many times (the paper's convergent and divergent answers are only the
first meeting in each direction). For the platforms of this package the curves are closed
loops: following one all the way round collects every solution on it.

:func:`assembly_modes` follows such curves from a set of starts:

1. the start configuration (default ``model.home``), on the line from its ``theta`` to
   ``theta0``: the whole curve;
2. alternately,

   a. a known solution (the least used one) on a line through ``theta0`` in a random
      direction (the solution is the point ``s = 1`` of that curve): the whole curve;
   b. a random assembled configuration on the line from its ``theta`` to ``theta0`` (the
      paper's kind of start, ``theta1 = IK(y1)``): random unknowns ranked by their closure
      residual at ``theta0`` and taken away from the known solutions; the first crossing of
      ``s = 1`` each way (the paper's convergent and divergent answers). These reach the
      solutions that no curve through a known one connects to (e.g. the mirror images
      below the base of a nearly planar 6-6 platform);

until the last ``patience`` curves of each kind found nothing new and every known solution
was met again ``cover`` times since the last new one (or the time budget or the curve limit
runs out). A curve ends when it comes back to its start, when it meets a solution or a
turning point of ``s`` a second time (the follower went round a loop it jumped onto near
two nearly touching branches), or at its arc-length or step budget.

The curves are followed by a predictor-corrector on the SC tangent (RK4 predictor along the
unit tangent of ``nu``, Newton corrector on the plane normal to it, ``STEPS`` steps per call of
one CasADi function, SX or generated C) with adaptive arc-length steps; each ``s = 1``
crossing is polished by Newton at ``theta0``, verified and deduplicated.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..errors import InputError, ScdkError
from ..follower.geometry import difference, features, in_chart, kinds, local_features, periodic  # noqa: F401
from ..model.model import Model, as_vector
from ..results import Configuration
from .sc import null_direction, validate_start

#: Predictor-corrector steps evaluated per call of the compiled step function.
STEPS = 16
#: Newton corrections per step.
CORRECTIONS = 3
#: Newton steps of the final polish at ``theta0``.
POLISH_STEPS = 8
#: A step is accepted when the corrector moved the prediction by less than this fraction of
#: the step and the tangent turned by less than acos(MIN_COS).
MAX_PREDICTOR_ERROR = 0.1
MIN_COS = 0.7
#: ... and the last Newton correction was below this (relative to the model size).
NEWTON_TOL = 1e-7
#: The step grows by 1.5 after a chunk whose steps all did better than these.
GROW_PREDICTOR = 0.02
GROW_COS = 0.95
BACKENDS = ("casadi", "compiled")
#: The orientation chart is re-centred when a Rodrigues parameter exceeds this (~53 deg).
RECENTRE = 0.5
#: Random starts: coordinates other than angles within this many model sizes of home.
RANDOM_SPREAD = 1.5


# ---------------------------------------------------------------------------- kernels


@dataclass(frozen=True)
class CurveKernels:
    """CasADi Functions of the curve follower of one model.

    Attributes:
        steps: (x[2(m+1)], h, p[2k], c) -> (X[2(m+1), STEPS], info[3, STEPS]): ``STEPS``
            predictor-corrector steps of arc length ``h`` from ``x = (q, v)`` (a point of the
            curve and its unit tangent), ``p = (theta1, dtheta)``; ``info`` rows: first and last
            Newton correction (weighted norm), cosine between the tangents before and after.
        tangent: (q, v, p, c) -> unit tangent of the curve at ``q`` oriented along ``v``.
        polish: (y, theta, c) -> (y, max|g|): ``POLISH_STEPS`` Newton steps at fixed theta.
    """

    steps: ca.Function
    tangent: ca.Function
    polish: ca.Function

    def all(self) -> list[ca.Function]:
        return [self.steps, self.tangent, self.polish]


def _build_curve_kernels(model: Model) -> CurveKernels:
    sym = model.symbolic
    m, k = sym.m, sym.k
    y, c = sym.y, sym.c
    s = ca.SX.sym("s")
    theta1 = ca.SX.sym("theta1", k)
    dtheta = ca.SX.sym("dtheta", k)
    p = ca.vertcat(theta1, dtheta)
    q = ca.vertcat(y, s)
    g, Jp, Js = ca.substitute([sym.g, sym.J_p, sym.J_s], [sym.theta], [theta1 + s * dtheta])
    H = ca.horzcat(Jp, -(Js @ dtheta))
    w2 = ca.dot(dtheta, dtheta)
    weight = ca.vertcat(ca.DM.ones(m), w2)
    v = ca.SX.sym("v", m + 1)
    e = ca.DM.zeros(m + 1)
    e[m] = 1.0
    # [H; v^T] t = e gives t parallel to nu = [adj(J_p) j_s; det J_p] with v.t > 0 (Cramer):
    # regular on the singular manifold, oriented by continuity with v.
    t = ca.solve(ca.vertcat(H, v.T), e)
    t = t / ca.sqrt(ca.dot(weight * t, t))
    f_tan = ca.Function("scdk_curve_tangent", [q, v, p, c], [t], ["q", "v", "p", "c"], ["t"])
    f_gH = ca.Function("scdk_curve_gH", [q, p, c], [g, H])

    x = ca.SX.sym("x", 2 * (m + 1))
    h = ca.SX.sym("h")
    q0, v0 = x[: m + 1], x[m + 1 :]
    t1 = v0  # the caller passes the unit tangent at q0
    t2 = f_tan(q0 + h / 2 * t1, t1, p, c)
    t3 = f_tan(q0 + h / 2 * t2, t1, p, c)
    t4 = f_tan(q0 + h * t3, t1, p, c)
    q_pred = q0 + h / 6 * (t1 + 2 * t2 + 2 * t3 + t4)
    row = (weight * t1).T
    qk = q_pred
    corrections = []
    for _ in range(CORRECTIONS):
        gk, Hk = f_gH(qk, p, c)
        dq = -ca.solve(ca.vertcat(Hk, row), ca.vertcat(gk, row @ (qk - q_pred)))
        corrections.append(ca.sqrt(ca.dot(weight * dq, dq)))
        qk = qk + dq
    t_new = f_tan(qk, t1, p, c)
    info = ca.vertcat(corrections[0], corrections[-1], ca.dot(weight * t_new, t1))
    step = ca.Function("scdk_curve_step", [x, h, p, c], [ca.vertcat(qk, t_new), info])
    f_steps = step.mapaccum("scdk_curve_steps", STEPS)

    theta = ca.SX.sym("theta", k)
    g0, J0 = ca.substitute([sym.g, sym.J_p], [sym.theta], [theta])
    newton = ca.Function("scdk_newton1", [y, theta, c], [y - ca.solve(J0, g0)])
    yk = y
    for _ in range(POLISH_STEPS):
        yk = newton(yk, theta, c)
    res = ca.norm_inf(ca.substitute(g0, y, yk))
    f_polish = ca.Function(
        "scdk_curve_polish", [y, theta, c], [yk, res], ["y", "theta", "c"], ["y_solved", "residual"]
    )
    return CurveKernels(f_steps, f_tan, f_polish)


def curve_kernels(model: Model, backend: str = "casadi") -> CurveKernels:
    """The (cached) curve-following kernels of a model.

    Args:
        model: the model.
        backend: "casadi" (SX virtual machine) or "compiled" (generated C compiled with the
            system compiler once, cached on disk by content hash; ~4x faster).

    Raises:
        InputError: unknown backend.
        BuildError: no C compiler (compiled backend).
    """
    if backend not in BACKENDS:
        raise InputError(f"unknown backend {backend!r}; backends: {', '.join(BACKENDS)}")
    store = model.__dict__.setdefault("_curve_kernels", {})
    if backend not in store:
        kern = _build_curve_kernels(model)
        if backend == "compiled":
            kern = _compile(kern)
        store[backend] = kern
    return store[backend]


def _compile(kern: CurveKernels) -> CurveKernels:
    from ..kernels.compile import cached_library

    target = cached_library(kern.all(), "scdk_curve")
    return CurveKernels(*(ca.external(f.name(), str(target)) for f in kern.all()))


# ---------------------------------------------------------------------------- geometry


def _scale(model: Model) -> float:
    return max(1.0, model.length_scale)


# ---------------------------------------------------------------------------- one curve


@dataclass
class Curve:
    """What following one solution curve met.

    Attributes:
        hits: canonical unknowns (m,) of the verified solutions met at ``s = 1``, in order.
        hit_arcs: arc length at which each hit was met (to half a step).
        turns: the singular-manifold crossings (turning points of ``s``) as (arc, canonical
            unknowns, s), interpolated between two samples (accurate to the step squared).
        arc: arc length followed (metric ``|dy|^2 + (|dtheta| ds)^2``).
        steps: accepted predictor-corrector steps.
        rejected: rejected steps.
        closed: the curve came back to its start.
        reversed: ... but backwards (the follower jumped between nearly touching branches).
        repeated: a solution or a turning point of s was met twice (the follower went round
            a loop again: it jumped onto a loop that does not pass through its start).
        crossings: singular-manifold crossings (``det J_p`` changed sign).
        timed_out: stopped by the deadline.
        path: (when recorded) accepted samples ``(y canonical, s)`` (m + 1,).
    """

    hits: list[np.ndarray] = field(default_factory=list)
    hit_arcs: list[float] = field(default_factory=list)
    turns: list[tuple[float, np.ndarray, float]] = field(default_factory=list)
    arc: float = 0.0
    steps: int = 0
    rejected: int = 0
    closed: bool = False
    reversed: bool = False
    repeated: bool = False
    crossings: int = 0
    timed_out: bool = False
    path: list[np.ndarray] = field(default_factory=list, repr=False)


def follow_curve(
    model: Model,
    theta1: np.ndarray,
    dtheta: np.ndarray,
    y_start: np.ndarray,
    s_start: float,
    direction: float,
    *,
    max_arc: float,
    deadline: float = math.inf,
    backend: str = "casadi",
    record: bool = False,
    max_hits: int | float = math.inf,
    max_steps: int = 20000,
    step: float | None = None,
) -> Curve:
    """Follow the curve ``g(y, theta1 + s dtheta) = 0`` from ``(y_start, s_start)``.

    The orientation is the SC field's: ``direction = +1`` follows ``nu`` (``s' = det J_p``),
    ``-1`` follows ``-nu``. The curve is followed until it closes (comes back to the start),
    the arc-length budget is spent or the deadline passes; every crossing of ``s = 1`` is
    polished by Newton at ``theta1 + dtheta`` and kept if verified.

    Args:
        model: the model.
        theta1: (k,) actuated values at ``s = 0``.
        dtheta: (k,) direction of the line (``theta0 = theta1 + dtheta`` at ``s = 1``).
        y_start: (m,) canonical unknowns of an assembled point of the curve.
        s_start: its path parameter.
        direction: +1 or -1.
        max_arc: arc-length budget, in the metric ``|dy|^2 + (|dtheta| ds)^2`` [model length
            unit and rad, as y and theta].
        deadline: ``time.perf_counter()`` value at which to stop.
        backend: "casadi" or "compiled".
        record: keep the accepted samples in ``curve.path``.
        max_hits: stop after this many solutions (at the end of the chunk that met them).
        max_steps: stop after this many accepted steps.
        step: initial arc-length step (default 0.02 model sizes); adapted as the curve bends.

    Returns:
        A :class:`Curve`.
    """
    kern = curve_kernels(model, backend)
    m = model.m
    theta0 = theta1 + dtheta
    p = np.concatenate([theta1, dtheta])
    w2 = float(dtheta @ dtheta)
    weight = np.append(np.ones(m), w2)
    per = periodic(model)
    rots = model.chart.rotations
    rot_idx = kinds(model)[1]
    out = Curve()
    y_loc, c = model.chart.to_local(y_start)
    q = np.append(y_loc, s_start)
    Jp, Js = (np.array(a) for a in model.kernels.jac(y_loc, theta1 + s_start * dtheta, c))
    nu = null_direction(Jp, Js @ dtheta)
    v = np.array(kern.tangent(q, direction * nu, p, c)).ravel()
    q_first, c_first, t_first = q.copy(), c.copy(), v.copy()
    scale = _scale(model)
    h = 0.02 * scale if step is None else float(step)
    h_max = 0.5 * scale
    tol = 1e-6 * scale
    f_seen = np.zeros((0, 0))
    turning: list[tuple[np.ndarray, float]] = []  # (features, arc) of the turning points of s
    w = math.sqrt(w2)
    left = False  # moved away from the start (closure is tested only afterwards)
    while out.arc < max_arc:
        if time.perf_counter() > deadline:
            out.timed_out = True
            break
        X, info = (np.array(a) for a in kern.steps(np.concatenate([q, v]), h, p, c))
        good = (
            np.all(np.isfinite(X), axis=0)
            & (info[0] <= MAX_PREDICTOR_ERROR * h)
            & (info[1] <= NEWTON_TOL * scale)
            & (info[2] >= MIN_COS)
        )
        if rot_idx.size:  # stay well inside the orientation chart (Rodrigues: 2 = 127 deg)
            good &= np.max(np.abs(X[rot_idx]), axis=0) <= 2.0
        n_ok = int(np.argmin(good)) if not good.all() else good.size
        if n_ok == 0:
            out.rejected += 1
            h /= 2
            if h < 1e-10 * scale:
                break  # the curve cannot be followed further (e.g. it ends at a leg of zero length)
            continue
        Q = np.hstack([q[:, None], X[: m + 1, :n_ok]])
        T = np.hstack([v[:, None], X[m + 1 :, :n_ok]])
        s_vals = Q[-1]
        # a turning point of s between two samples could hide two crossings of s = 1
        if _hidden_pair(s_vals, T[-1], h):
            out.rejected += 1
            h /= 4
            continue
        turns = np.nonzero(T[-1, :-1] * T[-1, 1:] < 0)[0]
        out.crossings += int(turns.size)
        for i in turns:  # turning points of s: every loop has some; met again = going round
            a = T[-1, i] / (T[-1, i] - T[-1, i + 1])
            qt = Q[:, i] + a * (Q[:, i + 1] - Q[:, i])
            f = np.append(local_features(model, qt[:m], c), qt[m] * w)
            arc_t = out.arc + h * (i + a)
            if turning:
                F = np.array([t[0] for t in turning])
                A = np.array([t[1] for t in turning])
                near = np.max(np.abs(F - f), axis=1) < 2 * h + tol
                out.repeated |= bool(np.any(near & (arc_t - A > 4 * h)))
            turning.append((f, arc_t))
            out.turns.append((arc_t, model.chart.to_canonical(qt[:m], c), float(qt[m])))
        for i in np.nonzero((s_vals[:-1] - 1.0) * (s_vals[1:] - 1.0) <= 0)[0]:
            if s_vals[i] == s_vals[i + 1] or (out.steps == 0 and i == 0 and s_start == 1.0):
                continue
            y_loc = _polish_between(model, kern, Q[:, i], Q[:, i + 1], T[:, i], T[:, i + 1],
                                    h, theta0, c)  # fmt: skip
            if y_loc is not None:
                f_hit = local_features(model, y_loc, c)[None]
                if f_seen.size and np.min(np.max(np.abs(f_seen - f_hit), axis=1)) <= tol:
                    out.repeated = True  # met twice: the follower jumped onto a loop it went round
                    break
                out.hits.append(model.chart.to_canonical(y_loc, c))
                out.hit_arcs.append(out.arc + h * (i + 0.5))
                f_seen = np.vstack([f_seen, f_hit]) if f_seen.size else f_hit
        # closure: distance of the path to the start point expressed in the current chart
        q_ref = in_chart(q_first, c_first, c, rots)
        if q_ref is not None:
            D = Q - q_ref[:, None]
            if per.size:
                D[per] = (D[per] + math.pi) % (2 * math.pi) - math.pi
            E = np.diff(Q, axis=1)
            tau = np.clip(-(weight @ (D[:, :-1] * E)) / np.maximum(weight @ (E * E), 1e-300), 0, 1)
            P = D[:, :-1] + tau * E
            dist = np.sqrt(weight @ (P * P))
            if not left:
                left = bool(np.any(dist > 3 * h))
            elif np.any(dist < 0.1 * h):
                j = int(np.argmin(dist))
                out.closed = True
                # passing the start backwards: the follower jumped between two nearly touching
                # branches somewhere and came back over its own path
                out.reversed = bool(weight @ (T[:, j + 1] * t_first) < 0)
        if record:
            for j in range(1, Q.shape[1]):
                out.path.append(np.append(model.chart.to_canonical(Q[:m, j], c), Q[m, j]))
        out.steps += n_ok
        out.arc += h * n_ok
        if out.closed or out.repeated or len(out.hits) >= max_hits or out.steps >= max_steps:
            break
        q, v = Q[:, -1], T[:, -1]
        if rots and np.max(np.abs(q[rot_idx])) > RECENTRE:  # re-centre the orientation chart
            y_new, c = model.chart.recentre(q[:-1], c)
            q = np.append(y_new, q[-1])
            v = np.array(kern.tangent(q, v, p, c)).ravel()
        if n_ok < good.size:
            out.rejected += 1
            h /= 2
        elif info[0].max() < GROW_PREDICTOR * h and info[2].min() > GROW_COS:
            h = min(1.5 * h, h_max)
    return out


def _hermite(u: np.ndarray) -> np.ndarray:
    """Cubic Hermite basis (h00, h10, h01, h11) at the fractions ``u`` of a step."""
    u2, u3 = u * u, u * u * u
    return np.array([2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2])


_FINE = np.linspace(0.0, 1.0, 65)
_BASIS = _hermite(_FINE)


def _hidden_pair(s_vals: np.ndarray, ts: np.ndarray, h: float) -> bool:
    """Whether a turning point of s inside a step crosses s = 1 twice between two samples."""
    for i in np.nonzero(ts[:-1] * ts[1:] < 0)[0]:
        a, b = s_vals[i] - 1.0, s_vals[i + 1] - 1.0
        if a * b <= 0:
            continue
        # cubic Hermite interpolant of s - 1 on the step (slopes ds/darc = t_s)
        s = np.array([a, h * ts[i], b, h * ts[i + 1]]) @ _BASIS
        if np.any(s * a <= 0):
            return True
    return False


def _polish_between(model, kern, qa, qb, ta, tb, h, theta0, c) -> np.ndarray | None:
    """The solution at s = 1 between two samples (cubic Hermite guess + Newton), in chart c."""
    m = model.m
    # the arc fraction where the Hermite interpolant of s meets 1
    s = np.array([qa[-1] - 1.0, h * ta[-1], qb[-1] - 1.0, h * tb[-1]]) @ _BASIS
    j = np.nonzero(s[:-1] * s[1:] <= 0)[0]
    u = 0.5
    if j.size:
        i = j[0]
        u = _FINE[i] + (_FINE[i + 1] - _FINE[i]) * s[i] / (s[i] - s[i + 1] + 1e-300)
    H = _hermite(np.array([u]))[:, 0]
    y_guess = H[0] * qa[:m] + H[1] * h * ta[:m] + H[2] * qb[:m] + H[3] * h * tb[:m]
    y, res = kern.polish(y_guess, theta0, c)
    y = np.array(y).ravel()
    if not (np.all(np.isfinite(y)) and float(res) <= 0.1 * model.tolerance):
        return None
    return y


# ---------------------------------------------------------------------------- search


@dataclass
class ModeSearch:
    """Outcome of :func:`explore`.

    Attributes:
        solutions: the verified solutions, deduplicated and sorted (see :func:`assembly_modes`).
        curves: solution curves followed.
        steps: predictor-corrector steps taken (accepted + rejected chunks' accepted steps).
        arc: total arc length followed.
        elapsed: wall time [s].
        complete: the stopping rule was met (``False``: stopped by the time budget or the
            curve limit).
        met: for each solution, how many curves met it.
        lines: curves followed from a known solution on a random line through ``theta0``.
        random_starts: random start configurations drawn.
        last_new: (lines, random_starts) when the last new solution was found.
    """

    solutions: list[Configuration]
    curves: int = 0
    steps: int = 0
    arc: float = 0.0
    elapsed: float = 0.0
    complete: bool = False
    met: list[int] = field(default_factory=list)
    lines: int = 0
    random_starts: int = 0
    last_new: tuple[int, int] = (0, 0)


def _actuator_scale(model: Model) -> np.ndarray:
    types = {j.name: j.type for j in model.tree.joints}
    return np.array([_scale(model) if types[a] == "prismatic" else 1.0 for a in model.actuated])


def explore(
    model: Model,
    theta0: Sequence[float],
    *,
    start: Configuration | Sequence[Configuration] | None = None,
    seed: int = 0,
    time_budget: float | None = None,
    progress: bool = False,
    patience: int = 8,
    cover: int = 2,
    max_curves: int = 400,
    max_arc: float | None = None,
    backend: str = "casadi",
) -> ModeSearch:
    """Search the real direct-kinematics solutions at ``theta0`` (see :func:`assembly_modes`).

    Args:
        model, theta0, start, seed, time_budget, progress, patience, cover, max_curves,
            backend: as :func:`assembly_modes`.
        max_arc: arc-length budget of one curve (default 200 model sizes).

    Returns:
        A :class:`ModeSearch` with the solutions and statistics of the search.
    """
    t_begin = time.perf_counter()
    theta0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
    if backend not in BACKENDS:
        raise InputError(f"unknown backend {backend!r}; backends: {', '.join(BACKENDS)}")
    if time_budget is not None and not (time_budget > 0):
        raise InputError(f"time_budget must be a positive number of seconds, got {time_budget!r}")
    for name, value in (("patience", patience), ("cover", cover), ("max_curves", max_curves)):
        if int(value) != value or value < 0:
            raise InputError(f"{name} must be a non-negative integer, got {value!r}")
    starts = [start] if start is None or isinstance(start, Configuration) else list(start)
    starts = [validate_start(model, st) for st in starts]
    deadline = math.inf if time_budget is None else t_begin + float(time_budget)
    scale = _scale(model)
    arc_budget = 200.0 * scale if max_arc is None else float(max_arc)
    tol_same = 1e-6 * scale
    rng = np.random.default_rng(seed)
    act = _actuator_scale(model)
    sols: list[Configuration] = []
    feats: list[np.ndarray] = []
    met: list[int] = []
    since: list[int] = []  # times met since the last new solution
    used: list[int] = []  # times used as a start
    out = ModeSearch(solutions=[])
    bar = _progress_bar(progress)
    sampler = RandomStarts(model, rng, theta0)

    def record(curve: Curve, origin: int) -> int:
        new = 0
        seen: set[int] = set()
        for y in curve.hits:
            f = features(model, y)
            if feats:
                dist = np.max(np.abs(np.vstack(feats) - f), axis=1)
                i = int(np.argmin(dist))
                if dist[i] <= tol_same:
                    seen.add(i)
                    continue
            cfg = model.configuration(y, theta0)
            if not cfg.residual <= model.tolerance:
                continue
            sols.append(cfg)
            feats.append(f[0])
            met.append(0)
            since.append(0)
            used.append(0)
            seen.add(len(sols) - 1)
            new += 1
        for i in seen - {origin}:
            met[i] += 1
            since[i] += 1
        out.curves += 1
        if new:
            since[:] = [0] * len(since)
        out.steps += curve.steps
        out.arc += curve.arc
        if bar is not None:
            bar.update(1)
            bar.set_postfix(solutions=len(sols), refresh=False)
        return new

    def both_ways(theta1, dtheta, y, s, origin, max_hits=math.inf) -> int:
        new = 0
        for direction in (1.0, -1.0):
            curve = follow_curve(model, theta1, dtheta, y, s, direction, max_arc=arc_budget,
                                 deadline=deadline, backend=backend, max_hits=max_hits)  # fmt: skip
            new += record(curve, origin)
            if (curve.closed and not curve.reversed) or curve.timed_out:
                break
        return new

    try:
        # 1. from the start configurations, on the line to theta0
        for st in starts:
            dtheta = theta0 - st.theta
            if float(np.linalg.norm(dtheta)) <= 1e-12 * max(1.0, float(np.linalg.norm(theta0))):
                record(Curve(hits=[np.array(st.y)]), -1)
                continue
            both_ways(st.theta, dtheta, st.y, 0.0, -1)
        # 2. alternately from a known solution on a random line through theta0, and from a
        #    random assembled configuration on the line to theta0, until neither kind has
        #    found anything new for `patience` curves (and every solution was met again)
        idle = {"line": 0, "random": 0}
        while out.curves < max_curves and time.perf_counter() < deadline:
            if sols and min(idle.values()) >= patience and min(since) >= cover:
                out.complete = True
                break
            if not sols and out.random_starts >= max(8, 4 * patience):
                out.complete = True  # nothing reaches theta0 from anywhere tried
                break
            kind = "line" if sols and idle["line"] <= idle["random"] else "random"
            if kind == "line":
                i = int(np.argmin(used))
                used[i] += 1
                d = rng.normal(size=model.k) * act
                d *= 0.5 * scale / float(np.linalg.norm(d))
                out.lines += 1
                new = both_ways(theta0 - d, d, sols[i].y, 1.0, i)
            else:
                known = np.vstack(feats) if feats else np.zeros((0, 0))
                st = sampler.next(known, 0.25 * scale)
                out.random_starts += 1
                if st is None:
                    out.curves += 1  # counted, so that a failing sampler cannot loop forever
                    new = 0
                else:
                    # the paper's two answers from this start (first crossing each way)
                    new = both_ways(st.theta, theta0 - st.theta, st.y, 0.0, -1, max_hits=1)
            if new:
                idle = dict.fromkeys(idle, 0)
                out.last_new = (out.lines, out.random_starts)
            else:
                idle[kind] += 1
    finally:
        if bar is not None:
            bar.close()
    order = sorted(range(len(sols)), key=lambda i: _sort_key(sols[i]))
    out.solutions = [sols[i] for i in order]
    out.met = [met[i] for i in order]
    out.elapsed = time.perf_counter() - t_begin
    return out


class RandomStarts:
    """Random assembled starts (the paper's kind: ``theta1 = IK(y1)``) for the search.

    With as many unknowns as actuators, batches of random unknowns (revolute angles and
    rotations uniform, other coordinates within ``RANDOM_SPREAD`` model sizes of home) are
    ranked by their closure residual at ``theta0`` (the nearer the fibre over ``theta0``, the
    likelier the curve from there reaches ``s = 1``); a candidate near a known solution is
    skipped, the others get ``theta`` by Newton on ``g(y, theta) = 0``. Otherwise the inverse
    kinematics of random poses near home.

    Args:
        model: the model.
        rng: random generator.
        theta0: (k,) target actuated values.
        batch: candidates drawn at a time.
    """

    def __init__(self, model: Model, rng: np.random.Generator, theta0: np.ndarray, batch=256):
        self.model, self.rng, self.theta0, self.batch = model, rng, theta0, batch
        self.queue: list[np.ndarray] = []
        self.drawn = 0

    def _refill(self) -> None:
        model, n = self.model, self.batch
        Y = np.tile(np.array(model.home.y, dtype=float), (n, 1))
        per, _, plain = kinds(model)
        Y[:, per] = self.rng.uniform(-math.pi, math.pi, (n, per.size))
        spread = RANDOM_SPREAD * model.length_scale
        Y[:, plain] += self.rng.uniform(-spread, spread, (n, len(plain)))
        C = np.zeros((n, model.chart.size))
        for r, idx in enumerate(model.chart.rotations):
            quat = self.rng.normal(size=(n, 4))
            quat /= np.linalg.norm(quat, axis=1)[:, None]
            for j in range(n):  # uniform rotations, as charts (local rotation parameters 0)
                C[j, 9 * r : 9 * r + 9] = _quat_matrix(quat[j]).flatten(order="F")
            Y[:, list(idx)] = 0.0
        G = np.array(model.kernels.g.map(n)(Y.T, np.tile(self.theta0[:, None], (1, n)), C.T))
        score = np.max(np.abs(G), axis=0)
        score[~np.isfinite(score)] = np.inf
        order = np.argsort(score, kind="stable")
        self.queue = [model.chart.to_canonical(Y[j], C[j]) for j in order if np.isfinite(score[j])]
        self.queue.reverse()  # pop() takes the best

    def next(self, known: np.ndarray, radius: float) -> Configuration | None:
        """The next start away from the known solutions' features (None if it fails)."""
        model = self.model
        self.drawn += 1
        if model.m != model.k:
            return self._by_inverse_kinematics()
        while True:
            if not self.queue:
                self._refill()
            y = self.queue.pop()
            if (
                not known.size
                or np.min(np.max(np.abs(known - features(model, y)), axis=1)) > radius
            ):
                break
        y_loc, c = model.chart.to_local(y)
        theta = np.array(self.theta0, dtype=float)
        for _ in range(30):
            g = np.array(model.kernels.g(y_loc, theta, c)).ravel()
            if not np.all(np.isfinite(g)):
                return None
            if np.max(np.abs(g)) <= 0.1 * model.tolerance:
                break
            Js = np.array(model.kernels.jac(y_loc, theta, c)[1])
            try:
                theta = theta + np.linalg.solve(Js, g)
            except np.linalg.LinAlgError:
                return None
        return self._checked(model.configuration(y, theta))

    def _by_inverse_kinematics(self) -> Configuration | None:
        model = self.model
        x = np.array(model.home.x, dtype=float)
        for i, name in enumerate(model.workspace):
            if name in ("phi", "roll", "pitch", "yaw"):
                x[i] += self.rng.uniform(-math.pi, math.pi) * (0.5 if name == "pitch" else 1.0)
            else:
                x[i] += self.rng.uniform(-0.3, 0.3) * model.length_scale
        try:
            return self._checked(model.inverse_kinematics(x))
        except ScdkError:
            return None

    def _checked(self, cfg: Configuration) -> Configuration | None:
        ok = cfg.residual <= self.model.tolerance and np.all(np.isfinite(cfg.theta))
        return cfg if ok else None


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _sort_key(cfg: Configuration) -> tuple:
    return (*(round(float(v), 8) for v in cfg.x), *(round(float(v), 8) for v in cfg.y))


def _progress_bar(enabled: bool):
    if not enabled:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:  # pragma: no cover - tqdm is optional
        import warnings

        warnings.warn("progress=True needs tqdm: pip install tqdm", stacklevel=3)
        return None
    return tqdm(desc="assembly modes", unit="curve", leave=False)


def assembly_modes(
    model: Model,
    theta0: Sequence[float],
    *,
    seed: int = 0,
    time_budget: float | None = None,
    progress: bool = False,
    start: Configuration | Sequence[Configuration] | None = None,
    patience: int = 8,
    cover: int = 2,
    max_curves: int = 400,
    backend: str = "casadi",
) -> list[Configuration]:
    """All real direct-kinematics solutions (assembly modes) at ``theta0`` that can be found.

    Follows singularity-consistent solution curves (see the module documentation): from the
    start configuration on the line to ``theta0``, then alternately from the solutions found,
    on random lines through ``theta0``, and from random assembled configurations, on their
    lines to ``theta0``, collecting every ``s = 1`` crossing, until the stopping rule holds
    (the last ``patience`` curves of each kind found no new solution and every known one was
    met again ``cover`` times since the last new one), the time budget is spent or
    ``max_curves`` curves were followed. Measured: all 40 real modes of Dietmaier's 6-6
    platform in about half a second with the compiled backend (``benchmarks/modes_6_6.py``).

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        seed: seed of the random directions and starts (the result is deterministic for a
            seed, without a time budget).
        time_budget: wall-time limit [s] (``None``: no limit); the solutions found so far are
            returned when it runs out.
        progress: show a progress bar (tqdm) on stderr.
        start: assembled start configuration(s) (default ``model.home``).
        patience: curves of each kind in a row without a new solution before stopping.
        cover: times each known solution must be met again before stopping.
        max_curves: limit on the number of curves followed.
        backend: "casadi" or "compiled" (generated C, compiled once and cached on disk).

    Returns:
        The solutions as :class:`~scdk_sym.results.Configuration` (``theta = theta0``), each
        verified (``residual <= model.tolerance``), distinct (unknowns differ by more than
        1e-6 model sizes, angles modulo 2 pi), sorted by ``x`` then ``y`` (rounded to 1e-8).
        Empty if no curve from the starts reaches ``theta0``.

    Raises:
        InputError: bad ``theta0``, budget, counts or backend.
        NotAssembledError: a start configuration is not assembled.
    """
    return explore(
        model,
        theta0,
        start=start,
        seed=seed,
        time_budget=time_budget,
        progress=progress,
        patience=patience,
        cover=cover,
        max_curves=max_curves,
        backend=backend,
    ).solutions
