"""Rods between two ball joints, seen as the distance they keep.

A rod carried by a ball joint at each end (each ball written as three revolutes whose axes
meet at its centre, as Gepetto's legged robots write them, or as one spherical joint) and
welded shut by a 6d closure keeps one thing only: the distance between the two centres.
Its five or six angles add nothing but representations: every rotation of a revolute
triple has two angle triples, so a block of two such rods has four times the configurations
of the mechanism, and a start system that many roots.

:func:`find_rods` finds them; :func:`distance_model` is the model with each rod replaced by
one distance row between its ball centres (its unknowns are the rest of the model's); and
:func:`lift` gives a reduced solution its rod angles back, the representation nearest the
model's home. The assembly modes of a model with rods are those of its distance model, one
configuration per assembly of its links (:func:`scdk_sym.solvers.block_modes`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels.fastcall import model_calls
from ..model.spec import Closure
from ..model.urdf import Joint
from ..products import ROD_REDUCTION
from .model import Model

#: Largest distance of a ball's revolute axis from the ball's centre, relative to the model's
#: size, for the triple to be a ball.
CONCURRENT_TOL = 1e-9
#: Smallest singular value of a ball's three unit axes (at home) for the triple to span every
#: rotation there.
INDEPENDENT_TOL = 1e-3
#: Gauss-Newton steps of one rod's angles (:func:`lift`) from one seed.
LIFT_STEPS = 30
#: Seeds of one rod's angles tried by :func:`lift` after the home values.
LIFT_SEEDS = 24


@dataclass(frozen=True)
class Rod:
    """A rod between two ball joints, closed by one 6d closure.

    Attributes:
        closure: index into ``model.closures`` of the weld.
        joints: the revolute joints of both balls (tree joints, locked ones included).
        centres: the links whose origins are the ball centres (side a, side b).
        length: distance between the centres [model length unit].
    """

    closure: int
    joints: tuple[str, ...]
    centres: tuple[str, str]
    length: float


def _ball(
    side: list[Joint], axes: dict[str, np.ndarray], scale: float, spins: set[str]
) -> list[Joint] | None:
    """The ball ending a loop side, with only fixed joints after it: a spherical joint, a
    ball whose spin was locked by turning it into a universal joint (``<ball>_U1``,
    ``<ball>_U2``, see :func:`~scdk_sym.robot.locking.lock_spins`), or three revolutes with
    axes through one point that span every rotation; else ``None``."""
    movable = [i for i, j in enumerate(side) if j.movable]
    if not movable:
        return None
    if side[movable[-1]].type == "spherical":
        return [side[movable[-1]]]
    size = 2 if side[movable[-1]].name.removesuffix("_U2") in spins else 3
    if len(movable) < size or movable[-size] != movable[-1] - size + 1:
        return None
    run = side[movable[-size] : movable[-1] + 1]
    if any(j.type not in ("revolute", "continuous") for j in run):
        return None
    if any(np.linalg.norm(j.origin[:3, 3]) > CONCURRENT_TOL * scale for j in run[1:]):
        return None
    A = np.array([axes[j.name] for j in run])
    if np.linalg.svd(A, compute_uv=False)[-1] < INDEPENDENT_TOL:
        return None
    return run


def find_rods(model: Model) -> tuple[Rod, ...]:
    """The rods between balls of ``model``: 6d closures whose two loop sides each end in a
    ball whose joints are unknowns or locked, nothing else (no other closure frame, no
    reported frame) carried past either ball."""
    tree = model.tree
    home = model.placements(model.home)
    axes = {}
    for j in tree.joints:
        if j.type in ("revolute", "continuous"):
            axes[j.name] = home[j.child][:3, :3] @ np.asarray(j.axis, dtype=float)
    free = set(model.unknowns) | set(model.locked)
    frames = {c.frame_a for c in model.closures} | {c.frame_b for c in model.closures}
    spins = set(model.spins)
    rods = []
    for ci, c in enumerate(model.closures):
        if c.type != "6d":
            continue
        pa, pb = tree.path(c.frame_a), tree.path(c.frame_b)
        common = 0
        while common < min(len(pa), len(pb)) and pa[common].name == pb[common].name:
            common += 1
        ball_a = _ball(pa[common:], axes, model.length_scale, spins)
        ball_b = _ball(pb[common:], axes, model.length_scale, spins)
        if ball_a is None or ball_b is None:
            continue
        balls = (ball_a, ball_b)
        joints = [j for b in balls for j in b]
        if any(set(j.coordinates) - free for j in joints):
            continue
        carried = tree.subtree(balls[0][0].child) | tree.subtree(balls[1][0].child)
        if (frames - {c.frame_a, c.frame_b}) & carried or model.frame in carried:
            continue
        centres = (balls[0][0].child, balls[1][0].child)
        length = float(np.linalg.norm(home[centres[0]][:3, 3] - home[centres[1]][:3, 3]))
        rods.append(Rod(ci, tuple(j.name for j in joints), centres, length))
    return tuple(rods)


def _closure_rows(model: Model, ci: int) -> list[int]:
    """Indices into the model's kept rows ``g`` of closure ``ci``'s rows."""
    lo, hi = model.row_offsets[ci], model.row_offsets[ci + 1]
    return [i for i, r in enumerate(model.rows) if lo <= r < hi]


def _check_rows(model: Model, ci: int) -> slice:
    """Closure ``ci``'s rows in the model's verification rows (a 6d closure's include its
    whole rotation matrix, so a weld closed with a half turn is no closure)."""
    size = [c.rows + (9 if c.type == "6d" else 0) for c in model.closures]
    return slice(sum(size[:ci]), sum(size[: ci + 1]))


def _rod_unknowns(model: Model, rod: Rod) -> list[int]:
    """Indices into ``model.unknowns`` of a rod's unknown coordinates."""
    names = {c for j in rod.joints for c in model.tree.joint(j).coordinates}
    return [i for i, n in enumerate(model.unknowns) if n in names]


