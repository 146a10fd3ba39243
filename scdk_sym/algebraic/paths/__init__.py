"""Homotopy path tracking: the numpy tracker (:mod:`.continuation`, the reference) and its C twin
(:mod:`.continuation_c` with ``continuation.c`` and ``continuation.h`` beside it, for the parameter
homotopies of a model's algebraic form)."""

from .continuation import (
    DIVERGED,
    DONE,
    RUNNING,
    STEP_LIMIT,
    UNDERFLOW,
    TrackerOptions,
    TrackOutcome,
    newton,
    rel_norm,
    track,
)
from .continuation_c import BoundTracker, CTracker, SplitOutcome, c_tracker

__all__ = [
    "BoundTracker",
    "CTracker",
    "DIVERGED",
    "DONE",
    "RUNNING",
    "STEP_LIMIT",
    "SplitOutcome",
    "TrackOutcome",
    "TrackerOptions",
    "UNDERFLOW",
    "c_tracker",
    "newton",
    "rel_norm",
    "track",
]
