"""The home a model is reduced at: the closure side file's ``home`` checked, a stated home (an
MJCF file's) settled onto the closures (:mod:`scdk_sym.robot.home`), or, without a home, the
neutral configuration projected onto the closures and, when that does not close them, assembled
by continuation from a relaxed closure (:mod:`scdk_sym.robot.assembly`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import NoReturn

import casadi as ca
import numpy as np

from ..errors import NotAssembledError
from ..model.urdf import Tree, slides_along_carrier
from ..symbolic.system import Symbolic, build_symbolic
from . import assembly
from .assembly import assemble, closure_rows, least_squares
from .diagnosis import weld_diagnosis
from .home import settle as settle_home
from .mechanism import REDUNDANT_TOL, Mechanism


@dataclass(frozen=True)
class Start:
    """An assembled start of the square reduction.

    Attributes:
        y: (m,) unknowns, in the chart of the reduction.
        theta: (k,) actuated values [rad or model length unit].
        assembly: how home was assembled (a settled MJCF home, or a continuation from the
            neutral configuration), else ``None``.
        preferred: the closure rows a settled home closes, kept first by the reduction; else
            ``None``.
    """

    y: np.ndarray
    theta: np.ndarray
    assembly: str | None = None
    preferred: tuple[int, ...] | None = None


def project(f_all: ca.Function, y: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Levenberg-Marquardt least squares on the closures over y (theta fixed).

    The verification rows are minimised (for 6d closures the whole ``R_a^T R_b - I``):
    the skew part alone also vanishes at a half turn, a false minimum.

    Every step is a minimum-norm one: it has no component along the directions the
    closures do not see (singular values below ``1e-10`` of the largest). Where the
    closures leave idle freedoms (joints locked at the result), a step along them would be
    driven by rounding alone, and the locked values would depend on the floating-point
    library; this way the result is the same on every machine to rounding.
    """

    def rows(yv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        _, _, g, J, *_ = (np.array(v) for v in f_all(yv, theta))
        return g.ravel(), J

    return least_squares(rows, y)[0]


def start_at_home(
    mech: Mechanism,
    full: Symbolic,
    c0: np.ndarray,
    f_all: ca.Function,
    y0: np.ndarray,
    th0: np.ndarray,
) -> Start:
    """The start ``(y0, th0)`` assembled: a stated MJCF home settled, the spec's home as
    given (refused when it does not close), or assembled from the neutral configuration
    when the spec has no home.

    Args:
        mech: the mechanism.
        full: its unreduced closure system over every candidate unknown.
        c0: the chart of ``y0``.
        f_all: the closure rows of ``full`` in the chart ``c0`` (see
            :func:`~scdk_sym.robot.reduction.closure_function`).
        y0: (m,) unknowns in the chart ``c0``.
        th0: (k,) actuated values [rad or model length unit].

    Raises:
        NotAssembledError: the home does not close, or no start assembles.
    """
    if getattr(mech.source, "settle_home", False):
        return settled(mech, f_all, y0, th0)
    if mech.spec.home:
        check = np.abs(np.array(f_all(y0, th0)[2])).ravel()
        if check.max() > mech.tolerance:
            _refuse(mech, f"'home' is not assembled: {mech.violation(check)} "
                    f"(tolerance {mech.tolerance:.1e})", check)  # fmt: skip
        return Start(y0, th0)
    y0 = mech.project(f_all, y0, th0)
    check = np.abs(np.array(f_all(y0, th0)[2])).ravel()
    if check.max() > mech.tolerance:
        return assembled(mech, full, c0, f_all, y0, th0, check)
    return Start(y0, th0)


def settled(mech: Mechanism, f_all: ca.Function, y0: np.ndarray, th0: np.ndarray) -> Start:
    """A stated home projected onto the closures and moved off a singular configuration
    (see :mod:`scdk_sym.robot.home`), saying what was done."""

    def rows(y, th):
        g, Gy, _, _, Gt, _ = (np.array(v) for v in f_all(y, th))
        return g.ravel(), Gy, Gt

    names = (*mech.candidates, *mech.actuated)
    done = settle_home(rows, y0, th0, names, 1e-2 * mech.tolerance)
    at_home = f_all(done.y, done.theta)
    check = np.abs(np.array(at_home[2])).ravel()
    preferred = None
    if done.subset is not None:  # the rows home closes; the others within rounding
        g = np.abs(np.array(at_home[0]).ravel())
        rest = float(np.delete(g, list(done.subset)).max(initial=0.0))
        preferred = done.subset
        check = g[list(done.subset)] if rest <= REDUNDANT_TOL * mech.length_scale else g
    if check.max() > mech.tolerance:
        _refuse(mech, f"home does not assemble: {mech.violation(check)} after a least-change "
                f"projection over every joint (tolerance {mech.tolerance:.1e}); "
                f"{mech.source.home_hint}", check)  # fmt: skip
    if not done.regular:
        _refuse(mech, f"{done.note}: a start must be regular; give a regular home (MJCF: a "
                "keyframe named 'home') or other inputs (inputs=[...])", check)  # fmt: skip
    return Start(done.y, done.theta, done.note or None, preferred)


def assembled(
    mech: Mechanism,
    full: Symbolic,
    c0: np.ndarray,
    f_all: ca.Function,
    y: np.ndarray,
    theta: np.ndarray,
    check: np.ndarray,
) -> Start:
    """Assemble from the neutral configuration over every joint (actuators too), where a
    least-squares projection with the actuators at zero does not close the loops.

    Returns:
        The assembled unknowns (chart centred at neutral) and actuators, and how.

    Raises:
        NotAssembledError: no seed assembles (says how far the projection got).
    """

    m = y.size
    z0 = np.zeros(m + len(mech.actuated))
    found = assemble(
        lambda start: closure_rows(full, mech.closures, c0, start),
        z0,
        1e-2 * mech.tolerance,
        np.concatenate([y, theta]),
    )
    worst = np.inf
    if found is not None:
        worst = float(np.abs(np.array(f_all(found.z[:m], found.z[m:])[2])).max())
    if found is None or worst > mech.tolerance:
        suspects = slides_along_carrier(mech.tree, mech.actuated)
        hint = "add 'home' to the YAML"
        welds = weld_hint(mech, full, c0, np.concatenate([y, theta]))
        if welds:
            hint = welds
        elif suspects:
            listed = ", ".join(f"{p} along the axis of revolute {r}" for p, r in suspects)
            hint = (
                f"linear actuators that slide only along their own hinge axis ({listed}) "
                "cannot drive a loop: check those joint axes in the URDF, or add 'home'"
            )
        _refuse(mech, "no 'home' given, and the neutral configuration does not assemble "
                f"(least squares: {mech.violation(check)}; continuation from a relaxed closure "
                f"over every joint failed from {assembly.SEEDS + 1} starts); {hint}",
                check)  # fmt: skip
    names = (*mech.candidates, *mech.actuated)
    found = nearest_turns(mech.tree, found, names)
    far = int(np.argmax(np.abs(found.z)))
    start = "the neutral configuration" if found.seed == 0 else f"perturbed seed {found.seed}"
    note = (
        f"assembled from {start} by continuation from a relaxed closure over every joint "
        f"({found.steps} steps, residual {found.residual:.1e}); largest change from neutral "
        f"{found.change:.3g} ({names[far]}); write it as 'home' with `scdk assemble --write`"
    )
    return Start(found.z[:m], found.z[m:], note)


def weld_hint(mech: Mechanism, full: Symbolic, c0: np.ndarray, z: np.ndarray) -> str:
    """A sentence when the welds are what keeps the model from assembling, else empty
    (see :mod:`scdk_sym.robot.diagnosis`); ``full`` is the closure system of ``mech``."""

    def build(closures):
        return build_symbolic(mech.tree, closures, mech.actuated, mech.candidates,
                              mech.held, None, mech.frame, mech.workspace)  # fmt: skip

    return weld_diagnosis(full, build, mech.closures, c0, z, mech.tolerance)


def _refuse(mech: Mechanism, message: str, check: np.ndarray) -> NoReturn:
    """Refuse a start: ``message``, the largest verification row of ``check``."""
    raise NotAssembledError(message, float(check.max()), mech.path)


def nearest_turns(tree: Tree, found: assembly.Assembly, names: Sequence[str]) -> assembly.Assembly:
    """``found`` with each revolute angle replaced by the equivalent one (a whole number
    of turns away) nearest to neutral within the joint's limits (a continuation may wind a
    joint past a turn: -6.08 rad where 0.20 rad is the same configuration and the only one
    within the URDF's limits)."""
    z = found.z.copy()
    joints = {j.name: j for j in tree.joints}
    for i, name in enumerate(names):
        joint = joints.get(name)
        if joint is None or joint.type not in ("revolute", "continuous"):
            continue
        turns = z[i] + 2.0 * np.pi * np.arange(-3, 4)
        inside = turns[(turns >= joint.lower) & (turns <= joint.upper)]
        if inside.size:
            z[i] = inside[np.argmin(np.abs(inside))]
    return replace(found, z=z, change=float(np.abs(z).max()))
