"""The singularity-consistent (SC) direct-kinematics solver.

Direct kinematics as path tracking (Bhattacharya, Nenchev & Uchiyama): from an assembled
start ``(y1, theta1)``, follow the solution curve of ``g(y, theta1 + s (theta0 - theta1)) = 0``
in ``q = (y, s)`` along the SC field until ``s = 1``. The field is integrated with CasADi's
CVODES in chunks of arc length; every crossing of the singular manifold (``det J_p`` changes
sign, ``s`` turns) is located by Newton on ``[g; t_s] = 0``; each ``s = 1`` crossing is finished
with ``dy/ds = J_p^{-1} j_s`` and a Newton polish, then verified.

:func:`trace` follows the curve and reports every ``s = 1`` crossing it meets (used by the
tracker and the assembly-mode search); :func:`solve` returns the first one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from ..backends import Resolved, resolve
from ..errors import (
    InputError,
    NotAssembledError,
    PathError,
    ScdkError,
    SolveError,
    VerificationError,
)
from ..follower.curve import follow
from ..follower.cvodes import GRID, Engine, engine  # noqa: F401
from ..follower.finish import jacobian, parity_checked, singular_jp, touching
from ..follower.options import FollowOptions
from ..follower.surface import det_sign
from ..follower.tangent import null_direction
from ..follower.walk import Hit, Line, Walk  # noqa: F401
from ..kernels.fastcall import model_calls
from ..results import Configuration, Crossing, PathSamples, SolveResult
from ..robot import Model, as_vector
from .background import without_waiting
from .blocks import solve_blocks
from .solve_c import solve_c


def validate_start(
    model: Model, start: Configuration | None, check_residual: bool = True
) -> Configuration:
    """The start configuration (default home), checked to be assembled."""
    if start is None:
        return model.home
    if not isinstance(start, Configuration):
        raise InputError(
            f"start must be a Configuration (e.g. model.inverse_kinematics(x)), got {start!r}"
        )
    as_vector(start.y, model.m, "start.y")
    as_vector(start.theta, model.k, "start.theta")
    if not check_residual:
        return start
    res = model.residual(start.y, start.theta)
    if res > model.tolerance:
        raise NotAssembledError(
            f"start configuration is not assembled (residual {res:.3g} > {model.tolerance:.1e})",
            res,
        )
    return start


def start_direction(
    model: Model, theta0: np.ndarray, start: Configuration, backend: str = "cvodes"
):
    """(nu unit vector, det J_p) at the start of the path towards ``theta0``."""
    nu, det, _Jp = _at_start(model, theta0, start)
    return nu, det


def _at_start(model: Model, theta0: np.ndarray, start: Configuration):
    """(nu unit vector, det J_p, J_p) at the start: one evaluation of the Jacobians for the
    branch, the singularity check and the first tangent of the path."""
    y_loc, c = model.chart.to_local(start.y)
    Jp, Js = model_calls(model).jac(y_loc, start.theta, c)
    return null_direction(Jp, Js @ (theta0 - start.theta)), float(np.linalg.det(Jp)), Jp


def trace(
    model: Model,
    theta0: np.ndarray,
    start: Configuration,
    direction: float,
    *,
    max_hits: int = 1,
    max_arc: float | None = None,
    backend: str = "cvodes",
    record_path: bool = False,
    predictor: str = "cvodes",
    tangent: np.ndarray | None = None,
) -> Walk:
    """Follow the SC solution curve from ``start`` towards ``theta0`` and collect what it meets.

    The curve follower (:func:`scdk_sym.follower.curve.follow`) on the line from
    ``start.theta`` to ``theta0``, with CVODES integrating the SC ODE (``predictor="cvodes"``).

    Args:
        model: the model.
        theta0: (k,) target actuated values (must differ from ``start.theta``).
        start: assembled start configuration.
        direction: +1 to follow ``nu``, -1 to follow ``-nu`` (the sign of the paper's b).
        max_hits: stop after this many ``s = 1`` crossings.
        max_arc: arc-length budget (default: 60 times the linear prediction of the distance
            to ``s = 1`` plus 20 model sizes).
        backend: kernel backend.
        record_path: keep the sampled curve.
        predictor: "cvodes" or "rk4" (see :mod:`scdk_sym.follower.curve`).
        tangent: (m+1,) the first tangent's orientation when already known (``direction``
            times the unit ``nu`` at the start, e.g. from :func:`start_direction`).

    Returns:
        The :class:`~scdk_sym.follower.curve.Walk`: ``hits`` (``s = 1`` crossings),
        ``singular`` (folds and bifurcations), ``stalled``, ``closed``, ``s_range``, ``path``.
    """
    theta1 = np.array(start.theta, dtype=float)
    line = Line(theta1, np.asarray(theta0, float) - theta1)
    options = FollowOptions(
        predictor=predictor, backend=backend, max_hits=max_hits, max_arc=max_arc, record=record_path
    )
    return follow(model, line, start.y, 0.0, direction, options, tangent=tangent)


def solve(
    model: Model,
    theta0: ArrayLike,
    start: Configuration | None = None,
    branch: str = "convergent",
    b: float | None = None,
    *,
    backend: str = "cvodes",
    max_arc: float | None = None,
    record_path: bool = True,
    fast: bool = True,
) -> SolveResult:
    """Solve the direct kinematics at ``theta0`` by the singularity-consistent method.

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        start: assembled start configuration (default: ``model.home``).
        branch: "convergent" (``b det J_p > 0`` at the start: the solution reached without
            leaving the start's side of the singular surface, along the paper's straight path)
            or "divergent" (the solution across the nearest singular surface: the nearest
            singular configuration on the assembled manifold is located, crossed, and the
            path converges from the other side to ``theta0``; see
            :mod:`scdk_sym.follower.singular`).
        b: the paper's signed scalar; when given, its sign selects the direction of ``nu``
            on the paper's straight path ``theta1 + s (theta0 - theta1)`` and overrides
            ``branch`` (the literal algorithm).
        backend: a name of :mod:`scdk_sym.backends` that solve offers
            (``backends.offered("solve")``): "cvodes" (default), "compiled", "c" (the
            convergent solve, and the divergent one along the paper's divergent path, in one
            call of the generated C follower, :mod:`scdk_sym.solvers.solve_c`) or "auto".
        max_arc: arc-length budget of the path (see :func:`trace`).
        record_path: keep the sampled curve in ``result.path`` (for plots).
        fast: for a convergent solve without ``record_path``, first try one call of the warm
            kernel (an RK4 step in s with a Newton polish); it is accepted only if the polish
            moved the prediction by less than 1e-7 (relative) and ``det J_p`` kept its sign,
            else the full CVODES path is integrated.

    Returns:
        A verified :class:`SolveResult`; ``result.crossings`` lists the singular points met on
        the way (each with ``kind`` "fold" or "bifurcation"); ``result.status`` is
        "converged", or "singular" when the solution itself is singular (``theta0`` on the
        singular surface: ``J_p`` singular to 1e-6 relative).

    Raises:
        InputError: bad shapes, NaN, unknown branch, a backend solve does not offer.
        SolveError: the start is singular and no ``b`` was given (the branch is undefined).
        PathError: no solution was reached (the message says what was tried; every real
            solution at ``theta0`` is listed by :func:`scdk_sym.assembly_modes`).
        VerificationError: the final configuration failed its residual check.
    """
    name = without_waiting(
        model,
        resolve(backend, "solve"),
        lambda built: _warm(model, built),
    )
    res = _solve(model, theta0, start, branch, b, name, max_arc, record_path, fast)
    return res if res.backend else replace(res, backend=name)


def _warm(model: Model, backend: Resolved) -> None:
    """One solve at home with ``backend`` each way it can run (the C follower's one call,
    and the compiled follower it hands a recorded path to): what builds its products."""
    solve(model, model.home.theta, model.home, backend=backend, record_path=False)
    solve(model, model.home.theta, model.home, backend=backend)


def _solve(
    model: Model,
    theta0: ArrayLike,
    start: Configuration | None,
    branch: str,
    b: float | None,
    backend: str,
    max_arc: float | None,
    record_path: bool,
    fast: bool,
) -> SolveResult:
    """:func:`solve` (its arguments in order); the result's backend is set by the caller."""
    subs = model.blocks
    if len(subs) > 1:  # independent blocks (the legs of a biped): one solve each
        theta0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
        options = dict(branch=branch, b=b, backend=backend, max_arc=max_arc)
        options.update(record_path=False, fast=fast)
        return solve_blocks(model, subs, theta0, validate_start(model, start), solve, **options)
    if backend == "c":  # one call of the generated C follower (scdk_sym.solvers.solve_c)
        return solve_c(model, theta0, start, branch, b, max_arc=max_arc, record_path=record_path)
    theta0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
    if b is None and branch not in ("convergent", "divergent"):
        raise InputError(f"unknown branch {branch!r}; branches: convergent, divergent")
    if b is not None and (not math.isfinite(b) or b == 0):
        raise InputError(f"b must be a non-zero finite number, got {b!r}")
    if max_arc is not None and not (max_arc > 0):
        raise InputError(f"max_arc must be a positive arc length, got {max_arc!r}")
    checked = False
    if fast and not record_path and b is None and branch == "convergent":
        start = validate_start(model, start, check_residual=False)
        res = _fast_convergent(model, theta0, start, backend)
        if res is not None:
            return res
        checked = True  # the warm kernel checked the start's residual (it raises otherwise)
    start = validate_start(model, start, check_residual=not checked)
    nu, det0, Jp = _at_start(model, theta0, start)
    same = _same_theta(theta0, start.theta)
    if b is not None:
        if same:
            return solve_result(model, start.y, theta0, (), "convergent", 1.0, start, None)
        direction = 1.0 if b > 0 else -1.0
        name = "convergent" if direction * det0 > 0 else "divergent"
        return _along_line(model, theta0, start, 1.0 if det0 > 0 else -1.0, direction, name,
                           backend, max_arc, record_path, nu)  # fmt: skip
    if singular_start(model, start, Jp):
        raise SolveError(
            f"the start configuration is singular (J_p singular, det {det0:.3g}): the branch "
            "is undefined; pass b=+1 or b=-1, or start from a nearby non-singular configuration"
        )
    sign = 1.0 if det0 > 0 else -1.0
    if branch == "convergent":
        if same:
            return solve_result(model, start.y, theta0, (), "convergent", sign, start, None)
        return _along_line(model, theta0, start, sign, sign, "convergent", backend, max_arc,
                           record_path, nu, detour=True)  # fmt: skip
    return _divergent(model, theta0, start, sign, backend, max_arc, record_path, nu)


