"""All real assembly modes with a proof: parameter homotopy from a certified start system.

The pipeline of :func:`homotopy_modes`:

1. the model's algebraic form ``G(z, p) = 0`` (:func:`scdk_sym.algebraic.algebraic_form`,
   generated C when a C compiler is present);
2. its start system: every complex solution at one random complex parameter point, by
   monodromy, proven complete (cached on disk under the form's content hash) when the
   number of distinct regular roots found equals the form's BKK root bound
   (:mod:`scdk_sym.algebraic.rootbound`), or else by a trace test
   (:func:`scdk_sym.algebraic.trace_test`). The traced functions are the entries of
   the placement of the model's frame (translation and rotation), which stay finite where a
   quaternion chart does not;
3. the parameter homotopy from there to ``params(theta0)``
   (:func:`scdk_sym.algebraic.solve_homotopy`): every isolated solution at ``theta0`` is an
   endpoint;
4. real endpoints -> the model's unknowns, Newton-polished on the model's own closure rows
   ``g`` (max |g| <= :data:`RESIDUAL` verified), deduplicated and sorted as the curve search
   sorts them;
5. each one certified by a Krawczyk test on ``g`` in one common chart, the boxes pairwise
   disjoint (:func:`scdk_sym.algebraic.certify_configurations`).

The result is certified only when every link of that chain holds; otherwise its ``report``
names the first one that does not. All work is bounded (monodromy loops, tracker steps,
homotopy attempts, Newton steps).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from ..backends import resolve
from ..errors import InputError, ScdkError
from ..follower.geometry import features
from ..kernels.cache import read_entry, write_entry
from ..kernels.fastcall import model_calls
from ..model.rotations import rot_exp
from ..products import START_SYSTEM
from ..results import AssemblyModes, Configuration, mode_orders
from ..robot import Model, as_vector
from ..robot.rods import rod_reduction
from .rod_modes import lifted_modes

#: Largest relative imaginary part of a real endpoint (as ``solve_homotopy`` selects them).
REAL_TOL = 1e-8
#: Endpoints with a relative imaginary part in (REAL_TOL, UNDECIDED_TOL] leave the set
#: uncertified: a real solution computed with that much error would be missed.
UNDECIDED_TOL = 1e-5
#: A singular endpoint at which a weld's ``tr(R_a^T R_b)`` is within this of -1 lies on a
#: set of roots of the form closing that weld with a half turn (the trace is -1 or 3 there,
#: constant on a connected set): none of its points is a closure (:func:`weld_traces`).
HALF_TURN = 1.0
#: Largest max |g| of a polished real solution [model length unit].
RESIDUAL = 1e-9
#: A real root of the form with max |g| above this many model sizes, before and after Newton,
#: is no solution of the model (e.g. a weld closed with a half turn in its rotation rows).
SPURIOUS = 1e-3
#: Real endpoints whose polished configurations agree to this many model sizes (chart-free
#: features) are one solution.
DUPLICATE = 1e-10
#: Newton steps on the model's rows per real endpoint.
NEWTON_STEPS = 8
#: Default bound on the monodromy loops of a start system.
MAX_LOOPS = 60
#: Largest relative trace residual of a complete start system.
TRACE_TOL = 1e-9
#: Version of the start-system test (part of the cache file name).
MODES_CACHE_VERSION = "6"
#: Budget of the BKK root bound of a form [s of CPU time]; beyond it only the trace tests
#: remain.
ROOT_BOUND_BUDGET = 2.0
#: Budget of the monodromy loops of a start system [s of CPU time] (the largest one certified
#: here, the shipped stewart_gough's 28 roots, takes about 7 s; a 12-unknown Gepetto ankle
#: block, whose joint-angle representations multiply its roots, ran on for many minutes);
#: beyond it the start system is not certified, and says so.
MONODROMY_BUDGET = 120.0
#: Largest condition number (rows and columns scaled) of ``dG/dz`` at a root counted
#: against the root bound: a regular, hence isolated, root.
REGULAR_COND = 1e10
#: Smallest distance between two roots counted against the root bound, relative to
#: ``1 + max |z|``: distinct roots.
DISTINCT = 1e-6
#: Gamma of the homotopy from a neighbour's root set (:func:`modes_from_neighbour`): a fixed
#: non-real one, so the arc between two real parameter points runs through complex ones and
#: misses the real discriminant between them (where two real roots meet).
NEIGHBOUR_GAMMA = complex(np.exp(2j * np.pi * 0.2137))


@dataclass(frozen=True)
class ModeSeed:
    """The complete set of complex roots of a model's algebraic form at one parameter point:
    what the homotopy of a neighbouring point starts from.

    Attributes:
        p: (n_params,) complex parameters of the form (``form.params(theta)``).
        roots: (R, n) complex roots, R the start system's root count, pairwise distinct and
            every one the regular end of its path.
    """

    p: np.ndarray
    roots: np.ndarray


def _complex_map(form, p: np.ndarray, name: str, entries):
    """``f(z (N, n)) -> (N, E)`` complex: ``entries(T)`` (SX, a function of the links' world
    placements ``T``, link name -> (4, 4) SX, polynomial in ``z``) at fixed parameters ``p``."""
    from ..algebraic.pairs import complexify
    from ..algebraic.polynomial import polynomial_joint_values, polynomial_motion

    model = form.model
    z, ps = ca.SX.sym("z", form.n), ca.SX.sym("p", form.n_params)
    values, _ = polynomial_joint_values(model, form.rows.slots, z, ps)
    T = {model.tree.root: ca.SX.eye(4)}
    for j in model.tree.joints:
        M = T[j.parent] @ ca.DM(j.origin)
        if j.movable:
            M = M @ polynomial_motion(j.type, j.axis, values[j.name])
        T[j.child] = M
    F = complexify(ca.Function(name, [z, ps], [entries(T)]), f"{name}_c")
    p = np.asarray(p, dtype=complex)

    def evaluate(Z: np.ndarray) -> np.ndarray:
        Z = np.atleast_2d(Z)
        N = len(Z)
        out = F.map(N)(Z.real.T, Z.imag.T, np.tile(p.real[:, None], (1, N)),
                       np.tile(p.imag[:, None], (1, N)))  # fmt: skip
        return (np.array(out[0]) + 1j * np.array(out[1])).T

    return evaluate


def frame_trace_map(form, p: np.ndarray):
    """The traced functions of a form: placements of the model frame and the closure frames.

    The closure rows are polynomials in these placements (linear for point closures), so
    their trace along an offset pencil is a polynomial of low degree where a plain chart
    coordinate would have poles.

    Args:
        form: an :class:`~scdk_sym.algebraic.form.AlgebraicForm`.
        p: (n_params,) complex parameters held fixed along the trace pencil.

    Returns:
        ``f(z) -> (N, 12 F)`` complex: translation and rotation entries of the ``F`` frames,
        polynomial in ``z``.
    """
    model = form.model
    frames = [model.frame] + [f for cl in model.closures for f in (cl.frame_a, cl.frame_b)]

    def entries(T):
        out = ca.vertcat(*[ca.vec(T[f][:3, :]) for f in dict.fromkeys(frames)])
        return out / model.length_scale

    return _complex_map(form, p, "frames", entries)


def weld_traces(form, p: np.ndarray):
    """The traces of ``R_a^T R_b`` of the model's 6d closures, as polynomial maps of ``z``.

    A 6d closure's rotation rows ``vee(R_a^T R_b) = 0`` hold exactly where ``R_a^T R_b`` is
    symmetric, i.e. (an orthogonal matrix, complex or real) the identity, of trace 3, or a
    half turn, of trace -1. Trace being continuous and two valued on that set, a connected
    set of roots of the form keeps one trace: a component on which it is -1 holds no closure
    of the model, real or complex.

    Args:
        form: an :class:`~scdk_sym.algebraic.form.AlgebraicForm` (scaled or not).
        p: (n_params,) complex parameters.

    Returns:
        ``f(z (N, n)) -> (N, W)`` complex traces, one column per 6d closure (``W`` may be 0).
    """
    welds = [cl for cl in form.model.closures if cl.type == "6d"]

    def entries(T):
        traces = [ca.trace(T[cl.frame_a][:3, :3].T @ T[cl.frame_b][:3, :3]) for cl in welds]
        return ca.vertcat(*traces, 0)

    f = _complex_map(form, p, "welds", entries)
    return lambda Z: f(Z)[:, : len(welds)]


def form_root_bound(form, p: np.ndarray, seed: int = 0):
    """The BKK root bound of a form at ``p`` within :data:`ROOT_BOUND_BUDGET`.

    Args:
        form: the model's algebraic form (scaled or not).
        p: (n_params,) complex parameters.
        seed: seed of the bound's random choices.

    Returns:
        ``(bound, note)``: a :class:`~scdk_sym.algebraic.rootbound.RootBound` and ``""``, or
        ``None`` and why no bound was computed.
    """
    from ..algebraic.rootbound import root_bound

    try:
        return root_bound(form, p, seed, ROOT_BOUND_BUDGET), ""
    except (ScdkError, ValueError) as exc:  # ValueError: numpy's LinAlgError among others
        return None, str(exc)


def complete_by_bound(
    form, solutions: np.ndarray, p: np.ndarray, b: np.ndarray, bound: int,
    kind: str = "BKK root bound",
):  # fmt: skip
    """Whether ``solutions`` are all the isolated roots of ``G(z, p) + b = 0``, by count.

    They are when they are roots (two Newton steps converge), regular (scaled condition
    number of ``dG/dz`` at most :data:`REGULAR_COND`, so each is isolated), pairwise distinct
    (relative distance at least :data:`DISTINCT`) and exactly ``bound`` many, ``bound`` an
    upper bound on the isolated roots (the BKK bound).

    Args:
        form: the model's algebraic form (scaled or not).
        solutions: (R, n) complex candidate roots.
        p: (n_params,) complex parameters.
        b: (n,) complex offsets.
        bound: the upper bound on the isolated roots.
        kind: what the bound is (for the note).

    Returns:
        ``(complete, note)``: the verdict and one line saying why.
    """
    from ..algebraic.homotopy import scaled_cond
    from ..algebraic.monodromy import refine_solutions

    count = len(solutions)
    if count != bound:
        return False, f"{count} roots found, root bound {bound}"
    z, ok = refine_solutions(form, np.asarray(solutions, dtype=complex), p, b)
    if not ok.all():
        return False, f"{int((~ok).sum())} of {count} roots do not refine by Newton"
    _, Jz, _ = form.evaluate(z, np.broadcast_to(p, (count, form.n_params)))
    cond = scaled_cond(Jz)
    if count and cond.max() > REGULAR_COND:
        return False, f"a root has condition number {cond.max():.1e} > {REGULAR_COND:.0e}"
    scale = 1.0 + np.abs(z).max(axis=1)
    d = np.abs(z[:, None] - z[None]).max(axis=2) / np.minimum(scale[:, None], scale[None])
    np.fill_diagonal(d, np.inf)
    if count > 1 and d.min() < DISTINCT:
        return False, f"two roots lie {d.min():.1e} apart (< {DISTINCT:.0e})"
    return True, f"{count} distinct regular roots = {kind}"


def model_start_system(
    form,
    seed: int = 0,
    *,
    progress: bool = False,
    max_loops: int = MAX_LOOPS,
    cache: bool = True,
    rebuild: bool = False,
):
    """The start system of a model's form, with its completeness test (cached).

    Monodromy (:func:`scdk_sym.algebraic.monodromy_solve`) runs until the solution count has
    been stable for 5 loops (or has reached the form's BKK root bound,
    :func:`form_root_bound`), then tests the set and stops as soon as it passes, else loops
    on (testing again at each stable count) within ``max_loops``. The set is proven complete
    when its roots are as many as the root bound, distinct and regular
    (:func:`complete_by_bound`: no isolated root is missing), or when the trace of the
    frames' placements (:func:`frame_trace_map`) along a random offset
    pencil is a polynomial of degree 1 (:func:`scdk_sym.algebraic.trace_test`, relative
    residual <= :data:`TRACE_TOL`), or, where solutions escape along that pencil, when the
    trace over the curve of an offset line is
    (:func:`scdk_sym.algebraic.pencil.pencil_trace_test`, the hyperplane on the first
    unknown's coordinates), which is linear for every form. No weaker test certifies: a
    rational fit of the trace on a circle of the pencil is passed by the trace of a subset
    that no branch point inside the circle connects to the rest (a random 6-6 platform with
    38 of its 40 roots passed one).

    Every result, proven or not, is stored on disk under the form's content hash and kept in
    memory on the model; a stored failure (with its ``reason``) is returned as it is, without
    a new monodromy, until ``rebuild`` asks for one.

    Args:
        form: the model's algebraic form.
        seed: seed of the monodromy.
        progress: progress bar of the monodromy loops (shown after the first 2 s).
        max_loops: bound on the monodromy loops.
        cache: use the disk cache.
        rebuild: compute the start system again, ignoring the memory and disk caches (the
            new result replaces the stored one).

    Returns:
        A :class:`~scdk_sym.algebraic.monodromy.StartSystem` whose ``trace_passed`` is the
        verdict of the tests above, ``certificate`` names the one that passed,
        ``root_bound`` is the BKK bound (-1 if not computed) and ``trace_residual`` the last
        trace test's (NaN if none ran).
    """
    products = form.model.products
    key = (form.backend, seed, max_loops)
    stored = products.peek(START_SYSTEM, key)
    if stored is not None and not rebuild:
        return stored
    path = _cache_path(form, seed) if cache else None
    start = None
    if path is not None and not rebuild:
        start = read_entry(path, lambda p: _load(form, p), "start system")
    if start is None:
        start = _compute_start_system(form, seed, max_loops, progress)
        if path is not None:
            _save(start, path)
    return products.put(START_SYSTEM, start, key)


def _compute_start_system(form, seed: int, max_loops: int, progress: bool):
    """Monodromy from a random parameter point until a completeness test passes (the root
    bound, the linear trace test, the trace on an offset line's curve; see
    :func:`model_start_system`), or the loops or the budget run out."""
    from ..algebraic import monodromy_solve, trace_test
    from ..algebraic.pencil import pencil_trace_test

    _, p_star = form.random_point(np.random.default_rng(seed))
    trace_map = frame_trace_map(form, p_star)
    rng = np.random.default_rng(seed + 1)
    bound, bound_note = form_root_bound(form, p_star, seed)
    verdict: dict[str, Any] = {"certificate": "", "trace": float("nan"), "note": ""}

    def test(sols: np.ndarray, p: np.ndarray, b: np.ndarray) -> float:
        if bound is not None and np.array_equal(p, p_star):
            ok, verdict["note"] = complete_by_bound(form, sols, p, b, bound.bound, bound.kind)
            if ok:
                verdict["certificate"] = verdict["note"]
                return 0.0
        linear = trace_test(form, sols, p, b, rng, trace_map=trace_map)
        verdict["trace"] = linear
        if linear <= TRACE_TOL:
            verdict["certificate"] = f"linear trace test (residual {linear:.1e})"
            return linear
        pencil = pencil_trace_test(
            form, sols, p, b, rng, coords=np.array(form.rows.slots[0].z), tol=TRACE_TOL
        )
        verdict["trace"] = pencil.residual
        if pencil.passed:
            verdict["certificate"] = (
                f"trace test on the curve of an offset line ({pencil.witnesses} "
                f"witnesses on a hyperplane, residual {pencil.residual:.1e})"
            )
        return pencil.residual

    start = monodromy_solve(
        form, seed, stable_loops=5, max_loops=max_loops, trace_tol=TRACE_TOL,
        trace_map=trace_map, progress=progress, test=test,
        target=None if bound is None else bound.bound, budget=MONODROMY_BUDGET,
    )  # fmt: skip
    reason = start.reason
    if not start.trace_passed:
        reason += (
            f"; root bound: {verdict['note']}" if bound is not None and verdict["note"]
            else f"; {bound.kind} {bound.bound}" if bound is not None
            else f"; no root bound ({bound_note})"
        )  # fmt: skip
    start = replace(
        start,
        trace_residual=float(verdict["trace"]),
        root_bound=-1 if bound is None else int(bound.bound),
        certificate=str(verdict["certificate"]) if start.trace_passed else "",
        reason=reason,
    )
    return start


def _cache_path(form, seed: int):
    from ..algebraic.monodromy import cache_path

    p = cache_path(form, seed)
    return p.with_name(f"{p.stem}-modes{MODES_CACHE_VERSION}.npz")


def _load(form, path):
    """The start system stored at ``path`` (raises when unreadable), or ``None`` when it
    no longer refines to its own solutions."""
    from ..algebraic.monodromy import StartSystem, refine_solutions

    with np.load(path) as f:
        s = StartSystem(**{name: f[name] for name in _FIELDS})
    s = replace(
        s,
        root_count=int(s.root_count),
        trace_residual=float(s.trace_residual),
        trace_passed=bool(s.trace_passed),
        loops=int(s.loops),
        seed=int(s.seed),
        reason=str(s.reason),
        root_bound=int(s.root_bound),
        certificate=str(s.certificate),
    )
    if len(s.solutions) != s.root_count:
        return None
    if not s.trace_passed:
        return s  # a stored failure: its reason stands until a rebuild
    _, ok = refine_solutions(form, s.solutions, s.p, s.b)
    return s if ok.all() else None


def _save(s, path) -> None:
    fields = {name: getattr(s, name) for name in _FIELDS}

    def write(tmp) -> None:
        with open(tmp, "wb") as f:
            np.savez(f, **fields)

    write_entry(path, write)


_FIELDS = (
    "p", "b", "solutions", "root_count", "trace_residual", "trace_passed", "loops", "seed",
    "reason", "root_bound", "certificate",
)  # fmt: skip


def _polish(model: Model, ys: np.ndarray, cs: np.ndarray, theta: np.ndarray):
    """Newton on the model's rows, each point (N, m) in its chart (N, chart size) at its
    actuated values (``theta`` (k,) for all or (N, k)), all points in each kernel call; a
    point stops when ``max |g| <= RESIDUAL / 100``, after ``NEWTON_STEPS``, or when its
    Jacobian is singular. Returns ``(ys, residuals)``, the residual
    :meth:`~scdk_sym.robot.Model.residual` (``inf`` where ``g`` went non-finite)."""
    calls = model_calls(model)
    N = len(ys)
    ys = np.array(ys, dtype=float).reshape(N, model.m)
    cs = np.asarray(cs, dtype=float).reshape(N, model.chart.size)
    if not N:
        return ys, np.zeros(0)
    g_all, jac_all = calls.mapped("g", N), calls.mapped("jac", N)
    theta = np.asarray(theta, dtype=float)
    theta = theta.T if theta.ndim == 2 else theta  # one column per point
    lost = np.zeros(N, dtype=bool)  # g went non-finite
    active = np.ones(N, dtype=bool)
    for _ in range(NEWTON_STEPS):
        G = np.asarray(g_all(ys.T, theta, cs.T)).reshape(-1, N).T  # (N, rows)
        r = np.abs(G).max(axis=1) if G.shape[1] else np.zeros(N)
        lost |= active & ~np.isfinite(r)
        active &= np.isfinite(r) & ~(r <= 0.01 * RESIDUAL)
        rows = np.flatnonzero(active)
        if not rows.size:
            break
        J = jac_all(ys.T, theta, cs.T)[0].reshape(model.m, N, model.m).transpose(1, 0, 2)
        try:
            ys[rows] -= np.linalg.solve(J[rows], G[rows][..., None])[..., 0]
        except np.linalg.LinAlgError:  # a singular one: those stop, the others step
            for i in rows:
                try:
                    ys[i] -= np.linalg.solve(J[i], G[i])
                except np.linalg.LinAlgError:
                    active[i] = False
    check = np.asarray(calls.mapped("check", N)(ys.T, theta, cs.T)).reshape(-1, N)
    residuals = np.abs(check).max(axis=0)
    residuals[lost] = np.inf
    return ys, residuals


def _common_chart(model: Model, ys: np.ndarray) -> np.ndarray | None:
    """A chart of the floating joints far from a half turn of every configuration.

    Candidates: each configuration's own rotations and 32 random ones; the one with the
    largest ``min 1 + trace(R_c^T R)`` over the configurations (0 at a half turn) is taken.
    """
    rots = model.chart.rotations
    if not rots or not len(ys):
        return None
    # (N, F, 3, 3) rotations of the configurations
    R = np.stack([rot_exp(ys[:, list(idx)]) for idx in rots], axis=1)
    cands = np.concatenate([R, _random_rotations(len(rots))])
    # score[c] = min over configurations and joints of 1 + trace(C^T R)
    score = (1.0 + np.einsum("cfij,nfij->cnf", cands, R)).min(axis=(1, 2))
    best = cands[int(np.argmax(score))]
    return np.concatenate([C.flatten(order="F") for C in best])


@functools.cache
def _random_rotations(count: int) -> np.ndarray:
    """(32, count, 3, 3) rotations of random axes and angles in [0, pi) (seeded: the same
    candidates for every query)."""
    rng = np.random.default_rng(0)
    w = rng.normal(size=(32, count, 3))
    w *= (np.pi * rng.uniform(size=(32, count, 1))) / np.linalg.norm(w, axis=2, keepdims=True)
    rand = np.array([[rot_exp(v) for v in row] for row in w])
    rand.flags.writeable = False
    return rand


def homotopy_modes(
    model: Model,
    theta0: ArrayLike,
    *,
    seed: int = 0,
    progress: bool = False,
    backend: str = "auto",
    max_loops: int = MAX_LOOPS,
    cache: bool = True,
    rebuild: bool = False,
    certified_only: bool = False,
) -> AssemblyModes:
    """Every real assembly mode at ``theta0``, with a certificate of completeness.

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        seed: seed of the start system and of the gammas of the homotopy's retries.
        progress: progress bar while the start system is computed (first call per model).
        backend: ``"auto"`` (generated C when a C compiler is found), ``"cvodes"`` (SX
            kernels) or ``"compiled"``; see :mod:`scdk_sym.backends`.
        max_loops: bound on the monodromy loops of the start system.
        cache: read and write the start system's disk cache.
        rebuild: compute the start system again even if one (proven or failed) is cached.
        certified_only: for callers that use only a certified set: when the start system is
            not proven complete, return at once (no solutions, not certified, the report
            saying why) instead of tracking its paths.

    Returns:
        :class:`~scdk_sym.results.AssemblyModes` (see the module documentation).

    Raises:
        InputError: bad ``theta0`` or backend.
        AlgebraicFormError: a joint type with no algebraic form.
    """
    theta0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
    modes, _, _ = _modes_many(
        model, theta0[None], [None], seed=seed, progress=progress, backend=backend,
        max_loops=max_loops, cache=cache, rebuild=rebuild, certified_only=certified_only,
        seeds=False,
    )[0]  # fmt: skip
    return modes


def modes_from_neighbour(
    model: Model, theta0: ArrayLike, neighbour: ModeSeed | None, *, backend: str = "compiled"
) -> tuple[AssemblyModes, ModeSeed | None, bool]:
    """The certified assembly modes at ``theta0`` from a neighbouring point's complete root
    set: one step of a mode map.

    The neighbour's R roots (R the start system's root count, every one regular and distinct:
    its set is complete) are tracked to ``params(theta0)`` along an arc through complex
    parameters (:data:`NEIGHBOUR_GAMMA`). When every path ends regular and the R ends are
    pairwise distinct, they are all the isolated roots at ``theta0`` (R bounds their number),
    and the rest is :func:`homotopy_modes`' chain (real ends polished on the model's rows,
    each proven by a Krawczyk test). Otherwise (or without a neighbour) the homotopy runs from
    the start system, as :func:`homotopy_modes` does.

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        neighbour: the complete root set of a neighbouring point, or None.
        backend: as for :func:`homotopy_modes`.

    Returns:
        ``(modes, seed, continued)``: the :class:`~scdk_sym.results.AssemblyModes` at
        ``theta0``; its complete root set for the next point (None when the ends are not R
        distinct regular roots); whether the neighbour's set was used.
    """
    theta0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
    return _modes_many(model, theta0[None], [neighbour], backend=backend)[0]


def modes_from_neighbours(
    model: Model,
    thetas: ArrayLike,
    neighbours: list[ModeSeed | None],
    *,
    backend: str = "compiled",
) -> list[tuple[AssemblyModes, ModeSeed | None, bool]]:
    """:func:`modes_from_neighbour` at several points at once (e.g. one front of a mode map):
    the paths of all points tracked in one batch, the real ends of all polished and
    certified in batches. Every point's answer is the one :func:`modes_from_neighbour` gives.

    Args:
        model: the model.
        thetas: (W, k) actuated joint values [rad or model length unit].
        neighbours: W complete root sets of neighbouring points (None where there is none).
        backend: as for :func:`homotopy_modes`.

    Returns:
        W ``(modes, seed, continued)`` as :func:`modes_from_neighbour` returns them.

    Raises:
        InputError: ``thetas`` is not (W, k) finite values, or not one neighbour per point.
    """
    th = np.asarray(thetas, dtype=float)
    if th.ndim != 2 or th.shape[1] != model.k or len(neighbours) != len(th):
        raise InputError(
            f"thetas must be (W, {model.k}) actuated values with one neighbour each, got shape "
            f"{th.shape} and {len(neighbours)} neighbours"
        )
    for bad in th[~np.isfinite(th).all(axis=1)][:1]:  # its error says what is wrong
        as_vector(bad, model.k, f"theta ({', '.join(model.actuated)})")
    return _modes_many(model, th, list(neighbours), backend=backend)


def _complete_set(res, root_count: int) -> bool:
    """Every path ended regular, at ``root_count`` pairwise distinct finite roots."""
    return bool(_complete_sets([res], root_count)[0])


def _complete_sets(results: list, root_count: int, block: int = 1 << 22) -> np.ndarray:
    """:func:`_complete_set` of each result (W,) bool, the pairwise distances of up to
    ``block`` entries at once."""
    from ..algebraic.distinct import pair_distances

    out = np.zeros(len(results), dtype=bool)
    full = [
        i for i, res in enumerate(results)
        if len(res.endpoints) == root_count and (res.status == "success").all()
        and np.isfinite(res.endpoints).all()
    ]  # fmt: skip
    if root_count < 2 or not full:
        out[full] = True
        return out
    n = results[full[0]].endpoints.shape[1]
    step = max(1, block // (root_count * root_count * max(n, 1)))
    for a in range(0, len(full), step):
        rows = full[a : a + step]
        z = np.stack([results[i].endpoints for i in rows])  # (S, R, n)
        scale = 1.0 + np.abs(z).max(axis=2)
        least = np.minimum(scale[:, :, None], scale[:, None])
        # the moduli only where a pair may be nearer than DISTINCT (margin: the division)
        d = pair_distances(z, DISTINCT * (1.0 + 1e-9) * least) / least
        diag = np.arange(root_count)
        d[:, diag, diag] = np.inf
        out[rows] = d.min(axis=(1, 2)) >= DISTINCT
    return out


def _modes_many(
    model: Model,
    thetas: np.ndarray,
    neighbours: list[ModeSeed | None],
    *,
    seed: int = 0,
    progress: bool = False,
    backend: str = "auto",
    max_loops: int = MAX_LOOPS,
    cache: bool = True,
    rebuild: bool = False,
    certified_only: bool = False,
    seeds: bool = True,
) -> list[tuple[AssemblyModes, ModeSeed | None, bool]]:
    """The modes at each of W points (W, k): from its neighbour's set where that gives a
    complete set (all such points in one batch), else from the start system; with
    ``seeds=False`` no point's set is tested for completeness, and only those from a
    neighbour are returned as seeds (a single query does not pass its set on)."""
    from ..algebraic import algebraic_form, solve_homotopy
    from ..algebraic.homotopy import solve_homotopies
    from ..algebraic.scaled import scaled_form

    options = dict(seed=seed, progress=progress, backend=backend, max_loops=max_loops,
                   cache=cache, rebuild=rebuild, certified_only=certified_only,
                   seeds=seeds)  # fmt: skip
    rods, reduced = rod_reduction(model)
    if reduced is not None:  # rods between balls: the distance model's modes, lifted
        distances = _modes_many(reduced, thetas, neighbours, **options)  # type: ignore[arg-type]
        return [
            (
                lifted_modes(model, rods, reduced, modes, th, _certifier(model, th)),
                seed_out,
                used,
            )  # fmt: skip
            for (modes, seed_out, used), th in zip(distances, thetas, strict=True)
        ]
    form = scaled_form(algebraic_form(model, resolve(backend, "modes")))
    start = model_start_system(
        form, seed, progress=progress, max_loops=max_loops, cache=cache, rebuild=rebuild
    )
    W = len(thetas)
    reasons: list[list[str]] = [[] for _ in range(W)]
    if not start.trace_passed:
        why = start.reason or (
            f"trace residual {start.trace_residual:.1e} after {start.loops} monodromy loops"
        )
        for r in reasons:
            r.append(f"start system not proven complete: {why} (rebuild=True recomputes it)")
        if certified_only:
            note = f"not certified: {reasons[0][0]}; its paths not tracked (certified_only)"
            skipped = AssemblyModes(
                solutions=(),
                certified=False,
                root_count=int(start.root_count),
                report=note,
                certificates=(),
                method="homotopy",
            )
            return [(skipped, None, False)] * W
    P0 = np.stack([form.params(th) for th in thetas])
    results: list = [None] * W
    continued = [False] * W
    near = [w for w, nb in enumerate(neighbours) if nb is not None and start.trace_passed]
    if near:
        ends = solve_homotopies(
            form, np.stack([neighbours[w].p for w in near]),  # type: ignore[union-attr]
            np.stack([neighbours[w].roots for w in near]),  # type: ignore[union-attr]
            P0[near], gamma=NEIGHBOUR_GAMMA, real_tol=REAL_TOL,
        )  # fmt: skip
        for w, res, ok in zip(near, ends, _complete_sets(ends, start.root_count), strict=True):
            if ok:
                results[w], continued[w] = res, True
    complete = list(continued)
    for w in range(W):
        if results[w] is None:
            results[w] = solve_homotopy(form, start, P0[w], seed=seed, real_tol=REAL_TOL)
            complete[w] = (
                seeds and start.trace_passed and _complete_set(results[w], start.root_count)
            )
    half_turns = _path_reasons_many(form, results, thetas, reasons)
    found = _real_modes(model, form, results, thetas, reasons)
    certs = _certificates_many(model, [ys for _, _, ys in found], thetas, reasons)
    out = []
    for w in range(W):
        modes = _assembly_modes(start, found[w], certs[w], reasons[w], half_turns[w],
                                continued[w])  # fmt: skip
        out.append((modes, ModeSeed(P0[w], results[w].endpoints) if complete[w] else None,
                    continued[w]))  # fmt: skip
    return out


def _certifier(model: Model, theta0: np.ndarray):
    """``(configurations, reasons) -> certificates`` at ``theta0`` (see :func:`_certificates`)."""

    def certify(cfgs: list[Configuration], reasons: list[str]) -> tuple:
        return _certificates(model, cfgs, theta0, reasons)

    return certify


def _assembly_modes(start, found, certs, reasons, half_turns, continued) -> AssemblyModes:
    """The :class:`AssemblyModes` of one point from its chain's outcomes."""
    cfgs, spurious, _ = found
    certified = not reasons
    if certified:
        source = (
            f"tracked from a neighbouring point's complete set to {start.root_count} distinct "
            "regular ends"
            if continued
            else f"start system complete: {start.certificate}"
        )
        report = (
            f"certified complete: {len(cfgs)} real of {start.root_count} complex solutions "
            f"({source}); each real one proven unique in its Krawczyk box, boxes pairwise "
            "disjoint"
        )
        if spurious:
            report += (
                f"; {spurious} real root(s) of the algebraic form are no closures of the model"
            )
    else:
        report = "not certified: " + "; ".join(reasons)
    if half_turns:
        report += (
            f"; {half_turns} path(s) ended on roots of the form that close a weld with a half "
            "turn (tr R_a^T R_b = -1 on all of them): no closures"
        )
    return AssemblyModes(
        solutions=tuple(cfgs),
        certified=certified,
        root_count=int(start.root_count),
        report=report,
        certificates=certs,
        method="homotopy",
    )


