"""Joint grids of an atlas: ``NAME=lo:hi:n`` axes over actuated joints, flattened in C order.

Point ``i`` of a grid is the C-order (last axis fastest) flattening of its axes, in the order
the names were given; every actuated joint that is not an axis stays at the start
configuration's value (the model's home, or the configuration given as ``start``), recorded
as ``fixed``. The ``theta`` rows are always in the model's actuated order.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, UnknownNameError


@dataclass(frozen=True)
class Axis:
    """One grid axis: ``n`` values evenly spaced from ``lo`` to ``hi`` (both included)."""

    name: str
    lo: float
    hi: float
    n: int

    @property
    def values(self) -> np.ndarray:
        """(n,) the axis values [rad or model length unit]."""
        return np.linspace(self.lo, self.hi, self.n)

    def to_text(self) -> str:
        return f"{self.name}={self.lo!r}:{self.hi!r}:{self.n}"


@dataclass(frozen=True)
class Grid:
    """A joint grid over some actuated joints of a model.

    Attributes:
        axes: the axes in flattening order (the first varies slowest).
        actuated: the model's actuated names (the column order of ``theta``).
        fixed: actuated joints that are not axes -> their value (from the start).
    """

    axes: tuple[Axis, ...]
    actuated: tuple[str, ...]
    fixed: tuple[tuple[str, float], ...]

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(a.n for a in self.axes)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64))

    def thetas(self, start: int, stop: int) -> np.ndarray:
        """(stop - start, k) the ``theta`` rows of points ``start`` to ``stop - 1``."""
        idx = np.unravel_index(np.arange(start, stop, dtype=np.int64), self.shape)
        out = np.empty((stop - start, len(self.actuated)))
        values = dict(self.fixed)
        for j, name in enumerate(self.actuated):
            if name in values:
                out[:, j] = values[name]
        for a, i in zip(self.axes, idx, strict=True):
            out[:, self.actuated.index(a.name)] = a.values[i]
        return out

    def to_attrs(self) -> dict:
        """JSON-able description (the store's ``grid`` attribute)."""
        return {
            "axes": [{"name": a.name, "lo": a.lo, "hi": a.hi, "n": a.n} for a in self.axes],
            "fixed": {n: v for n, v in self.fixed},
            "order": "C (last axis fastest)",
        }

    def to_text(self) -> str:
        return ",".join(a.to_text() for a in self.axes)


def parse_axes(text: str) -> dict[str, tuple[float, float, int]]:
    """``"a=lo:hi:n,b=lo:hi:n"`` -> ``{"a": (lo, hi, n), ...}`` (order kept)."""
    axes: dict[str, tuple[float, float, int]] = {}
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        name, sep, rng = part.partition("=")
        bits = rng.split(":")
        if not sep or len(bits) != 3:
            raise InputError(f"--grid: expected NAME=lo:hi:n, got {part!r}")
        try:
            lo, hi, n = float(bits[0]), float(bits[1]), int(bits[2])
        except ValueError as exc:
            raise InputError(f"--grid {part!r}: lo, hi must be numbers and n an integer") from exc
        if name.strip() in axes:
            raise InputError(f"--grid: {name.strip()!r} is given twice")
        axes[name.strip()] = (lo, hi, n)
    if not axes:
        raise InputError(f"--grid: no axis in {text!r}; expected NAME=lo:hi:n[,NAME=lo:hi:n]")
    return axes


def make_grid(
    model, axes: str | Mapping[str, tuple[float, float, int]], fixed_theta: np.ndarray
) -> Grid:
    """A :class:`Grid` from axis specifications.

    Args:
        model: the model (its actuated names).
        axes: ``"NAME=lo:hi:n,..."`` or a mapping ``name -> (lo, hi, n)`` (order kept).
        fixed_theta: (k,) values of the actuated joints that are not axes (the start's theta).

    Raises:
        UnknownNameError: a name is not an actuated joint (the valid ones are listed).
        InputError: malformed text, n < 1, non-finite bounds.
    """
    spec = parse_axes(axes) if isinstance(axes, str) else dict(axes)
    out = []
    for name, rng in spec.items():
        if name not in model.actuated:
            raise UnknownNameError("actuated joint", name, model.actuated)
        try:
            lo, hi, n = float(rng[0]), float(rng[1]), int(rng[2])
        except (TypeError, ValueError, IndexError) as exc:
            raise InputError(f"grid axis {name!r}: expected (lo, hi, n), got {rng!r}") from exc
        if n < 1 or not (np.isfinite(lo) and np.isfinite(hi)):
            raise InputError(f"grid axis {name!r}: need finite lo, hi and n >= 1, got {rng!r}")
        out.append(Axis(name, lo, hi, n))
    fixed = tuple(
        (name, float(v))
        for name, v in zip(model.actuated, fixed_theta, strict=True)
        if name not in spec
    )
    return Grid(tuple(out), tuple(model.actuated), fixed)
