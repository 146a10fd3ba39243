"""The polynomial-system protocol shared by the algebraic form and the homotopy engine.

A model's algebraic form and every hand-written test system satisfy
:class:`PolynomialSystem`; the engine (:mod:`scdk_sym.algebraic.paths.continuation`,
:mod:`scdk_sym.algebraic.monodromy`, :mod:`scdk_sym.algebraic.homotopy`) uses nothing else.
The homotopy family is ``F(z; p, b) = G(z, p) + b`` with ``b_i = 0`` on structural rows.

Optional, outside the protocol: a system may define ``trace_map(z: (N, n)) -> (N, m)``,
polynomial functions of the solutions that stay finite where an affine chart's coordinates do
not (e.g. a platform's translation and rotation matrix entries); the trace test of
:mod:`scdk_sym.algebraic.monodromy` sums those instead of ``z``.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class PolynomialSystem(Protocol):
    """A square family G(z, p) = 0, holomorphic in z (C^n) and in the parameters p (C^n_params)."""

    @property
    def n(self) -> int:
        """Number of complex unknowns z (= number of rows)."""
        ...

    @property
    def n_params(self) -> int:
        """Number of complex parameters p."""
        ...

    @property
    def offset_rows(self) -> np.ndarray:
        """(n,) bool: rows that take a generic constant offset b_i in the homotopy family
        G(z, p) + b = 0 (closure rows). Structural rows (c^2 + s^2 - 1, a quaternion chart
        a.q - 1, w (q.q) - 1) are False: b_i = 0 there always."""
        ...

    def evaluate(self, z: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """z: (N, n) complex, p: (N, n_params) complex ->
        G (N, n), dG/dz (N, n, n), dG/dp (N, n, n_params), all complex."""
        ...

    def random_point(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """A random complex z (n,) on which every structural row (offset_rows False) vanishes,
        and a random complex parameter point p (n_params,)."""
        ...

    def content_hash(self) -> str:
        """A hex digest of everything G depends on (start systems are cached under it)."""
        ...
