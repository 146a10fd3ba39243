"""Root counts of the algebraic form of 6-6 platforms by random-start complex Newton.

A general 6-6 Stewart-Gough platform has 40 complex assembly modes at generic leg lengths
(Raghavan; Lazard). This check needs no homotopy: at a random complex parameter point
``p = random_point(rng)[1]`` of ``algebraic_form(model)``, step-limited complex Newton runs
from ``--starts`` random points of the structural variety (all at once, one ``evaluate`` per
iteration) and the distinct limits that solve ``G = 0`` are counted (at most 40 for any 6-6).
Printed for ``--model`` (default models/stewart_gough) and Dietmaier's general platform, per
seed, then for Dietmaier's platform at its real leg lengths (40 real modes): how many of the
roots are real, and the model's own closure residual at them.

    python benchmarks/algebraic_newton_count.py [--model DIR] [--starts 1000] [--seeds 2]
        [--iterations 150] [--backend compiled|cvodes]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.algebraic import algebraic_form

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from roots import newton_roots  # noqa: E402  (shared with the tests)
from stewart import (  # noqa: E402
    DIETMAIER_BASE,
    DIETMAIER_LENGTHS,
    DIETMAIER_PLATFORM,
)


def count(name: str, model, p, args, seed: int, real_theta=None) -> None:
    form = algebraic_form(model, backend=args.backend)
    t = time.perf_counter()
    roots = newton_roots(form, p(form), args.starts, args.iterations, np.random.default_rng(seed))
    dt = time.perf_counter() - t
    line = f"  {name}: {len(roots)} distinct roots"
    if real_theta is not None:
        real = roots[form.is_real(roots, 1e-8)] if len(roots) else roots
        worst = max(
            (model.residual(y, real_theta, c) for y, c in map(form.to_model, real)),
            default=float("nan"),
        )
        line += f", {len(real)} real (worst model residual {worst:.1e})"
    print(f"{line} ({dt:.1f} s)", flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=str(ROOT / "models" / "stewart_gough"))
    ap.add_argument("--starts", type=int, default=1000)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--iterations", type=int, default=150)
    ap.add_argument("--backend", default="compiled")
    args = ap.parse_args(argv)
    print(f"step-limited Newton, {args.starts} random starts, {args.iterations} steps each")
    model = sc.load_model(args.model)
    dietmaier = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    for seed in range(args.seeds):

        def p(form, seed=seed):
            return form.random_point(np.random.default_rng(seed))[1]

        count(f"{model.name}, random complex p (seed {seed})", model, p, args, 100 + seed)
        count(f"Dietmaier, random complex p (seed {seed})", dietmaier, p, args, 200 + seed)
    count(
        "Dietmaier, its real leg lengths",
        dietmaier,
        lambda form: form.params(DIETMAIER_LENGTHS),
        args,
        300,
        real_theta=DIETMAIER_LENGTHS,
    )


if __name__ == "__main__":
    main()
