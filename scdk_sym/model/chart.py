"""Charts of floating joints: canonical rotation vectors <-> local Rodrigues parameters.

A :class:`~scdk_sym.results.Configuration` stores the rotation of a floating joint as its
rotation vector (``log R``, canonical, chart-free). The kernels work in a local chart: Rodrigues
(Gibbs) parameters ``rho`` of the rotation relative to a reference rotation ``R_ref`` passed as
the parameter ``c`` (see :func:`scdk_sym.symbolic.kinematics.floating_motion`). The solvers
re-centre the chart (``R_ref <- R_ref cayley(rho)``, ``rho <- 0``) as the platform turns, so a
platform tilted 80 deg or turned 170 deg is as regular as one at rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rotations import cayley, rot_exp, rot_log


@dataclass(frozen=True)
class Chart:
    """Where the floating-joint rotations sit in ``y`` (indices of their three coordinates)."""

    rotations: tuple[tuple[int, int, int], ...] = ()

    @classmethod
    def for_unknowns(cls, unknowns: tuple[str, ...], floating: tuple[str, ...]) -> Chart:
        rots: list[tuple[int, int, int]] = []
        for f in floating:
            names = [f"{f}.rx", f"{f}.ry", f"{f}.rz"]
            if all(n in unknowns for n in names):
                i, j, k = (unknowns.index(n) for n in names)
                rots.append((i, j, k))
        return cls(tuple(rots))

    @property
    def size(self) -> int:
        return 9 * len(self.rotations)

    def to_local(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Canonical y -> (local y with rho = 0, chart c centred on it)."""
        y = np.array(y, dtype=float)
        c = np.zeros(self.size)
        for i, idx in enumerate(self.rotations):
            c[9 * i : 9 * i + 9] = rot_exp(y[list(idx)]).flatten(order="F")
            y[list(idx)] = 0.0
        return y, c

    def to_canonical(self, y: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Local (y, c) -> canonical y (rotation vectors)."""
        y = np.array(y, dtype=float)
        for i, idx in enumerate(self.rotations):
            R = c[9 * i : 9 * i + 9].reshape(3, 3, order="F") @ cayley(y[list(idx)])
            y[list(idx)] = rot_log(R)
        return y

    def to_canonical_many(self, ys: np.ndarray, cs: np.ndarray) -> np.ndarray:
        """:meth:`to_canonical` of several points at once: (N, m) local ``ys`` in their charts
        (N, size) ``cs`` -> (N, m) canonical."""
        ys = np.array(ys, dtype=float)
        for i, idx in enumerate(self.rotations):
            ref = np.asarray(cs)[:, 9 * i : 9 * i + 9].reshape(-1, 3, 3).transpose(0, 2, 1)
            ys[:, list(idx)] = rot_log(ref @ cayley(ys[:, list(idx)]))
        return ys

    def recentre(self, y: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Move the chart centre to the current rotation (rho becomes 0)."""
        if not self.rotations:
            return y, c
        y = np.array(y, dtype=float)
        c = np.array(c, dtype=float)
        for i, idx in enumerate(self.rotations):
            R = c[9 * i : 9 * i + 9].reshape(3, 3, order="F") @ cayley(y[list(idx)])
            u, _, vt = np.linalg.svd(R)  # re-orthonormalise
            c[9 * i : 9 * i + 9] = (u @ vt).flatten(order="F")
            y[list(idx)] = 0.0
        return y, c

    def recentred(self, y, c):
        """Symbolic twin of :meth:`recentre` on CasADi SX: ``(y, c)`` in the chart centred on
        ``y`` (``R_ref <- R_ref cayley(rho)``, ``rho <- 0``), without the re-orthonormalisation
        (``c`` stays orthonormal to rounding over one step).

        Args:
            y: (m,) SX local unknowns.
            c: (9 * number of rotations,) SX chart (column-major reference rotations).

        Returns:
            (y0, c0): SX expressions of the re-centred unknowns and chart.
        """
        import casadi as ca

        from .rotations import cayley

        y_out, c_out = ca.SX(y), ca.SX(c)
        for i, idx in enumerate(self.rotations):
            R = ca.reshape(c[9 * i : 9 * i + 9], 3, 3) @ cayley(ca.vertcat(*[y[j] for j in idx]))
            c_out[9 * i : 9 * i + 9] = ca.reshape(R, 9, 1)
            for j in idx:
                y_out[j] = 0
        return y_out, c_out
