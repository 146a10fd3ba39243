"""Cost of one batched evaluation of the algebraic form, per backend and batch size.

For ``--model`` (default models/stewart_gough) prints the median wall time of
``form.evaluate(Z, P)`` (G, dG/dz, dG/dp at N random complex points) for N = 1, 40 and 1000
with the ``cvodes`` (SX virtual machine) and ``compiled`` (generated C, built once and cached)
backends, and the ratio compiled / cvodes measured in the same run.

    python benchmarks/algebraic_evaluate.py [--model DIR] [--repeat 7]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.algebraic import algebraic_form

ROOT = Path(__file__).resolve().parents[1]


def median_time(f, Z, P, repeat: int) -> float:
    f.evaluate(Z, P)  # the mapped Function of this batch size is built once
    inner = max(1, 2000 // len(Z))
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(inner):
            f.evaluate(Z, P)
        times.append((time.perf_counter() - t) / inner)
    return float(np.median(times))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=str(ROOT / "models" / "stewart_gough"))
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args(argv)
    model = sc.load_model(args.model)
    forms = {b: algebraic_form(model, backend=b) for b in ("cvodes", "compiled")}
    rng = np.random.default_rng(0)
    points = [forms["cvodes"].random_point(rng) for _ in range(1000)]
    Z = np.array([z for z, _ in points])
    P = np.array([p for _, p in points])
    print(f"{model.name}: n = {forms['cvodes'].n}, n_params = {forms['cvodes'].n_params}")
    for N in (1, 40, 1000):
        t = {b: median_time(f, Z[:N], P[:N], args.repeat) for b, f in forms.items()}
        print(
            f"  N = {N:4d}: cvodes {t['cvodes'] * 1e6:9.1f} us ({t['cvodes'] / N * 1e6:6.1f} us "
            f"per point), compiled {t['compiled'] * 1e6:9.1f} us ({t['compiled'] / N * 1e6:6.1f} "
            f"us per point), compiled / cvodes {t['compiled'] / t['cvodes']:.2f}"
        )


if __name__ == "__main__":
    main()
