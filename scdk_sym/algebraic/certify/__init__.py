"""Interval (Krawczyk) certificates of real solutions of square systems ``f(x, p) = 0``.

For a box ``X`` with centre ``m``, a floating-point ``Y ~ J(m)^-1`` and the interval Jacobian
``J(X)`` (``casadi.jacobian`` of ``f`` replayed in ball arithmetic,
:mod:`scdk_sym.algebraic.interval`), the Krawczyk operator is

    K(X) = m - Y f(m) + (I - Y J(X)) (X - m).

If ``K(X)`` lies in the interior of ``X``, then ``X`` holds exactly one zero of ``f(., p)``
(for every ``p`` of the parameter box) and the zero lies in ``K(X)`` (Krawczyk 1969; Moore
1977; Rump 1983). Every operation rounds outward, so the statement is a proof about the
Function's expression graph with its binary64 constants.

The test has two twins side by side: :mod:`.krawczyk_arb` in Arb ball arithmetic (boxes chosen
adaptively by epsilon-inflation, a proven enclosure shrunk by Krawczyk steps; it alone tries
more boxes and says why a test fails) and :mod:`.krawczyk_c` with ``krawczyk.c``, the first
box of many points at once in binary64 interval arithmetic in C when the system is rational
(the box built the same way, the same operator and tightening, every bound rounded
outward). The modules:

- :mod:`.certificate`: what a test proves (:class:`Certificate`, :class:`CertificateSet`);
- :mod:`.inputs`: the checks of the input; :mod:`.square`: the replays of one square system;
  :mod:`.rounding`: binary64 bounds of balls;
- :mod:`.points`: the tests of points of a CasADi system (:func:`krawczyk`,
  :func:`certify_all`, :func:`certify_sets`); :mod:`.disjoint`: whether the proven boxes are
  pairwise disjoint (each then holds a different zero);
- :mod:`.configurations`: the closure system ``g(y, theta) = 0`` of a loaded model
  (:func:`closure_function`, :func:`certify_solution`, :func:`certify_configurations`,
  :func:`certify_configuration_sets`), unknowns ``y`` in the local chart of the floating
  joints, ``theta`` and the chart as exact parameters.
"""

from .certificate import Certificate, CertificateSet
from .configurations import (
    certify_configuration_sets,
    certify_configurations,
    certify_solution,
    closure_function,
)
from .inputs import ARITHMETICS
from .krawczyk_arb import EPS, INFLATION, MAX_CONDITION, TIGHTEN, TINY, TRIES
from .points import certify_all, certify_sets, krawczyk

__all__ = [
    "ARITHMETICS",
    "Certificate",
    "CertificateSet",
    "EPS",
    "INFLATION",
    "MAX_CONDITION",
    "TIGHTEN",
    "TINY",
    "TRIES",
    "certify_all",
    "certify_configuration_sets",
    "certify_configurations",
    "certify_sets",
    "certify_solution",
    "closure_function",
    "krawczyk",
]
