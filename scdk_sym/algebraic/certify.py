"""Interval (Krawczyk) certificates of real solutions of square systems ``f(x, p) = 0``.

For a box ``X`` with centre ``m``, a floating-point ``Y ~ J(m)^-1`` and the interval Jacobian
``J(X)`` (``casadi.jacobian`` of ``f`` replayed in ball arithmetic,
:mod:`scdk_sym.algebraic.interval`), the Krawczyk operator is

    K(X) = m - Y f(m) + (I - Y J(X)) (X - m).

If ``K(X)`` lies in the interior of ``X``, then ``X`` holds exactly one zero of ``f(., p)``
(for every ``p`` of the parameter box) and the zero lies in ``K(X)`` (Krawczyk 1969; Moore
1977; Rump 1983). Every operation rounds outward, so the statement is a proof about the
Function's expression graph with its binary64 constants.

The box is chosen adaptively: its radius starts at twice the Newton correction ``|Y f(m)|``
at the given point (plus the rounding floor of the interval Newton point), and where
``K(X)`` is not inside ``X`` the next box is ``K(X)`` inflated by half its radius around
``m`` (epsilon-inflation), for a few tries. A proven enclosure wider than a few ulps (from
a rough ``x``) is shrunk by Krawczyk steps centred on its midpoint (the zero stays in
``K(X) & X``); the uniqueness box stays the ``X`` that was proven.

The first box of each point is tested in binary64 interval arithmetic in C when the system
is rational (:mod:`scdk_sym.algebraic.ckrawczyk`: the box built the same way, the same
operator and tightening, every bound rounded outward, all points in one call); the points
it does not prove go through the ``arb`` test above, which alone tries more boxes and says
why a test fails.

:func:`certify_all` certifies a list of solutions and checks that their boxes are pairwise
disjoint: each proven box then holds a different zero. :func:`closure_function` and
:func:`certify_solution` apply the test to the closure system ``g(y, theta) = 0`` of a loaded
model (unknowns ``y`` in the local chart of the floating joints; ``theta`` and the chart as
exact parameters); :func:`certify_configurations` certifies several solutions of a model in
one common chart.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import repeat
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
from flint import arb, arb_mat, ctx
from numpy.typing import ArrayLike

from ..errors import InputError
from ..kernels.fastcall import Buffered
from ..model.rotations import gibbs, rot_exp
from ..products import CLOSURE_FUNCTION
from ..results import frozen_array, unchecked_many
from .ckrawczyk import IntervalKrawczyk, interval_krawczyk
from .interval import FunctionCache, IntervalFunction, as_sx_function, interval_function

if TYPE_CHECKING:
    from ..robot import Model

#: Boxes tried by :func:`krawczyk` before giving up.
TRIES = 6
#: Radius factor of the epsilon-inflation: the next radius is ``INFLATION * rad K(X)``.
INFLATION = 1.5
#: Condition number of ``J(m)`` above which no certificate is attempted.
MAX_CONDITION = 1e14
#: Smallest box radius tried (absolute).
TINY = 1e-300
#: Most Krawczyk steps that shrink a proven enclosure (see :func:`krawczyk`).
TIGHTEN = 8
#: Arithmetics of the tests: ``"auto"`` (the first box of a rational system in binary64
#: intervals in C where a compiler is present, then Arb) or ``"arb"`` (Arb only).
ARITHMETICS = ("auto", "arb")
EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class Certificate:
    """The outcome of a Krawczyk test around one approximate solution.

    Attributes:
        proven: ``K(X)`` lies in the interior of ``X``: ``domain`` holds exactly one zero of
            ``f(., p)`` (for every ``p`` in the parameter box), and it lies in ``box``.
        box: (n, 2) ``[lo, hi]`` per unknown, rounded outward to binary64: the enclosure
            ``K(X)`` of the zero (tightened) when proven; the last box ``X`` tried otherwise
            (NaN when none was built).
        domain: (n, 2) the box ``X`` rounded inward: no other zero lies in it (NaN when not
            proven).
        radius: largest half-width of ``box`` (in the units of ``x``; inf when unbounded).
        reason: one line: what was proven, or why not.
        x: (n,) the centre ``m`` of the boxes (the point given).
        tries: boxes ``X`` tried.
    """

    proven: bool
    box: np.ndarray
    domain: np.ndarray
    radius: float
    reason: str
    x: np.ndarray
    tries: int = 0

    def __post_init__(self) -> None:
        for name in ("box", "domain", "x"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))

    def contains(self, point: ArrayLike) -> bool:
        """Whether ``point`` (n,) lies in ``box``."""
        q = np.asarray(point, dtype=float)
        return bool(np.all((self.box[:, 0] <= q) & (q <= self.box[:, 1])))


@dataclass(frozen=True)
class CertificateSet:
    """Certificates of several solutions of one system, and whether they are distinct.

    Attributes:
        certificates: one per solution given, in order.
        overlaps: pairs ``(i, j)``, ``i < j``, of proven certificates whose boxes intersect:
            possibly one zero counted twice.
        duplicates: the overlapping pairs proven to be one zero (one box lies in the other's
            ``domain``, where the zero is unique).
        count: distinct real zeros proven: the connected components of the overlap graph of
            the proven boxes (exact when every overlap is a duplicate, a lower bound else).
        reason: one-line summary.
    """

    certificates: tuple[Certificate, ...]
    overlaps: tuple[tuple[int, int], ...]
    duplicates: tuple[tuple[int, int], ...]
    count: int
    reason: str

    @property
    def proven(self) -> bool:
        """Every solution proven and every pair of boxes disjoint: ``count`` distinct zeros."""
        return all(c.proven for c in self.certificates) and not self.overlaps


@dataclass(frozen=True)
class _Square:
    """The replays a Krawczyk test needs for one square system."""

    n: int
    n_params: int
    value: IntervalFunction  # (x, p) -> f, (n,)
    jacobian_t: IntervalFunction  # (x, p) -> J^T, dense column-major = J row-major
    numeric: Buffered  # (x, p) -> (f, J column-major) in binary64
    identity: arb_mat
    fast: IntervalKrawczyk | None  # the binary64 interval test (rational systems)


def _build_square(f: ca.Function) -> _Square:
    f = as_sx_function(f)
    name = f.name()
    if f.n_in() not in (1, 2) or f.n_out() < 1:
        raise InputError(
            f"{name}: a system f(x) or f(x, p) has 1 or 2 inputs and an output, got "
            f"{f.n_in()} inputs, {f.n_out()} outputs; wrap it as casadi.Function([x, p], [f])"
        )
    n = f.numel_in(0)
    n_params = f.numel_in(1) if f.n_in() == 2 else 0
    x = ca.SX.sym("x", n)
    p = ca.SX.sym("p", n_params)
    args = [ca.reshape(x, f.size_in(0))]
    if f.n_in() == 2:
        args.append(ca.reshape(p, f.size_in(1)))
    g = ca.densify(ca.vec(f.call(args)[0]))
    if g.numel() != n:
        raise InputError(
            f"{name}: not square: {g.numel()} rows (output 0) for {n} unknowns (input 0); "
            f"select as many rows as unknowns"
        )
    J = ca.jacobian(g, x)
    value = ca.Function(f"{name}_value", [x, p], [g])
    jacobian_t = ca.Function(f"{name}_jacobian", [x, p], [J.T])
    return _Square(
        n=n,
        n_params=n_params,
        value=interval_function(value),
        jacobian_t=interval_function(jacobian_t),
        numeric=Buffered(ca.Function(f"{name}_newton", [x, p], [g, ca.densify(J)])),
        identity=arb_mat(n, n, [1.0 if i == j else 0.0 for i in range(n) for j in range(n)]),
        fast=interval_krawczyk(value, jacobian_t, n, n_params),
    )


_SQUARES = FunctionCache(_build_square)


def _real(value: ArrayLike, what: str) -> np.ndarray:
    """``value`` as a float array; complex input only with zero imaginary parts."""
    a = np.asarray(value)
    if np.iscomplexobj(a):
        if np.any(a.imag != 0):
            raise InputError(
                f"{what} has nonzero imaginary parts (max {np.max(np.abs(a.imag)):.1e}); "
                f"certificates are for real zeros: pass the real part of a real solution"
            )
        a = a.real
    return np.asarray(a, dtype=float)


def _vector(value: ArrayLike, size: int, what: str) -> np.ndarray:
    v = _real(value, what).ravel()
    if v.size != size or not np.all(np.isfinite(v)):
        raise InputError(
            f"{what} must be {size} finite numbers, got shape {np.shape(value)}"
            f"{'' if v.size != size else ' with non-finite entries'}; pass a ({size},) array"
        )
    return v


def _parameters(p: ArrayLike, size: int) -> tuple[np.ndarray, np.ndarray, bool]:
    """Binary64 midpoints, (k, 2) bounds and whether the values are exact, from (k,) exact
    values or (k, 2) bounds (:func:`_balls` makes their balls)."""
    a = _real(p, "parameters p")
    if a.ndim == 2 and a.shape == (size, 2):
        if not np.all(np.isfinite(a)) or np.any(a[:, 0] > a[:, 1]):
            raise InputError(
                "parameter bounds must be finite with lo <= hi per row; pass (k, 2) [lo, hi]"
            )
        return a.mean(axis=1), a.copy(), False
    v = _vector(a, size, "parameters p")
    return v, np.stack([v, v], axis=1), True


def _balls(bounds: np.ndarray, exact: bool) -> list[arb]:
    """The parameter balls of :func:`_parameters`' bounds (the Arb test's)."""
    if exact:
        return [arb(float(t)) for t in bounds[:, 0]]
    return [arb(lo).union(arb(hi)) for lo, hi in bounds]


def _down(a: arb) -> float:
    """Largest binary64 <= every point of ``a`` (``-inf`` if unbounded or NaN)."""
    if not a.is_finite():
        return -math.inf
    lo = a.lower()
    f = float(lo)
    return math.nextafter(f, -math.inf) if arb(f) > lo else f


def _up(a: arb) -> float:
    """Smallest binary64 >= every point of ``a`` (``inf`` if unbounded or NaN)."""
    if not a.is_finite():
        return math.inf
    hi = a.upper()
    f = float(hi)
    return math.nextafter(f, math.inf) if arb(f) < hi else f


def _inward(m: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(n, 2) binary64 bounds inside ``[m - r, m + r]`` (one ulp in from the nearest)."""
    return np.stack([np.nextafter(m - r, np.inf), np.nextafter(m + r, -np.inf)], axis=1)


