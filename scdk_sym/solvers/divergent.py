"""The divergent branch: the solution across the nearest singular surface.

The branch tries declared ways in order (:data:`DIVERGENT_STRATEGIES`, each with when it
applies, what its answer is and the case that needs it); the first verified answer that
crossed a singular point and differs from the convergent answer is kept, and every answer is
checked against its crossings (:func:`~scdk_sym.follower.finish.parity_checked`).
:class:`_DivergentSearch` holds what the ways share; the convergent answers they compare with
or continue from come from the public solve, handed in by its caller.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..errors import PathError, ScdkError
from ..follower.finish import parity_checked
from ..results import Configuration, Crossing, SolveResult
from .divergent_modes import across_by_modes
from .line import along_line
from .query import Query, same_theta
from .result import is_same_side, joined, on_path, same_configuration, solve_result


@dataclass(frozen=True)
class Strategy:
    """One way of the divergent branch: a method of :class:`_DivergentSearch`.

    Attributes:
        name: what :attr:`SolveResult.strategy` reports when it answers.
        when: when it applies (otherwise it returns nothing and says why).
        guarantees: what an answer of it is.
        case: the case that needs it (the one earlier ways miss).
    """

    name: str
    when: str
    guarantees: str
    case: str


#: The divergent branch's ways, tried in order; the first verified answer that crossed a
#: singular point and differs from the convergent answer is kept (every answer is checked
#: against its crossings: ``parity_checked``).
DIVERGENT_STRATEGIES: tuple[Strategy, ...] = (
    Strategy(
        "paper",
        "the line away from theta0 turns within one |theta0 - theta1| of the start",
        "the paper's divergent path: back through the start's theta on the other sheet, then "
        "the convergent path to theta0",
        "the paper's example (planar_hexa)",
    ),
    Strategy(
        "nearest",
        "a singular configuration is found near the start on its manifold",
        "the solution at theta0 on the other side of the nearest singular configuration, "
        "nearest to it",
        "where the paper's line does not turn near: revolute actuators whose line wraps round, "
        "theta0 equal to the start's theta, starts on either side of a nearby singular surface",
    ),
    Strategy(
        "aimed",
        "a line aimed at the singular surface reaches it",
        "the convergent path from the mirror point across the surface reached",
        "no case pinned by a test of its own yet",
    ),
    Strategy(
        "straight",
        "theta0 differs from the start's theta",
        "the paper's literal straight path in the divergent direction, however far",
        "no case pinned by a test of its own yet",
    ),
    Strategy(
        "modes",
        "every real solution at theta0 is certified complete",
        "among every real solution, the one across the nearest singular configuration "
        "nearest to it",
        "the Delta's mirror assembly above its base",
    ),
    Strategy(
        "along-axes",
        "a singular surface is met along an actuator's own axis",
        "the convergent path from the mirror point across that surface",
        "Gepetto's cassie_like (a non-singular valley of sigma_min around the start)",
    ),
)


def divergent(
    query: Query, sign: float, nu: np.ndarray | None, solve: Callable[..., SolveResult]
) -> SolveResult:
    """The solution across the nearest singular surface: the first answer of the ways of
    :data:`DIVERGENT_STRATEGIES`, in order, named in its ``strategy``.

    Args:
        query: the checked query.
        sign: the sign of ``det J_p`` at the start.
        nu: the unit SC vector at the start, when known.
        solve: the public solve (:func:`scdk_sym.solvers.solve.solve`), called for the
            convergent answers the ways compare with or continue from.

    Raises:
        PathError: no way answered (each one's reason in the message).
    """
    theta0 = query.theta0
    search = _DivergentSearch(query, sign, nu, solve)
    for strategy in DIVERGENT_STRATEGIES:
        res = getattr(search, "way_" + strategy.name.replace("-", "_"))()
        if res is not None:
            return replace(res, strategy=strategy.name)
    raise PathError(
        f"divergent branch at theta0={theta0.tolist()}: no solution across a singular surface "
        f"was reached ({'; '.join(search.tried)}); every real solution: "
        "sc.assembly_modes(model, theta0)"
    )


class _DivergentSearch:
    """What the ways of the divergent branch share: the query, the convergent answer
    (computed once, when a way needs it), the nearest singular configuration (located once)
    and why each way failed (``tried``)."""

    def __init__(
        self, query: Query, sign: float, nu: np.ndarray | None, solve: Callable[..., SolveResult]
    ) -> None:
        self.query, self.solve = query, solve
        self.model, self.theta0, self.start = query.model, query.theta0, query.start
        self.backend, self.max_arc = query.backend, query.max_arc
        self.record_path, self.sign, self.nu = query.record_path, sign, nu
        self.tried: list[str] = []
        self._memo: list[SolveResult | None] = []
        self._near: list = []  # [fold, beside] once located

    # ------------------------------------------------------------------ shared pieces

    def convergent(self) -> SolveResult | None:
        """The convergent answer at ``theta0`` (None where it fails), computed once."""
        if not self._memo:
            try:
                self._memo.append(
                    self.solve(self.model, self.theta0, start=self.start, branch="convergent",
                               backend=self.backend, max_arc=self.max_arc, record_path=False)
                )  # fmt: skip
            except ScdkError:
                self._memo.append(None)
        return self._memo[0]

    def nearest(self) -> tuple[Crossing | None, Configuration | None]:
        """The nearest singular configuration to the start and, where branches cross there,
        the convergent answer to exclude (any other solution is on its other side)."""
        from ..follower.nearest import nearest_singular

        if not self._near:
            fold = nearest_singular(self.model, self.start, self.backend)
            beside = None
            if fold is not None and fold.kind == "bifurcation":
                conv = self.convergent()
                beside = None if conv is None else conv.configuration
            self._near = [fold, beside]
        return self._near[0], self._near[1]

    def other_than_convergent(self, res: SolveResult | None, how: str) -> SolveResult | None:
        """``res`` if it crossed a singular point, its crossings account for its side and it
        is not the convergent answer; else None, the reason in ``tried``."""
        model, start = self.model, self.start
        if res is None:
            return None
        if not res.crossings:
            self.tried.append(f"{how}: no singular point crossed")
            return None
        try:  # the crossings reported must account for the answer's side
            res = parity_checked(model, res, self.sign)
        except PathError as exc:
            self.tried.append(f"{how}: {exc}")
            return None
        # through folds only, det J_p has the start's sign at the convergent answer (an even
        # number of turns) and the other one here (odd): they differ; across crossing
        # branches, compare with the convergent answer itself
        folds_only = all(c.kind == "fold" for c in res.crossings) and len(res.crossings) % 2
        if folds_only and not is_same_side(model, start, res):
            return res
        conv = self.convergent()
        if conv is not None and same_configuration(model, res, conv):
            self.tried.append(f"{how}: came back to the convergent solution")
            return None
        return res

    def from_mirror(self, other, how: str) -> SolveResult | None:
        """The convergent path to ``theta0`` from the mirror point ``other`` across a
        singular surface, the crossing prepended."""
        try:
            res = self.solve(self.model, self.theta0, start=other.start, branch="convergent",
                             backend=self.backend, max_arc=self.max_arc,
                             record_path=self.record_path)  # fmt: skip
        except ScdkError as exc:
            self.tried.append(f"{how}: {exc}")
            return None
        path = res.path
        if other.path is not None and path is not None:
            path = joined(other.path, path, -self.sign)
        out = SolveResult(
            x=res.x, y=res.y, theta=res.theta, platform_pose=res.platform_pose,
            joints=res.joints, residual=res.residual,
            crossings=(on_path(other.crossing, self.start, self.theta0), *res.crossings),
            status=res.status, branch="divergent", b=-self.sign, start=self.start, path=path,
        )  # fmt: skip
        return self.other_than_convergent(out, how)

    def across_from(self, near, exclude, how: str) -> SolveResult | None:
        """The solution at ``theta0`` on the other side of the singular configuration
        ``near`` (found from the start), crossed on the way from the start."""
        from ..follower.other_sheet import across_fold

        model, theta0, start = self.model, self.theta0, self.start
        leg = across_fold(model, start, near, theta0, backend=self.backend, exclude=exclude)
        if leg is None:
            self.tried.append(f"{how}: no solution")
            return None
        cfg, met = leg
        crossings = (on_path(near, start, theta0), *met)
        res = solve_result(model, cfg.y, theta0, crossings, "divergent", -self.sign, start, None)
        return self.other_than_convergent(res, how)

    # ------------------------------------------------------------------ the ways

    def way_paper(self) -> SolveResult | None:
        from ..follower.singular import across

        other = across(self.model, self.start, first=self.start.theta - self.theta0,
                       backend=self.backend, record=self.record_path,
                       paper_only=True)  # fmt: skip
        return None if other is None else self.from_mirror(other, "along the paper's path")

    def way_nearest(self) -> SolveResult | None:
        fold, beside = self.nearest()
        if fold is None:
            self.tried.append("no singular configuration found near the start")
            return None
        return self.across_from(fold, beside,
                                "across the nearest singular configuration")  # fmt: skip

    def way_aimed(self) -> SolveResult | None:
        from ..follower.singular import across

        other = across(self.model, self.start, backend=self.backend)
        if other is None:
            self.tried.append("no singular surface reached by aiming at it")
            return None
        return self.from_mirror(other, "from across the surface aimed at")

    def way_straight(self) -> SolveResult | None:
        if same_theta(self.theta0, self.start.theta):
            return None
        try:
            res = along_line(self.query, self.sign, -self.sign, "divergent", self.nu)
        except PathError as exc:
            self.tried.append(f"along the straight path: {exc}")
            return None
        return self.other_than_convergent(res, "along the straight path")

    def way_modes(self) -> SolveResult | None:
        fold, _ = self.nearest()
        return across_by_modes(self.model, self.theta0, self.start, self.sign, fold,
                                self.convergent, self.backend, self.tried)  # fmt: skip

    def way_along_axes(self) -> SolveResult | None:
        from ..follower.singular import across_axes

        other = across_axes(self.model, self.start, backend=self.backend)
        if other is None:
            self.tried.append("no singular surface met along any actuator's axis")
            return None
        return self.from_mirror(other, "from across the surface met along an actuator's axis")
