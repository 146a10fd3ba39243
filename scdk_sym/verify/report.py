"""Cross-check of a model: its symbolic kinematics against Pinocchio and finite differences.

:func:`verify_model` runs three kinds of checks and returns a :class:`VerifyReport`:

- ``placements``: every link placement of the symbolic build against Pinocchio's
  (:func:`~scdk_sym.verify.pinocchio.placement_errors`), at home and at random joint values
  around it (assembled or not: the spanning tree alone);
- ``closures``: every closure residual evaluated by Pinocchio's constraint models
  (:func:`~scdk_sym.verify.pinocchio.closure_residuals`) at home and at solutions that
  :func:`scdk_sym.solve` reaches from home at random nearby actuated values;
- ``jacobians``: the symbolic ``J_p = dg/dy`` and ``J_s = -dg/dtheta`` against central finite
  differences of ``g`` at the same configurations.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError, ScdkError
from ..kernels.fastcall import model_calls
from ..results import Configuration
from ..robot import Model
from ..solvers.solve import solve

#: Kinds of checks, in report order.
KINDS = ("placements", "closures", "jacobians")


@dataclass(frozen=True)
class Check:
    """One check of :func:`verify_model`.

    Attributes:
        kind: "placements", "closures" or "jacobians".
        where: the configuration checked ("home", "random configuration 1", "solution 2").
        error: the largest discrepancy [model length unit for placements and closures;
            relative to the largest Jacobian entry for Jacobians]; ``inf`` when the check
            could not be evaluated.
        tolerance: largest accepted ``error`` [same unit].
        item: where the largest discrepancy is (a frame, a closure, a Jacobian entry), or why
            the check could not be evaluated.
    """

    kind: str
    where: str
    error: float
    tolerance: float
    item: str

    @property
    def passed(self) -> bool:
        """True when ``error <= tolerance``."""
        return bool(self.error <= self.tolerance)

    def line(self) -> str:
        """One line of the text report."""
        verdict = "ok" if self.passed else "FAILED"
        error = f"{self.error:.2e}" if math.isfinite(self.error) else "n/a"
        return (
            f"{self.kind:<10}  {self.where:<24}  error {error:>9}  tol {self.tolerance:.1e}  "
            f"{verdict:<6}  {self.item}"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (a non-finite ``error`` becomes ``None``)."""
        return {
            "kind": self.kind,
            "where": self.where,
            "error": self.error if math.isfinite(self.error) else None,
            "tolerance": self.tolerance,
            "item": self.item,
            "passed": self.passed,
        }


@dataclass(frozen=True)
class VerifyReport:
    """Result of :func:`verify_model`.

    Attributes:
        model: the model's name.
        checks: every check, placements first, then closures, then Jacobians.
        seed: seed of the random configurations.
    """

    model: str
    checks: tuple[Check, ...]
    seed: int

    @property
    def passed(self) -> bool:
        """True when every check passed."""
        return all(c.passed for c in self.checks)

    @property
    def failures(self) -> tuple[Check, ...]:
        """The checks that failed."""
        return tuple(c for c in self.checks if not c.passed)

    def text(self) -> str:
        """The report as text: one line per check and a verdict naming the first failure."""
        lines = [c.line() for c in self.checks]
        n = len(self.checks)
        if self.passed:
            lines.append(f"passed: {n} of {n} checks")
        else:
            first = self.failures[0]
            lines.append(
                f"FAILED: {len(self.failures)} of {n} checks; first: {first.kind} at "
                f"{first.where}, {first.item}"
            )
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "model": self.model,
            "passed": self.passed,
            "seed": self.seed,
            "checks": [c.to_dict() for c in self.checks],
        }


def _checker(model: Model) -> Any:
    """The reference a model is checked against: MuJoCo for a model read from MJCF, else
    Pinocchio (each a module with ``placement_errors`` and ``closure_residuals``)."""
    if getattr(model.source, "layout", None) is not None:
        from . import mujoco

        return mujoco
    from . import pinocchio

    return pinocchio


def _scales(model: Model, names: tuple[str, ...]) -> np.ndarray:
    """Size of a typical change of each joint coordinate: the model size for lengths
    (prismatic joints, floating translations), 1 for angles [rad]."""
    size = max(1.0, model.length_scale)
    out = []
    for name in names:
        base, _, part = name.partition(".")
        if part:  # a floating joint's coordinate
            out.append(size if part in ("x", "y", "z") else 1.0)
        else:
            out.append(size if model.tree.joint(base).type == "prismatic" else 1.0)
    return np.array(out)


def _worst(errors: dict[str, float]) -> tuple[float, str]:
    name = max(errors, key=lambda k: errors[k])
    return errors[name], name


