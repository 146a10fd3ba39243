"""The validated pieces of a direct-kinematics query.

What :func:`scdk_sym.solvers.solve.solve`, the tracker, the curve search and the atlas check
before they follow a path: the start configuration (assembled, the right shapes), the target
``theta0`` and the options of a solve, and whether the start is singular (where the branch is
undefined). :class:`Query` carries a checked query to the branch strategies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError, NotAssembledError
from ..follower.surface import det_jp
from ..follower.tangent import null_direction
from ..kernels.fastcall import model_calls
from ..products import CHECKED_START
from ..results import Configuration
from ..robot import Model, as_vector


@dataclass(frozen=True)
class Query:
    """A checked solve query, as the branch strategies read it.

    Attributes:
        model: the model.
        theta0: (k,) target actuated values [rad or model length unit].
        start: the assembled start configuration.
        backend: the kernel backend (already resolved).
        max_arc: arc-length budget of a path (None: the follower's default).
        record_path: keep the sampled curve in the answer.
    """

    model: Model
    theta0: np.ndarray
    start: Configuration
    backend: str
    max_arc: float | None
    record_path: bool


@dataclass
class StartMemo:
    """What a model remembers of its last starts (a :class:`Configuration` is immutable, so
    one checked once stays checked).

    Attributes:
        checked: the last start checked assembled (shapes and residual).
        det: the last start whose ``det J_p`` was asked for, and that determinant.
    """

    checked: Configuration | None = None
    det: tuple[Configuration, float] | None = None


def _memo(model: Model) -> StartMemo:
    return model.products.get(CHECKED_START, StartMemo)


def validate_start(
    model: Model, start: Configuration | None, check_residual: bool = True
) -> Configuration:
    """The start configuration (default home), checked to be assembled (the last start
    checked is not checked again)."""
    if start is None:
        return model.home
    memo = _memo(model)
    if start is memo.checked:
        return start
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
    memo.checked = start
    return start


def start_det(model: Model, start: Configuration) -> float:
    """``det J_p`` at a start configuration, in the chart centred on it (the last start's
    remembered)."""
    memo = _memo(model)
    if memo.det is not None and memo.det[0] is start:
        return memo.det[1]
    det = det_jp(model, start)
    memo.det = (start, det)
    return det


def target(model: Model, theta0: ArrayLike) -> np.ndarray:
    """``theta0`` as a (k,) vector of finite values (raises :class:`InputError` otherwise)."""
    return as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")


def check_options(branch: str, b: float | None, max_arc: float | None) -> None:
    """Raise :class:`InputError` for an unknown branch, a zero or non-finite ``b`` or a
    non-positive ``max_arc`` [model length unit]."""
    if b is None and branch not in ("convergent", "divergent"):
        raise InputError(f"unknown branch {branch!r}; branches: convergent, divergent")
    if b is not None and (not math.isfinite(b) or b == 0):
        raise InputError(f"b must be a non-zero finite number, got {b!r}")
    if max_arc is not None and not (max_arc > 0):
        raise InputError(f"max_arc must be a positive arc length, got {max_arc!r}")


def at_start(model: Model, theta0: np.ndarray, start: Configuration):
    """(nu unit vector, det J_p, J_p) at the start: one evaluation of the Jacobians for the
    branch, the singularity check and the first tangent of the path."""
    y_loc, c = model.chart.to_local(start.y)
    Jp, Js = model_calls(model).jac(y_loc, start.theta, c)
    return null_direction(Jp, Js @ (theta0 - start.theta)), float(np.linalg.det(Jp)), Jp


def same_theta(a: np.ndarray, b: np.ndarray) -> bool:
    """Two actuated vectors are equal to 1e-14 (relative to ``|a|``, at least 1)."""
    return float(np.linalg.norm(a - b)) <= 1e-14 * max(1.0, float(np.linalg.norm(a)))


def singular_start(model: Model, start: Configuration, Jp: np.ndarray | None = None) -> bool:
    """``J_p`` at the start is singular to 1e-10 relative (smallest over largest singular
    value); ``Jp``: ``J_p`` there when already evaluated."""
    if Jp is None:
        y_loc, c = model.chart.to_local(start.y)
        Jp = model_calls(model).jac(y_loc, start.theta, c)[0]
    S = np.linalg.svd(Jp, compute_uv=False)
    return not S[-1] > 1e-10 * S[0]