def _outward(balls: Sequence[arb]) -> np.ndarray:
    """(n, 2) binary64 bounds around the balls."""
    if ctx.prec <= 53 and all(b.is_finite() for b in balls):
        # midpoints (<= 53 bits) and radii (30 bits) are binary64 numbers: one rounding of
        # mid -/+ rad, undone by one step outward
        mid = np.array([float(b.mid()) for b in balls])
        rad = np.array([float(b.rad()) for b in balls])
        return np.stack([np.nextafter(mid - rad, -np.inf), np.nextafter(mid + rad, np.inf)], 1)
    return np.array([[_down(b), _up(b)] for b in balls])


def _result(
    proven: bool,
    box: np.ndarray,
    m: np.ndarray,
    reason: str,
    tries: int,
    domain: np.ndarray | None = None,
) -> Certificate:
    n = m.size
    radius = float(np.max((box[:, 1] - box[:, 0]) / 2)) if n else 0.0
    return Certificate(
        proven=proven,
        box=box,
        domain=np.full((n, 2), np.nan) if domain is None else domain,
        radius=radius if math.isfinite(radius) else math.inf,
        reason=reason,
        x=m,
        tries=tries,
    )


def _inverse(sq: _Square, m: np.ndarray, p_mid: np.ndarray) -> tuple[np.ndarray | None, str]:
    """``Y ~ J(m)^-1`` in binary64, or None and the reason."""
    n = sq.n
    F, J = sq.numeric(m, p_mid)
    J = J.reshape(n, n, order="F")
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(J))):
        return None, "f or its Jacobian is not finite at x"
    try:
        Y = np.linalg.inv(J)
        cond = float(np.abs(J).sum(axis=1).max() * np.abs(Y).sum(axis=1).max())  # infinity norm
    except np.linalg.LinAlgError:
        Y, cond = None, math.inf
    if not cond < MAX_CONDITION:
        return None, (
            f"the Jacobian is singular at x (condition number {cond:.1e}): a multiple zero or "
            f"a singular configuration, which Krawczyk's test cannot isolate"
        )
    return Y, ""


