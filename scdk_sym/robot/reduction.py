"""The square reduction: a closure system that is not square as written (redundant rows, idle
freedoms) reduced at home to an independent square one (pivoted selections of rows and
unknowns), the idle joints locked there (:mod:`scdk_sym.robot.locking`), and the dropped
redundant rows checked against the kept ones."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NoReturn

import casadi as ca
import numpy as np

from ..errors import NonSquareSystemError
from ..model.chart import Chart
from ..symbolic.system import Symbolic, build_symbolic
from .home_assembly import Start, start_at_home
from .locking import judge_idle, lock_spins, null_space
from .mechanism import REDUNDANT_TOL, Mechanism


@dataclass(frozen=True)
class Reduction:
    """A mechanism's square closure system at its home.

    Attributes:
        mechanism: the mechanism reduced (its tree with the locked rod spins' balls turned
            into universal joints).
        rows: indices of the closure rows kept.
        unknowns: the unknown joint names kept (y order).
        locked: held and idle joints -> value at home.
        note: one line describing the reduction, or ``None`` when nothing was dropped.
        assembly: how home was assembled, or ``None``.
        spins: ball joint -> (rotation at home (3, 3), spin axis (3,)) of the balls turned
            into universal joints.
        chart: the chart of the unknowns.
        home_y: (m,) canonical unknowns at home.
        home_theta: (k,) actuated values at home.
    """

    mechanism: Mechanism
    rows: tuple[int, ...]
    unknowns: tuple[str, ...]
    locked: dict[str, float]
    note: str | None
    assembly: str | None
    spins: dict[str, tuple[np.ndarray, np.ndarray]]
    chart: Chart
    home_y: np.ndarray
    home_theta: np.ndarray


@dataclass(frozen=True)
class _Selection:
    """The square selection of one pass of the reduction, at its start."""

    mech: Mechanism
    chart: Chart
    c0: np.ndarray
    start: Start
    G: np.ndarray
    rows: list[int]
    keep: list[int]
    rank: int
    note: str | None

    def floating_locked(self) -> list[str]:
        """The chart coordinates (of floating and ball joints) the selection would lock."""
        candidates = self.mech.candidates
        return [candidates[c] for c in range(self.G.shape[1])
                if c not in self.keep and "." in candidates[c]]  # fmt: skip

    def refuse_floating(self, floating: list[str]) -> NoReturn:
        """Refuse a selection that locks the chart coordinates ``floating``."""
        nrows, ncols = self.G.shape
        raise NonSquareSystemError(
            f"{ncols} unknown joints, {nrows} closure rows, rank {self.rank}: the reduction "
            f"would lock floating coordinates {floating}; cannot reduce to a square system",
            nrows,
            ncols,
            self.rank,
            self.mech.path,
        )

    def reduction(
        self, note: str | None, spins: dict[str, tuple[np.ndarray, np.ndarray]]
    ) -> Reduction:
        """The reduction this selection makes, described by ``note``."""
        candidates = self.mech.candidates
        y0, ncols = self.start.y, self.G.shape[1]
        unknowns = tuple(candidates[c] for c in self.keep)
        locked = {
            **self.mech.held,
            **{candidates[c]: float(y0[c]) for c in range(ncols) if c not in self.keep},
        }
        chart = Chart.for_unknowns(unknowns, self.mech.tree.rotation_joints)
        home_y = self.chart.to_canonical(y0, self.c0)[self.keep]
        return Reduction(self.mech, tuple(self.rows), unknowns, locked, note,
                         self.start.assembly, spins, chart, home_y, self.start.theta)  # fmt: skip


def pivoted_selection(M: np.ndarray, count: int) -> list[int]:
    """Indices of ``count`` columns of M chosen by Gram-Schmidt with column pivoting."""
    A = np.array(M, dtype=float)
    chosen: list[int] = []
    for _ in range(count):
        norms = np.linalg.norm(A, axis=0)
        norms[chosen] = -1
        # the first of the columns tied with the largest (to rounding): the two revolutes on
        # one axis at a cut have equal columns, and argmax alone picks one by rounding
        i = int(np.flatnonzero(norms >= norms.max() * (1 - 1e-9))[0])
        chosen.append(i)
        u = A[:, i] / norms[i]
        A = A - np.outer(u, u @ A)
    return sorted(chosen)


def closure_function(full: Symbolic, c0: np.ndarray) -> ca.Function:
    """(y, theta) -> (g_all, dg_all/dy, g_check, dg_check/dy, dg_all/dtheta,
    dg_check/dtheta) of the unreduced closures, in the chart ``c0``."""
    return ca.Function(
        "all",
        [full.y, full.theta],
        [
            ca.substitute(e, full.c, ca.DM(c0))
            for e in (
                full.g_all,
                ca.jacobian(full.g_all, full.y),
                full.g_check,
                ca.jacobian(full.g_check, full.y),
                ca.jacobian(full.g_all, full.theta),
                ca.jacobian(full.g_check, full.theta),
            )
        ],
    )


def reduce_closures(mech: Mechanism) -> Reduction:
    """Reduce the closures of ``mech`` over its candidates to a square system at home:
    redundant rows dropped, idle joints locked, the assembled home kept. When the reduction
    would lock the coordinates of ball joints only (the spin of a rod between two balls),
    those balls become universal joints without the spin and the mechanism is reduced again
    from the same home.

    Raises:
        NonSquareSystemError: the closures do not make a square system of the inputs.
        NotAssembledError: home does not assemble.
    """
    first = _select(mech)
    floating = first.floating_locked()
    balls = sorted({n.partition(".")[0] for n in floating})
    if floating and all(mech.tree.joint(b).type == "spherical" for b in balls):
        canonical = first.chart.to_canonical(first.start.y, first.c0)
        null = null_space(first.G, first.rank)
        tree, spins, values = lock_spins(mech, balls, null, canonical, first.start.theta)
        again = _select(replace(mech, tree=tree), values, first.start)
        if still := again.floating_locked():
            again.refuse_floating(still)
        note = (again.note or "reduced to a square system") + (
            f"; ball joint(s) {', '.join(balls)} turned into universal joints (the spin of a "
            "rod between two ball joints locked at home)"
        )
        return again.reduction(note, spins)
    if floating:
        first.refuse_floating(floating)
    return first.reduction(first.note, {})


def _select(
    mech: Mechanism, values: dict[str, float] | None = None, previous: Start | None = None
) -> _Selection:
    """The square selection at home, or at ``values`` projected onto the closures (a start
    found by a ``previous`` pass, whose assembly note and preferred rows are kept)."""
    candidates = mech.candidates
    full = build_symbolic(mech.tree, mech.closures, mech.actuated, candidates, mech.held,
                          None, mech.frame, mech.workspace)  # fmt: skip
    chart = Chart.for_unknowns(candidates, mech.tree.rotation_joints)
    given = mech.spec.home if values is None else values
    y0 = np.array([given.get(j, 0.0) for j in candidates])
    th0 = np.array([given.get(j, 0.0) for j in mech.actuated])
    y0, c0 = chart.to_local(y0)
    f_all = closure_function(full, c0)
    if previous is None:
        start = start_at_home(mech, full, c0, f_all, y0, th0)
    else:
        start = replace(previous, y=mech.project(f_all, y0, th0), theta=th0)
    G = np.array(f_all(start.y, start.theta)[1])
    rows, keep, rank, note = select_square(mech, full, f_all, G, start, c0)
    return _Selection(mech, chart, c0, start, G, rows, keep, rank, note)


def select_square(
    mech: Mechanism,
    full: Symbolic,
    f_all: ca.Function,
    G: np.ndarray,
    start: Start,
    c0: np.ndarray,
) -> tuple[list[int], list[int], int, str | None]:
    """``(rows, keep, rank, note)``: the closure rows and unknowns of a square system of
    full rank at the start (pivoted selections; chart coordinates of floating and ball
    joints kept first), idle freedoms judged by what they move, and a note saying what
    was dropped and locked (``None`` when nothing was).

    Raises:
        NonSquareSystemError: the closures constrain no unknown, bind the inputs alone, or
            leave freedoms that are not idle.
    """
    nrows, ncols = G.shape
    candidates = mech.candidates
    sv = np.linalg.svd(G, compute_uv=False)
    rank = int(np.sum(sv > 1e-8 * max(1.0, sv[0] if sv.size else 1.0)))
    if rank == 0:
        raise NonSquareSystemError(
            f"the closures do not constrain any unknown joint ({', '.join(candidates)})",
            nrows,
            ncols,
            rank,
            mech.path,
        )
    labels = mech.row_labels()
    check_actuation(mech, G, np.array(f_all(start.y, start.theta)[4]), rank, labels)
    if rank == nrows == ncols:
        return list(range(nrows)), list(range(ncols)), rank, None
    weight = np.ones(nrows)
    if start.preferred is not None:  # rows home closes first (see home_assembly.settled)
        weight[[r for r in range(nrows) if r not in start.preferred]] = 1e-6
    rows = pivoted_selection((G * weight[:, None]).T, rank)
    keep = pivoted_selection(G[rows], rank)
    if any("." in candidates[c] for c in range(ncols) if c not in keep):
        # lock single-coordinate joints: weigh the chart coordinates up so that the
        # pivoting keeps them (a spin is locked at a revolute of its chain)
        weight = np.array([1e3 if "." in n else 1.0 for n in candidates])
        keep = pivoted_selection(G[rows] * weight, rank)
    idle = [c for c in range(ncols) if c not in keep]
    dropped = [labels[r] for r in range(nrows) if r not in rows]
    if idle:
        judge_idle(mech, full, start.y, start.theta, c0, G, rank, dropped)
    parts = [f"{nrows} rows x {ncols} unknowns, rank {rank}"]
    if dropped:
        parts.append(f"dropped {len(dropped)} redundant row(s) {dropped}")
    if idle:
        parts.append(f"locked idle joint(s) {[candidates[c] for c in idle]} at home")
    return rows, keep, rank, "reduced to a square system: " + "; ".join(parts)


def check_actuation(
    mech: Mechanism, G: np.ndarray, G_theta: np.ndarray, rank: int, labels: list[str]
) -> None:
    """Refuse more actuators than the mechanism has freedoms (rows that bind theta alone).

    With ``rank [G, G_theta] > rank G`` at home, some closure rows constrain the actuated
    joints whatever the unknowns: the actuators cannot be set independently and almost
    every ``theta`` has no assembly.
    """
    both = np.hstack([G, G_theta])
    sv = np.linalg.svd(both, compute_uv=False)
    full = int(np.sum(sv > 1e-8 * max(1.0, sv[0] if sv.size else 1.0)))
    if full <= rank:
        return
    nrows, ncols = G.shape
    k = len(mech.actuated)
    dof = ncols + k - full
    # the rows outside the span of G's rows that involve theta
    U, _, _ = np.linalg.svd(G)
    left = U[:, rank:]  # combinations of rows free of y
    bound = [labels[r] for r in range(nrows) if np.abs(left[r]).max() > 1e-6]
    raise NonSquareSystemError(
        f"over-actuated: {k} actuated joints {list(mech.actuated)} but the mechanism "
        f"has {dof} degree(s) of freedom ({ncols} unknown + {k} actuated coordinates, "
        f"{full} independent closure rows, {full - rank} binding the actuators alone: "
        f"{bound}); remove {full - rank} joint(s) from 'name_mot', or check the joint "
        "types (a ball joint written as one revolute over-constrains its loop)",
        nrows,
        ncols,
        rank,
        mech.path,
    )


def inconsistent_rows(
    reduced: Reduction, samples: int = 6, spread: float = 0.5
) -> tuple[tuple[int, ...], str | None]:
    """The dropped redundant rows that disagree with the kept ones by more than the
    tolerance, but within rounding (:data:`REDUNDANT_TOL` of the model size), at home or
    along continuations of the kept rows to seeded inputs up to ``spread`` away, and the
    reduction's note saying what they do. Disagreeing beyond rounding is refused.

    Returns:
        ``(rows, note)``: those rows of the full closure system (none: the note unchanged).

    Raises:
        NonSquareSystemError: a dropped row disagrees beyond rounding.
    """
    mech = reduced.mechanism
    total = int(np.cumsum([0, *[c.rows for c in mech.closures]])[-1])
    dropped = [r for r in range(total) if r not in reduced.rows]
    if not dropped:
        return (), reduced.note
    sym = build_symbolic(mech.tree, mech.closures, mech.actuated, reduced.unknowns,
                         reduced.locked, reduced.rows, mech.frame, mech.workspace)  # fmt: skip
    f = ca.Function("redundant", [sym.y, sym.theta, sym.c], [sym.g, sym.J_p, sym.g_all])
    y0, c = reduced.chart.to_local(reduced.home_y)
    rng = np.random.default_rng(0)
    worst = np.abs(np.array(f(y0, reduced.home_theta, c)[2])).ravel()
    for _ in range(samples):  # a continuation in 10 steps to a random nearby input
        step = spread * rng.standard_normal(len(mech.actuated)) / 10
        y = y0.copy()
        for i in range(1, 11):
            theta = reduced.home_theta + i * step
            for _ in range(12):
                g, J, _ = (np.array(v) for v in f(y, theta, c))
                if np.abs(g).max() < 1e-14 * max(1.0, mech.length_scale):
                    break
                y = y - np.linalg.lstsq(J, g.ravel(), rcond=1e-12)[0]
            else:
                break  # no solution of the kept rows on the way: nothing to compare
            worst = np.maximum(worst, np.abs(np.array(f(y, theta, c)[2])).ravel())
    bad = [r for r in dropped if worst[r] > mech.tolerance]
    if not bad:
        return (), reduced.note
    labels = mech.row_labels()
    big = [labels[r] for r in bad if worst[r] > REDUNDANT_TOL * mech.length_scale]
    if big:
        raise NonSquareSystemError(
            f"redundant closure row(s) {big} disagree with the others by up to "
            f"{worst[bad].max():.2g} away from home: the closures over-constrain the "
            "mechanism beyond rounding; check the file's geometry or lock a joint",
            total,
            len(mech.candidates),
            len(reduced.rows),
            mech.path,
        )
    note = (reduced.note or "reduced to a square system") + (
        f"; redundant row(s) {[labels[r] for r in bad]} disagree with the others by up to "
        f"{worst[bad].max():.2g} (the file's rounding): solved on an independent subset, "
        "those rows left out of the verification"
    )
    return tuple(bad), note
