"""Many readings in one call: the convergent direct kinematics of an array of ``theta``.

:func:`solve_many` is :func:`scdk_sym.solve` at each row of an array of readings, from one
start, with what a repeated call does once done once: the start and the readings are checked
once, the model's C library and the start's chart are found once, the generated C follower
answers each reading into preallocated arrays, and the answers are verified together (the
pose and closure kernels and ``J_p`` evaluated over every answer in one call each). Every row
equals the single solve's answer (the same C call, the same verification: its tests compare
them bit for bit); a reading the C follower hands over is solved by :func:`scdk_sym.solve`
itself, and a reading that fails is reported in its row, never filled in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..backends import offered
from ..errors import InputError, ScdkError, VerificationError
from ..follower.finish import singular_jp
from ..kernels.fastcall import model_calls
from ..results import Configuration
from ..robot import Model, as_vector
from .query import validate_start
from .solve import solve

__all__ = ["SolveBatch", "solve_many"]

#: Backends of :func:`solve_many`: "c" answers in the generated C follower, the others call
#: :func:`scdk_sym.solve` at each row.
BATCH_BACKENDS = ("c", "compiled", "cvodes", "auto")


@dataclass(frozen=True)
class SolveBatch:
    """The verified solutions at N readings from one start (:func:`solve_many`).

    Attributes:
        theta: (N, k) the readings [rad or model length unit].
        y: (N, m) unknowns of each solution, canonical (NaN in a failed row).
        x: (N, n) workspace coordinates (NaN in a failed row).
        residual: (N,) max |closure row| of each solution [model length unit] (verified <=
            the model's tolerance; NaN in a failed row).
        status: (N,) "converged", "singular" (``J_p`` singular to 1e-6 relative at the
            answer) or "failed".
        errors: row -> the error that stopped it (the failed rows only).
        handed_over: the rows the C follower handed over to :func:`scdk_sym.solve`.
        branch: the branch solved ("convergent" or "divergent").
        start: the start configuration.
    """

    theta: np.ndarray
    y: np.ndarray
    x: np.ndarray
    residual: np.ndarray
    status: np.ndarray
    errors: dict[int, ScdkError]
    handed_over: tuple[int, ...]
    branch: str
    start: Configuration

    @property
    def ok(self) -> bool:
        """Whether every reading was solved."""
        return not self.errors


def solve_many(
    model: Model,
    thetas: ArrayLike,
    start: Configuration | None = None,
    branch: str = "convergent",
    *,
    backend: str = "c",
) -> SolveBatch:
    """:func:`scdk_sym.solve` at every row of ``thetas``, from one start, in one call.

    Args:
        model: the model.
        thetas: (N, k) readings of the actuated joints [rad or model length unit].
        start: assembled start configuration of every solve (default: ``model.home``).
        branch: "convergent" or "divergent" (as :func:`scdk_sym.solve`).
        backend: "c" (default: each convergent row in one call of the generated C follower,
            verified together), or "compiled", "cvodes", "auto" (:func:`scdk_sym.solve` at
            each row, as a loop would).

    Returns:
        The :class:`SolveBatch`: row ``i`` is ``solve(model, thetas[i], start, branch,
        backend=backend)``'s answer, or its error.

    Raises:
        InputError: ``thetas`` is not (N, k) finite values, or an unknown branch or backend.
        NotAssembledError: the start does not close.
    """
    if backend not in BATCH_BACKENDS or backend not in offered("solve"):
        raise InputError(f"solve_many: unknown backend {backend!r}; backends: {BATCH_BACKENDS}")
    if branch not in ("convergent", "divergent"):
        raise InputError(f"solve_many: branch must be 'convergent' or 'divergent', got {branch!r}")
    th = _readings(model, thetas)
    start = validate_start(model, start)
    N = len(th)
    y = np.full((N, model.m), np.nan)
    errors: dict[int, ScdkError] = {}
    handed: list[int] = []
    if backend == "c" and branch == "convergent":
        done = _c_rows(model, th, start, y)
    else:
        done = np.zeros(N, dtype=bool)
    for i in np.flatnonzero(~done):
        try:
            res = solve(model, th[i], start, branch, backend=backend, record_path=False)
        except ScdkError as exc:
            errors[int(i)] = exc
            continue
        y[i] = res.y
        if res.fallback:
            handed.append(int(i))
    x, residual, status = _verified(model, th, y, errors)
    for a in (th, y, x, residual, status):
        a.setflags(write=False)
    return SolveBatch(th, y, x, residual, status, errors, tuple(handed), branch, start)


def _readings(model: Model, thetas: ArrayLike) -> np.ndarray:
    """``thetas`` as an owned (N, k) array of finite values."""
    th = np.array(thetas, dtype=float)
    if th.ndim != 2 or th.shape[1] != model.k:
        raise InputError(
            f"solve_many: thetas must be (N, {model.k}) rows ({', '.join(model.actuated)}), "
            f"got shape {th.shape}"
        )
    for i in np.flatnonzero(~np.isfinite(th).all(axis=1))[:1]:  # its error names the values
        as_vector(th[i], model.k, f"thetas[{i}]")
    return th


def _c_rows(model: Model, th: np.ndarray, start: Configuration, y: np.ndarray) -> np.ndarray:
    """Solve each reading in the C follower (:func:`~scdk_sym.solvers.solve_c.solve_c`'s
    call); fills the rows of ``y`` it answers and returns which (the others, refused or
    failed, go to :func:`scdk_sym.solve`)."""
    from ..codegen.library import tracker_library

    y1, c1 = model.chart.to_local(start.y)
    call = tracker_library(model).bound_solve(y1, c1, start.theta)
    done = np.zeros(len(th), dtype=bool)
    for i, theta0 in enumerate(th):
        out = call(theta0)
        if out.status >= 0:
            y[i] = model.chart.to_canonical(out.y, out.c)
            done[i] = True
    return done


def _verified(
    model: Model, th: np.ndarray, y: np.ndarray, errors: dict[int, ScdkError]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x, residual, status)`` of the answered rows, the kernels evaluated over all of them
    at once (each row's values those of a single call: ``Function.map``); a row whose
    residual exceeds the tolerance joins ``errors``."""
    N = len(th)
    x = np.full((N, len(model.workspace)), np.nan)
    residual = np.full(N, np.nan)
    status = np.full(N, "failed", dtype=object)
    rows = np.flatnonzero(np.isfinite(y).all(axis=1))
    if not len(rows):
        return x, residual, status
    local = [model.chart.to_local(y[i]) for i in rows]  # the single solve's own chart
    ys = np.array([a for a, _ in local]).T
    cs = np.array([c for _, c in local]).reshape(len(rows), -1).T
    calls = model_calls(model)
    args = (ys, th[rows].T, cs)
    pose = calls.mapped("pose", len(rows))(*args)[1]
    check = np.abs(calls.mapped("check", len(rows))(*args)).max(axis=0)
    jac = np.asarray(calls.mapped("jac", len(rows))(*args)[0]).reshape(model.m, -1, model.m)
    jac = np.ascontiguousarray(jac.transpose(1, 0, 2))  # (rows, m, m): each point's J_p
    for j, i in enumerate(rows):
        if not check[j] <= model.tolerance:
            errors[int(i)] = VerificationError(
                f"solution at theta0={th[i].tolist()} failed verification: residual "
                f"{check[j]:.3g} > {model.tolerance:.1e}",
                float(check[j]),
            )
            y[i] = np.nan
            continue
        x[i] = np.asarray(pose)[:, j]
        residual[i] = check[j]
        status[i] = "singular" if singular_jp(jac[j]) else "converged"
    return x, residual, status