def _newton_point(
    sq: _Square, m: np.ndarray, P: list[arb], Y: np.ndarray
) -> tuple[list[arb], arb_mat, arb_mat]:
    """``(mid, Y, m - Y f(m))`` as balls: the point, ``Y`` exactly, the interval Newton point."""
    n = sq.n
    mid = [arb(float(t)) for t in m]
    Ya = arb_mat(n, n, Y.ravel().tolist())
    return mid, Ya, arb_mat(n, 1, mid) - Ya * arb_mat(n, 1, sq.value(mid, P)[0])


def _operator(
    sq: _Square, X: list[arb], mid: list[arb], P: list[arb], Ya: arb_mat, newton: arb_mat
) -> tuple[list[arb], arb_mat]:
    """``K(X) = m - Y f(m) + (I - Y J(X)) (X - m)`` as balls, and ``I - Y J(X)``."""
    n = sq.n
    C = sq.identity - Ya * arb_mat(n, n, sq.jacobian_t(X, P)[0])
    K = newton + C * arb_mat(n, 1, [X[i] - mid[i] for i in range(n)])
    return [K[i, 0] for i in range(n)], C


def _tighten(
    sq: _Square, K: list[arb], P: list[arb], p_mid: np.ndarray, steps: int, floor: float
) -> list:
    """Shrink an enclosure of the zero by Krawczyk steps centred on its midpoint, while each
    step at least halves its largest radius and that radius exceeds twice ``floor``, the
    largest radius of the last interval Newton point (a step's enclosure holds a Newton point
    about that wide: it cannot halve the radius then)."""
    n = sq.n
    for _ in range(steps):
        m = np.array([float(b.mid()) for b in K])
        width = max(float(b.rad()) for b in K)  # radii are exact in binary64
        if width <= 64 * EPS * (1 + float(np.max(np.abs(m)))) or width <= 2 * floor:
            break
        Y, _ = _inverse(sq, m, p_mid)
        if Y is None:
            break
        mid, Ya, newton = _newton_point(sq, m, P, Y)
        if not all(K[i].contains(mid[i]) for i in range(n)):  # the mean value form needs m in K
            break
        K2, _ = _operator(sq, K, mid, P, Ya, newton)
        try:  # the zero lies in K and in K2
            K2 = [K2[i].intersection(K[i]) for i in range(n)]
        except ValueError:
            break
        shrunk = max(float(b.rad()) for b in K2)
        if not shrunk < width:
            break
        K = K2
        if not shrunk <= 0.5 * width:  # at the rounding's floor: more steps gain little
            break
        floor = max(float(newton[i, 0].rad()) for i in range(n))
    return K


