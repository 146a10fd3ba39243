"""Exception hierarchy: every failure of the package is an :class:`ScdkError`.

Each exception keeps the offending data as attributes so callers can react
programmatically, and its message is one line that names the cause.
"""

from __future__ import annotations

from collections.abc import Iterable
from os import PathLike


class ScdkError(Exception):
    """Base class of every error raised by scdk_sym."""


class ModelError(ScdkError):
    """A model description (URDF or YAML) is malformed or inconsistent."""

    def __init__(self, message: str, path: str | None = None) -> None:
        self.path = path
        super().__init__(f"{path}: {message}" if path else message)


class UnknownNameError(ModelError):
    """A frame, joint or coordinate name does not exist.

    Attributes:
        kind: what was looked up ("frame", "joint", ...).
        name: the name that was not found.
        valid: the valid names.
        reason: why ``name`` is refused when it exists but does not fit (e.g. a fixed joint
            named as actuated); ``None`` when it does not exist.
    """

    def __init__(
        self,
        kind: str,
        name: str,
        valid: Iterable[str],
        path: str | None = None,
        reason: str | None = None,
    ):
        self.kind = kind
        self.name = name
        self.valid = tuple(valid)
        self.reason = reason
        listed = ", ".join(self.valid) if self.valid else "(none)"
        what = f"{name!r} {reason}" if reason else f"unknown {kind} {name!r}"
        super().__init__(f"{what}; {kind}s: {listed}", path)


class NonSquareSystemError(ModelError):
    """The loop-closure system cannot be reduced to an independent square one."""

    def __init__(self, message: str, rows: int, unknowns: int, rank: int, path: str | None = None):
        self.rows = rows
        self.unknowns = unknowns
        self.rank = rank
        super().__init__(message, path)


class NotAssembledError(ModelError):
    """A configuration given as assembled violates the loop closures."""

    def __init__(self, message: str, residual: float, path: str | None = None):
        self.residual = residual
        super().__init__(message, path)


class InputError(ScdkError, ValueError):
    """A numeric argument has the wrong shape, is not finite, or is out of range."""


class IntervalError(ScdkError):
    """A Function cannot be evaluated in interval arithmetic.

    Attributes:
        operation: the CasADi operation without an interval counterpart (e.g. ``"call"``).
    """

    def __init__(self, message: str, operation: str):
        self.operation = operation
        super().__init__(message)


class SolveError(ScdkError):
    """A solver could not produce a verified solution."""


class PathError(SolveError):
    """The singularity-consistent solution curve never reached its target (s = 1)."""


class UnreachableError(SolveError):
    """No assembled configuration exists (or was found) for the requested input."""


class VerificationError(SolveError):
    """A computed configuration failed its residual check."""

    def __init__(self, message: str, residual: float):
        self.residual = residual
        super().__init__(message)


class SingularTransmissionError(SolveError):
    """A motor <-> joint map is singular where it was asked for (its velocities and torques
    are not defined there).

    Attributes:
        margin: the map's margin there (relative smallest singular value).
        theta: the motor values.
    """

    def __init__(self, message: str, margin: float, theta) -> None:
        self.margin = margin
        self.theta = theta
        super().__init__(message)


class TrackError(SolveError):
    """Tracking failed at a sample: no decision, no solution, or a failed verification.

    Attributes:
        index: index of the failing sample in ``thetas``.
        status: the tracker's status code (see :data:`scdk_sym.codegen.library.STATUS`;
            the same codes for every backend): -9 the readings are too coarse to decide
            between two candidate solutions, -5 no solution was met, ..., or 0 when the
            tracker succeeded but the final verification failed.
        residual: the sample's residual (NaN if none was computed).
        theta: (k,) the reading at the failing sample (None if unknown).
        candidates: workspace coordinates (n,) of the candidate solutions the tracker could
            not decide between, best first (empty unless ``status`` is -9).
    """

    def __init__(
        self,
        message: str,
        index: int,
        status: int,
        residual: float = float("nan"),
        *,
        theta=None,
        candidates=(),
    ):
        import numpy as np

        self.index = int(index)
        self.status = int(status)
        self.residual = residual
        self.theta = None if theta is None else np.array(theta, dtype=float)
        self.candidates = tuple(np.array(x, dtype=float) for x in candidates)
        super().__init__(message)


class BuildError(ScdkError):
    """Building or compiling kernels failed (e.g. no C compiler)."""


class AtlasError(ScdkError):
    """An atlas run or store failed (missing dependency, unusable store, lost workers)."""


class StoreMismatchError(AtlasError):
    """An existing atlas store was written for another model, grid or set of options."""


class StoreLockedError(AtlasError):
    """Another run is writing the atlas store.

    Attributes:
        path: the store.
        holder: what the lock file says of the writer (``pid``, ``host``, ``started``).
    """

    def __init__(self, message: str, path: str = "", holder: dict | None = None):
        super().__init__(message)
        self.path = path
        self.holder = dict(holder or {})


class Interrupted(KeyboardInterrupt):
    """A long run was stopped by SIGINT or SIGTERM; what it finished is kept.

    Not a failure, so not an :class:`ScdkError`: a ``KeyboardInterrupt``, which ``except
    Exception`` does not swallow and ``except KeyboardInterrupt`` catches as before.

    Attributes:
        signal: the signal's name (``"SIGINT"``, ``"SIGTERM"``).
        resume: how to resume, when the run can be resumed (empty otherwise).
    """

    def __init__(self, message: str, signal: str = "SIGINT", resume: str = ""):
        super().__init__(message)
        self.signal = signal
        self.resume = resume


class OutputError(ScdkError):
    """An output file or folder cannot be written.

    Attributes:
        path: the file or folder that was asked for.
    """

    def __init__(self, message: str, path: str | PathLike[str]) -> None:
        self.path = str(path)
        super().__init__(f"{self.path}: {message}")


class PlotError(ScdkError):
    """A figure could not be made (matplotlib missing, nothing to draw, unwritable path)."""


class HomotopyError(SolveError):
    """The homotopy engine could not produce a start system or track a parameter homotopy."""


class AlgebraicFormError(ModelError):
    """A model's closure system has no polynomial (algebraic) form, or a point cannot be mapped
    between the model's coordinates and the form's unknowns."""


class ViewError(ScdkError):
    """The 3-D viewer could not show or write a scene (viser missing, nothing to show, an
    unwritable page, a port in use)."""


class DependencyError(ScdkError):
    """An optional dependency that a command needs is not installed (the message gives the
    install command)."""


class ModelWarning(UserWarning):
    """A model file says something the loader reads as its source tool does, but that looks
    like a mistake (e.g. a joint edit naming a joint the URDF does not have)."""
