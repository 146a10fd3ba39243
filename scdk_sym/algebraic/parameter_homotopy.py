"""The homotopy between two members of a parameter family ``F(z; p, b) = G(z, p) + b``.

A path runs from ``(p_a, b_a)`` to ``(p_b, b_b)`` along ``p(s) = p_a + s (p_b - p_a)``,
``b(s)`` likewise, with the gamma trick ``s(t) = gamma t / (1 + (gamma - 1) t)``, ``t`` real
in [0, 1] (``gamma = 1``: the straight segment).
"""

from __future__ import annotations

import numpy as np


class ParameterHomotopy:
    """H(z, t) = G(z, p(s(t))) + b(s(t)) for a batch of paths, each with its own segment.

    Args:
        system: the polynomial system.
        p_from: (D, n_params) complex parameters at t = 0 (one row per path datum).
        p_to: (D, n_params) complex parameters at t = 1.
        b_from: (D, n) complex offsets at t = 0 (zero on structural rows).
        b_to: (D, n) complex offsets at t = 1.
        gamma: (D,) complex gamma of each path (1 for a straight segment).
    """

    def __init__(self, system, p_from, p_to, b_from, b_to, gamma) -> None:
        self.system = system
        self.p_from = np.asarray(p_from, dtype=complex)
        self.dp = np.asarray(p_to, dtype=complex) - self.p_from
        self.b_from = np.asarray(b_from, dtype=complex)
        self.db = np.asarray(b_to, dtype=complex) - self.b_from
        self.gamma = np.asarray(gamma, dtype=complex)

    def __call__(self, z: np.ndarray, t: np.ndarray, idx: np.ndarray):
        """z (M, n), t (M,) complex, idx (M,) -> H (M, n), H_z (M, n, n), H_t (M, n).

        Paths going to infinity overflow to non-finite values, which the tracker tells and
        ends (status "at_infinity" or "failed"): no warning is raised for them."""
        g = self.gamma[idx]
        den = 1.0 + (g - 1.0) * t
        s = (g * t / den)[:, None]
        ds = (g / den**2)[:, None]
        dp, db = self.dp[idx], self.db[idx]
        with np.errstate(over="ignore", invalid="ignore"):
            G, Gz, Gp = self.system.evaluate(z, self.p_from[idx] + s * dp)
            H = G + self.b_from[idx] + s * db
            Ht = (np.einsum("mij,mj->mi", Gp, dp) + db) * ds
        return H, Gz, Ht
