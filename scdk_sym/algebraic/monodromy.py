"""Start systems by monodromy, certified complete by a trace test, cached on disk.

Monodromy (Duff, Hill, Jensen, Lee, Leykin, Sommars 2019): the start pair ``(z*, p*)`` is a
random point of the system with offsets ``b* = -G(z*, p*)`` on the offset rows, so ``z*``
solves ``F(z; p*, b*) = 0``. Every loop tracks all known solutions around a random triangle
``(p*, b*) -> (p1, b1) -> (p2, b2) -> (p*, b*)`` of complex parameters; endpoints not yet
known are new solutions. Since the incidence variety ``{(z, b): G(z, p*) + b = 0}`` is a graph
over the (irreducible) structural variety, the monodromy group acts transitively, and loops
eventually reach every solution.

Trace test (Leykin, Rodriguez, Sottile 2018): along the offset pencil
``b(lambda) = b* + lambda v`` the sum ``T(lambda)`` of ``f(z_j)`` over the whole fibre is a
symmetric function of it: single valued, and a polynomial in ``lambda`` as long as ``f`` stays
finite (no pole), whereas the sum over a proper subset is not single valued (the monodromy of
a general line is the full group). The test samples ``T`` at ``K`` points
``rho e^(2 pi i (k + u)/K)`` and requires its Fourier modes above ``degree`` to vanish relative
to ``sum_j |f(z_j)|``; ``degree = 1`` is the linear trace of the paper, which holds for every
system tested here. ``f`` must stay finite along the pencil: an affine chart is not enough
(on a 6-6 platform the quaternion ``q`` in the chart ``a . q = 1`` goes to infinity where the
complex rotation's quaternion crosses ``a . q = 0``, so the trace of ``z`` has poles); a
system may therefore provide ``trace_map(z) -> (N, m)``, polynomial functions that stay
finite there (e.g. translation and rotation matrix entries); otherwise ``f(z) = z``. A poorly
chosen ``f`` only makes a complete set fail the test (a false negative), never the reverse.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import HomotopyError
from .distinct import dedup
from .homotopy import track_parameter_homotopy
from .parameter_homotopy import ParameterHomotopy
from .paths.continuation import TrackerOptions, newton, rel_norm
from .system import PolynomialSystem

#: Version of the engine; part of the cache key of start systems.
ENGINE_VERSION = "1"


@dataclass(frozen=True)
class StartSystem:
    """A complete solution set of the family at one generic complex parameter point.

    Attributes:
        p: (n_params,) complex base parameters ``p*``.
        b: (n,) complex base offsets ``b*`` (zero on structural rows).
        solutions: (R, n) complex, every solution of ``G(z, p*) + b* = 0``.
        root_count: R.
        trace_residual: relative size of the trace's non-polynomial Fourier modes (NaN when
            the set was proven complete without a trace test).
        trace_passed: the set passed its completeness test (the trace test,
            ``trace_residual <= trace_tol``, or the one ``certificate`` names): it is complete.
        loops: monodromy loops run.
        seed: the seed the start system was computed with.
        reason: why the set is not proven complete (empty when ``trace_passed``).
        root_bound: an upper bound on the isolated roots of the family at ``p*`` (e.g. the
            BKK bound of :mod:`scdk_sym.algebraic.rootbound`); -1 when none was computed.
        certificate: what proved the set complete (empty when ``trace_passed`` is False).
    """

    p: np.ndarray
    b: np.ndarray
    solutions: np.ndarray
    root_count: int
    trace_residual: float
    trace_passed: bool
    loops: int
    seed: int
    reason: str = ""
    root_bound: int = -1
    certificate: str = ""


@dataclass(frozen=True)
class LoopRules:
    """When the loops of :func:`monodromy_solve` run the completeness test, and when they stop.

    Attributes:
        stable_loops: loops without a new solution before the trace test.
        max_loops: bound on the loops.
        trace_tol: largest trace residual of a complete set.
        target: the number of solutions at which the test runs at once (an upper bound on
            the isolated solutions: no loop can add one beyond it); ``None``: no target.
        budget: CPU time [s] after which no new loop starts (``None``: no limit); the set
            found so far is returned, its test not passed.
    """

    stable_loops: int = 5
    max_loops: int = 200
    trace_tol: float = 1e-8
    target: int | None = None
    budget: float | None = None


#: The keywords of :func:`monodromy_solve` that are :class:`LoopRules`.
_RULES = tuple(f.name for f in fields(LoopRules))


def _cnormal(rng: np.random.Generator, shape) -> np.ndarray:
    return (rng.normal(size=shape) + 1j * rng.normal(size=shape)) / np.sqrt(2.0)


def _track_segment(system, z, pa, pb, ba, bb, options):
    """Track the points z (M, n) from (pa, ba) to (pb, bb) along one straight segment."""
    hom = ParameterHomotopy(system, pa[None], pb[None], ba[None], bb[None], [1.0])
    return track_parameter_homotopy(
        system, z, hom, np.zeros(len(z), dtype=int), options, endgame=False
    )


def refine_solutions(system, z, p, b):
    """Newton-polish points at (p, b); returns the points and a mask of the converged ones."""
    if len(z) == 0:
        return z, np.zeros(0, dtype=bool)
    hom = ParameterHomotopy(system, p[None], p[None], b[None], b[None], [1.0])
    z, nu = newton(hom, z, np.zeros(len(z), dtype=complex), np.zeros(len(z), dtype=int), 2)
    return z, np.isfinite(z).all(axis=1) & (nu[:, -1] <= 1e-11)


def trace_test(
    system: PolynomialSystem,
    solutions: np.ndarray,
    p: np.ndarray,
    b: np.ndarray,
    rng: np.random.Generator,
    *,
    samples: int = 16,
    degree: int = 1,
    radius: float = 0.5,
    trace_map: Callable[[np.ndarray], np.ndarray] | None = None,
    options: TrackerOptions | None = None,
) -> float:
    """Relative size of the part of the trace above ``degree`` along a random offset pencil.

    Args:
        system: the polynomial system.
        solutions: (R, n) complex solutions at ``(p, b)``.
        p: (n_params,) complex base parameters.
        b: (n,) complex base offsets.
        rng: random generator (pencil direction and sample phase).
        samples: Fourier samples ``K`` (> degree + 1).
        degree: the trace's degree in ``lambda`` for a complete set.
        radius: sample circle radius, relative to ``1 + max|b|`` (or ``|p|`` without offsets).
        trace_map: ``f``, (N, n) -> (N, m); default ``system.trace_map`` if it exists, else z.
        options: tracker step control.

    Returns:
        ``max_{degree < m < K} |c_m|_inf / mean_k sum_j |f(z_j(lambda_k))|_inf``; ``inf`` if a
        path failed or two paths met (a path jump).
    """
    f = trace_map or getattr(system, "trace_map", None) or (lambda z: z)
    R, n = solutions.shape
    offs = np.asarray(system.offset_rows, dtype=bool)
    if offs.any():
        vb = np.where(offs, _cnormal(rng, n), 0.0) * (1.0 + np.abs(b).max())
        vp = np.zeros(system.n_params, dtype=complex)
    else:
        vb = np.zeros(n, dtype=complex)
        vp = _cnormal(rng, system.n_params) * (1.0 + np.abs(p).max())
    lam = radius * np.exp(2j * np.pi * (np.arange(samples) + rng.uniform()) / samples)
    pb = p[None] + lam[:, None] * vp[None]
    bb = b[None] + lam[:, None] * vb[None]
    hom = ParameterHomotopy(
        system,
        np.repeat(p[None], samples, 0),
        pb,
        np.repeat(b[None], samples, 0),
        bb,
        np.ones(samples),
    )
    z = np.tile(solutions, (samples, 1))
    idx = np.repeat(np.arange(samples), R)
    ends = track_parameter_homotopy(system, z, hom, idx, options, endgame=False)
    if not (ends.status == "success").all():
        return float("inf")
    zk = ends.z.reshape(samples, R, n)
    for k in range(samples):  # a path jump would merge two solutions
        if len(dedup(zk[k], 1e-8)) != R:
            return float("inf")
    fk = np.asarray(f(ends.z)).reshape(samples, R, -1)
    c = np.fft.fft(fk.sum(axis=1), axis=0) / samples
    scale = np.abs(fk).max(axis=2).sum(axis=1).mean()
    return float(np.abs(c[degree + 1 :]).max() / scale)


def monodromy_solve(
    system: PolynomialSystem,
    seed: int = 0,
    *,
    trace_map: Callable[[np.ndarray], np.ndarray] | None = None,
    options: TrackerOptions | None = None,
    progress: bool = True,
    test: Callable[[np.ndarray, np.ndarray, np.ndarray], float] | None = None,
    start: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    **rules: Any,
) -> StartSystem:
    """A complete start system by monodromy loops and a trace test.

    Loops run until the solution count has not changed for ``stable_loops`` loops (or has
    reached ``target``); then the completeness test runs and the loops stop as soon as it
    passes; if it fails, loops continue (and the test reruns when the count is stable again)
    until ``max_loops``.

    Args:
        system: the polynomial system.
        seed: seed of every random choice (start pair, loops, pencil).
        trace_map: the traced functions (see :func:`trace_test`).
        options: tracker step control.
        progress: show a tqdm progress bar (on stderr, after the first 2 s).
        test: ``test(solutions, p, b) -> residual``, the completeness test (default:
            :func:`trace_test` with ``trace_map``); the set is complete when the residual is
            at most ``trace_tol``.
        start: ``(z0 (n,), p (n_params,), b (n,))``, a known solution ``G(z0, p) + b = 0``
            to start the loops from (default: ``system.random_point`` with ``b = -G``).
        **rules: the fields of :class:`LoopRules` as keywords (``stable_loops``,
            ``max_loops``, ``trace_tol``, ``target``, ``budget``), each defaulting to its
            default there.

    Returns:
        A :class:`StartSystem` (``trace_passed`` False if the budget ran out, ``reason``
        saying so).

    Raises:
        HomotopyError: the random point does not satisfy the structural rows.
        TypeError: a keyword that is no field of :class:`LoopRules`.
    """
    from tqdm.auto import tqdm

    unknown = [name for name in rules if name not in _RULES]
    if unknown:
        raise TypeError(f"monodromy_solve() got an unexpected keyword argument {unknown[0]!r}")
    r = LoopRules(**rules)

    rng = np.random.default_rng(seed)
    offs = np.asarray(system.offset_rows, dtype=bool)
    z0, p, b = _start_pair(system, rng, offs, start)
    sols = z0[None].copy()
    # the system's own step per parameter if it has one (a form's angles), else |p|'s size
    pscale = getattr(system, "param_widths", None)
    scales = (1.0 + np.abs(p).max() if pscale is None else pscale, 1.0 + np.abs(b).max())
    residual, passed, stable, loops = float("inf"), False, 0, 0
    failed_count = -1  # solution count at the last failed completeness test
    if test is None:

        def test(sols, p, b):
            return trace_test(system, sols, p, b, rng, trace_map=trace_map, options=options)

    bar = tqdm(
        total=r.max_loops, desc="monodromy", unit="loop", disable=not progress, leave=False, delay=2
    )
    deadline = math.inf if r.budget is None else time.process_time() + r.budget
    out_of_time = False
    try:
        while loops < r.max_loops:
            if time.process_time() > deadline:
                out_of_time = True
                break
            before = len(sols)
            sols = _loop(system, sols, p, b, scales, offs, rng, options)
            loops += 1
            stable = stable + 1 if len(sols) == before else 0
            bar.update(1)
            bar.set_postfix(solutions=len(sols))
            if stable >= r.stable_loops or (len(sols) != before and len(sols) == r.target):
                residual = float(test(sols, p, b))
                passed = residual <= r.trace_tol
                bar.set_postfix(solutions=len(sols), trace=f"{residual:.0e}")
                if passed:
                    break
                # the same count failed its test before, 2 x stable_loops loops without a
                # new solution: more loops of this kind are not finding any
                if failed_count == len(sols):
                    break
                failed_count = len(sols)
                stable = 0
    finally:
        bar.close()
    reason = (
        "" if passed else _failure(residual, r.trace_tol, loops, len(sols), out_of_time, r.budget)
    )
    return StartSystem(p, b, sols, len(sols), residual, passed, loops, seed, reason=reason)


def _start_pair(system: PolynomialSystem, rng: np.random.Generator, offs: np.ndarray, start):
    """The first solution ``z0`` of the loops, at parameters ``p`` and offsets ``b``."""
    if start is None:
        z0, p = system.random_point(rng)
        z0, p = np.asarray(z0, dtype=complex), np.asarray(p, dtype=complex)
        G, _, _ = system.evaluate(z0[None], p[None])
        G = G[0]
        if np.abs(G[~offs]).max(initial=0.0) > 1e-10 * (1.0 + np.abs(z0).max()):
            raise HomotopyError(
                f"random_point gives structural residual {np.abs(G[~offs]).max():.1e}; "
                "fix the system's random_point so structural rows vanish"
            )
        return z0, p, np.where(offs, -G, 0.0)
    z0, p, b = (np.asarray(x, dtype=complex) for x in start)
    G = system.evaluate(z0[None], p[None])[0][0] + b
    if np.abs(G).max(initial=0.0) > 1e-10 * (1.0 + np.abs(z0).max()):
        raise HomotopyError(f"the given start is no solution (residual {np.abs(G).max():.1e})")
    return z0, p, b


def _loop(system, sols, p, b, scales, offs, rng, options) -> np.ndarray:
    """One monodromy loop through two random parameter points: ``sols`` and the new
    solutions it brought back (refined, distinct)."""
    pscale, bscale = scales
    nodes = [(p, b)]
    for _ in range(2):
        nodes.append(
            (
                p + pscale * _cnormal(rng, p.shape),
                b + bscale * np.where(offs, _cnormal(rng, b.shape), 0),
            )
        )
    nodes.append((p, b))
    z = sols
    for (pa, ba), (pc, bc) in zip(nodes[:-1], nodes[1:], strict=True):
        ends = _track_segment(system, z, pa, pc, ba, bc, options)
        z = ends.z[ends.status == "success"]
    z, ok = refine_solutions(system, z, p, b)
    for row in z[ok]:
        if rel_norm(sols - row[None], sols).min() > 1e-8:
            sols = np.vstack([sols, row[None]])
    return sols


def _failure(
    residual: float, trace_tol: float, loops: int, count: int, out_of_time: bool, budget
) -> str:
    """Why a set is not proven complete after its loops."""
    if out_of_time:
        return f"out of time ({budget:g} s of CPU) after {loops} monodromy loops, {count} solutions"
    if np.isfinite(residual):
        return (
            f"trace test failed (residual {residual:.1e} > {trace_tol:.0e}) after {loops} "
            f"monodromy loops, {count} solutions"
        )
    return (
        f"no completeness test passed: {count} solutions after {loops} monodromy loops "
        "(the count never stayed stable, or paths failed along the trace pencil)"
    )


def cache_path(system: PolynomialSystem, seed: int) -> Path:
    """Cache file of a start system: ``<cache_dir>/homotopy/<hash>-v<version>-s<seed>.npz``."""
    from ..kernels.cache import cache_dir

    d = cache_dir() / "homotopy"
    d.mkdir(parents=True, exist_ok=True)
    return d / f"{system.content_hash()}-v{ENGINE_VERSION}-s{seed}.npz"


def start_system(
    system: PolynomialSystem,
    seed: int = 0,
    *,
    cache: bool = True,
    progress: bool = True,
    **kwargs,
) -> StartSystem:
    """The start system of ``system``: loaded from the cache, else by :func:`monodromy_solve`.

    The cache (under :func:`scdk_sym.kernels.cache.cache_dir`, ``SCDK_CACHE_DIR`` honoured) is
    keyed by ``system.content_hash()``, :data:`ENGINE_VERSION` and ``seed``; only start
    systems whose trace test passed are stored, and a loaded one is re-checked (residuals).

    Args:
        system: the polynomial system.
        seed: seed of the monodromy.
        cache: read and write the disk cache.
        progress: show a progress bar during monodromy.
        **kwargs: passed to :func:`monodromy_solve`.

    Returns:
        A :class:`StartSystem`.
    """
    from ..kernels.cache import read_entry, write_entry

    def read(path: Path) -> StartSystem | None:
        with np.load(path) as f:
            s = StartSystem(
                p=f["p"],
                b=f["b"],
                solutions=f["solutions"],
                root_count=int(f["root_count"]),
                trace_residual=float(f["trace_residual"]),
                trace_passed=bool(f["trace_passed"]),
                loops=int(f["loops"]),
                seed=int(f["seed"]),
            )
        _, ok = refine_solutions(system, s.solutions, s.p, s.b)
        return s if ok.all() and len(s.solutions) == s.root_count else None

    path = cache_path(system, seed) if cache else None
    stored = None if path is None else read_entry(path, read, "start system")
    if stored is not None:
        return stored
    s = monodromy_solve(system, seed, progress=progress, **kwargs)
    if path is not None and s.trace_passed:
        fields = {name: getattr(s, name) for name in _STORED}
        write_entry(path, lambda tmp: _savez(tmp, fields))
    return s


#: The fields of a :class:`StartSystem` that :func:`start_system` stores.
_STORED = ("p", "b", "solutions", "root_count", "trace_residual", "trace_passed", "loops", "seed")


def _savez(path: Path, fields: dict) -> None:
    """``np.savez`` to exactly ``path`` (through a file object: no ``.npz`` appended)."""
    with open(path, "wb") as f:
        np.savez(f, **fields)
