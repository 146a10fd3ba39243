"""Assembly modes by the real-curve search: every real solution met by following SC curves.

For a target ``theta0`` and a line ``theta(s) = theta1 + s (theta0 - theta1)`` in joint space,
the solutions of ``g(y, theta(s)) = 0`` form curves in ``q = (y, s)``; every point of them with
``s = 1`` is a direct-kinematics solution at ``theta0``. The curve through an assembled start
usually meets ``s = 1`` many times (the paper's convergent and divergent answers are only the
first meeting in each direction). For the platforms of this package the curves are closed
loops: following one all the way round collects every solution on it.

:func:`explore` (``assembly_modes(method="curves")``) follows such curves from a set of
starts:

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

The curves are followed by the one curve follower (:mod:`scdk_sym.follower.curve`, explicit
predictor-corrector on the SC tangent, folds and bifurcations handled there), with kernels as
SX Functions or generated C; each ``s = 1``
crossing is polished by Newton at ``theta0``, verified and deduplicated.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..backends import resolve
from ..errors import InputError
from ..follower.calls import follower_kernels
from ..follower.curve import follow
from ..follower.geometry import features
from ..follower.options import FollowOptions
from ..follower.walk import Line
from ..results import AssemblyModes, Configuration, mode_order
from ..robot import Model
from .query import target, validate_start
from .random_starts import RandomStarts

#: The search accepts explicit steps whose tangent turned by up to acos(0.7) (it collects
#: solutions; a jump between nearby branches only changes the curve it explores).
SEARCH_MIN_COS = 0.7


def curve_kernels(model: Model, backend: str = "cvodes"):
    """The curve follower's kernels (:func:`scdk_sym.follower.calls.follower_kernels`)."""
    return follower_kernels(model, backend)


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


@dataclass(frozen=True)
class CurveOptions:
    """How far :func:`follow_curve` follows one curve, and with which kernels.

    Attributes:
        max_arc: arc-length budget, in the metric ``|dy|^2 + (|dtheta| ds)^2``.
        deadline: ``time.perf_counter()`` value at which to stop [s].
        backend: "cvodes" or "compiled" kernels (see :mod:`scdk_sym.backends`).
        record: keep the accepted samples in ``curve.path``.
        max_hits: stop after this many solutions.
        max_steps: stop after this many accepted steps.
        step: initial arc-length step (default 0.02 model sizes).
    """

    max_arc: float
    deadline: float = math.inf
    backend: str = "cvodes"
    record: bool = False
    max_hits: int | float = math.inf
    max_steps: int = 20000
    step: float | None = None


def follow_curve(
    model: Model,
    theta1: np.ndarray,
    dtheta: np.ndarray,
    y_start: np.ndarray,
    s_start: float,
    direction: float,
    options: CurveOptions,
) -> Curve:
    """Follow the curve ``g(y, theta1 + s dtheta) = 0`` from ``(y_start, s_start)`` with the
    curve follower (:func:`scdk_sym.follower.curve.follow`, explicit predictor-corrector) and
    collect its ``s = 1`` crossings.

    Args:
        model: the model.
        theta1: (k,) actuated values at ``s = 0``.
        dtheta: (k,) direction of the line (``theta0 = theta1 + dtheta`` at ``s = 1``).
        y_start: (m,) canonical unknowns of an assembled point of the curve.
        s_start: its path parameter.
        direction: +1 follows ``nu`` (``s' = det J_p``), -1 follows ``-nu``.
        options: the budgets, the kernels and the recording (:class:`CurveOptions`).

    Returns:
        A :class:`Curve`.
    """
    step, record = options.step, options.record
    line = Line(np.asarray(theta1, float), np.asarray(dtheta, float))
    h = 0.02 * _scale(model) if step is None else float(step)
    follow_options = FollowOptions(
        predictor="rk4",
        backend=options.backend,
        max_hits=options.max_hits,
        max_arc=options.max_arc,
        max_steps=options.max_steps,
        deadline=options.deadline,
        step=h,
        record=record,
        locate=False,
        min_cos=SEARCH_MIN_COS,
    )
    walk = follow(model, line, y_start, s_start, direction, follow_options)
    out = Curve(
        hits=[hit.y for hit in walk.hits],
        hit_arcs=[hit.arc for hit in walk.hits],
        turns=[
            (a, cr.y, cr.s)
            for cr, a in zip(walk.singular, walk.singular_arcs, strict=True)
            if cr.kind == "fold"
        ],
        arc=walk.arc,
        steps=walk.steps,
        rejected=walk.rejected,
        closed=walk.closed,
        reversed=walk.reversed,
        repeated=walk.repeated,
        crossings=len(walk.singular),
        timed_out=walk.timed_out,
    )
    if record and walk.path is not None:
        out.path = [np.append(y, s) for y, s in zip(walk.path.y, walk.path.s, strict=True)]
    return out


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