def _checked(tries: int, tighten: int, arithmetic: str) -> None:
    if tries < 1 or tighten < 0:
        raise InputError(f"tries >= 1 and tighten >= 0 required, got {tries}, {tighten}")
    if arithmetic not in ARITHMETICS:
        raise InputError(
            f"unknown arithmetic {arithmetic!r}; arithmetics: {', '.join(ARITHMETICS)}"
        )


def _fast(
    sq: _Square, ms: np.ndarray, bounds: np.ndarray, tighten: int, arithmetic: str = "auto"
) -> list:
    """Certificates of the points (N, n) the binary64 interval test proves, ``None`` for the
    others (and for all when the test does not apply: see :mod:`.ckrawczyk`; Arb at another
    precision than binary64's 53 bits asks for its own arithmetic)."""
    if arithmetic != "auto" or sq.fast is None or ctx.prec != 53 or not len(ms):
        return [None] * len(ms)
    proven, r, box = sq.fast.test(ms, bounds, tighten, TINY, MAX_CONDITION)
    if not sq.n:
        return [None] * len(ms)
    # every point at once, as _result and _inward make them one by one
    domain = np.stack([np.nextafter(ms - r, np.inf), np.nextafter(ms + r, -np.inf)], axis=2)
    radius = np.max((box[:, :, 1] - box[:, :, 0]) / 2, axis=1)
    radius = np.where(np.isfinite(radius), radius, np.inf)
    box, ms = np.array(box), np.array(ms)  # owned, then read-only: the rows are not copied
    for a in (box, domain, ms):
        a.setflags(write=False)
    rows = np.flatnonzero(proven).tolist()
    r_max, radius = np.max(r, axis=1).tolist(), radius.tolist()
    every = len(rows) == len(ms)  # the usual case: the arrays' rows as they are
    certs = unchecked_many(
        Certificate, len(rows), proven=repeat(True), box=box if every else [box[i] for i in rows],
        # inside X = [m - r, m + r] rounded outward
        domain=domain if every else [domain[i] for i in rows],
        radius=radius if every else [radius[i] for i in rows],
        reason=[f"K(X) lies in the interior of X (radius {r_max[i]:.1e}): exactly one zero in X"
                for i in rows],
        x=ms if every else [ms[i] for i in rows], tries=repeat(1),
    )  # fmt: skip
    if every:
        return certs
    out: list = [None] * len(ms)
    for i, cert in zip(rows, certs, strict=True):
        out[i] = cert
    return out