def _jacobian_check(model: Model, cfg: Configuration, where: str, tol: float) -> Check:
    """Symbolic ``J_p``, ``J_s`` against central differences of ``g`` in the local chart."""
    calls = model_calls(model)
    y, c = model.chart.to_local(cfg.y)
    theta = np.array(cfg.theta)
    J_p, J_s = (np.array(a, dtype=float) for a in calls.jac(y, theta, c))

    def g(yy: np.ndarray, tt: np.ndarray) -> np.ndarray:
        return np.array(calls.g(yy, tt, c), dtype=float).ravel()

    def central(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
        cols = []
        for i in range(x.size):
            h = 1e-6 * max(1.0, abs(float(x[i])))
            e = np.zeros_like(x)
            e[i] = h
            cols.append((f(x + e) - f(x - e)) / (2 * h))
        return np.array(cols).T

    fd_p = central(lambda v: g(v, theta), y)
    fd_s = -central(lambda v: g(y, v), theta)
    size = max(1.0, float(np.abs(J_p).max()), float(np.abs(J_s).max()))
    labels = model.row_labels()
    rows = [labels[r] for r in model.rows]
    errors: dict[str, float] = {}
    for name, J, fd, cols in (
        ("J_p", J_p, fd_p, model.unknowns),
        ("J_s", J_s, fd_s, model.actuated),
    ):
        diff = np.abs(J - fd) / size
        r, k = np.unravel_index(int(np.argmax(diff)), diff.shape)
        errors[f"{name}[{rows[r]}, {cols[k]}]"] = float(diff[r, k])
    error, item = _worst(errors)
    return Check("jacobians", where, error, tol, f"entry {item}")


def verify_model(
    model: Model,
    samples: int = 3,
    seed: int = 0,
    spread: float = 0.05,
    tolerance: float = 1e-9,
    jacobian_tolerance: float = 1e-6,
) -> VerifyReport:
    """Cross-check a model's symbolic kinematics against Pinocchio and finite differences.

    Args:
        model: the model (e.g. from :func:`scdk_sym.load_model`).
        samples: random configurations, and random solutions, to check besides home.
        seed: seed of the random generator.
        spread: size of the random changes from home [rad for angles; fraction of the model
            size for lengths].
        tolerance: largest accepted placement or closure error, relative to the model size
            (times ``max(1, model.length_scale)``) [1].
        jacobian_tolerance: largest accepted Jacobian error relative to the largest Jacobian
            entry [1].

    Returns:
        The :class:`VerifyReport`; ``report.passed`` is True when every check passed.

    Raises:
        InputError: ``samples`` negative or ``spread`` not positive.
    """
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 0:
        raise InputError(f"verify_model: samples must be an integer >= 0, got {samples!r}")
    if not (isinstance(spread, (int, float)) and math.isfinite(spread) and spread > 0):
        raise InputError(f"verify_model: spread must be a positive number, got {spread!r}")
    rng = np.random.default_rng(seed)
    tol = tolerance * max(1.0, model.length_scale)
    home = model.home
    y_scale = _scales(model, model.unknowns)
    th_scale = _scales(model, model.actuated)
    checks: list[Check] = []

    points = [("home", home.y, home.theta)]
    for i in range(samples):
        y = home.y + spread * y_scale * rng.standard_normal(model.m)
        th = home.theta + spread * th_scale * rng.standard_normal(model.k)
        points.append((f"random configuration {i + 1}", y, th))
    checker = _checker(model)
    for where, y, th in points:
        error, frame = _worst(checker.placement_errors(model, y, th))
        checks.append(Check("placements", where, error, tol, f"frame {frame!r}"))

    labels = [c.label for c in model.closures]
    solutions: list[tuple[str, Configuration | None, str]] = [("home", home, "")]
    for i in range(samples):
        step = spread * th_scale * rng.standard_normal(model.k)
        cfg, why = None, ""
        for _ in range(4):  # halve the step while the path does not reach it
            try:
                cfg = solve(
                    model, home.theta + step, branch="convergent", record_path=False
                ).configuration
                break
            except ScdkError as exc:
                why = f"sc.solve failed: {exc}"
                step = step / 2
        solutions.append((f"solution {i + 1}", cfg, why))
    for where, cfg, why in solutions:
        if cfg is None:
            checks.append(Check("closures", where, math.inf, tol, why))
            continue
        res = checker.closure_residuals(model, cfg.coordinates)
        error, closure = _worst(dict(zip(labels, res.tolist(), strict=True)))
        checks.append(Check("closures", where, error, tol, f"closure {closure}"))

    for where, cfg, why in solutions:
        if cfg is None:
            checks.append(Check("jacobians", where, math.inf, jacobian_tolerance, why))
            continue
        checks.append(_jacobian_check(model, cfg, where, jacobian_tolerance))
        if checker.__name__.endswith("mujoco"):
            error, item = checker.jacobian_error(model, cfg)
            checks.append(Check("jacobians", f"{where} vs MuJoCo", error, jacobian_tolerance, item))
    return VerifyReport(model.name, tuple(checks), seed)