@dataclass(frozen=True)
class StoppingRule:
    """When :func:`explore` stops (besides its time budget), and how far one curve goes.

    Attributes:
        patience: curves of each kind in a row without a new solution before stopping.
        cover: times each known solution must be met again since the last new one.
        max_curves: bound on the curves followed.
        max_arc: arc-length budget of one curve (default 200 model sizes).
    """

    patience: int = 8
    cover: int = 2
    max_curves: int = 400
    max_arc: float | None = None


def explore(
    model: Model,
    theta0: ArrayLike,
    *,
    start: Configuration | Sequence[Configuration] | None = None,
    seed: int = 0,
    time_budget: float | None = None,
    progress: bool = False,
    backend: str = "cvodes",
    rule: StoppingRule | None = None,
) -> ModeSearch:
    """Search the real direct-kinematics solutions at ``theta0`` (see :func:`assembly_modes`).

    Args:
        model, theta0, start, seed, time_budget, progress, backend: as
            :func:`assembly_modes`.
        rule: the stopping rule (default :class:`StoppingRule`: ``patience`` 8, ``cover`` 2,
            ``max_curves`` 400, ``max_arc`` 200 model sizes).

    Returns:
        A :class:`ModeSearch` with the solutions and statistics of the search.
    """
    t_begin = time.perf_counter()
    rule = StoppingRule() if rule is None else rule
    patience, cover, max_curves, max_arc = rule.patience, rule.cover, rule.max_curves, rule.max_arc
    theta0 = target(model, theta0)
    backend = resolve(backend, "curves")
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
    search = _Search(model, theta0, np.random.default_rng(seed), scale, arc_budget, deadline,
                     backend, _progress_bar(progress))  # fmt: skip
    try:
        search.from_starts(starts)  # 1. from the start configurations, on the line to theta0
        search.alternate(patience, cover, max_curves)  # 2. from solutions and random points
    finally:
        if search.bar is not None:
            search.bar.close()
    return search.result(t_begin)


