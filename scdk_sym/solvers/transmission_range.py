"""A certified range of a leg's motor <-> joint map: proven invertible, with no singular
configuration, over a box of output joint values.

For a box ``B`` of outputs (an ankle's pitch and roll limits), with the map's inverse model
``g_inv(z, q_out) = 0`` (unknowns ``z``: the motors and the passive joints; parameters: the
outputs):

1. the Krawczyk test (as :func:`scdk_sym.algebraic.certify.krawczyk`, in outward-rounded
   ball arithmetic; the parameters in mean-value form), stage after stage of the inverse
   model's block-triangular decomposition, with the outputs (and the earlier stages'
   enclosures) as a parameter box, proves that for every ``q_out`` in ``B`` exactly one
   solution lies in a box ``X``, inside the enclosure ``K(X)``; its contraction
   ``|I - Y J(X)| < 1`` proves ``d g_inv / d z`` nonsingular over it (the inverse map is
   defined and smooth);
2. each block of the forward model's ``J_p`` (motors held; the stages of its block-triangular
   decomposition) is evaluated in ball arithmetic over that enclosure and ``B``,
   preconditioned by the inverse of its midpoint ``Y``: ``|I - Y J_p|_inf <= d < 1`` proves
   every matrix of the enclosure nonsingular, and ``sigma_min >= (1 - d) / (sqrt(m)
   |Y|_inf)``.

Both regular means the map is invertible on ``B`` with no singular configuration (a singular
``d outputs / d theta`` with both regular would give a motion of the mechanism with the outputs
held, against (1)). Where a box is not proven it is halved along its widest output, down to a
depth; the boxes left are those that may hold a singular configuration (or that the test could
not decide at that size).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from flint import arb
from numpy.typing import ArrayLike

from ..algebraic.interval import interval_function
from ..errors import InputError, ScdkError
from ..results import frozen_array

#: Halvings of the box before a part is left undecided.
DEPTH = 6
#: Boxes tested at most.
MAX_BOXES = 200
#: Largest step of the outputs between two solutions along the path to a box's centre [rad].
STEP = 0.02


@dataclass(frozen=True)
class RangeCertificate:
    """The outcome of :func:`certify_range`.

    Attributes:
        proven: every part of the box is proven (the map is invertible with no singular
            configuration over the whole box).
        lower: (n,) the box's lower output values [rad or length unit].
        upper: (n,) its upper values.
        boxes: (B, n, 2) the proven parts ``[lo, hi]``.
        open_boxes: (U, n, 2) the parts not proven: they may hold a singular configuration.
        sigma_lower: a lower bound of the smallest singular value of each block of the
            forward ``J_p`` (the stages of the leg: its knee loop, its ankle) over the proven
            parts (0 when none is) [closure unit per joint unit].
        margin_lower: ``sigma_lower`` over an upper bound of the largest singular value: a
            lower bound of the map's forward margin (:meth:`Transmission.margin`'s ``J_p``
            part) [1].
        reasons: why each open part is open.
    """

    proven: bool
    lower: np.ndarray
    upper: np.ndarray
    boxes: np.ndarray
    open_boxes: np.ndarray
    sigma_lower: float
    margin_lower: float
    reasons: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        for name in ("lower", "upper", "boxes", "open_boxes"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))

    def contains_open(self, q_out: ArrayLike) -> bool:
        """Whether ``q_out`` lies in an open part."""
        q = np.asarray(q_out, dtype=float)
        return bool(any(np.all((b[:, 0] <= q) & (q <= b[:, 1])) for b in self.open_boxes))


def _up(a: arb) -> float:
    return float(a.mid()) + float(a.rad()) if a.is_finite() else math.inf


def _mat(flat: list[arb], rows: int, cols: int) -> list[list[arb]]:
    """A column-major list of balls as rows of balls."""
    return [[flat[i + rows * j] for j in range(cols)] for i in range(rows)]


def _matvec(A: np.ndarray | list, x: list[arb]) -> list[arb]:
    return [sum((arb(float(a)) * v if not isinstance(a, arb) else a * v
                 for a, v in zip(row, x, strict=True)), arb(0)) for row in A]  # fmt: skip


def _parametric_krawczyk(
    F, n: int, z: np.ndarray, P: list[arb], tries: int = 6
) -> tuple[list[arb] | None, str]:
    """The Krawczyk test of ``g(z, p) = 0`` for every ``p`` in the balls ``P``, with the
    parameters in mean-value form (``g(m, P) in g(m, p_c) + G_p(m, P) (P - p_c)``: the width
    of the parameters enters linearly, not through every operation of the kinematic chain).

    Args:
        F: the ball replay of ``(z, p) -> (g, dg/dz, dg/dp)``.
        n: unknowns.
        z: (n,) an approximate zero at the parameters' centres.
        P: the parameter balls.

    Returns:
        ``(enclosure, reason)``: the balls ``K(X)`` holding the one zero of each ``p`` (and
        ``dg/dz`` proven nonsingular over ``X``), or ``None`` and why not.
    """
    pc = [arb(p.mid()) for p in P]
    dP = [p - c for p, c in zip(P, pc, strict=True)]
    mz = [arb(float(v)) for v in z]
    g_c, J_c, _ = F(mz, pc)
    Jm = np.array([[float(a.mid()) for a in row] for row in _mat(J_c, n, n)])
    try:
        Y = np.linalg.inv(Jm)
    except np.linalg.LinAlgError:
        return None, "dg/dz singular at the centre"
    _, _, Gp_m = F(mz, P)
    Gp = _mat(Gp_m, n, len(P))
    # the Newton point's ball: Y g(m, p_c) + Y G_p(m, P) (P - p_c)
    shift = [a + b for a, b in zip(_matvec(Y, g_c), _matvec(Y, _matvec(Gp, dP)), strict=True)]
    r = np.array([2 * _up(abs(v)) + 1e-14 * max(1.0, abs(float(c))) for v, c in zip(shift, z,
                  strict=True)])  # fmt: skip
    for _ in range(tries):
        X = [arb(float(c), float(w)) for c, w in zip(z, r, strict=True)]
        _, JX, GpX = F(X, P)
        A = _mat(JX, n, n)
        YA = [[sum((arb(float(Y[i, k])) * A[k][j] for k in range(n)), arb(0)) for j in range(n)]
              for i in range(n)]  # fmt: skip
        C = [[(arb(1) if i == j else arb(0)) - YA[i][j] for j in range(n)] for i in range(n)]
        norm = max(sum(_up(abs(c)) for c in row) for row in C)
        if not norm < 1:
            return None, f"I - Y dg/dz does not contract over X (norm <= {norm:.2g})"
        # the parameter term over X too (mean value between the centre and any point of X x P)
        GpXm = _mat(GpX, n, len(P))
        term = _matvec(Y, _matvec(GpXm, dP))
        dX = [x - arb(float(c)) for x, c in zip(X, z, strict=True)]
        K = [arb(float(c)) - a - b + d for c, a, b, d in
             zip(z, _matvec(Y, g_c), term, _matvec(C, dX), strict=True)]  # fmt: skip
        if all(x.contains_interior(k) for x, k in zip(X, K, strict=True)):
            return K, "K(X) inside X"
        r = np.maximum(r, 1.5 * np.array([_up(abs(k - arb(float(c)))) for k, c in
                                          zip(K, z, strict=True)]))  # fmt: skip
    return None, f"K(X) not inside X after {tries} boxes (radius {float(r.max()):.1e})"


class _Prover:
    """The two tests on one box of outputs, stage by stage."""

    def __init__(self, T: Any) -> None:
        inv, fwd = T.inverse_model, T.model
        if inv.chart.size or fwd.chart.size:
            raise InputError(
                "certify_range: the model has ball or free unknowns (a rotation chart); "
                "the certified range covers mechanisms of revolute and prismatic joints"
            )
        self.T, self.inv, self.fwd = T, inv, fwd
        self.inv_stages = [(s, _replay(s, both=True)) for s in inv.stages]
        self.fwd_stages = [(s, _replay(s, both=False)) for s in fwd.stages]

    def centre(self, q_out: np.ndarray) -> dict[str, float]:
        """Every joint coordinate at ``q_out``, continued from home along a line."""
        home = self.inv.home
        n = max(1, int(np.ceil(np.abs(q_out - home.theta).max() / STEP)))
        path = home.theta + np.linspace(0, 1, n + 1)[1:, None] * (q_out - home.theta)
        self.T._inverse.reset()
        self.T.inverse_many(path)
        return dict(self.T._inverse.last.coordinates)

    def test(self, box: np.ndarray) -> tuple[bool, float, float, str]:
        """``(proven, sigma_lower, sigma_upper, reason)`` of one box ``(n, 2)``."""
        try:
            at = self.centre(box.mean(axis=1))
        except Exception as exc:  # noqa: BLE001 - any failure leaves the box open
            return False, 0.0, math.inf, f"no solution reached at its centre ({exc})"
        balls: dict[str, arb] = {n: arb(v) for n, v in self.inv.locked.items()}
        balls.update({n: _ball(box[i]) for i, n in enumerate(self.inv.actuated)})
        for stage, F in self.inv_stages:
            P = [balls[n] for n in stage.actuated]
            K, why = _parametric_krawczyk(F, stage.m, np.array([at[n] for n in stage.unknowns]), P)
            if K is None:
                return False, 0.0, math.inf, f"inverse map, block {list(stage.unknowns)}: {why}"
            balls.update(zip(stage.unknowns, K, strict=True))
        sigma, big = math.inf, 0.0
        for stage, F in self.fwd_stages:
            (J,) = F([balls[n] for n in stage.unknowns], [balls[n] for n in stage.actuated])
            ok, s, b, why = _regular(_mat(J, stage.m, stage.m))
            if not ok:
                return False, 0.0, math.inf, f"forward map, block {list(stage.unknowns)}: {why}"
            sigma, big = min(sigma, s), max(big, b)
        return True, sigma, big, "both maps regular"


def _replay(stage: Any, both: bool) -> Any:
    """The ball replay of a stage's ``(y, theta) -> (g, J_p, dg/dtheta)`` (``both``) or of
    its ``J_p``."""
    s = stage.symbolic
    outs = [s.g, s.J_p, -s.J_s] if both else [s.J_p]
    return interval_function(ca.Function("stage", [s.y, s.theta], outs))


def _regular(A: list[list[arb]]) -> tuple[bool, float, float, str]:
    """Every matrix of the ball matrix ``A`` nonsingular: ``|I - Y A|_inf <= d < 1`` with
    ``Y`` the inverse of its midpoint; ``(ok, sigma_min lower bound, sigma_max upper bound,
    reason)``."""
    m = len(A)
    Amid = np.array([[float(a.mid()) for a in row] for row in A])
    try:
        Y = np.linalg.inv(Amid)
    except np.linalg.LinAlgError:
        return False, 0.0, math.inf, "J_p singular at the box's midpoint"
    d = 0.0
    for i in range(m):
        row = 0.0
        for j in range(m):
            e = sum((arb(float(Y[i, k])) * A[k][j] for k in range(m)), arb(0))
            row += _up(abs((arb(1) if i == j else arb(0)) - e))
        d = max(d, row)
    if not d < 1:
        return False, 0.0, math.inf, f"|I - Y J_p| <= {d:.2g} (not < 1)"
    sigma = (1 - d) / (math.sqrt(m) * float(np.abs(Y).sum(axis=1).max())) * (1 - 1e-12)
    big = math.sqrt(sum(_up(abs(a)) ** 2 for row in A for a in row)) * (1 + 1e-12)
    return True, sigma, big, "regular"


def _ball(bounds: np.ndarray) -> arb:
    lo, hi = float(bounds[0]), float(bounds[1])
    return arb((lo + hi) / 2, (hi - lo) / 2 * (1 + 1e-15) + 1e-300) if hi > lo else arb(lo)


def certify_range(
    T: Any,
    lower: ArrayLike,
    upper: ArrayLike,
    *,
    depth: int = DEPTH,
    max_boxes: int = MAX_BOXES,
) -> RangeCertificate:
    """Prove the map invertible with no singular configuration over a box of outputs.

    Args:
        T: the transmission (:class:`~scdk_sym.solvers.transmission.Transmission`).
        lower: (n,) lower output values [rad or length unit] (an output held at one value:
            equal bounds).
        upper: (n,) upper output values.
        depth: halvings of a part before it is left open.
        max_boxes: parts tested at most.

    Returns:
        The :class:`RangeCertificate`: proven parts, open parts (where a singular
        configuration may lie) and a lower bound of the margin over the proven ones.

    Raises:
        InputError: bounds of the wrong size, not finite, or ``lower > upper``; a model with
            ball or free unknowns.
    """
    n = len(T.outputs)
    lo = np.asarray(lower, dtype=float).reshape(-1)
    hi = np.asarray(upper, dtype=float).reshape(-1)
    if lo.size != n or hi.size != n or not np.all(np.isfinite(lo) & np.isfinite(hi)):
        raise InputError(f"certify_range: lower and upper must be {n} finite values each")
    if np.any(lo > hi):
        raise InputError(f"certify_range: lower > upper at {np.flatnonzero(lo > hi).tolist()}")
    prover = _Prover(T)
    todo = [(np.stack([lo, hi], axis=1), 0)]
    proven, open_boxes, reasons = [], [], []
    sigma, big = math.inf, 0.0
    tested = 0
    while todo:
        box, level = todo.pop(0)
        tested += 1
        ok, s, b, why = prover.test(box) if tested <= max_boxes else (False, 0, 0, "too many")
        if ok:
            proven.append(box)
            sigma, big = min(sigma, s), max(big, b)
            continue
        w = box[:, 1] - box[:, 0]
        if level >= depth or tested > max_boxes or not np.any(w > 0):
            open_boxes.append(box)
            reasons.append(why)
            continue
        i = int(np.argmax(w))
        cut = box[i].mean()
        left, right = box.copy(), box.copy()
        left[i, 1], right[i, 0] = cut, cut
        todo += [(left, level + 1), (right, level + 1)]
    T._inverse.reset()
    sigma = sigma if proven else 0.0
    return RangeCertificate(
        proven=not open_boxes,
        lower=lo,
        upper=hi,
        boxes=np.array(proven).reshape(-1, n, 2),
        open_boxes=np.array(open_boxes).reshape(-1, n, 2),
        sigma_lower=sigma,
        margin_lower=sigma / big if proven and big > 0 else 0.0,
        reasons=tuple(reasons),
    )


@dataclass(frozen=True)
class MarginGrid:
    """A transmission's block margins sampled over a box of two outputs.

    Attributes:
        outputs: the two outputs varied (rows, then columns).
        rows: (n,) values of the first [rad or length unit].
        columns: (n,) values of the second.
        margin: (n, n) the smallest block margin at each point (NaN where the sweep did not
            reach it) [1].
    """

    outputs: tuple[str, str]
    rows: np.ndarray
    columns: np.ndarray
    margin: np.ndarray


def margin_grid(
    T: Any, lower: ArrayLike, upper: ArrayLike, n: int = 25, steps: int = 8
) -> MarginGrid:
    """Sample :meth:`Transmission.margin` over the box's two widest outputs (the others at
    their lower values), row after row in a serpentine with ``steps`` readings at a steady
    rate between two points (as a controller's readings are), continuing from home.

    Raises:
        InputError: fewer than two outputs vary, or ``n < 2``.
    """
    lo = np.asarray(lower, dtype=float).reshape(-1)
    hi = np.asarray(upper, dtype=float).reshape(-1)
    widths = hi - lo
    if n < 2 or np.sum(widths > 0) < 2:
        raise InputError("margin_grid: give a box in which two outputs vary, and n >= 2")
    i, j = (int(k) for k in np.argsort(-widths, kind="stable")[:2])
    rows, cols = np.linspace(lo[i], hi[i], n), np.linspace(lo[j], hi[j], n)
    grid = np.full((n, n), np.nan)
    T.reset()
    last = T.inverse_model.home.theta.copy()
    for r in range(n):
        for c in range(n) if r % 2 == 0 else range(n - 1, -1, -1):
            q = lo.copy()
            q[i], q[j] = rows[r], cols[c]
            try:
                far = max(1, int(np.ceil(np.abs(q - last).max() / STEP)))
                path = last + np.linspace(0, 1, max(steps, far) + 1)[1:, None] * (q - last)
                T.forward_many(T.inverse_many(path))
                grid[r, c] = T.margin().value
                last = q
            except ScdkError:
                continue  # not reached from the last point: left blank
    T.reset()
    return MarginGrid((T.outputs[i], T.outputs[j]), rows, cols, grid)
