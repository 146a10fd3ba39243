"""Algebraic form of a model and the homotopy engine that lists all its assembly modes.

Engine: :class:`PolynomialSystem` (the protocol every system satisfies), start systems by
monodromy certified by a trace test (:func:`start_system`, :func:`monodromy_solve`,
:class:`StartSystem`, cached on disk), and the query solve from a start system
(:func:`solve_homotopy`, :class:`HomotopyResult`).
"""

from .homotopy import HomotopyResult, solve_homotopy
from .monodromy import ENGINE_VERSION, StartSystem, monodromy_solve, start_system, trace_test
from .system import PolynomialSystem
from .tracker import TrackerOptions

__all__ = [
    "ENGINE_VERSION",
    "HomotopyResult",
    "PolynomialSystem",
    "StartSystem",
    "TrackerOptions",
    "monodromy_solve",
    "solve_homotopy",
    "start_system",
    "trace_test",
]