def _path_reasons_many(form, results: list, thetas: np.ndarray, reasons: list[list[str]]) -> list:
    """:func:`_path_reasons` of each point: the points of one path count screened at once,
    the function itself run only where some path failed, ended singular or nearly real."""
    out = [0] * len(results)
    by_paths: dict[tuple, list[int]] = {}
    for w, res in enumerate(results):
        by_paths.setdefault(res.endpoints.shape, []).append(w)
    for group in by_paths.values():
        S = np.stack([results[w].status for w in group])  # (G, R)
        Z = np.stack([results[w].endpoints for w in group])  # (G, R, n)
        ok = S == "success"
        with np.errstate(invalid="ignore"):
            imag = np.abs(Z.imag).max(axis=2) / np.maximum(1.0, np.abs(Z).max(axis=2))
        undecided = ok & (imag > REAL_TOL) & (imag <= UNDECIDED_TOL)
        look = (S == "failed").any(axis=1) | (S == "singular").any(axis=1) | undecided.any(axis=1)
        for w in np.asarray(group)[look].tolist():
            out[w] = _path_reasons(form, results[w], thetas[w], reasons[w])
    return out


def _path_reasons(form, res, theta0: np.ndarray, reasons: list[str]) -> int:
    """What the homotopy's paths leave unproven (appended to ``reasons``); the number of
    singular endpoints that close a weld with a half turn (no closures, set apart)."""
    n_failed = int((res.status == "failed").sum())
    if n_failed:
        reasons.append(f"{n_failed} of {len(res.status)} paths failed before t = 1")
    singular = res.endpoints[res.status == "singular"]
    half_turns = 0
    if len(singular):
        # roots on a set where a weld's rotation rows close with a half turn: no closures
        p0 = form.params(theta0)
        traces = weld_traces(form, p0)(singular)
        G, _, _ = form.evaluate(singular, np.broadcast_to(p0, (len(singular), form.n_params)))
        near = np.abs(G).max(axis=1) <= 1e-6 * (1.0 + np.abs(singular).max(axis=1))
        on_half_turn = near & (np.abs(traces + 1.0) < HALF_TURN).any(axis=1)
        half_turns = int(on_half_turn.sum())
        singular = singular[~on_half_turn]
    if len(singular):
        n_real = int(np.sum(form.is_real(singular, 1e-6)))
        reasons.append(
            f"{len(singular)} path(s) ended at singular points ({n_real} real): multiple or "
            "non-isolated solutions (e.g. a positive-dimensional set), whose real points are "
            "not all listed"
        )
    ok = res.endpoints[res.status == "success"]
    imag = np.abs(ok.imag).max(axis=1) / np.maximum(1.0, np.abs(ok).max(axis=1))
    undecided = int(np.sum((imag > REAL_TOL) & (imag <= UNDECIDED_TOL)))
    if undecided:
        reasons.append(
            f"{undecided} endpoint(s) nearly real (imaginary part between {REAL_TOL:.0e} and "
            f"{UNDECIDED_TOL:.0e}): real or complex undecided"
        )
    return half_turns


