"""Homotopy path tracking: the numpy tracker (:mod:`.tracker`, the reference) and its C twin
(:mod:`.ctracker` with ``ptrack.c`` and ``ptrack.h`` beside it, for the parameter
homotopies of a model's algebraic form)."""

from .ctracker import BoundTracker, CTracker, SplitOutcome, c_tracker
from .tracker import (
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
