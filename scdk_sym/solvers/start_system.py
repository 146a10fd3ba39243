"""The start system of a model's algebraic form, proven complete and cached on disk.

Every complex root at one random parameter point, with the proof that none is missing.
Monodromy from a random complex parameter point, tested for completeness by the form's BKK
root bound (:mod:`scdk_sym.algebraic.rootbound`) or a trace test
(:func:`scdk_sym.algebraic.trace_test`) on the placements of the model's frames
(:func:`~scdk_sym.solvers.form_maps.frame_trace_map`); every result, proven or not, is stored
under the form's content hash and kept on the model (``START_SYSTEM``).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import ScdkError
from ..kernels.cache import read_entry, write_entry
from ..products import START_SYSTEM
from .form_maps import frame_trace_map

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