def _real_modes(model, form, results, thetas: np.ndarray, reasons: list[list[str]]) -> list:
    """Each point's real endpoints as distinct model configurations polished on ``g``, sorted,
    the number of real roots of the form that are no closures of the model and the
    configurations' canonical unknowns (N_w, m) (all points' kernels in common calls; a
    failure appended to the point's ``reasons``)."""
    scale = max(1.0, model.length_scale)
    Zs = [np.asarray(res.real_solutions, dtype=float) for res in results]
    finite = [np.isfinite(Z).all(axis=1) for Z in Zs]
    dropped = [int((~f).sum()) for f in finite]
    spurious = [0] * len(Zs)
    owner = np.repeat(np.arange(len(Zs)), [int(f.sum()) for f in finite])
    # real endpoints -> model unknowns, polished on g
    Y0, C = form.to_model(  # (K, m), (K, chart size)
        np.concatenate([Z[f] for Z, f in zip(Zs, finite, strict=True)] or [np.zeros((0, form.n))]),
        reference=model.home.y,
    )
    Th = thetas[owner]
    Y, R = _polish(model, Y0, C, Th)
    good = R <= RESIDUAL
    for i in np.flatnonzero(~good).tolist():
        w = int(owner[i])
        if R[i] > SPURIOUS * scale and model.residual(Y0[i], thetas[w], C[i]) > SPURIOUS * scale:
            spurious[w] += 1  # a root of the form that is no closure of the model
        else:
            dropped[w] += 1
    polished, ys, xs = model.configuration_table(Y[good], Th[good], C[good], R[good])
    # distinct endpoints of the homotopy are distinct roots; only images of one configuration
    # (polished to the same point) are merged: two real solutions next to a singular surface
    # may lie 1e-5 model sizes apart, and the Krawczyk boxes below decide (they must be
    # pairwise disjoint)
    feats = features(model, ys)
    keys = mode_orders(xs if len(xs) else np.zeros((0, 0)), ys)
    per_point: list[list[int]] = [[] for _ in Zs]
    for i, w in enumerate(owner[good].tolist()):
        per_point[w].append(i)
    out = []
    for w, rows in enumerate(per_point):
        kept = [rows[j] for j in _first_of_images(feats[rows], DUPLICATE * scale)]
        if dropped[w]:
            reasons[w].append(
                f"{dropped[w]} real endpoint(s) did not polish to max |g| <= {RESIDUAL:.0e}"
            )
        kept.sort(key=keys.__getitem__)  # stable, as sorting the configurations by mode_order
        out.append(([polished[i] for i in kept], spurious[w], ys[kept]))
    return out


