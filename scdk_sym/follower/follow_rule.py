"""The constants of the curve follower's rule that the generated C follower mirrors.

One definition for both followers: :func:`scdk_sym.follower.curve.follow` reads them here
and :mod:`scdk_sym.codegen.generate` writes them into the generated C tracker's ``follow``
(acceptance and growth of a step, the orientation chart, the check of a step for a level
crossing, the bound telling folds from bifurcations).
"""

from __future__ import annotations

#: A predictor-corrector step is accepted when its first correction is below this fraction of
#: the step, its last below NEWTON_TOL model sizes, and the tangent turned by < acos(MIN_COS).
MAX_PREDICTOR_ERROR = 0.1
NEWTON_TOL = 1e-7
MIN_COS = 0.97
#: Accepted steps whose first correction is below SMOOTH_CORRECTION of the step and whose
#: tangent turned by < acos(SMOOTH_COS) are smooth: the next step grows by GROW.
SMOOTH_CORRECTION = 0.02
SMOOTH_COS = 0.95
GROW = 1.6
#: Intervals of a step on which the cubic Hermite of s is checked for a crossing of a level.
FINE = 64
#: A singular point where H' = [J_p, -j_s] drops rank is a bifurcation when the left null
#: vector w of J_p there is one of J_s too, |w^T J_s| / |J_s| below this (the singularity does
#: not depend on the actuators). Where only w^T J_s dtheta vanishes the line grazes the
#: singular surface: two folds close together, not two branches crossing.
STRUCTURAL = 1e-4
#: The orientation chart is re-centred when a Rodrigues parameter exceeds this (~53 deg).
RECENTRE = 0.5
#: Rodrigues parameters of the chart stay below this (127 deg) inside one call.
CHART_LIMIT = 2.0