def distance_model(model: Model, rods: tuple[Rod, ...]) -> Model | None:
    """``model`` with each rod replaced by a distance closure between its ball centres and
    its angles held at home; ``None`` when that system is not square (a weld whose rows the
    reduction thinned, or a rod with other than one row more than its unknowns)."""
    held = dict(model.locked)
    gone: set[int] = set()
    for rod in rods:
        cols = _rod_unknowns(model, rod)
        if len(_closure_rows(model, rod.closure)) != len(cols) + 1:
            return None
        gone.update(cols)
        held.update({model.unknowns[i]: float(model.home.y[i]) for i in cols})
    unknowns = tuple(n for i, n in enumerate(model.unknowns) if i not in gone)
    welds = {rod.closure for rod in rods}
    closures: list[Closure] = []
    rows: list[int] = []
    unchecked: list[int] = []
    start = 0
    for ci, c in enumerate(model.closures):
        if ci in welds:
            continue
        lo = int(model.row_offsets[ci])
        rows += [start + r - lo for r in model.rows if lo <= r < lo + c.rows]
        unchecked += [start + r - lo for r in model.unchecked if lo <= r < lo + c.rows]
        closures.append(c)
        start += c.rows
    for rod in rods:
        closures.append(Closure(*rod.centres, "distance", rod.length))
        rows.append(start)
        start += 1
    if len(rows) != len(unknowns) or not unknowns:
        return None
    sub = Model.restricted(
        model, unknowns, model.actuated, tuple(closures), tuple(rows), held,
        model.block if model.block is not None else (0, None), tuple(unchecked),
    )  # fmt: skip
    sub._restriction = (*model._restriction, "rods", *(c.label for c in closures))
    return sub


def rod_reduction(model: Model) -> tuple[tuple[Rod, ...], Model | None]:
    """``(rods, distance model)`` of ``model`` (:func:`find_rods`, :func:`distance_model`);
    the distance model is ``None`` without rods or when it is not square. Built once per
    model (``model.products``)."""

    def build() -> tuple[tuple[Rod, ...], Model | None]:
        rods = find_rods(model)
        return rods, (distance_model(model, rods) if rods else None)

    return model.products.get(ROD_REDUCTION, build)


def lift(model: Model, rods: tuple[Rod, ...], reduced: Model, y: np.ndarray, theta: np.ndarray,
         seed: int = 0) -> np.ndarray | None:  # fmt: skip
    """The model's canonical unknowns at a solution ``y`` of its distance model, every rod's
    angles seated from their home values (:func:`seat`); ``None`` if a rod does not close
    (its ball centres are not at its length).

    Args:
        model: the model.
        rods: its rods (:func:`find_rods`).
        reduced: its distance model (:func:`distance_model`).
        y: (reduced.m,) canonical unknowns of the distance model.
        theta: (model.k,) actuated values [rad or model length unit].
        seed: seed of the random starts.
    """
    full = np.array(model.home.y, dtype=float)
    full[[model.unknowns.index(n) for n in reduced.unknowns]] = y
    return seat(model, rods, full, theta, full, seed)


def seat(model: Model, rods: tuple[Rod, ...], y: np.ndarray, theta: np.ndarray,
         near: np.ndarray, seed: int = 0) -> np.ndarray | None:  # fmt: skip
    """``y`` with every rod's angles solved again by Gauss-Newton on its weld's rows, from
    their values in ``near`` first, then from seeded random angles: the first that closes the
    weld (its whole rotation matrix checked) is kept. From a configuration ``near`` on the
    same motion this is the representation of the balls' angles that continues it (the sign
    of ``det J_p`` depends on that representation). ``None`` if a rod does not close.

    Args:
        model: the model.
        rods: its rods (:func:`find_rods`).
        y: (m,) canonical unknowns; the rods' angles are replaced.
        theta: (k,) actuated values [rad or model length unit].
        near: (m,) canonical unknowns whose rod angles are the first seed.
        seed: seed of the random starts.
    """
    full = np.array(y, dtype=float)
    calls = model_calls(model)
    rng = np.random.default_rng(seed)
    for rod in rods:
        cols, rows = _rod_unknowns(model, rod), _closure_rows(model, rod.closure)
        check = _check_rows(model, rod.closure)
        first = np.asarray(near, dtype=float)[cols]
        seeds = [first] + [first + rng.uniform(-np.pi, np.pi, len(cols)) for _ in range(LIFT_SEEDS)]
        for s in seeds:
            z = full.copy()
            z[cols] = s
            for _ in range(LIFT_STEPS):
                loc, c = model.chart.to_local(z)
                g = np.array(calls.g(loc, theta, c)).ravel()[rows]
                if np.max(np.abs(g)) <= 1e-3 * model.tolerance:
                    break
                J = np.array(calls.jac(loc, theta, c)[0])[np.ix_(rows, cols)]
                loc[cols] -= np.linalg.lstsq(J, g, rcond=None)[0]
                z = model.chart.to_canonical(loc, c)
            loc, c = model.chart.to_local(z)
            closed = np.abs(np.array(calls.check(loc, theta, c)).ravel()[check])
            if np.max(closed) <= model.tolerance:
                full = z
                break
        else:
            return None
    return full
