"""What a walk along a solution curve is given and what it reports: the line in joint space,
the level crossings met, the walk's report and its sampled path."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..kernels.fastcall import model_calls
from ..results import Crossing, PathSamples


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
    """What :func:`~scdk_sym.follower.curve.follow` met along one curve.

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


@dataclass
class PathRecord:
    """The accepted samples of a walk, kept when it records its path.

    Attributes:
        q: points ``(y local, s)``, each in its chart.
        c: the chart of each point.
        det: ``det J_p`` at each.
        arc: arc length from the start at each [model length unit].
    """

    q: list[np.ndarray] = field(default_factory=list)
    c: list[np.ndarray] = field(default_factory=list)
    det: list[float] = field(default_factory=list)
    arc: list[float] = field(default_factory=list)

    def add(self, q: np.ndarray, c: np.ndarray, det: float, arc: float) -> None:
        """Keep one sample (copies of ``q`` and ``c``)."""
        self.q.append(np.array(q, dtype=float))
        self.c.append(np.array(c, dtype=float))
        self.det.append(float(det))
        self.arc.append(float(arc))

    def samples(self, model, line: Line, direction: float) -> PathSamples:
        """The recorded samples as canonical unknowns, poses and ``det J_p`` along ``line``.

        Args:
            model: the model.
            line: the line the walk followed.
            direction: the walk's orientation (+1 along ``nu``, -1 along ``-nu``).
        """
        Q = np.array(self.q)
        Y = np.array(
            [model.chart.to_canonical(r[:-1], cc) for r, cc in zip(Q, self.c, strict=True)]
        )
        X = []
        for r, cc in zip(Q, self.c, strict=True):
            X.append(np.array(model_calls(model).pose(r[:-1], line.at(r[-1]), cc)[1]).ravel())
        det = np.array(self.det)
        return PathSamples(
            s=Q[:, -1],
            y=Y,
            x=np.array(X),
            det_jp=det,
            sdot=direction * det,
            arc=np.array(self.arc),
        )