class _Search:
    """The state of :func:`explore`: the solutions found, how often each was met, used as a
    start and met since the last new one, and the search's statistics."""

    def __init__(self, model, theta0, rng, scale, arc_budget, deadline, backend, bar) -> None:
        self.model, self.theta0, self.rng, self.scale = model, theta0, rng, scale
        self.arc_budget, self.deadline, self.backend, self.bar = arc_budget, deadline, backend, bar
        self.tol_same = 1e-6 * scale
        self.act = _actuator_scale(model)
        self.sols: list[Configuration] = []
        self.feats: list[np.ndarray] = []
        self.met: list[int] = []
        self.since: list[int] = []  # times met since the last new solution
        self.used: list[int] = []  # times used as a start
        self.out = ModeSearch(solutions=[])
        self.sampler = RandomStarts(model, rng, theta0)

    def _known(self, y: np.ndarray) -> tuple[np.ndarray, int | None]:
        """(features of y, index of the known solution within tol_same of it or None)."""
        f = features(self.model, y)
        if self.feats:
            dist = np.max(np.abs(np.vstack(self.feats) - f), axis=1)
            i = int(np.argmin(dist))
            if dist[i] <= self.tol_same:
                return f, i
        return f, None

    def record(self, curve: Curve, origin: int) -> int:
        """Keep the new solutions a curve met; returns their number."""
        new = 0
        seen: set[int] = set()
        for y in curve.hits:
            f, i = self._known(y)
            if i is not None:
                seen.add(i)
                continue
            cfg = self.model.configuration(y, self.theta0)
            if not cfg.residual <= self.model.tolerance:
                continue
            self.sols.append(cfg)
            self.feats.append(f[0])
            self.met.append(0)
            self.since.append(0)
            self.used.append(0)
            seen.add(len(self.sols) - 1)
            new += 1
        for i in seen - {origin}:
            self.met[i] += 1
            self.since[i] += 1
        self.out.curves += 1
        if new:
            self.since[:] = [0] * len(self.since)
        self.out.steps += curve.steps
        self.out.arc += curve.arc
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix(solutions=len(self.sols), refresh=False)
        return new

    def both_ways(self, theta1, dtheta, y, s, origin, max_hits=math.inf) -> int:
        """The curve through ``(y, s)`` on the line ``theta1 + s dtheta``, followed each way
        (the second way skipped where the first closed or ran out of time)."""
        new = 0
        for direction in (1.0, -1.0):
            options = CurveOptions(max_arc=self.arc_budget, deadline=self.deadline,
                                   backend=self.backend, max_hits=max_hits)  # fmt: skip
            curve = follow_curve(self.model, theta1, dtheta, y, s, direction, options)
            new += self.record(curve, origin)
            if (curve.closed and not curve.reversed) or curve.timed_out:
                break
        return new

    def from_starts(self, starts: Sequence[Configuration]) -> None:
        """Each start's curve on its line to ``theta0`` (a start at ``theta0`` is a solution)."""
        for st in starts:
            dtheta = self.theta0 - st.theta
            if float(np.linalg.norm(dtheta)) <= 1e-12 * max(
                1.0, float(np.linalg.norm(self.theta0))
            ):
                self.record(Curve(hits=[np.array(st.y)]), -1)
                continue
            self.both_ways(st.theta, dtheta, st.y, 0.0, -1)

    def from_solution(self) -> int:
        """The curve of the least used solution on a random line through ``theta0``."""
        i = int(np.argmin(self.used))
        self.used[i] += 1
        d = self.rng.normal(size=self.model.k) * self.act
        d *= 0.5 * self.scale / float(np.linalg.norm(d))
        self.out.lines += 1
        return self.both_ways(self.theta0 - d, d, self.sols[i].y, 1.0, i)

    def from_random(self) -> int:
        """The paper's two answers (first crossing each way) from a random assembled point."""
        known = np.vstack(self.feats) if self.feats else np.zeros((0, 0))
        drawn = self.sampler.next(known, 0.25 * self.scale)
        self.out.random_starts += 1
        if drawn is None:
            self.out.curves += 1  # counted, so that a failing sampler cannot loop forever
            return 0
        return self.both_ways(drawn.theta, self.theta0 - drawn.theta, drawn.y, 0.0, -1,
                              max_hits=1)  # fmt: skip

    def alternate(self, patience: int, cover: int, max_curves: int) -> None:
        """Alternately from a known solution on a random line through theta0, and from a
        random assembled configuration on the line to theta0, until neither kind has found
        anything new for ``patience`` curves (and every solution was met ``cover`` times)."""
        out = self.out
        idle = {"line": 0, "random": 0}
        while out.curves < max_curves and time.perf_counter() < self.deadline:
            if self.sols and min(idle.values()) >= patience and min(self.since) >= cover:
                out.complete = True
                break
            if not self.sols and out.random_starts >= max(8, 4 * patience):
                out.complete = True  # nothing reaches theta0 from anywhere tried
                break
            kind = "line" if self.sols and idle["line"] <= idle["random"] else "random"
            new = self.from_solution() if kind == "line" else self.from_random()
            if new:
                idle = dict.fromkeys(idle, 0)
                out.last_new = (out.lines, out.random_starts)
            else:
                idle[kind] += 1

    def result(self, t_begin: float) -> ModeSearch:
        """The search's record, the solutions in their canonical order."""
        order = sorted(range(len(self.sols)), key=lambda i: mode_order(self.sols[i]))
        self.out.solutions = [self.sols[i] for i in order]
        self.out.met = [self.met[i] for i in order]
        self.out.elapsed = time.perf_counter() - t_begin
        return self.out


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


def curves_result(search: ModeSearch) -> AssemblyModes:
    """The :class:`~scdk_sym.results.AssemblyModes` of a curve search (never certified)."""
    why = "the stopping rule held" if search.complete else "stopped by the budget"
    return AssemblyModes(
        solutions=tuple(search.solutions),
        certified=False,
        root_count=0,
        report=(
            f"not certified: real-curve search ({search.curves} curves, {why}); it cannot "
            "prove that no solution lies on a curve it never entered"
        ),
        method="curves",
    )