def _same_theta(a: np.ndarray, b: np.ndarray) -> bool:
    return float(np.linalg.norm(a - b)) <= 1e-14 * max(1.0, float(np.linalg.norm(a)))


def singular_start(model: Model, start: Configuration, Jp: np.ndarray | None = None) -> bool:
    if Jp is None:
        y_loc, c = model.chart.to_local(start.y)
        Jp = model_calls(model).jac(y_loc, start.theta, c)[0]
    S = np.linalg.svd(Jp, compute_uv=False)
    return not S[-1] > 1e-10 * S[0]


def _along_line(model, theta0, start, sign0, direction, name, backend, max_arc, record_path,
                nu=None, detour=False):  # fmt: skip
    """The first ``s = 1`` crossing along the straight path in one direction (or the singular
    solution where the curve only touches ``s = 1``); ``sign0``: the sign of ``det J_p`` at
    the start; ``nu``: the unit SC vector at the start (:func:`start_direction`), when known.

    With ``detour`` (the convergent branch): where the path leaves the start's side at a fold
    before ``theta0`` that it grazes, or leaves it and never reaches ``s = 1``, the solution
    reached on the start's side along a bent path (see :func:`_detour`) is returned when there
    is one."""
    tangent = _first_tangent(theta0, start, direction, nu)

    def walk(predictor: str) -> Walk:
        return trace(model, theta0, start, direction, max_arc=max_arc, backend=backend,
                     record_path=record_path, predictor=predictor, tangent=tangent)  # fmt: skip

    def first_hit(tr: Walk) -> SolveResult:
        hit = tr.hits[0]
        crossings = tuple(tr.singular[: hit.crossings])
        res = solve_result(model, hit.y, theta0, crossings, name, direction, start, tr.path)
        return parity_checked(model, res, sign0)

    tr = walk("cvodes")
    explicit = not tr.hits and tr.stalled
    if explicit:  # CVODES stalled: the explicit predictor-corrector
        tr = walk("rk4")
    if detour and tr.singular and (not tr.hits or tr.hits[0].crossings):
        res = _detour(model, theta0, start, direction, tr.singular[0], backend, max_arc,
                      any_fold=not tr.hits)  # fmt: skip
        if res is not None:
            return res
    if tr.hits:
        try:
            return first_hit(tr)
        except PathError:
            if explicit:
                raise
            # the CVODES walk's answer is on another sheet (it crossed between two close
            # sheets without a sign change in its samples): the explicit
            # predictor-corrector's, if its parity holds (else the first answer's error)
            again = walk("rk4")
            if not again.hits:
                raise
        return first_hit(again)
    touch = touching(model, theta0, tr, sign0)
    if touch is not None:
        y, n = touch
        crossings = tuple(tr.singular[:n])
        res = solve_result(model, y, theta0, crossings, name, direction, start, tr.path)
        return parity_checked(model, res, sign0)
    if tr.stalled:
        why = "the curve could not be followed further"
    elif tr.closed:
        why = "the curve closed on itself"
    else:
        why = f"not within arc length {tr.arc:.3g}"
    raise PathError(
        f"{name} branch: the solution curve from the start did not reach s = 1 (theta0="
        f"{theta0.tolist()}): {why}; s stayed in [{tr.s_range[0]:.3g}, {tr.s_range[1]:.3g}]; "
        "every real solution: sc.assembly_modes(model, theta0)"
    )


