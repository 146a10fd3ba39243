"""Steps and time of the homotopy tracker with its third Newton iteration, against the rule
without it (two iterations, the tighter predictor target), on seeded 6-6 platforms.

Both rules track the same parameter homotopy (the model's start system to each platform's
legs, C tracker, BLAS pinned to one thread) in the same run; printed per platform: the step
attempts of all 40 paths, the median time of the whole homotopy solve, both rules' real
root counts (they must agree), and the medians of the ratios (third / baseline).

    OMP_NUM_THREADS=1 python benchmarks/homotopy_steps.py [--platforms 10] [--repeat 5]

Each random platform's start system is made by monodromy once (a few seconds) and then read
from the disk cache.
"""

from __future__ import annotations

import argparse
import time

from common import pin_blas_threads, test_references

pin_blas_threads()  # before numpy is imported

import numpy as np  # noqa: E402

import scdk_sym as sc  # noqa: E402
from scdk_sym.algebraic import algebraic_form, solve_homotopy  # noqa: E402
from scdk_sym.algebraic.paths.continuation import TrackerOptions  # noqa: E402
from scdk_sym.algebraic.scaled import scaled_form  # noqa: E402
from scdk_sym.solvers.start_system import model_start_system  # noqa: E402

stewart = test_references("stewart")  # the references shared with the tests

#: The rule before the third iteration: two Newton iterations, eta 1e-5, trust 1e-3.
BASELINE = TrackerOptions(third=False, eta=1e-5, trust=1e-3)


def platforms(count: int):
    """Dietmaier's platform, then ``count - 1`` seeded random ones: (name, A, B, legs)."""
    s = stewart
    yield "Dietmaier", s.DIETMAIER_BASE, s.DIETMAIER_PLATFORM, s.DIETMAIER_LENGTHS
    for seed in range(1, count):
        A, B, legs = stewart.random_platform(seed)
        yield f"random #{seed}", A, B, legs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--platforms", type=int, default=10)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    step_ratio, time_ratio = [], []
    for name, A, B, legs in platforms(args.platforms):
        form = scaled_form(algebraic_form(sc.builders.stewart_gough(A, B), "compiled"))
        start = model_start_system(form, 0)
        p0 = form.params(legs)
        row = {}
        for label, options in (("baseline", BASELINE), ("third", TrackerOptions())):
            times = []
            for _ in range(args.repeat):
                t = time.perf_counter()
                res = solve_homotopy(form, start, p0, seed=0, real_tol=1e-6, options=options,
                                     tracker="c")  # fmt: skip
                times.append(time.perf_counter() - t)
            row[label] = (int(res.steps.sum()), float(np.median(times)), len(res.real_solutions))
        (s0, t0, r0), (s1, t1, r1) = row["baseline"], row["third"]
        step_ratio.append(s1 / s0)
        time_ratio.append(t1 / t0)
        print(f"{name:<12} steps {s0:5d} -> {s1:5d} ({s1 / s0:.2f}x), solve {1e3 * t0:6.2f} -> "
              f"{1e3 * t1:6.2f} ms ({t1 / t0:.2f}x), real roots {r0} and {r1}"
              f"{'' if r0 == r1 else '  DIFFERENT'}")  # fmt: skip
    print(f"{len(step_ratio)} platforms, medians of third / baseline: steps "
          f"{np.median(step_ratio):.2f}x, solve time {np.median(time_ratio):.2f}x")  # fmt: skip


if __name__ == "__main__":
    main()
