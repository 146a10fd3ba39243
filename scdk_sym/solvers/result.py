"""The verified answer of a solve, and how two answers compare.

:func:`solve_result` turns the unknowns reached at ``theta0`` into a :class:`SolveResult`,
verified on the model's closure rows (``status`` "singular" where ``J_p`` is); the other
functions place an answer relative to the start (its side of the singular surface, the
crossings it is reported with) and join the legs of the paper's divergent path.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import VerificationError
from ..follower.finish import singular_jp
from ..follower.surface import det_sign
from ..kernels.fastcall import model_calls
from ..results import Configuration, Crossing, PathSamples, SolveResult, frozen_array, frozen_joints
from ..robot import Model

#: The checks of an answer at ``(y_loc, theta, c)``: ``(T, x, residual, singular)``, the
#: platform placement (4, 4), the workspace coordinates (n,), max |closure row| [model length
#: unit] and whether ``J_p`` is singular to 1e-6 relative.
Checks = Callable[[Model, np.ndarray, np.ndarray, np.ndarray],
                  tuple[np.ndarray, np.ndarray, float, bool]]  # fmt: skip


def kernel_checks(
    model: Model, y_loc: np.ndarray, theta: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float, bool]:
    """The :data:`Checks` of an answer by the model's kernels: the pose, the closure rows and
    ``J_p`` in one call (each value that of its own kernel, as
    :meth:`~scdk_sym.robot.Model.configuration` computes them)."""
    T, x, residual, Jp = model_calls(model).verify(y_loc, theta, c)
    return T, x, residual, singular_jp(Jp)


def solve_result(
    model: Model,
    y: np.ndarray,
    theta0: np.ndarray,
    crossings: tuple[Crossing, ...],
    branch: str,
    direction: float,
    start: Configuration,
    path: PathSamples | None,
    backend: str = "",
    checks: Checks = kernel_checks,
) -> SolveResult:
    """The verified :class:`SolveResult` of canonical unknowns ``y`` at ``theta0`` (raises
    :class:`~scdk_sym.errors.VerificationError` when it does not close), checked by
    ``checks`` at ``y`` in the chart centred on it."""
    y = np.asarray(y, dtype=float).reshape(model.m)  # a solver's unknowns
    theta = np.asarray(theta0, dtype=float).reshape(model.k)  # the query's checked target
    y_loc, c = model.chart.to_local(y)
    T, x, residual, singular = checks(model, y_loc, theta, c)
    if not residual <= model.tolerance:
        raise VerificationError(
            f"solution at theta0={np.asarray(theta0).tolist()} failed verification: residual "
            f"{residual:.3g} > {model.tolerance:.1e}",
            residual,
        )
    T.setflags(write=False)  # fresh arrays of the checks, read-only as a Configuration's
    x.setflags(write=False)
    return SolveResult(
        x=x,
        y=frozen_array(y),
        theta=frozen_array(theta),
        platform_pose=T,
        joints=frozen_joints(model.joint_values(y, theta)),
        residual=residual,
        crossings=crossings,
        status="singular" if singular else "converged",
        branch=branch,
        b=direction,
        start=start,
        path=path,
        backend=backend,
    )


def is_same_side(model: Model, a: Configuration, b) -> bool:
    """det J_p has the same sign at two configurations."""
    return det_sign(model, a) * det_sign(model, b) > 0


def same_configuration(model: Model, a, b) -> bool:
    """Two configurations coincide (chart-free features within 1e-7 model sizes)."""
    from ..follower.geometry import features

    scale = max(1.0, float(model.length_scale))
    return float(np.max(np.abs(features(model, a.y) - features(model, b.y)))) <= 1e-7 * scale


def joined(first: PathSamples, rest: PathSamples, b: float) -> PathSamples:
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


def on_path(cr: Crossing, start: Configuration, theta0: np.ndarray) -> Crossing:
    """A crossing with ``s`` the projection of its ``theta`` on the line from the start to
    ``theta0`` (exact when it lies on it; 0 when ``theta0`` is the start's)."""
    d = theta0 - start.theta
    dd = float(d @ d)
    s = float((cr.theta - start.theta) @ d / dd) if dd else 0.0
    return Crossing(s, cr.x, cr.y, cr.theta, kind=cr.kind)
