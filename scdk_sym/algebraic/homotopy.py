"""Parameter homotopies of a :class:`PolynomialSystem` and the query solve from a start system.

The family is ``F(z; p, b) = G(z, p) + b`` (``b = 0`` on structural rows). A path runs from
``(p_a, b_a)`` to ``(p_b, b_b)`` along ``p(s) = p_a + s (p_b - p_a)``, ``b(s)`` likewise, with
the gamma trick ``s(t) = gamma t / (1 + (gamma - 1) t)``, ``t`` real in [0, 1]: for a random
unit complex ``gamma`` the path ``s`` is a circular arc from 0 to 1 that, with probability
one, meets no singular member of the family before ``t = 1``.

:func:`solve_homotopy` tracks the straight segment (``gamma = 1``) first: its start
``(p*, b*)`` is a random complex point, and the parameters where some solution is singular
or escapes (the discriminant) form a complex hypersurface, of real codimension 2, so for all
targets but a set of measure zero the real segment from ``(p*, b*)`` meets it at most at
``t = 1`` (the parameter homotopy of HomotopyContinuation.jl is this segment). It is
shorter than an arc (about half the steps on 6-6 platforms; an arc with ``gamma`` near -1
swings far out). A path that fails on it is retried on arcs with random ``gamma``.

The homotopy itself is :class:`~scdk_sym.algebraic.parameter_homotopy.ParameterHomotopy`;
the real points among the endpoints are :mod:`scdk_sym.algebraic.real_endpoints`, distinct
rows :mod:`scdk_sym.algebraic.distinct`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import HomotopyError, InputError
from .distinct import dedup, pair_distances
from .endgame import EG_INFINITY, EG_SINGULAR, cauchy_endgame
from .parameter_homotopy import ParameterHomotopy
from .paths.continuation import DIVERGED, DONE, TrackerOptions, newton, track
from .paths.continuation_c import c_tracker
from .real_endpoints import real_endpoints, real_endpoints_many
from .system import PolynomialSystem

#: Path statuses of :class:`PathEndpoints` and :class:`HomotopyResult`.
STATUSES = ("success", "singular", "at_infinity", "failed")


@dataclass(frozen=True)
class PathEndpoints:
    """Endpoints at t = 1 of a batch of parameter-homotopy paths.

    Attributes:
        z: (M, n) complex endpoints (NaN where failed or at infinity).
        status: (M,) str, one of :data:`STATUSES`.
        winding: (M,) int winding numbers (1 for regular endpoints, 0 if unknown).
        steps: (M,) int tracker step attempts.
    """

    z: np.ndarray
    status: np.ndarray
    winding: np.ndarray
    steps: np.ndarray


def scaled_cond(J: np.ndarray) -> np.ndarray:
    """Condition numbers (M,) of (M, n, n) matrices after scaling rows, then columns, to unit
    max norm (so that a badly scaled chart coordinate is not taken for a singularity)."""
    with np.errstate(all="ignore"):
        J = J / np.abs(J).max(axis=2, keepdims=True)
        J = J / np.abs(J).max(axis=1, keepdims=True)
        c = np.linalg.cond(J) if len(J) else np.zeros(0)
    return np.where(np.isfinite(c), c, np.inf)


def _regular(system, homotopy, z, idx, cond_max, ctrack=None, refined=None) -> tuple:
    """Newton-refine endpoints at t = 1; regular where it converges and J is well conditioned
    (the Newton steps in C with the C tracker ``ctrack``, else in numpy; ``refined``: the C
    steps' ``(z, nu, bound)`` already made, as :meth:`CTracker.track_split` gives them)."""
    if ctrack is not None:
        if refined is None:
            z_new, nu, Hz, bound = ctrack.newton(homotopy, z, np.ones(len(z)), idx, 2)
        else:
            (z_new, nu, bound), Hz = refined, None
        # the 2-norm condition number is at most the bound (Frobenius norms): the SVD only
        # where the bound does not decide (half of cond_max: room for rounding)
        well = bound <= 0.5 * cond_max
        if not well.all():
            open_ = np.flatnonzero(~well)
            if Hz is None:  # the same steps again (the same values) for their H_z
                Hz_open = ctrack.newton(homotopy, z[open_], np.ones(open_.size), idx[open_], 2)[2]
            else:
                Hz_open = Hz[open_]
            well[open_] = scaled_cond(Hz_open) <= cond_max
        z = z_new
    else:
        t1 = np.ones(len(z), dtype=complex)
        z, nu = newton(homotopy, z, t1, idx, 2)
        _, Hz, _ = homotopy(z, t1, idx)
        well = scaled_cond(Hz) <= cond_max
    ok = np.isfinite(z).all(axis=1) & (nu[:, -1] <= 1e-10) & well
    return z, ok


def track_parameter_homotopy(
    system: PolynomialSystem,
    z: np.ndarray,
    homotopy: ParameterHomotopy,
    idx: np.ndarray,
    options: TrackerOptions | None = None,
    endgame: bool = True,
    r0: float = 0.01,
    cond_max: float = 1e13,
    tracker: str = "python",
) -> PathEndpoints:
    """Track paths of a parameter homotopy from t = 0 to t = 1.

    Args:
        system: the polynomial system.
        z: (M, n) complex start points (solutions at t = 0).
        homotopy: the homotopy, with per-path data selected by ``idx``.
        idx: (M,) int path data indices.
        options: tracker step control.
        endgame: run the Cauchy endgame on paths that do not end regular (else they fail).
        r0: the endgame starts at t = 1 - r0.
        cond_max: largest condition number of H_z (rows and columns scaled) at a regular
            endpoint.
        tracker: ``"python"`` (numpy), ``"c"`` or ``"auto"`` (see
            :func:`~scdk_sym.algebraic.paths.continuation_c.c_tracker`): who tracks the
            straight part of the paths; the endgame always runs in numpy.

    Returns:
        :class:`PathEndpoints`.
    """
    M = len(z)
    idx = np.asarray(idx)
    tmap = _identity
    status = np.full(M, "failed", dtype=object)
    winding = np.zeros(M, dtype=int)
    out = np.full((M, system.n), np.nan + 0j)
    if M == 0:
        return PathEndpoints(out, status.astype(str), winding, np.zeros(0, dtype=int))
    t_split = 1.0 - r0 if endgame else 1.0
    ctrack = c_tracker(system, tracker)
    if not (isinstance(homotopy, ParameterHomotopy) and homotopy.system is system):
        ctrack = None  # the C tracker evaluates the system's own G

    def segment(z0, ix, tau0, tau1, h0=None):
        if ctrack is not None:
            return ctrack(homotopy, z0, ix, tau0, tau1, options, h0)
        return track(homotopy, tmap, z0, ix, tau0, tau1, options, h0)

    if endgame:
        refined = None
        if ctrack is not None:  # one call: both parts (a path's second in its lane), Newton
            sp = ctrack.split(homotopy, z, idx, t_split, options)
            ok1, z_split, steps = sp.reached, sp.z_split, sp.end.steps
            z_end, s_end = sp.end.z[ok1], sp.end.status[ok1]
            refined = (sp.z_newton, sp.nu, sp.bound)
        else:
            first = segment(z, idx, np.zeros(M), np.full(M, t_split))
            ok1 = np.flatnonzero(first.status == DONE)
            z_split = first.z[ok1]
            second = segment(z_split, idx[ok1], first.tau[ok1], np.ones(ok1.size), first.h[ok1])
            steps, z_end, s_end = first.steps.copy(), second.z, second.status
            steps[ok1] += second.steps
        arrived = np.flatnonzero(s_end == DONE)
        zr, reg = _regular(system, homotopy, z_end[arrived], idx[ok1[arrived]], cond_max, ctrack,
                           refined)  # fmt: skip
        good = ok1[arrived[reg]]
        out[good], status[good], winding[good] = zr[reg], "success", 1
        left = np.ones(ok1.size, dtype=bool)  # reached 1 - r0, not ended regular
        left[arrived[reg]] = False
        rest = ok1[left]
        if rest.size:
            eg = cauchy_endgame(homotopy, z_split[left], idx[rest], r0, options)
            sing = eg.verdict == EG_SINGULAR
            out[rest[sing]], status[rest[sing]] = eg.z[sing], "singular"
            status[rest[eg.verdict == EG_INFINITY]] = "at_infinity"
            winding[rest] = eg.winding
    else:
        first = segment(z, idx, np.zeros(M), np.full(M, t_split))
        steps = first.steps.copy()
        # before t = 1 a path only diverges by passing close to a solution's escape
        # (probability zero for a random start): "failed", so that the caller may retry with
        # another gamma
        status[first.status == DIVERGED] = "at_infinity"
        ok1 = np.flatnonzero(first.status == DONE)
        zr, reg = _regular(system, homotopy, first.z[ok1], idx[ok1], cond_max, ctrack)
        good = ok1[reg]
        out[good], status[good], winding[good] = zr[reg], "success", 1
    _fail_jumps(out, status, idx)
    return PathEndpoints(out, status.astype(str), winding, steps)


def _fail_jumps(out: np.ndarray, status: np.ndarray, idx: np.ndarray) -> None:
    """A regular solution ends exactly one path: two paths at one regular endpoint of the same
    target (datum) mean a path jump, and both fail (``status`` and ``out`` changed in place).
    Data with equally many regular ends are compared all at once."""
    ends = np.flatnonzero(status == "success")
    if ends.size < 2:
        return
    ie = idx[ends]
    if (ie == ie[0]).all():  # one datum (a single query)
        groups_by_size = {int(ends.size): [ends[None]]}
    else:
        groups_by_size = _blocks_by_size(ends, ie)
    for size, blocks in groups_by_size.items():
        if size < 2:
            continue
        rows = np.concatenate(blocks)  # (G, size)
        zs = out[rows]  # (G, size, n)
        # the scale of the column's end, as one datum's (size, size) takes it
        bound = 1e-8 * (1.0 + np.abs(zs).max(axis=2))[:, None, :]
        close = pair_distances(zs, bound) <= bound
        jumped = rows[close.sum(axis=2) > 1]
        status[jumped], out[jumped] = "failed", np.nan


def _blocks_by_size(ends: np.ndarray, ie: np.ndarray) -> dict[int, list[np.ndarray]]:
    """The paths ``ends`` (E,) grouped by their data ``ie`` (E,): number of paths -> blocks
    (1, size) or (G, size), one row per datum (all data at once when sizes agree)."""
    if np.any(ie[1:] < ie[:-1]):
        order = np.argsort(ie, kind="stable")
        ends, ie = ends[order], ie[order]
    first = np.concatenate([[0], np.flatnonzero(ie[1:] != ie[:-1]) + 1])
    sizes = np.diff(np.append(first, len(ie)))
    if np.all(sizes == sizes[0]):  # every datum with equally many ends: one block
        return {int(sizes[0]): [ends.reshape(len(first), int(sizes[0]))]}
    out: dict[int, list[np.ndarray]] = {}
    for a, k in zip(first.tolist(), sizes.tolist(), strict=True):
        out.setdefault(k, []).append(ends[a : a + k][None])
    return out


def _identity(tau, idx):
    return tau + 0j, np.ones_like(tau, dtype=complex)


@dataclass(frozen=True)
class HomotopyResult:
    """All solutions of G(z, p0) = 0 reached from a start system.

    Attributes:
        endpoints: (R, n) complex endpoint of every start solution's path (NaN if none).
        status: (R,) str per path: ``"success"`` (regular endpoint), ``"singular"`` (endpoint
            located by the Cauchy endgame, see ``winding``), ``"at_infinity"``, ``"failed"``.
        winding: (R,) int winding number of each path at t = 1 (0 where unknown).
        real_solutions: (K, n) float, the distinct real endpoints (regular ones refined by
            real Newton), sorted lexicographically.
        complete: every path ended at t = 1 regular, singular with a converged endgame, or
            at infinity — with a complete start system, every isolated solution at ``p0`` is
            then among ``endpoints``.
        start_certified: the start system passed its trace test (``complete`` and this
            together: the list is complete).
        gamma: the complex gamma of the homotopy (1: the straight segment).
        steps: (R,) int tracker step attempts per path.
        attempts: homotopies tried (the straight segment, then an arc with a new gamma while a
            path failed on the way).
    """

    endpoints: np.ndarray
    status: np.ndarray
    winding: np.ndarray
    real_solutions: np.ndarray
    complete: bool
    start_certified: bool
    gamma: complex
    steps: np.ndarray
    attempts: int


def solve_homotopy(
    system: PolynomialSystem,
    start,
    p0: np.ndarray,
    *,
    seed: int = 0,
    options: TrackerOptions | None = None,
    real_tol: float = 1e-8,
    attempts: int = 3,
    tracker: str = "auto",
    gamma: complex = 1.0,
) -> HomotopyResult:
    """Every solution of G(z, p0) = 0 by the parameter homotopy from a start system.

    Tracks all ``start.root_count`` paths from ``(start.p, start.b)`` to ``(p0, b = 0)`` on
    the straight segment, then, while a path fails on the way, on arcs of the gamma trick
    (see the module documentation); paths that do not end regular go through the Cauchy
    endgame.

    Args:
        system: the polynomial system the start system was computed for.
        start: a :class:`~scdk_sym.algebraic.monodromy.StartSystem` of ``system``.
        p0: (n_params,) target parameters (real for a physical query; complex allowed).
        seed: seed of the random gammas of the attempts after the first.
        options: tracker step control.
        real_tol: largest ``max|Im z| / (1 + max|z|)`` of a real solution.
        attempts: homotopies tried while some path fails on the way (the straight segment,
            then arcs with random gammas; each attempt reruns all paths).
        tracker: ``"auto"`` (the C tracker for a model's algebraic form when a C compiler is
            present, else numpy), ``"c"`` or ``"python"``.
        gamma: the gamma of the first attempt (1: the straight segment; a non-real one: an
            arc through complex parameters, which misses the real discriminant between two
            real parameter points).

    Returns:
        A :class:`HomotopyResult` (of the last attempt).

    Raises:
        InputError: ``p0`` has the wrong shape or is not finite.
        HomotopyError: the start system does not belong to ``system``.
    """
    p0 = np.asarray(p0, dtype=complex).ravel()
    if p0.shape != (system.n_params,) or not np.isfinite(p0).all():
        raise InputError(
            f"p0 must be {system.n_params} finite parameters, got shape {p0.shape}; "
            "pass the model's parameter vector"
        )
    if start.solutions.shape[1:] != (system.n,) or start.p.shape != (system.n_params,):
        raise HomotopyError(
            f"start system of shape {start.solutions.shape} does not fit a system with "
            f"n = {system.n}; recompute it with start_system(system)"
        )
    rng = None  # made on the first retry
    attempt = 0
    while attempt < attempts:
        attempt += 1
        # a path that fails on the way passed close to a point where its solution escapes to
        # infinity; an arc with a random gamma moves every path away from it (all paths are
        # rerun, so the endpoints stay one arc's complete set)
        if attempt == 1:
            g = complex(gamma)
        else:
            rng = rng or np.random.default_rng(seed)
            g = complex(np.exp(2j * np.pi * rng.uniform()))
        ends = _track_all(system, start.p[None], start.b[None], start.solutions[None],
                          p0[None], g, options, tracker)  # fmt: skip
        if not (ends.status == "failed").any():
            break
    return _results(system, ends, p0[None], g, attempt, bool(start.trace_passed), real_tol,
                    tracker)[0]  # fmt: skip


def solve_homotopies(
    system: PolynomialSystem,
    p_from: np.ndarray,
    roots: np.ndarray,
    P0: np.ndarray,
    *,
    gamma: complex,
    options: TrackerOptions | None = None,
    real_tol: float = 1e-8,
    tracker: str = "auto",
    start_certified: bool = True,
) -> list[HomotopyResult]:
    """One homotopy attempt to each of several targets, all paths tracked in one batch.

    Target ``w`` is reached from the roots ``roots[w]`` at ``p_from[w]`` (offsets ``b`` zero)
    along the arc of ``gamma``; each target's result is the one :func:`solve_homotopy` with
    ``attempts=1`` returns from a start system of those roots (every path is tracked on its
    own: the batch changes no value).

    Args:
        system: the polynomial system.
        p_from: (W, n_params) complex parameters of the root sets.
        roots: (W, R, n) complex roots at ``p_from``.
        P0: (W, n_params) the targets' parameters.
        gamma: the gamma of every arc.
        options: tracker step control.
        real_tol: as :func:`solve_homotopy`.
        tracker: as :func:`solve_homotopy`.
        start_certified: what each result's ``start_certified`` says.

    Returns:
        W :class:`HomotopyResult`.
    """
    P0 = np.asarray(P0, dtype=complex).reshape(-1, system.n_params)
    roots = np.asarray(roots, dtype=complex).reshape(len(P0), -1, system.n)
    b = np.zeros((len(P0), system.n), dtype=complex)
    ends = _track_all(system, np.asarray(p_from, dtype=complex), b, roots, P0, gamma, options,
                      tracker)  # fmt: skip
    return _results(system, ends, P0, complex(gamma), 1, start_certified, real_tol, tracker)


def _track_all(system, p_from, b_from, roots, P0, gamma, options, tracker) -> PathEndpoints:
    """The paths of W homotopies (datum w: ``roots[w]`` from ``(p_from[w], b_from[w])`` to
    ``(P0[w], 0)``) in one batch, datum after datum."""
    W, R = roots.shape[:2]
    b_to = np.zeros((W, system.n), dtype=complex)
    hom = ParameterHomotopy(system, p_from, P0, b_from, b_to, np.full(W, complex(gamma)))
    idx = np.repeat(np.arange(W), R)
    return track_parameter_homotopy(
        system, roots.reshape(W * R, system.n), hom, idx, options, tracker=tracker
    )


def _results(system, ends, P0, g, attempt, start_certified, real_tol, tracker) -> list:
    """The :class:`HomotopyResult` of each of the W data of a batch's endpoints."""
    W = len(P0)
    R = len(ends.z) // W if W else 0
    ctrack = c_tracker(system, tracker)
    cut = [slice(w * R, (w + 1) * R) for w in range(W)]
    success = ends.status == "success"
    regs = real_endpoints_many(system, [ends.z[c][success[c]] for c in cut], P0, real_tol,
                               ctrack=ctrack)  # fmt: skip
    out = []
    for w, c in enumerate(cut):
        z, status = ends.z[c], ends.status[c]
        # endgame estimates are accurate to about 1e-8 relative: looser tests for them
        merged = regs[w]
        if (status == "singular").any():
            sing = real_endpoints(system, z[status == "singular"], P0[w], 1e-6, 1e-6, False)
            merged = dedup(np.concatenate([regs[w], sing]), 1e-6) if len(sing) else regs[w]
        out.append(
            HomotopyResult(
                endpoints=z,
                status=status,
                winding=ends.winding[c],
                real_solutions=merged,
                complete=bool(
                    (
                        (status == "success") | (status == "singular") | (status == "at_infinity")
                    ).all()
                ),
                start_certified=start_certified,
                gamma=g,
                steps=ends.steps[c],
                attempts=attempt,
            )
        )
    return out
