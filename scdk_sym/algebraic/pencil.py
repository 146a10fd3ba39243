"""A trace test that is linear for every polynomial system: the trace over a curve's pencil.

The offset trace test of :mod:`scdk_sym.algebraic.monodromy` sums the solutions along a line
``b(lambda) = b* + lambda v`` of offsets. That sum is a polynomial in ``lambda`` only where no
solution escapes to infinity along the line, and of degree 1 only for some traced functions
(:func:`~scdk_sym.solvers.form_maps.frame_trace_map` on the zoo's families); on other
forms (a 3-RPS, a robot leg) a complete set fails it.

This module tests completeness with a map that is linear for every system (Leykin,
Rodriguez, Sottile, "Trace test", 2018; the augmented system of HomotopyContinuation.jl's
``verify_solution_completeness``). Let ``C = {(z, lambda): G(z, p) + b + lambda v = 0}`` be
the curve over the offset line and ``phi(z, lambda) = -(a . z - 1) lambda`` on it, for a
random hyperplane ``a . z = 1``. The fibre of ``phi`` over 0 is the solution set at ``(p, b)``
(``lambda = 0``) together with the *witnesses* ``W``: the points of ``C`` on the hyperplane.
``phi`` is finite on ``C`` (it goes to infinity on every branch of ``C`` at infinity, for
generic ``a`` and ``v``), so the sum of ``(z, lambda)`` over its fibre at ``t`` is a
polynomial in ``t``; its pole order on each branch at infinity is at most ``phi``'s, so the
polynomial has degree at most 1. ``C`` is irreducible (the preimage of a generic line under
the dominant offset map of an irreducible structural variety), so the sum over a proper
subset of a fibre is not single valued, hence not linear. The test: track the union from
``t = 0`` to two random ``t1``, ``t2`` (a parameter homotopy of the augmented system
``[G(z, p) + b + lambda v; (a . z - 1) lambda + t]``) and require the three sums to be
collinear.

The hyperplane may involve a few coordinates ``z_K`` only (one angle's ``(cos, sin)``, say):
then ``phi`` need not go to infinity where other coordinates do, but the traced
``(z_K, lambda)`` stay bounded there, so their sum is still entire and of degree at most 1;
the witnesses are then the points of ``C`` at two values of that angle, far fewer than a
general hyperplane's (48 instead of about 240 on talos_like's ankle).

The witnesses are found by monodromy on the hyperplane (the curve held fixed, the hyperplane
moved around loops: hyperplane sections of an irreducible curve have the full symmetric group
as monodromy), from one witness known by construction: the line is drawn through
``-G(z1, p)`` for a random ``z1`` on the structural variety, and the hyperplane through
``z1``. The test is repeated each time the witness count is stable, so an incomplete witness
set only delays the verdict; it never passes an incomplete solution set.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .distinct import dedup
from .homotopy import track_parameter_homotopy
from .parameter_homotopy import ParameterHomotopy
from .paths.continuation import TrackerOptions
from .system import PolynomialSystem

#: Modulus of the two pencil values ``t1``, ``t2`` the union is tracked to.
PENCIL_RADIUS = 0.5


def _cnormal(rng: np.random.Generator, shape) -> np.ndarray:
    return (rng.normal(size=shape) + 1j * rng.normal(size=shape)) / np.sqrt(2.0)


def _evaluate(system: PolynomialSystem, z: np.ndarray, p: np.ndarray):
    """``G, dG/dz`` at the points ``z`` (N, n), NaN on the non-finite ones (paths that
    overflow on their way to infinity; the tracker ends them)."""
    N, n = z.shape
    G = np.full((N, n), np.nan + 0j)
    Gz = np.full((N, n, n), np.nan + 0j)
    ok = np.isfinite(z).all(axis=1)
    if ok.any():
        g, gz, _ = system.evaluate(z[ok], np.broadcast_to(p, (int(ok.sum()), len(p))))
        G[ok], Gz[ok] = g, gz
    return G, Gz


@dataclass(frozen=True, eq=False)
class PencilTrace:
    """The verdict of :func:`pencil_trace_test`, with the pencil it was drawn on.

    Attributes:
        residual: the sum's deviation from a line in ``t``, relative to the points' own
            (:func:`collinear_residual`); ``inf`` when a path failed or two met.
        witnesses: number of points of the curve on the hyperplane found by monodromy.
        loops: monodromy loops run on the hyperplane.
        passed: ``residual <= tol``.
        points: (witnesses, n + 1) complex, the witnesses ``(z, lambda)``.
        line: (n,) complex direction ``v`` of the offset line ``b + lambda v``.
        hyperplane: (len(coords),) complex ``a`` of the hyperplane ``a . z_K = 1``.
        coords: (len(coords),) int, the coordinates ``K`` of ``z`` it involves.
    """

    residual: float
    witnesses: int
    loops: int
    passed: bool
    points: np.ndarray = field(repr=False)
    line: np.ndarray = field(repr=False)
    hyperplane: np.ndarray = field(repr=False)
    coords: np.ndarray = field(repr=False)


class _Witnesses:
    """``[G(z, p) + b + lambda v; a . z] + offsets`` in ``w = (z, lambda)``, parameters ``a``.

    Only the hyperplane row takes an offset (the curve is fixed, the hyperplane moves), so the
    monodromy of :func:`~scdk_sym.algebraic.monodromy.monodromy_solve` walks hyperplane
    sections of the curve.
    """

    def __init__(self, system: PolynomialSystem, p, b, v, coords: np.ndarray):
        self.system, self.p, self.b, self.v, self.coords = system, p, b, v, coords
        self.n = system.n + 1
        self.n_params = len(coords)
        self.offset_rows = np.zeros(self.n, dtype=bool)
        self.offset_rows[-1] = True

    def evaluate(self, w: np.ndarray, a: np.ndarray):
        w = np.atleast_2d(w)
        N, m = len(w), self.system.n
        K = self.coords
        a = np.broadcast_to(a, (N, len(K)))
        z, lam = w[:, :m], w[:, m]
        G, Gz = _evaluate(self.system, z, self.p)
        H = np.empty((N, m + 1), dtype=complex)
        H[:, :m] = G + self.b + lam[:, None] * self.v
        H[:, m] = (a * z[:, K]).sum(axis=1)
        Hw = np.zeros((N, m + 1, m + 1), dtype=complex)
        Hw[:, :m, :m] = Gz
        Hw[:, :m, m] = self.v
        Hw[:, m, K] = a
        Ha = np.zeros((N, m + 1, len(K)), dtype=complex)
        Ha[:, m, :] = z[:, K]
        return H, Hw, Ha

    def random_point(self, rng):  # pragma: no cover - monodromy starts from a given pair
        raise NotImplementedError("the witness system starts from its constructed witness")

    def content_hash(self) -> str:  # pragma: no cover - never cached
        raise NotImplementedError("the witness system is not cached")


class _Pencil:
    """``[G(z, p) + b + lambda v; (a . z - 1) lambda + t]`` in ``w = (z, lambda)``, parameter
    ``t``, no offsets."""

    def random_point(self, rng):  # pragma: no cover - tracked from its known fibre only
        raise NotImplementedError("the pencil system is tracked from its known fibre")

    def content_hash(self) -> str:  # pragma: no cover - never cached
        raise NotImplementedError("the pencil system is not cached")

    def __init__(self, system, p, b, v, a, coords):
        self.system, self.p, self.b, self.v, self.a, self.coords = system, p, b, v, a, coords
        self.n = system.n + 1
        self.n_params = 1
        self.offset_rows = np.zeros(self.n, dtype=bool)

    def evaluate(self, w: np.ndarray, t: np.ndarray):
        w = np.atleast_2d(w)
        N, m = len(w), self.system.n
        t = np.broadcast_to(t, (N, 1))
        z, lam = w[:, :m], w[:, m]
        G, Gz = _evaluate(self.system, z, self.p)
        K = self.coords
        az = z[:, K] @ self.a - 1.0
        H = np.empty((N, m + 1), dtype=complex)
        H[:, :m] = G + self.b + lam[:, None] * self.v
        H[:, m] = az * lam + t[:, 0]
        Hw = np.zeros((N, m + 1, m + 1), dtype=complex)
        Hw[:, :m, :m] = Gz
        Hw[:, :m, m] = self.v
        Hw[:, m, K] = lam[:, None] * self.a[None]
        Hw[:, m, m] = az
        Ht = np.zeros((N, m + 1, 1), dtype=complex)
        Ht[:, m, 0] = 1.0
        return H, Hw, Ht


def collinear_residual(fibres: list[np.ndarray], ts: np.ndarray) -> float:
    """How far the fibres' sum is from a line in ``t``, relative to the points' own bends.

    Each point's deviation from the chord through its values at ``ts[0] = 0`` and ``ts[1]``,
    ``d_j = w_j(t2) - w_j(0) - (t2 / t1) (w_j(t1) - w_j(0))``, is its path's bend; the sum's
    deviation is the sum of the bends. A complete fibre's bends cancel (to rounding); a
    fibre without the point ``j`` keeps ``-d_j``. Normalising by the bends (not by the size
    of the coordinates) makes the test scale free: a missing point near the origin counts
    as much as one far out.

    Args:
        fibres: three (R, m) complex point sets at ``ts[0] = 0``, ``ts[1]``, ``ts[2]``.
        ts: (3,) complex pencil values.

    Returns:
        ``max_i |sum_j d_ji| / max_i sum_j |d_ji|``; ``inf`` when the bends are below
        ``1e-8`` of the coordinates (the paths are too straight for the test to tell).
    """
    d = fibres[2] - fibres[0] - (ts[2] / ts[1]) * (fibres[1] - fibres[0])
    bends = np.abs(d).sum(axis=0).max()
    size = max(np.abs(f).sum(axis=0).max() for f in fibres)
    if not bends > 1e-8 * size:
        return float("inf")
    return float(np.abs(d.sum(axis=0)).max() / bends)


def _fibre(solutions: np.ndarray, witnesses: np.ndarray) -> np.ndarray:
    lam0 = np.zeros((len(solutions), 1), dtype=complex)
    return np.vstack([np.hstack([solutions, lam0]), witnesses])


def pencil_residual(
    system: PolynomialSystem,
    solutions: np.ndarray,
    p: np.ndarray,
    b: np.ndarray,
    pencil: PencilTrace,
    rng: np.random.Generator,
    options: TrackerOptions | None = None,
) -> float:
    """The trace residual of ``solutions`` with the witnesses of an earlier test.

    Args:
        system: the polynomial system.
        solutions: (R, n) complex solutions at ``(p, b)``.
        p: (n_params,) complex parameters of that test.
        b: (n,) complex offsets of that test.
        pencil: the earlier :func:`pencil_trace_test` (its line, hyperplane and witnesses).
        rng: random generator (the two pencil values).
        options: tracker step control.

    Returns:
        The residual (see :class:`PencilTrace`).
    """
    curve = _Pencil(system, p, b, pencil.line, pencil.hyperplane, pencil.coords)
    fibre0 = _fibre(np.asarray(solutions, dtype=complex), pencil.points)
    return _trace(curve, fibre0, rng, options)


def _trace(pencil: _Pencil, fibre0: np.ndarray, rng, options) -> float:
    ts = np.array([0.0, *(PENCIL_RADIUS * np.exp(2j * np.pi * rng.uniform(size=2)))])
    R = len(fibre0)
    zero = np.zeros((2, pencil.n), dtype=complex)
    hom = ParameterHomotopy(
        pencil, np.zeros((2, 1), dtype=complex), ts[1:, None], zero, zero, np.ones(2)
    )
    z = np.tile(fibre0, (2, 1))
    idx = np.repeat(np.arange(2), R)
    ends = track_parameter_homotopy(pencil, z, hom, idx, options, endgame=False)
    if not (ends.status == "success").all():
        return float("inf")
    fibres = [fibre0, *ends.z.reshape(2, R, pencil.n)]
    if any(len(dedup(f, 1e-8)) != R for f in fibres[1:]):  # a path jump
        return float("inf")
    traced = np.append(pencil.coords, pencil.n - 1)
    return collinear_residual([f[:, traced] for f in fibres], ts)


def pencil_trace_test(
    system: PolynomialSystem,
    solutions: np.ndarray,
    p: np.ndarray,
    b: np.ndarray,
    rng: np.random.Generator,
    *,
    coords: Sequence[int] | np.ndarray | None = None,
    tol: float = 1e-9,
    stable_loops: int = 10,
    max_loops: int = 200,
    options: TrackerOptions | None = None,
) -> PencilTrace:
    """Whether ``solutions`` are all the solutions of ``G(z, p) + b = 0``: the pencil's trace.

    Args:
        system: the polynomial system.
        solutions: (R, n) complex, regular solutions at ``(p, b)``.
        p: (n_params,) complex parameters (generic).
        b: (n,) complex offsets (generic; zero on structural rows).
        rng: random generator (line, hyperplane, loops, pencil values).
        coords: indices of the coordinates of ``z`` the hyperplane and the trace involve
            (default: all); e.g. one angle's ``(cos, sin)``, which makes the witnesses the
            points of the curve at two values of that angle.
        tol: largest residual of a complete set.
        stable_loops: monodromy loops without a new witness before each test.
        max_loops: bound on the monodromy loops on the hyperplane.
        options: tracker step control.

    Returns:
        A :class:`PencilTrace`; ``passed`` proves the set complete (with probability one
        over the random choices), a failure only says no proof was found.
    """
    from .monodromy import monodromy_solve

    solutions = np.asarray(solutions, dtype=complex)
    R, n = solutions.shape
    offs = np.asarray(system.offset_rows, dtype=bool)
    for _ in range(8):  # a z1 that solves the system already gives no line
        z1, _ = system.random_point(rng)
        z1 = np.asarray(z1, dtype=complex)
        G1 = system.evaluate(z1[None], np.asarray(p, dtype=complex)[None])[0][0]
        v = np.where(offs, -G1 - b, 0.0)  # the line's point lambda = 1 is -G(z1, p): z1 on C
        if np.abs(v).max(initial=0.0) > 1e-6 * (1.0 + np.abs(b).max(initial=0.0)):
            break
    K = np.arange(n) if coords is None else np.asarray(coords, dtype=int)
    r = _cnormal(rng, len(K))
    a = r / (r @ z1[K])  # the hyperplane a . z = 1 through z1
    witness = _Witnesses(system, p, b, v, K)
    pencil = _Pencil(system, p, b, v, a, K)
    verdict = {"residual": float("inf")}

    def test(ws: np.ndarray, a_: np.ndarray, b_: np.ndarray) -> float:
        verdict["residual"] = _trace(pencil, _fibre(solutions, ws), rng, options)
        return verdict["residual"]

    bw = np.zeros(n + 1, dtype=complex)
    bw[-1] = -1.0
    found = monodromy_solve(
        witness, int(rng.integers(2**31)), stable_loops=stable_loops, max_loops=max_loops,
        trace_tol=tol, options=options, progress=False, test=test,
        start=(np.append(z1, 1.0), a, bw),
    )  # fmt: skip
    return PencilTrace(
        residual=verdict["residual"],
        witnesses=int(found.root_count),
        loops=int(found.loops),
        passed=bool(found.trace_passed),
        points=found.solutions,
        line=v,
        hyperplane=a,
        coords=K,
    )
