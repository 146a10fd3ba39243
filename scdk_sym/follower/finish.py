"""The answer at ``s = 1`` of a walk along a line: where the curve only touches the level
(``theta0`` on the singular surface) and the parity check of every answer.

:func:`~scdk_sym.follower.curve.follow` finishes each ``s = 1`` crossing it meets (Newton at
``theta0`` from the crossing); this module adds what a solve needs of the whole walk:
:func:`touching`, the singular solution where a fold lies at ``s = 1``, and
:func:`parity_checked`, which refuses an answer whose ``det J_p`` sign disagrees with the
number of singular points crossed on the way.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import PathError
from ..kernels.fastcall import model_calls
from ..results import SolveResult
from .calls import follower_calls
from .surface import det_sign


def jacobian(model, y_loc, theta, c) -> np.ndarray:
    """(m, m) ``J_p`` at a point of the local chart ``c``."""
    return np.array(model_calls(model).jac(y_loc, theta, c)[0])


def singular_jp(Jp: np.ndarray) -> bool:
    """``J_p`` singular to 1e-6 relative (a singular solution): its smallest singular value at
    most 1e-6 times its largest.

    A small regular ``J_p`` is told without its singular values: ``sigma_min / sigma_max >=
    |det| / |J_p|_F^n`` (``|det|`` is the product of the singular values, each at most
    ``|J_p|_F``), so a bound above 2e-6 decides as the singular values would (the factor 2
    covers the rounding of both); elsewhere the singular values decide.
    """
    n = len(Jp)
    if 0 < n <= 8:
        v = Jp.ravel()
        if clearly_regular(_det(Jp), math.sqrt(float(v @ v)), n):
            return False
    S = np.linalg.svd(Jp, compute_uv=False)
    return not S[-1] > 1e-6 * S[0]


def clearly_regular(det: float, frob: float, n: int) -> bool:
    """An n x n ``J_p`` with determinant ``det`` and Frobenius norm ``frob`` is not singular to
    1e-6 relative, by the bound of :func:`singular_jp` (``False``: undecided, or n > 8)."""
    return 0 < n <= 8 and frob > 0.0 and abs(det) > 2e-6 * frob**n


def _det(A: np.ndarray) -> float:
    """``det A`` of a square matrix: written out up to 3 x 3 (a Python float expression costs
    a fraction of a LAPACK call there), else LAPACK's."""
    n = len(A)
    if n > 3:
        return float(np.linalg.det(A))
    a = A.tolist()
    if n == 1:
        return a[0][0]
    if n == 2:
        return a[0][0] * a[1][1] - a[0][1] * a[1][0]
    return (
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    )


def touching(model, theta0, tr, sign0: float) -> tuple[np.ndarray, int] | None:
    """A fold of the curve at ``s = 1`` (``theta0`` on the singular surface): the singular
    solution there, polished at ``theta0``, and the number of crossings before it.

    Where the fold lies only nearly at ``s = 1`` there are two solutions at ``theta0`` next
    to it, one on each sheet: Newton from the fold may converge to either. The one on the
    incoming sheet (``det J_p`` of sign ``sign0 (-1)^i`` after ``i`` crossings) is kept; from
    a solution on the other sheet Newton is restarted at its reflections through the fold.
    """
    polish = follower_calls(model).polish

    def newton(y, c):
        for _ in range(8):  # Newton converges only linearly to a double root
            y_new, res = polish(y, theta0, c)
            y = np.array(y_new).ravel()
            if not np.all(np.isfinite(y)) or float(res) <= 1e-3 * model.tolerance:
                break
        ok = np.all(np.isfinite(y)) and model.residual(y, theta0, c) <= model.tolerance
        return y if ok else None

    for i, cr in enumerate(tr.singular):
        if cr.kind != "fold" or abs(cr.s - 1.0) > 1e-6:
            continue
        y_f, c = model.chart.to_local(cr.y)
        want = sign0 * (-1.0) ** i
        y = newton(y_f, c)
        if y is None:
            continue
        if _singular_or_sign(jacobian(model, y, theta0, c), want):
            return model.chart.to_canonical(y, c), i
        for k in (1.0, 0.5, 2.0, 4.0):
            y_r = newton(y_f - k * (y - y_f), c)
            if y_r is not None and _singular_or_sign(jacobian(model, y_r, theta0, c), want):
                return model.chart.to_canonical(y_r, c), i
    return None


def _singular_or_sign(Jp: np.ndarray, want: float) -> bool:
    """``J_p`` singular (:func:`singular_jp`), or its det has the sign ``want``."""
    return singular_jp(Jp) or float(np.linalg.det(Jp)) * want > 0


def parity_checked(model, res: SolveResult, sign0: float) -> SolveResult:
    """The answer of a path, verified against its crossings: ``det J_p`` changes sign at
    each crossing met, so a non-singular answer has the sign ``sign0 (-1)^n`` after ``n``.

    Raises:
        PathError: it has the other sign (the answer is on a sheet the path did not reach).
    """
    if res.status == "singular":
        return res
    n = len(res.crossings)
    got = det_sign(model, res)
    if got * sign0 * (-1.0) ** n > 0:
        return res
    raise PathError(
        f"{res.branch} branch at theta0={np.asarray(res.theta).tolist()}: the solution found "
        f"has det J_p of sign {got:+.0f} after {n} singular crossing(s) from a start of sign "
        f"{sign0:+.0f}: it is not on the path's sheet (theta0 is next to a singular surface); "
        "every real solution: sc.assembly_modes(model, theta0)"
    )
