"""Shared helpers of the builders: argument validation and the final regularity check."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TypeVar

import numpy as np

from ..errors import InputError, NonSquareSystemError
from ..model.spec import Spec
from ..model.urdf import Tree
from ..robot import Model, model_from_tree

T = TypeVar("T")

#: Smallest accepted ratio of the extreme singular values of the (scaled) J_p at home.
MIN_CONDITION = 1e-6


def points(value, shape: tuple[int, ...], name: str) -> np.ndarray:
    """A finite float array of the given shape (raises :class:`InputError` naming ``name``)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be an array of shape {shape}, got {value!r}") from exc
    if arr.shape != shape:
        raise InputError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def positive(value, name: str, allow_zero: bool = False) -> float:
    """A finite positive (or, with ``allow_zero``, non-negative) length."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a length (a number), got {value!r}") from exc
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        kind = "a non-negative" if allow_zero else "a positive"
        raise InputError(f"{name} must be {kind} length, got {value!r}")
    return v


def lengths(value, count: int, name: str) -> np.ndarray:
    """``count`` positive lengths from a scalar (repeated) or a sequence."""
    arr = np.asarray(value, dtype=float) if not np.isscalar(value) else None
    if arr is None or arr.ndim == 0:
        return np.full(count, positive(value, name))
    arr = points(arr, (count,), name)
    for i, v in enumerate(arr):
        positive(v, f"{name}[{i}]")
    return arr


def affine_rank(pts: np.ndarray) -> int:
    """Dimension of the affine hull of a point set (0: coincident, 1: collinear, ...)."""
    centred = pts - pts.mean(axis=0)
    scale = max(float(np.abs(pts).max()), 1e-300)
    sv = np.linalg.svd(centred, compute_uv=False)
    return int(np.sum(sv > 1e-9 * scale))


def duplicate_legs(base: np.ndarray, platform: np.ndarray, name: str) -> None:
    """Refuse two legs joining the same pair of anchors (the system would be degenerate)."""
    scale = max(float(np.abs(base).max()), float(np.abs(platform).max()), 1e-300)
    for i in range(len(base)):
        for j in range(i):
            if (
                np.linalg.norm(base[i] - base[j]) < 1e-9 * scale
                and np.linalg.norm(platform[i] - platform[j]) < 1e-9 * scale
            ):
                raise InputError(
                    f"{name}: legs {j + 1} and {i + 1} join coincident anchors "
                    f"(base {base[i].tolist()}, platform {platform[i].tolist()}): "
                    "the system is degenerate"
                )


def line_jacobian(
    units: np.ndarray, arms: np.ndarray | None = None, size: float = 1.0
) -> np.ndarray:
    """Jacobian of leg lengths w.r.t. the platform twist: rows ``[u_i, (r_i x u_i) / size]``.

    Args:
        units: (n, d) unit leg directions (d = 2 planar, 3 spatial).
        arms: (n, d) platform anchors relative to the platform origin, world axes; ``None``
            for a translational platform.
        size: length that scales the rotation columns (so the ratio is unit-free).
    """
    if arms is None:
        return units
    if units.shape[1] == 2:
        moment = arms[:, 0] * units[:, 1] - arms[:, 1] * units[:, 0]
        return np.column_stack([units, moment / size])
    return np.hstack([units, np.cross(arms, units) / size])


def conditioning(J: np.ndarray) -> float:
    """Ratio of the smallest to the largest singular value (0 when singular)."""
    sv = np.linalg.svd(J, compute_uv=False)
    return float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0


def pick(candidates: Sequence[T], score: Callable[[T], float]) -> T | None:
    """The first candidate scoring at least half the best score (``None`` if all score 0)."""
    scores = [score(c) for c in candidates]
    best = max(scores)
    if not best > 0:
        return None
    return next(c for c, s in zip(candidates, scores, strict=True) if s >= 0.5 * best)


def finish(tree: Tree, spec: Spec, names: str) -> Model:
    """Load the built model and check that its closure system is square and regular at home.

    Args:
        tree: the built spanning tree.
        spec: its closures, actuated joints and home configuration.
        names: the arguments to blame if the system is degenerate (e.g. "base_points/home_x").

    Raises:
        InputError: the closure Jacobian is rank-deficient or ill-conditioned at home.
    """
    try:
        model = model_from_tree(tree, spec)
    except NonSquareSystemError as exc:
        raise InputError(
            f"{names} give a degenerate mechanism: the closure Jacobian has rank {exc.rank} "
            f"of {exc.unknowns} at the home pose"
        ) from exc
    if model.reduction is not None:
        raise InputError(f"{names} give a degenerate mechanism ({model.reduction})")
    y, c = model.chart.to_local(model.home.y)
    Jp = np.array(model.kernels.jac(y, model.home.theta, c)[0])
    ratio = conditioning(Jp)
    if ratio < MIN_CONDITION:
        raise InputError(
            f"{names} give a (nearly) singular home pose: J_p has condition number "
            f"{1 / max(ratio, 1e-300):.3g}; pass another home_x"
        )
    return model
