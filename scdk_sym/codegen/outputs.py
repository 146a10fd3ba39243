"""What the generated C tracker's calls take and return, as Python sees them: the ctypes
mirrors of its option and refusal structs, and the raw outputs of a track, a solve and a sweep
(before any verification: :mod:`scdk_sym.codegen.library` calls the library,
:mod:`scdk_sym.solvers` verifies)."""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Options", "Refusal", "SolveOutput", "SweepOutput", "TrackOutput", "refusal_type"]


class Options(ctypes.Structure):
    """Mirror of ``<prefix>_options`` (see the generated header for the meaning)."""

    _fields_ = [
        ("tol", ctypes.c_double),
        ("length_scale", ctypes.c_double),
        ("accept", ctypes.c_double),
        ("margin", ctypes.c_double),
        ("arc_budget", ctypes.c_double),
        ("max_steps", ctypes.c_int),
        ("order", ctypes.c_int),
    ]


def refusal_type(m: int, k: int, n: int, nc: int) -> type[ctypes.Structure]:
    """Mirror of ``<prefix>_refusal`` for a model with m unknowns, k actuators, n workspace
    coordinates and a chart of nc entries (see the generated header)."""

    class CRefusal(ctypes.Structure):
        _fields_ = [
            ("y", (ctypes.c_double * m) * 2),
            ("c", ctypes.c_double * max(1, nc)),
            ("x", (ctypes.c_double * n) * 2),
            ("theta", ctypes.c_double * k),
            ("miss", ctypes.c_double * 2),
            ("accuracy", ctypes.c_double),
            ("step", ctypes.c_double),
            ("count", ctypes.c_int),
        ]

    return CRefusal


@dataclass(frozen=True)
class Refusal:
    """The two candidates of a sample the tracker refused to decide (status -9), best first.

    Attributes:
        y: (count, m) unknowns in the chart ``c``.
        c: (nc,) that chart.
        x: (count, n) workspace coordinates.
        theta: (k,) the reading.
        miss: (count,) distance of each from the predicted configuration (max norm).
        accuracy: accuracy of the prediction (its error at the last sample; 0 if unknown).
        step: the predicted step (max norm; infinite when no motion was known).
    """

    y: np.ndarray
    c: np.ndarray
    x: np.ndarray
    theta: np.ndarray
    miss: np.ndarray
    accuracy: float
    step: float


@dataclass(frozen=True)
class TrackOutput:
    """Raw output of one call of ``<prefix>_tracker_track``.

    Attributes:
        status: the call's status (0, or the first error code).
        failed: index of the failing sample, -1 if none.
        y: (N, m) unknowns in the local charts ``c`` (NaN from the failing sample on).
        c: (N, nc) charts (reference rotations, column-major 3x3 per floating joint).
        x: (N, n) workspace coordinates.
        det: (N,) ``det J_p`` at each sample.
        codes: (N,) status of each sample (0: cheap step, 1: followed the SC curve,
            2: corrected from the predicted motion).
        residual: (N,) max |g| of each sample, evaluated in the call by the generated closure
            function and checked against the tolerance there (NaN from the failing sample on).
        refusal: the candidates of the failing sample when ``status`` is -9 (the readings
            are too coarse to decide between them), else None.
    """

    status: int
    failed: int
    y: np.ndarray
    c: np.ndarray
    x: np.ndarray
    det: np.ndarray
    codes: np.ndarray
    residual: np.ndarray
    refusal: Refusal | None = None


@dataclass(frozen=True)
class SolveOutput:
    """Raw output of one call of ``<prefix>_solve_convergent`` or ``<prefix>_solve_divergent``.

    Attributes:
        status: 1 (solved along the curve) or an error code (see :data:`STATUS`).
        y: (m,) unknowns in the chart ``c`` (NaN unless solved).
        c: (nc,) chart.
        x: (n,) workspace coordinates.
        residual: max |closure row| at the solution [model length unit].
        det: ``det J_p`` at the solution.
        fold_s: the divergent solve's fold: its ``s`` on the line (NaN otherwise).
        fold_y: (m,) its unknowns in the chart ``fold_c`` (divergent solve only).
        fold_x: (n,) its workspace coordinates (divergent solve only).
        fold_c: (nc,) the chart of ``fold_y`` (divergent solve only).
        checks: (18,) at the answer (its ``y``, ``c``): the platform placement (16 values,
            column-major), ``det J_p`` and ``|J_p|_F``, what the answer is verified by.
    """

    status: int
    y: np.ndarray
    c: np.ndarray
    x: np.ndarray
    residual: float
    det: float
    fold_s: float = math.nan
    fold_y: np.ndarray | None = None
    fold_x: np.ndarray | None = None
    fold_c: np.ndarray | None = None
    checks: np.ndarray | None = None


@dataclass(frozen=True)
class SweepOutput:
    """Raw output of one call of ``<prefix>_sweep`` over N points.

    Attributes:
        x: (N, n) workspace coordinates (NaN where the point is left to the caller).
        det: (N,) ``det J_p`` at each solution, in the chart centred on it.
        residual: (N,) max |closure row| at each solution [model length unit].
        codes: (N,) 0 continued from its neighbour, 1 solved from the start, < 0 left to
            the caller.
    """

    x: np.ndarray
    det: np.ndarray
    residual: np.ndarray
    codes: np.ndarray