def krawczyk(
    f: ca.Function,
    x: ArrayLike,
    p: ArrayLike = (),
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> Certificate:
    """Prove (or fail to prove) that one zero of ``f(., p)`` lies in a small box around ``x``.

    Args:
        f: square system, a CasADi SX Function ``(x[n]) -> f[n]`` or ``(x[n], p[k]) -> f[n]``
            (output 0; an MX Function is expanded).
        x: (n,) approximate zero: the centre of every box tried.
        p: (k,) parameter values, exact; or (k, 2) ``[lo, hi]`` bounds (the statement then
            holds for every ``p`` in the box).
        tries: boxes tried (the first from the Newton correction at ``x``, then inflated).
        tighten: at most this many Krawczyk steps shrink a proven enclosure wider than a few
            ulps (from a rough ``x``), each centred on the previous enclosure; they stop after
            a step that does not halve the enclosure's largest radius, and do not start when
            it is within twice the interval Newton point's (the rounding's floor: near a
            singular point ``cond(J) eps`` is wide, and more steps gain little).
        arithmetic: ``"auto"``: the first box in binary64 interval arithmetic in C where ``f``
            is rational (:mod:`scdk_sym.algebraic.ckrawczyk`), Arb balls if it proves
            nothing; ``"arb"``: Arb balls only (see :data:`ARITHMETICS`).

    Returns:
        The :class:`Certificate` (``proven`` False with a ``reason`` where the test fails: a
        singular Jacobian at ``x``, or ``K(X)`` not inside ``X`` for every box tried).

    Raises:
        InputError: ``f`` is not a square system, ``x``/``p`` have the wrong size, or an
            unknown ``arithmetic``.
        IntervalError: ``f`` uses an operation without an interval counterpart.
    """
    _checked(tries, tighten, arithmetic)
    sq: _Square = _SQUARES(f)
    m = _vector(x, sq.n, "x")
    p_mid, bounds, exact = _parameters(p, sq.n_params)
    fast = _fast(sq, m[None], bounds, tighten, arithmetic)[0]
    if fast is not None:
        return fast
    return _krawczyk(sq, m, _balls(bounds, exact), p_mid, tries, tighten)


def _krawczyk(
    sq: _Square, m: np.ndarray, P: list[arb], p_mid: np.ndarray, tries: int, tighten: int
) -> Certificate:
    """The test of :func:`krawczyk` in ``arb`` ball arithmetic, box after box."""
    n = sq.n
    Y, why = _inverse(sq, m, p_mid)
    if Y is None:
        return _result(False, np.full((n, 2), np.nan), m, why, 0)
    mid, Ya, newton = _newton_point(sq, m, P, Y)
    centre = [newton[i, 0] for i in range(n)]
    delta = np.array([float(b.mid()) for b in centre]) - m
    floor = 4 * np.array([float(b.rad()) for b in centre])  # radii are exact in binary64
    r = np.maximum(2 * np.max(np.abs(delta)) + floor, TINY)
    for t in range(1, tries + 1):
        X = [arb(m[i], r[i]) for i in range(n)]
        K, C = _operator(sq, X, mid, P, Ya, newton)
        tried = np.array([[m[i] - r[i], m[i] + r[i]] for i in range(n)])
        if all(X[i].contains_interior(K[i]) for i in range(n)):
            K = _tighten(sq, K, P, p_mid, tighten, float(np.max(floor)) / 4)
            return _result(
                True,
                _outward(K),
                m,
                f"K(X) lies in the interior of X (radius {float(np.max(r)):.1e}): "
                f"exactly one zero in X",
                t,
                _inward(m, r),  # inside X = arb(m, r), whose radius Arb rounds up
            )
        rho = np.array([_up(abs(K[i] - mid[i])) for i in range(n)])
        if not np.all(np.isfinite(rho)):
            reason = "f or its interval Jacobian is unbounded on X (e.g. a division by 0)"
            return _result(False, tried, m, reason, t)
        contraction = max(sum(_up(abs(C[i, j])) for j in range(n)) for i in range(n))
        if contraction >= 1:
            return _result(
                False,
                tried,
                m,
                f"I - Y J(X) does not contract (norm <= {contraction:.2g}, radius "
                f"{float(np.max(r)):.1e}): J is singular or varies too much over X "
                f"(a multiple zero, or x far from a zero)",
                t,
            )
        if t == tries:
            return _result(
                False,
                tried,
                m,
                f"K(X) is not inside X after {tries} boxes (last radius {float(np.max(r)):.1e}, "
                f"|I - Y J(X)| <= {contraction:.2g}): x is not close enough to a zero; "
                f"refine it with Newton steps",
                t,
            )
        r = np.maximum(r, INFLATION * rho) + floor
    raise AssertionError("unreachable")  # pragma: no cover


def _components(count: int, edges: Sequence[tuple[int, int]]) -> list[int]:
    parent = list(range(count))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in edges:
        parent[root(i)] = root(j)
    return [root(i) for i in range(count)]


def certify_all(
    f: ca.Function,
    xs: ArrayLike,
    p: ArrayLike = (),
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> CertificateSet:
    """Certify several approximate zeros of one system and check that they are distinct.

    Args:
        f: square system (see :func:`krawczyk`).
        xs: (N, n) approximate zeros.
        p: parameters (see :func:`krawczyk`), shared by every solution.
        tries: boxes tried per solution.
        tighten: Krawczyk steps that shrink each proven enclosure.
        arithmetic: see :func:`krawczyk` (``"auto"``: every point's first box in one C
            call).

    Returns:
        The :class:`CertificateSet`: ``proven`` when every solution is proven and every pair
        of boxes is disjoint (then ``count == N`` distinct real zeros).
    """
    return certify_sets(f, [xs], [p], tries=tries, tighten=tighten, arithmetic=arithmetic)[0]


def certify_sets(
    f: ca.Function,
    xs_list: list,
    p_list: list,
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> list[CertificateSet]:
    """:func:`certify_all` of several sets of one system, each at its own parameters; the
    first box of every point of every set in one C call (the certificates are those of
    separate calls).

    Args:
        f: square system (see :func:`krawczyk`).
        xs_list: S arrays (N_s, n) of approximate zeros.
        p_list: S parameter vectors (or bounds), one per set (see :func:`krawczyk`).
        tries: as :func:`certify_all`.
        tighten: as :func:`certify_all`.
        arithmetic: as :func:`certify_all`.

    Returns:
        S :class:`CertificateSet`.

    Raises:
        InputError: not one parameter vector per set, or a set or vector as
            :func:`certify_all` refuses it.
    """
    _checked(tries, tighten, arithmetic)
    if len(xs_list) != len(p_list):
        raise InputError(
            f"{len(xs_list)} sets of zeros and {len(p_list)} parameter vectors; pass one "
            "parameter vector per set"
        )
    sq: _Square = _SQUARES(f)
    sets, params = [], []
    for xs, p in zip(xs_list, p_list, strict=True):
        xs = _real(xs, "xs")
        if xs.ndim != 2:
            raise InputError(f"xs must be (N, n) approximate zeros, got shape {xs.shape}")
        if xs.shape[1] == sq.n and np.all(np.isfinite(xs)):
            ms = np.ascontiguousarray(xs)
        else:  # the first bad row says what is wrong
            ms = np.array([_vector(x, sq.n, "x") for x in xs]).reshape(len(xs), sq.n)
        sets.append(ms)
        params.append(_parameters(p, sq.n_params))
    if not sets:
        return []
    sizes = [len(ms) for ms in sets]
    bounds = np.concatenate(
        [np.broadcast_to(b, (n, *b.shape)) for (_, b, _), n in zip(params, sizes, strict=True)]
    )
    return _certify_many(sq, np.concatenate(sets), sizes, params, bounds, tries, tighten,
                         arithmetic)  # fmt: skip


def _certify_many(
    sq: _Square,
    ms_all: np.ndarray,
    sizes: list[int],
    params: list,
    bounds: np.ndarray,
    tries: int,
    tighten: int,
    arithmetic: str,
) -> list[CertificateSet]:
    """:func:`certify_sets` of checked input: the points of all sets (N, n), each set's
    size, its :func:`_parameters` and every point's parameter bounds (N, k, 2)."""
    fast = _fast(sq, ms_all, bounds, tighten, arithmetic)  # all points in one call
    meets = _sets_meeting(fast, sizes)
    out, start = [], 0
    for size, (p_mid, b, exact), meet in zip(sizes, params, meets, strict=True):
        ms = ms_all[start : start + size]
        ours = fast[start : start + size]
        P = _balls(b, exact) if any(c is None for c in ours) else []
        certs = tuple(
            c if c is not None else _krawczyk(sq, m, P, p_mid, tries, tighten)
            for c, m in zip(ours, ms, strict=True)
        )
        start += len(ms)
        out.append(_certificate_set(certs, disjoint=not meet))
    return out


def _sets_meeting(fast: list, sizes: list[int]) -> list[bool]:
    """Per set of :func:`_fast`'s certificates: whether two of its boxes may meet (False only
    when every point of the set is proven there and its boxes are pairwise disjoint), the
    sets of one size compared at once."""
    out = [True] * len(sizes)
    if len(sizes) < 2:  # one set: apart in the first coordinate, else its own comparison
        if sizes and all(c is not None for c in fast):
            out[0] = not _apart_in_first(np.array([c.box[0] for c in fast]).reshape(-1, 2))
        return out
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int).tolist()
    by_size: dict[int, list[int]] = {}
    for s, size in enumerate(sizes):
        if all(c is not None for c in fast[starts[s] : starts[s + 1]]):
            if size < 2:
                out[s] = False
            else:
                by_size.setdefault(size, []).append(s)
    for size, group in by_size.items():
        B = np.stack([c.box for s in group for c in fast[starts[s] : starts[s + 1]]])
        meet = _boxes_meet(B.reshape(len(group), size, *B.shape[1:]))  # (G, size, size)
        diag = np.arange(size)
        meet[:, diag, diag] = False
        for s, m in zip(group, np.any(meet, axis=(1, 2)).tolist(), strict=True):
            out[s] = bool(m)
    return out


def _apart_in_first(first: np.ndarray) -> bool:
    """Whether the intervals ``first`` (P, 2) ``[lo, hi]`` (the boxes' first coordinates)
    are pairwise disjoint, so that the boxes are: sorted by ``lo``, each starts above every
    one before it ends (False where a bound is NaN)."""
    if len(first) < 2:
        return True
    if np.isnan(first).any():
        return False
    order = np.argsort(first[:, 0], kind="stable")
    lo, hi = first[order, 0], first[order, 1]
    return bool(np.all(lo[1:] > np.maximum.accumulate(hi)[:-1]))


def _boxes_meet(box: np.ndarray) -> np.ndarray:
    """Which boxes of ``box`` (..., P, n, 2) ``[lo, hi]`` intersect: (..., P, P) bool, ``[i,
    j]`` true when every coordinate's intervals of boxes i and j meet (the diagonal true)."""
    lo, hi = box[..., 0], box[..., 1]
    return np.all(
        (lo[..., :, None, :] <= hi[..., None, :, :]) & (lo[..., None, :, :] <= hi[..., :, None, :]),
        axis=-1,
    )


def _certificate_set(certs: tuple, disjoint: bool = False) -> CertificateSet:
    """The :class:`CertificateSet` of certificates: which are proven, which boxes meet
    (``disjoint``: known pairwise disjoint, not compared again)."""
    proven = [i for i, c in enumerate(certs) if c.proven]
    overlaps, duplicates = [], []
    if len(proven) > 1 and not disjoint:
        box = np.array([certs[i].box for i in proven])  # (P, n, 2)
        dom = np.array([certs[i].domain for i in proven])
        meet = _boxes_meet(box)
        for a, b in zip(*np.nonzero(np.triu(meet, 1)), strict=True):
            i, j = proven[a], proven[b]
            overlaps.append((i, j))
            bi, di, bj, dj = box[a], dom[a], box[b], dom[b]
            inside_j = np.all((dj[:, 0] <= bi[:, 0]) & (bi[:, 1] <= dj[:, 1]))
            inside_i = np.all((di[:, 0] <= bj[:, 0]) & (bj[:, 1] <= di[:, 1]))
            if inside_i or inside_j:
                duplicates.append((i, j))
    if overlaps:
        roots = _components(len(certs), overlaps)
        count = len({roots[i] for i in proven})
    else:  # every proven zero its own component
        count = len(proven)
    failed = [i for i, c in enumerate(certs) if not c.proven]
    parts = [f"{len(proven)} of {len(certs)} solutions proven"]
    if failed:
        parts.append(f"not proven: {failed[:10]}{' ...' if len(failed) > 10 else ''}")
    if duplicates:
        parts.append(f"one zero counted twice: pairs {duplicates[:10]}")
    undecided = [e for e in overlaps if e not in duplicates]
    if undecided:
        parts.append(f"overlapping boxes (maybe one zero): pairs {undecided[:10]}")
    if not overlaps:
        parts.append(f"{count} distinct real zeros (boxes pairwise disjoint)")
    else:
        parts.append(f"{count} distinct real zeros{' at least' if undecided else ''}")
    return CertificateSet(
        certificates=certs,
        overlaps=tuple(overlaps),
        duplicates=tuple(duplicates),
        count=count,
        reason="; ".join(parts),
    )


def closure_function(model: Model) -> ca.Function:
    """The closure rows of ``model`` as a square system for :func:`krawczyk`.

    Args:
        model: a loaded model (``m`` unknowns, ``k`` actuated joints, ``f`` floating joints).

    Returns:
        The SX Function ``(y[m], q[k + 9 f]) -> g[m]`` of ``model.symbolic``, with the
        parameters ``q = [theta; c]`` (actuated values, then the chart: the reference rotations
        of the floating joints, column-major). Built once per model (``model.products``).
    """

    def build() -> ca.Function:
        s = model.symbolic
        q = ca.vertcat(s.theta, s.c)
        return ca.Function("closure", [s.y, q], [s.g], ["y", "q"], ["g"])

    return model.products.get(CLOSURE_FUNCTION, build)


def certify_solution(
    model: Model,
    y: ArrayLike,
    theta: ArrayLike,
    c: ArrayLike | None = None,
    *,
    tries: int = TRIES,
) -> Certificate:
    """Krawczyk certificate of one solution of the closure system of ``model``.

    Args:
        model: a loaded model.
        y: (m,) unknowns: canonical (``c`` None, e.g. ``SolveResult.y``) or local in the
            chart ``c``.
        theta: (k,) actuated values [rad or model length unit], exact.
        c: (9 f,) chart of the floating joints, or None to centre one on ``y``.
        tries: boxes tried.

    Returns:
        The certificate; its boxes are in the local chart coordinates of ``y`` (for models
        without floating joints, the joint coordinates themselves).
    """
    y = _vector(y, model.m, "y")
    theta = _vector(theta, model.k, "theta")
    if c is None:
        y, c = model.chart.to_local(y)
    c = _vector(c, model.chart.size, "chart c")
    return krawczyk(closure_function(model), y, np.concatenate([theta, c]), tries=tries)


def certify_configurations(
    model: Model,
    ys: ArrayLike,
    theta: ArrayLike,
    c: ArrayLike | None = None,
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> CertificateSet:
    """Certify several solutions of the closure system of ``model`` at one ``theta``.

    Every solution is expressed in one chart (so that their boxes are comparable): the
    rotation of each floating joint in Rodrigues parameters relative to the chart ``c``.

    Args:
        model: a loaded model.
        ys: (N, m) canonical unknowns (e.g. ``[cfg.y for cfg in sc.assembly_modes(...)]``).
        theta: (k,) actuated values, exact.
        c: (9 f,) common chart; None: the chart centred on ``ys[0]``. No solution may be
            turned by a half turn relative to it.
        tries: boxes tried per solution.
        tighten: Krawczyk steps that shrink each proven enclosure.
        arithmetic: see :func:`krawczyk`.

    Returns:
        The :class:`CertificateSet` (boxes in the local coordinates of the common chart).
    """
    return certify_configuration_sets(
        model, [(ys, theta, c)], tries=tries, tighten=tighten, arithmetic=arithmetic
    )[0]


def certify_configuration_sets(
    model: Model,
    sets: list,
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> list[CertificateSet]:
    """:func:`certify_configurations` of several sets, e.g. the modes of several points of a
    map, the first boxes of all in one C call (the certificates are those of separate calls).

    Args:
        model: a loaded model.
        sets: S tuples ``(ys, theta, c)``, each as :func:`certify_configurations` takes them.
        tries: as :func:`certify_configurations`.
        tighten: as :func:`certify_configurations`.
        arithmetic: as :func:`certify_configurations`.

    Returns:
        S :class:`CertificateSet`.

    Raises:
        InputError: a set as :func:`certify_configurations` raises it.
    """
    _checked(tries, tighten, arithmetic)
    batch = _local_sets(model, sets)
    if batch is not None:
        sq: _Square = _SQUARES(closure_function(model))
        local, qs, sizes = batch
        params = [(q, np.stack([q, q], axis=1), True) for q in qs]
        bounds = np.repeat(np.stack([qs, qs], axis=2), sizes, axis=0)
        return _certify_many(sq, local, sizes, params, bounds, tries, tighten, arithmetic)
    xs_list, q_list = [], []  # one set after the other: the first bad one says what is wrong
    for ys, theta, c in sets:
        local, q = _local(model, ys, theta, c)
        xs_list.append(local)
        q_list.append(q)
    return certify_sets(
        closure_function(model), xs_list, q_list, tries=tries, tighten=tighten,
        arithmetic=arithmetic,
    )  # fmt: skip


def _local_sets(model: Model, sets: list) -> tuple | None:
    """:func:`_local` of every set at once, as it makes them set by set: the local
    coordinates of all configurations (N, m), each set's parameters (S, k + chart size) and
    sizes; ``None`` where some set is not plain valid input (:func:`_local` says why)."""
    if not sets:
        return None
    ys_list, thetas, charts = [], [], []
    for ys, theta, c in sets:
        if not (isinstance(ys, np.ndarray) and isinstance(theta, np.ndarray)):
            return None
        if ys.dtype != np.float64 or ys.ndim != 2 or ys.shape[1] != model.m:
            return None
        if theta.dtype != np.float64 or theta.shape != (model.k,):
            return None
        ys_list.append(ys)
        thetas.append(theta)
        charts.append(c)
    sizes = [len(ys) for ys in ys_list]
    Y = np.concatenate(ys_list)
    T = np.stack(thetas)
    if not (np.isfinite(Y).all() and np.isfinite(T).all()):
        return None
    size = model.chart.size
    C = np.zeros((len(sets), size))
    for i, (ys, c) in enumerate(zip(ys_list, charts, strict=True)):
        if c is None:
            C[i] = model.chart.to_local(ys[0])[1] if len(ys) else np.zeros(size)
        elif isinstance(c, np.ndarray) and c.dtype == np.float64 and c.shape == (size,):
            C[i] = c
        else:
            return None
    if not np.isfinite(C).all():
        return None
    local = _in_charts(model, Y, np.repeat(C, sizes, axis=0))
    if not np.all(np.abs(local) < 1e8):
        return None
    return local, np.concatenate([T, C], axis=1), sizes


def _in_charts(model: Model, ys: np.ndarray, charts: np.ndarray) -> np.ndarray:
    """Canonical unknowns ``ys`` (N, m) in the local coordinates of the charts (N, chart
    size), one per row: each floating joint's rotation in Rodrigues parameters relative to
    its reference rotation (all rows at once)."""
    local = ys.copy()
    for i, idx in enumerate(model.chart.rotations):
        ref = charts[:, 9 * i : 9 * i + 9].reshape(-1, 3, 3, order="F")
        local[:, list(idx)] = gibbs(ref.transpose(0, 2, 1) @ rot_exp(local[:, list(idx)]))
    return local


def _local(model: Model, ys: ArrayLike, theta: ArrayLike, c: ArrayLike | None) -> tuple:
    """Configurations ``ys`` in the common chart ``c`` and the closure's parameters
    ``[theta; c]`` (see :func:`certify_configurations`)."""
    ys = _real(ys, "ys")
    if ys.ndim != 2 or ys.shape[1] != model.m or not np.all(np.isfinite(ys)):
        raise InputError(
            f"ys must be (N, {model.m}) finite canonical unknowns, got shape {ys.shape}; "
            f"pass one row per configuration"
        )
    theta = _vector(theta, model.k, "theta")
    if c is None:
        c = model.chart.to_local(ys[0])[1] if len(ys) else np.zeros(model.chart.size)
    c = _vector(c, model.chart.size, "chart c")
    local = _in_charts(model, ys, np.broadcast_to(c, (len(ys), len(c))))
    far = np.flatnonzero(~np.all(np.abs(local) < 1e8, axis=1))
    if far.size:
        raise InputError(
            f"configurations {far.tolist()} are turned by about a half turn from the chart; "
            f"pass a chart c nearer to them (e.g. certify them in separate sets)"
        )
    return local, np.concatenate([theta, c])