def _first_of_images(feats: np.ndarray, tol: float) -> list[int]:
    """The rows of ``feats`` (R, d) kept in order, each unless some kept row lies within
    ``tol`` of it (max-norm): all pairs compared at once (by their first coordinate, then,
    where two may meet, by all), the in-order rule run only where two rows meet."""
    from ..algebraic.distinct import pairs_apart

    R = len(feats)
    if R < 2 or pairs_apart(feats[None], tol):  # no two rows meet
        return list(range(R))
    dist = np.abs(feats[:, None] - feats[None]).max(axis=2)
    near = dist <= tol
    if np.count_nonzero(near) == np.count_nonzero(near.diagonal()):  # no two rows meet
        return list(range(R))
    kept: list[int] = []
    for i in range(R):
        d = dist[kept, i]
        if kept and not np.isnan(d).any() and d.min() <= tol:  # as min() of the column
            continue
        kept.append(i)
    return kept


def _certificates(model, cfgs, theta0: np.ndarray, reasons: list[str]) -> tuple:
    """Krawczyk certificates of the real configurations in one common chart (a failure
    appended to ``reasons``)."""
    ys = np.vstack([c.y for c in cfgs] or [np.zeros((0, model.m))])
    return _certificates_many(model, [ys], theta0[None], [reasons])[0]


def _certificates_many(model, ys_list, thetas: np.ndarray, reasons: list[list[str]]) -> list:
    """:func:`_certificates` of several points' configurations, each point's canonical
    unknowns (N_w, m) in ``ys_list``, the C tests of all in one call."""
    from ..algebraic import CertificateSet, certify_configuration_sets

    out: list[tuple] = [() for _ in ys_list]
    todo, sets = [], []
    for w, ys in enumerate(ys_list):
        if len(ys):
            todo.append(w)
            sets.append((ys, thetas[w], _common_chart(model, ys)))
    done: list[CertificateSet | None]
    try:
        done = list(certify_configuration_sets(model, sets))
    except ScdkError:  # which set: each on its own, as a single query makes them
        done = []
        for w, st in zip(todo, sets, strict=True):
            try:
                done.append(certify_configuration_sets(model, [st])[0])
            except ScdkError as exc:
                reasons[w].append(f"certificates not computed: {exc}")
                done.append(None)
    for w, cs in zip(todo, done, strict=True):
        if cs is None:
            continue
        out[w] = cs.certificates
        if not cs.proven:
            reasons[w].append(f"certificates: {cs.reason}")
    return out
