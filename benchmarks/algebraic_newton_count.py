"""Generic root count of the algebraic form of a 6-6 platform by random-start complex Newton.

A general 6-6 Stewart-Gough platform has 40 complex assembly modes at generic leg lengths
(Raghavan; Lazard). This check needs no homotopy: at a random complex parameter point
``p = random_point(rng)[1]`` of ``algebraic_form(model)``, damped complex Newton runs from
``--starts`` random points of the structural variety (all at once, one ``evaluate`` per
iteration); converged limits (|G| small, last step below 1e-10) are merged when they agree to
1e-6 (relative). It prints the number of distinct roots, which must not exceed 40, per seed,
and for Dietmaier's platform at its real leg lengths (40 real modes) how many distinct roots
are real.

    python benchmarks/algebraic_newton_count.py [--model models/stewart_gough] [--starts 4000]
        [--seeds 3] [--iterations 80] [--backend casadi|compiled]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.algebraic import algebraic_form

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from stewart import (  # noqa: E402  (references shared with the tests)
    DIETMAIER_BASE,
    DIETMAIER_LENGTHS,
    DIETMAIER_PLATFORM,
)


def newton_roots(form, p, starts: int, iterations: int, rng) -> np.ndarray:
    """Distinct roots (R, n) of G(., p) reached by damped Newton from random starts."""
    z = np.array([form.random_point(rng)[0] for _ in range(starts)])
    alive = np.ones(starts, dtype=bool)
    done = np.zeros(starts, dtype=bool)
    for _ in range(iterations):
        idx = np.flatnonzero(alive & ~done)
        if idx.size == 0:
            break
        G, Jz, _ = form.evaluate(z[idx], p)
        try:
            step = np.linalg.solve(Jz, G[..., None])[..., 0]
        except np.linalg.LinAlgError:
            step = np.array(
                [np.linalg.lstsq(J, g, rcond=None)[0] for J, g in zip(Jz, G, strict=True)]
            )
        size = np.abs(step).max(axis=1)
        limit = 1.0 + np.abs(z[idx]).max(axis=1)
        damp = np.minimum(1.0, limit / np.maximum(size, 1e-300))
        z[idx] -= damp[:, None] * step
        bad = ~np.all(np.isfinite(z[idx]), axis=1) | (np.abs(z[idx]).max(axis=1) > 1e8)
        alive[idx[bad]] = False
        done[idx[~bad & (size < 1e-10 * limit)]] = True
    ok = np.flatnonzero(done & alive)
    if ok.size == 0:
        return np.zeros((0, form.n), complex)
    G, _, _ = form.evaluate(z[ok], p)
    ok = ok[np.abs(G).max(axis=1) < 1e-9 * (1 + np.abs(z[ok]).max(axis=1))]
    roots: list[np.ndarray] = []
    for zi in z[ok]:
        if not any(np.abs(zi - r).max() < 1e-6 * (1 + np.abs(r).max()) for r in roots):
            roots.append(zi)
    return np.array(roots)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--model", default=str(Path(__file__).resolve().parents[1] / "models" / "stewart_gough")
    )
    ap.add_argument("--starts", type=int, default=4000)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--iterations", type=int, default=80)
    ap.add_argument("--backend", default="casadi")
    args = ap.parse_args(argv)
    model = sc.load_model(args.model)
    form = algebraic_form(model, backend=args.backend)
    print(f"{model.name}: n = {form.n}, n_params = {form.n_params}, {args.starts} starts")
    for seed in range(args.seeds):
        rng = np.random.default_rng(seed)
        _, p = form.random_point(rng)
        t = time.perf_counter()
        roots = newton_roots(form, p, args.starts, args.iterations, rng)
        dt = time.perf_counter() - t
        print(f"  seed {seed}: random complex p -> {len(roots)} distinct roots ({dt:.1f} s)")
    dietmaier = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    form = algebraic_form(dietmaier, backend=args.backend)
    rng = np.random.default_rng(100)
    t = time.perf_counter()
    roots = newton_roots(form, form.params(DIETMAIER_LENGTHS), args.starts, args.iterations, rng)
    dt = time.perf_counter() - t
    real = int(np.sum(form.is_real(roots, 1e-8))) if len(roots) else 0
    worst = max(
        (
            dietmaier.residual(
                *form.to_model(r.real)[:1], DIETMAIER_LENGTHS, form.to_model(r.real)[1]
            )
            for r in roots[form.is_real(roots, 1e-8)]
        ),
        default=float("nan"),
    )
    print(
        f"Dietmaier (real legs): {len(roots)} distinct roots, {real} real "
        f"(worst model residual of the real ones {worst:.1e}) ({dt:.1f} s)"
    )


if __name__ == "__main__":
    main()
