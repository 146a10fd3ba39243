"""How a track fails: the refusals of the rule and the verification of its samples.

The same errors for both backends (:mod:`scdk_sym.solvers.track`, :mod:`scdk_sym.solvers.track_c`):
a sample where no solution was met, a sample the rule refuses to decide (R4), and a sample
whose residual exceeds the model's tolerance.
"""

from __future__ import annotations

import math

import numpy as np

from ..codegen.status import TrackerStatus
from ..errors import TrackError
from ..follower.track_rule import ACCEPT, MARGIN
from ..robot import Model


def no_solution_error(index: int, theta: np.ndarray) -> TrackError:
    """The :class:`TrackError` of a sample where no solution was met (status -5)."""
    return TrackError(
        f"sample {index}: no solution at theta={np.asarray(theta).tolist()} was met from the "
        "previous sample along the solution curve (the readings leave the reachable set or jump "
        "too far)",
        index, TrackerStatus.ERR_NO_SOLUTION, theta=theta,
    )  # fmt: skip


def undecidable_error(index: int, theta, xs, miss, accuracy: float, step: float) -> TrackError:
    """The :class:`TrackError` of a sample the rule refuses to decide (status -9, rule R4).

    Args:
        index: the sample.
        theta: (k,) its reading.
        xs: workspace coordinates of the best candidate and the runner-up (if any).
        miss: their misses of the predicted configuration (max norm).
        accuracy: the accuracy of the prediction ``E``.
        step: the predicted step ``L``.
    """
    e1 = float(miss[0])
    if not math.isfinite(step):
        why = (
            f"no motion is known to predict from, and their distances {e1:.3g} and "
            f"{float(miss[1]):.3g} from the previous sample are within a factor {MARGIN:g}"
        )
    elif len(xs) < 2 or e1 > ACCEPT * step:
        why = f"the best misses the predicted motion by {e1:.3g} > {ACCEPT:g} x step {step:.3g}"
    else:
        why = (
            f"their misses {e1:.3g} and {float(miss[1]):.3g} of the predicted motion (accuracy "
            f"{accuracy:.3g}) are within a factor {MARGIN:g}"
        )
    listed = " and ".join(str(np.round(np.asarray(x, float), 6).tolist()) for x in xs)
    return TrackError(
        f"sample {index}: the readings are too coarse to decide between candidate solutions "
        f"x = {listed} at theta={np.asarray(theta).tolist()}: {why}",
        index, TrackerStatus.ERR_UNDECIDABLE, theta=theta, candidates=xs,
    )  # fmt: skip


def verify_samples(model: Model, residual: np.ndarray, thetas: np.ndarray) -> None:
    """Raise TrackError at the first sample whose residual exceeds the model's tolerance.

    Args:
        model: the model.
        residual: (N,) max |closure row| per sample [model length unit].
        thetas: (N, k) the readings.
    """
    ok = residual <= model.tolerance
    if not ok.all():
        bad = np.flatnonzero(~ok)
        i = int(bad[0])
        raise TrackError(
            f"sample {i} failed verification: residual {residual[i]:.3g} > "
            f"{model.tolerance:.1e} (theta={thetas[i].tolist()})",
            i, 0, float(residual[i]), theta=thetas[i],
        )  # fmt: skip
