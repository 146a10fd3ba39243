"""The checks of a Krawczyk test's input: real points, parameters (exact or bounds) and the
test's settings."""

from __future__ import annotations

import numpy as np
from flint import arb
from numpy.typing import ArrayLike

from ...errors import InputError

#: Arithmetics of the tests: ``"auto"`` (the first box of a rational system in binary64
#: intervals in C where a compiler is present, then Arb) or ``"arb"`` (Arb only).
ARITHMETICS = ("auto", "arb")


def real_array(value: ArrayLike, what: str) -> np.ndarray:
    """``value`` as a float array; complex input only with zero imaginary parts."""
    a = np.asarray(value)
    if np.iscomplexobj(a):
        if np.any(a.imag != 0):
            raise InputError(
                f"{what} has nonzero imaginary parts (max {np.max(np.abs(a.imag)):.1e}); "
                f"certificates are for real zeros: pass the real part of a real solution"
            )
        a = a.real
    return np.asarray(a, dtype=float)


def real_vector(value: ArrayLike, size: int, what: str) -> np.ndarray:
    """``value`` as ``size`` finite floats (:func:`real_array`, flattened).

    Raises:
        InputError: another size, a non-finite entry or a nonzero imaginary part (the
            message names ``what``).
    """
    v = real_array(value, what).ravel()
    if v.size != size or not np.all(np.isfinite(v)):
        raise InputError(
            f"{what} must be {size} finite numbers, got shape {np.shape(value)}"
            f"{'' if v.size != size else ' with non-finite entries'}; pass a ({size},) array"
        )
    return v


def parameters(p: ArrayLike, size: int) -> tuple[np.ndarray, np.ndarray, bool]:
    """Binary64 midpoints, (k, 2) bounds and whether the values are exact, from (k,) exact
    values or (k, 2) bounds (:func:`parameter_balls` makes their balls)."""
    a = real_array(p, "parameters p")
    if a.ndim == 2 and a.shape == (size, 2):
        if not np.all(np.isfinite(a)) or np.any(a[:, 0] > a[:, 1]):
            raise InputError(
                "parameter bounds must be finite with lo <= hi per row; pass (k, 2) [lo, hi]"
            )
        return a.mean(axis=1), a.copy(), False
    v = real_vector(a, size, "parameters p")
    return v, np.stack([v, v], axis=1), True


def parameter_balls(bounds: np.ndarray, exact: bool) -> list[arb]:
    """The parameter balls of :func:`parameters`' bounds (the Arb test's)."""
    if exact:
        return [arb(float(t)) for t in bounds[:, 0]]
    return [arb(lo).union(arb(hi)) for lo, hi in bounds]


def check_settings(tries: int, tighten: int, arithmetic: str) -> None:
    """Check the settings of a test.

    Args:
        tries: boxes tried (at least 1).
        tighten: Krawczyk steps that shrink a proven enclosure (at least 0).
        arithmetic: one of :data:`ARITHMETICS`.

    Raises:
        InputError: a setting out of its range, or an unknown arithmetic.
    """
    if tries < 1 or tighten < 0:
        raise InputError(f"tries >= 1 and tighten >= 0 required, got {tries}, {tighten}")
    if arithmetic not in ARITHMETICS:
        raise InputError(
            f"unknown arithmetic {arithmetic!r}; arithmetics: {', '.join(ARITHMETICS)}"
        )