def _first_tangent(theta0, start, direction, nu) -> np.ndarray | None:
    """``direction * nu``: the orientation the follower computes at the start of the line from
    ``start`` to ``theta0``, where ``nu`` was evaluated at the same point (the line's
    ``theta(0)`` equal to ``start.theta`` bit for bit), else None."""
    if nu is None:
        return None
    theta1 = np.array(start.theta, dtype=float)
    line = Line(theta1, np.asarray(theta0, float) - theta1)
    if line.at(0.0).tobytes() != theta1.tobytes():
        return None
    return direction * nu


#: Offsets of the bend of a detour, in units of |theta0 - theta1|, tried in order.
DETOUR_OFFSETS = (0.01, 0.03, 0.1, 0.3)


def _detour(
    model, theta0, start, direction, fold, backend, max_arc, any_fold=False
) -> SolveResult | None:
    """The convergent answer past a fold that the straight path grazes, or None.

    Where the line from the start meets the singular surface nearly tangentially it leaves
    the start's side only briefly (e.g. on Dietmaier's 6-6 platform from starts within
    ``det J_p ~ 1e-6`` of a surface): the straight path turns back at the fold, while a line
    bent by a little towards the start's side stays there. So the path goes from the start to
    the fold's ``theta`` moved along the surface normal towards the side where the start's
    solution exists (:func:`~scdk_sym.follower.singular.inward_normal`), then to ``theta0``,
    each leg along the convergent direction; it is taken only if neither leg meets a singular
    point (the answer is on the start's side, reached continuously), at the smallest of the
    ``DETOUR_OFFSETS`` that works. ``result.path`` is None (the path is not one line).
    With ``any_fold`` (the straight path never reached ``s = 1``) the fold need not be grazed,
    only met before ``theta0``: a line cutting a small cap off the start's side (e.g. Gepetto's
    5-bar with ``theta0`` just before a singular surface) leaves it and comes back just after.
    """
    from ..follower.surface import grazes, inward_normal

    if fold.kind != "fold" or not 0.0 < fold.s <= 1.0:
        return None
    if not (any_fold or grazes(model, fold, theta0 - start.theta)):
        return None
    n = inward_normal(model, fold, backend)
    if n is None:
        return None
    span = float(np.linalg.norm(theta0 - start.theta))
    for offset in DETOUR_OFFSETS:
        cfg = start
        for target in (np.asarray(fold.theta, float) + offset * span * n, theta0):
            line = Line(np.array(cfg.theta, dtype=float), target - cfg.theta)
            options = FollowOptions(
                predictor="cvodes", backend=backend, max_hits=1, max_singular=1, max_arc=max_arc
            )
            tr = follow(model, line, cfg.y, 0.0, direction, options)
            if not tr.hits or tr.hits[0].crossings:
                cfg = None
                break
            cfg = model.configuration(tr.hits[0].y, target)
            if not cfg.residual <= model.tolerance:
                cfg = None
                break
        if cfg is not None:
            return solve_result(model, cfg.y, theta0, (), "convergent", direction, start, None)
    return None


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


