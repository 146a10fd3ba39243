"""The Krawczyk test of one point in Arb ball arithmetic, box after box.

For a box ``X`` with centre ``m``, a floating-point ``Y ~ J(m)^-1`` and the interval Jacobian
``J(X)`` (``casadi.jacobian`` of ``f`` replayed in ball arithmetic,
:mod:`scdk_sym.algebraic.interval`), the Krawczyk operator is

    K(X) = m - Y f(m) + (I - Y J(X)) (X - m).

If ``K(X)`` lies in the interior of ``X``, then ``X`` holds exactly one zero of ``f(., p)``
(for every ``p`` of the parameter box) and the zero lies in ``K(X)``. The box is chosen
adaptively: its radius starts at twice the Newton correction ``|Y f(m)|`` at the given point
(plus the rounding floor of the interval Newton point), and where ``K(X)`` is not inside
``X`` the next box is ``K(X)`` inflated by half its radius around ``m``
(epsilon-inflation), for a few tries. A proven enclosure wider than a few ulps is shrunk by
Krawczyk steps centred on its midpoint (the zero stays in ``K(X) & X``).

Its C twin, :mod:`scdk_sym.algebraic.certify.krawczyk_c` (``krawczyk.c``), tests the first
box of many points at once in binary64 intervals.
"""

from __future__ import annotations

import math

import numpy as np
from flint import arb, arb_mat

from .certificate import Certificate
from .rounding import inward, outward, up
from .square import Square

#: Boxes tried by :func:`~scdk_sym.algebraic.certify.krawczyk` before giving up.
TRIES = 6
#: Radius factor of the epsilon-inflation: the next radius is ``INFLATION * rad K(X)``.
INFLATION = 1.5
#: Condition number of ``J(m)`` above which no certificate is attempted.
MAX_CONDITION = 1e14
#: Smallest box radius tried (absolute).
TINY = 1e-300
#: Most Krawczyk steps that shrink a proven enclosure (see
#: :func:`~scdk_sym.algebraic.certify.krawczyk`).
TIGHTEN = 8
#: Machine epsilon of binary64.
EPS = float(np.finfo(float).eps)


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


def _inverse(sq: Square, m: np.ndarray, p_mid: np.ndarray) -> tuple[np.ndarray | None, str]:
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
    sq: Square, m: np.ndarray, P: list[arb], Y: np.ndarray
) -> tuple[list[arb], arb_mat, arb_mat]:
    """``(mid, Y, m - Y f(m))`` as balls: the point, ``Y`` exactly, the interval Newton point."""
    n = sq.n
    mid = [arb(float(t)) for t in m]
    Ya = arb_mat(n, n, Y.ravel().tolist())
    return mid, Ya, arb_mat(n, 1, mid) - Ya * arb_mat(n, 1, sq.value(mid, P)[0])


def _operator(
    sq: Square, X: list[arb], mid: list[arb], P: list[arb], Ya: arb_mat, newton: arb_mat
) -> tuple[list[arb], arb_mat]:
    """``K(X) = m - Y f(m) + (I - Y J(X)) (X - m)`` as balls, and ``I - Y J(X)``."""
    n = sq.n
    C = sq.identity - Ya * arb_mat(n, n, sq.jacobian_t(X, P)[0])
    K = newton + C * arb_mat(n, 1, [X[i] - mid[i] for i in range(n)])
    return [K[i, 0] for i in range(n)], C


def _tighten(
    sq: Square, K: list[arb], P: list[arb], p_mid: np.ndarray, steps: int, floor: float
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


def arb_krawczyk(
    sq: Square, m: np.ndarray, P: list[arb], p_mid: np.ndarray, tries: int, tighten: int
) -> Certificate:
    """The Krawczyk test of one point in ``arb`` ball arithmetic, box after box (see the
    module docs).

    Args:
        sq: the square system.
        m: (n,) the point: the centre of every box tried.
        P: (k,) the parameter balls.
        p_mid: (k,) binary64 midpoints of the parameters (for ``J(m)``).
        tries: boxes tried.
        tighten: most Krawczyk steps that shrink a proven enclosure.

    Returns:
        The :class:`~scdk_sym.algebraic.certify.certificate.Certificate` (``proven`` False
        with a ``reason`` where the test fails).
    """
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
                outward(K),
                m,
                f"K(X) lies in the interior of X (radius {float(np.max(r)):.1e}): "
                f"exactly one zero in X",
                t,
                inward(m, r),  # inside X = arb(m, r), whose radius Arb rounds up
            )
        rho = np.array([up(abs(K[i] - mid[i])) for i in range(n)])
        if not np.all(np.isfinite(rho)):
            reason = "f or its interval Jacobian is unbounded on X (e.g. a division by 0)"
            return _result(False, tried, m, reason, t)
        contraction = max(sum(up(abs(C[i, j])) for j in range(n)) for i in range(n))
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
