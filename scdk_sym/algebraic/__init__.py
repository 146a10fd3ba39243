"""Algebraic form of a model, the homotopy engine that lists all its assembly modes, and
interval certificates of real solutions.

Engine: :class:`PolynomialSystem` (the protocol every system satisfies), start systems by
monodromy certified by a trace test (:func:`start_system`, :func:`monodromy_solve`,
:class:`StartSystem`, cached on disk), and the query solve from a start system
(:func:`solve_homotopy`, :class:`HomotopyResult`). Certificates: :func:`krawczyk` and friends.
"""

from .certify import (
    Certificate,
    CertificateSet,
    certify_all,
    certify_configuration_sets,
    certify_configurations,
    certify_sets,
    certify_solution,
    closure_function,
    krawczyk,
)
from .form import AlgebraicForm, algebraic_form
from .homotopy import HomotopyResult, solve_homotopy
from .interval import IntervalFunction, interval_function
from .monodromy import ENGINE_VERSION, StartSystem, monodromy_solve, start_system, trace_test
from .paths import TrackerOptions
from .system import PolynomialSystem

__all__ = [
    "AlgebraicForm",
    "ENGINE_VERSION",
    "Certificate",
    "CertificateSet",
    "HomotopyResult",
    "IntervalFunction",
    "PolynomialSystem",
    "StartSystem",
    "TrackerOptions",
    "algebraic_form",
    "certify_all",
    "certify_configuration_sets",
    "certify_configurations",
    "certify_sets",
    "certify_solution",
    "closure_function",
    "interval_function",
    "krawczyk",
    "monodromy_solve",
    "solve_homotopy",
    "start_system",
    "trace_test",
]