def _divergent(model, theta0, start, sign, backend, max_arc, record_path, nu=None) -> SolveResult:
    """The solution across the nearest singular surface (see :func:`solve`): the first
    answer of the ways of :data:`DIVERGENT_STRATEGIES`, in order, named in its ``strategy``.

    Raises:
        PathError: no way answered (each one's reason in the message).
    """
    search = _DivergentSearch(model, theta0, start, sign, backend, max_arc, record_path, nu)
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

    def __init__(self, model, theta0, start, sign, backend, max_arc, record_path, nu) -> None:
        self.model, self.theta0, self.start, self.sign = model, theta0, start, sign
        self.backend, self.max_arc, self.record_path, self.nu = backend, max_arc, record_path, nu
        self.tried: list[str] = []
        self._memo: list[SolveResult | None] = []
        self._near: list = []  # [fold, beside] once located

    # ------------------------------------------------------------------ shared pieces

    def convergent(self) -> SolveResult | None:
        """The convergent answer at ``theta0`` (None where it fails), computed once."""
        if not self._memo:
            try:
                self._memo.append(
                    solve(self.model, self.theta0, start=self.start, branch="convergent",
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
        if folds_only and not _is_same_side(model, start, res):
            return res
        conv = self.convergent()
        if conv is not None and _same_configuration(model, res, conv):
            self.tried.append(f"{how}: came back to the convergent solution")
            return None
        return res

    def from_mirror(self, other, how: str) -> SolveResult | None:
        """The convergent path to ``theta0`` from the mirror point ``other`` across a
        singular surface, the crossing prepended."""
        try:
            res = solve(self.model, self.theta0, start=other.start, branch="convergent",
                        backend=self.backend, max_arc=self.max_arc,
                        record_path=self.record_path)  # fmt: skip
        except ScdkError as exc:
            self.tried.append(f"{how}: {exc}")
            return None
        path = res.path
        if other.path is not None and path is not None:
            path = _joined(other.path, path, -self.sign)
        out = SolveResult(
            x=res.x, y=res.y, theta=res.theta, platform_pose=res.platform_pose,
            joints=res.joints, residual=res.residual,
            crossings=(_on_path(other.crossing, self.start, self.theta0), *res.crossings),
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
        crossings = (_on_path(near, start, theta0), *met)
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
        if _same_theta(self.theta0, self.start.theta):
            return None
        try:
            res = _along_line(self.model, self.theta0, self.start, self.sign, -self.sign,
                              "divergent", self.backend, self.max_arc, self.record_path,
                              self.nu)  # fmt: skip
        except PathError as exc:
            self.tried.append(f"along the straight path: {exc}")
            return None
        return self.other_than_convergent(res, "along the straight path")

    def way_modes(self) -> SolveResult | None:
        fold, _ = self.nearest()
        return _across_by_modes(self.model, self.theta0, self.start, self.sign, fold,
                                self.convergent, self.backend, self.tried)  # fmt: skip

    def way_along_axes(self) -> SolveResult | None:
        from ..follower.singular import across_axes

        other = across_axes(self.model, self.start, backend=self.backend)
        if other is None:
            self.tried.append("no singular surface met along any actuator's axis")
            return None
        return self.from_mirror(other, "from across the surface met along an actuator's axis")


def _across_by_modes(
    model, theta0, start, sign, fold, convergent, backend, tried
) -> SolveResult | None:
    """The ``modes`` way of :func:`_divergent`: the real solution at ``theta0`` on the other side of
    ``fold`` nearest to it, chosen among every real solution (certified assembly modes).

    Where no singular configuration was found near the start (``fold`` None: the descent
    stopped at a local minimum of ``sigma_min``), the candidate is the solution with
    ``det J_p`` of the other sign nearest to the start, and the singular surface crossed is
    located from the configuration midway between it and the convergent answer (or the
    start): near a fold the two sheets are mirror images, so the midpoint lies next to it;
    where ``sigma_min`` has no singular minimum near it either, by Gauss-Newton onto the
    singular manifold from the midpoint (:func:`~scdk_sym.follower.singular.singular_from`:
    a singular configuration, not necessarily the nearest).
    """
    from ..follower.nearest import nearest_singular, singular_from
    from ..follower.other_sheet import nearest_across
    from ..robot.rods import rod_reduction, seat
    from .modes import assembly_modes

    try:
        # the default (generated C where a compiler is found) whatever the solve's kernels:
        # the first call per model computes its start system (seconds: about 9 s for
        # Gepetto's robot_delta), cached on disk, proven or not
        sols = assembly_modes(model, theta0, certified_only=True)
    except ScdkError as exc:
        tried.append(f"every real solution at theta0: {exc}")
        return None
    if not sols.certified:
        tried.append("every real solution at theta0: the set is not certified complete")
        return None
    conv = convergent()
    anchor = start if fold is None else fold
    candidates = [cfg.y for cfg in sols]
    rods, _ = rod_reduction(model)
    if rods:  # one configuration per assembly: its balls' angles as the anchor's continue
        seated = [seat(model, rods, y, theta0, anchor.y) for y in candidates]
        candidates = [y if s is None else s for y, s in zip(candidates, seated, strict=True)]
    best = nearest_across(
        model,
        anchor.y,
        theta0,
        [(y, []) for y in candidates],
        det_sign(model, start),
        any_sign=fold is not None and fold.kind != "fold",
        exclude=None if conv is None else conv.configuration,
    )
    if best is None:
        tried.append(
            f"every real solution at theta0 ({len(sols)}, certified): none on the other side"
        )
        return None
    if fold is None:
        near = conv if conv is not None else start
        mid = model.configuration(0.5 * (near.y + best[0].y), 0.5 * (near.theta + theta0))
        for seed in (mid, best[0]):
            fold = nearest_singular(model, seed, backend)
            if fold is not None:
                break
        else:  # sigma_min has a non-singular local minimum there (the Delta near home)
            fold = singular_from(model, mid, backend)
        if fold is None:
            tried.append("every real solution at theta0: no singular surface located between")
            return None
    crossing = _on_path(fold, start, theta0)
    return solve_result(model, best[0].y, theta0, (crossing,), "divergent", -sign, start, None)


def _same_configuration(model: Model, a, b) -> bool:
    """Two configurations coincide (chart-free features within 1e-7 model sizes)."""
    from ..follower.geometry import features

    scale = max(1.0, float(model.length_scale))
    return float(np.max(np.abs(features(model, a.y) - features(model, b.y)))) <= 1e-7 * scale


def _fast_convergent(model, theta0, start, backend) -> SolveResult | None:
    """One call of the warm kernel (RK4 in s + Newton + checks); None when not conclusive."""
    eng = engine(model, backend)
    y1, c = model.chart.to_local(start.y)
    y0, corr, res1, res0, J1, J0, T, x = eng.warm(y1, start.theta, theta0, c)
    if not res1[0] <= model.tolerance:
        raise NotAssembledError(
            f"start configuration is not assembled (residual {res1[0]:.3g} > "
            f"{model.tolerance:.1e})",
            float(res1[0]),
        )
    m = model.m
    if not (np.all(np.isfinite(y0)) and res0[0] <= model.tolerance):
        return None
    step = float(np.max(np.abs(y0 - y1)))
    if corr[0] > 1e-7 * step + 1e-13:
        return None
    det1 = np.linalg.det(J1.reshape(m, m, order="F"))
    det0 = np.linalg.det(J0.reshape(m, m, order="F"))
    if not det1 * det0 > 0:
        return None
    y = model.chart.to_canonical(y0, c)
    theta = theta0.copy()
    return SolveResult(
        x=x.copy(),
        y=y,
        theta=theta,
        platform_pose=T.reshape(4, 4, order="F").copy(),
        joints=model.joint_values(y, theta),
        residual=float(res0[0]),
        crossings=(),
        status="converged",
        branch="convergent",
        b=1.0 if det1 > 0 else -1.0,
        start=start,
        path=None,
    )


def solve_result(model, y, theta0, crossings, branch, direction, start, path) -> SolveResult:
    """The verified :class:`SolveResult` of unknowns ``y`` at ``theta0`` (raises
    :class:`~scdk_sym.errors.VerificationError` when it does not close)."""
    cfg = model.configuration(y, theta0)
    if not cfg.residual <= model.tolerance:
        raise VerificationError(
            f"solution at theta0={np.asarray(theta0).tolist()} failed verification: residual "
            f"{cfg.residual:.3g} > {model.tolerance:.1e}",
            cfg.residual,
        )
    return SolveResult(
        x=cfg.x,
        y=cfg.y,
        theta=cfg.theta,
        platform_pose=cfg.platform_pose,
        joints=cfg.joints,
        residual=cfg.residual,
        crossings=crossings,
        status="singular" if _is_singular(model, cfg) else "converged",
        branch=branch,
        b=direction,
        start=start,
        path=path,
    )


#: The verified result of a solve (also of one assembled from blocks).
verified_result = solve_result


def _is_singular(model: Model, cfg: Configuration) -> bool:
    """``J_p`` singular to 1e-6 relative at a configuration."""
    y_loc, c = model.chart.to_local(cfg.y)
    return singular_jp(jacobian(model, y_loc, cfg.theta, c))


def _is_same_side(model: Model, a: Configuration, b) -> bool:
    """det J_p has the same sign at two configurations."""
    return det_sign(model, a) * det_sign(model, b) > 0


def _joined(first: PathSamples, rest: PathSamples, b: float) -> PathSamples:
    """The paper's divergent path: the line away from theta0 (``s -> -s``) and back through
    the start's theta, then the convergent path to theta0 (``s' = b det J_p``)."""
    det = np.concatenate([first.det_jp, rest.det_jp[1:]])
    return PathSamples(
        s=np.concatenate([-first.s, rest.s[1:]]),
        y=np.vstack([first.y, rest.y[1:]]),
        x=np.vstack([first.x, rest.x[1:]]),
        det_jp=det,
        sdot=b * det,
        arc=np.concatenate([first.arc, first.arc[-1] + rest.arc[1:]]),
    )


def _on_path(cr: Crossing, start: Configuration, theta0: np.ndarray) -> Crossing:
    """A crossing with ``s`` the projection of its ``theta`` on the line from the start to
    ``theta0`` (exact when it lies on it; 0 when ``theta0`` is the start's)."""
    d = theta0 - start.theta
    dd = float(d @ d)
    s = float((cr.theta - start.theta) @ d / dd) if dd else 0.0
    return Crossing(s, cr.x, cr.y, cr.theta, kind=cr.kind)
