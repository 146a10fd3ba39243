"""The constants of the tracking rule (R0-R4, stated in :mod:`scdk_sym.solvers.track`).

One definition for both trackers: :func:`scdk_sym.track` reads them here and
:mod:`scdk_sym.codegen.generate` writes them into the generated C tracker.
"""

from __future__ import annotations

#: R2, R4: the best candidate must miss the prediction by at most this fraction of the step.
ACCEPT = 0.5
#: R2, R4: the runner-up must miss the prediction by more than this many times the best miss
#: and the prediction's accuracy.
MARGIN = 3.0
#: R1: with two increments known, the extrapolation is quadratic if the motion's second
#: difference is at most this fraction of its step.
SMOOTH = 0.5
#: R3: arc length followed along the curve in each direction, in units of ``ell``.
BUDGET = 40.0
#: R2: evaluations of g and J_p (Newton iterations + 1) of the fast continuation.
FAST_ITERATIONS = 4
#: R2: Newton calls of the cheap continuation.
NEWTON_CALLS = 3
#: R3: Newton calls from the prediction and of the polish of each candidate.
PREDICTED_CALLS = 8
#: R3: inverse-iteration steps for the smallest singular pair of J_p (fold partners).
PARTNER_ITERATIONS = 3
#: R3: finite-difference step of the fold's curvature, relative to max(1, length scale).
PARTNER_STEP = 1e-7
#: R3: a fold partner farther from its root than this, relative to max(1, length scale), is
#: none (the fold's normal form says nothing that far: where the curvature vanishes it puts
#: the "partner" anywhere, and Newton from there lands back on the root, less polished).
PARTNER_REACH = 1.0
#: R3: crossings of s = 1 collected per direction.
HITS_PER_DIRECTION = 2
#: Predictor-corrector steps per direction of the C tracker's curve follower (a safety limit:
#: the arc budget ends the search first).
MAX_STEPS = 2000
