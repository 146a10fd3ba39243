"""Many readings in one call: the convergent direct kinematics of an array of ``theta``.

:func:`solve_many` is :func:`scdk_sym.solve` at each row of an array of readings, from one
start, with what a repeated call does once done once: the start and the readings are checked
once, the model's C library is found and bound to the start once, and the generated C
follower answers each reading, verified as a single solve verifies it. Every row equals the
single solve's answer (the same C call, the same verification: its tests compare them bit for
bit); a reading the C follower hands over is solved by :func:`scdk_sym.solve`
itself, and a reading that fails is reported in its row, never filled in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..backends import offered
from ..errors import InputError, ScdkError, VerificationError
from ..results import Configuration, SolveResult
from ..robot import Model, as_vector
from .query import validate_start
from .solve import solve
from .solve_c import bound_solve, convergent_answer

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
    answers: dict[int, SolveResult] = {}
    errors: dict[int, ScdkError] = {}
    if backend == "c" and branch == "convergent":
        _c_rows(model, th, start, answers, errors)
    for i in range(len(th)):
        if i in answers or i in errors:
            continue
        try:
            answers[i] = solve(model, th[i], start, branch, backend=backend, record_path=False)
        except ScdkError as exc:
            errors[i] = exc
    handed = tuple(i for i in sorted(answers) if answers[i].fallback)
    y, x, residual, status = _table(model, len(th), answers)
    for a in (th, y, x, residual, status):
        a.setflags(write=False)
    return SolveBatch(th, y, x, residual, status, errors, handed, branch, start)


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


def _c_rows(model: Model, th: np.ndarray, start: Configuration,
            answers: dict[int, SolveResult], errors: dict[int, ScdkError]) -> None:  # fmt: skip
    """Solve each reading in the C follower, bound to the start once, and verify each answer
    as the single solve does (:func:`~scdk_sym.solvers.solve_c.convergent_answer`): fills
    ``answers`` and, for an answer that fails its check, ``errors``; the rows the C follower
    refuses are left to :func:`scdk_sym.solve`."""
    start, call = bound_solve(model, start, "convergent")
    for i, theta0 in enumerate(th):
        out = call(theta0)
        if out.status < 0:
            continue
        try:
            answers[i] = convergent_answer(model, out, theta0, start)
        except VerificationError as exc:
            errors[i] = exc


def _table(
    model: Model, N: int, answers: dict[int, SolveResult]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(y, x, residual, status)`` of N rows from the verified answers (NaN and "failed"
    in the other rows)."""
    y = np.full((N, model.m), np.nan)
    x = np.full((N, len(model.workspace)), np.nan)
    residual = np.full(N, np.nan)
    status = np.full(N, "failed", dtype=object)
    for i, res in answers.items():
        y[i], x[i], residual[i], status[i] = res.y, res.x, res.residual, res.status
    return y, x, residual, status
