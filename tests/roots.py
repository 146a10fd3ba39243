"""Roots of a polynomial system (the algebraic-form protocol) by random-start complex Newton.

Shared by tests/test_algebraic_form.py and benchmarks/algebraic_newton_count.py. No homotopy:
a lower bound on the number of isolated roots, used to check generic root counts.
"""

from __future__ import annotations

import numpy as np


def newton_roots(form, p, starts: int, iterations: int, rng, b=None) -> np.ndarray:
    """Distinct roots (R, n) of G(., p) + b reached by step-limited Newton from random starts.

    Every start takes ``iterations`` Newton steps, each limited to 0.3 (1 + max |z|) in max
    norm; a limit with max |G| below 1e-10 is a root; roots closer than 1e-6 (1 + max |z|)
    are one.
    """
    z = np.array([form.random_point(rng)[0] for _ in range(starts)])
    b = np.zeros(form.n) if b is None else np.asarray(b)
    with np.errstate(all="ignore"):
        for _ in range(iterations):
            ok = np.all(np.isfinite(z), axis=1)
            G, Jz, _ = form.evaluate(z[ok], p)
            G = G + b
            step = np.full((ok.sum(), form.n), np.nan, complex)
            regular = np.linalg.cond(Jz) < 1e14
            step[regular] = np.linalg.solve(Jz[regular], G[regular][..., None])[..., 0]
            size = np.abs(step).max(axis=1)
            limit = 0.3 * (1 + np.abs(z[ok]).max(axis=1))
            z[ok] -= np.minimum(1.0, limit / size)[:, None] * step
        ok = np.all(np.isfinite(z), axis=1)
        G = form.evaluate(z[ok], p)[0] + b
    roots: list[np.ndarray] = []
    for zi in z[ok][np.abs(G).max(axis=1) < 1e-10]:
        if not any(np.abs(zi - r).max() < 1e-6 * (1 + np.abs(r).max()) for r in roots):
            roots.append(zi)
    return np.array(roots).reshape(-1, form.n)
