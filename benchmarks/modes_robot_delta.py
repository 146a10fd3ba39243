"""Certified assembly modes of Gepetto's ``robot_delta``: start system, disk cache, queries.

Prints, in one run, in a fresh cache directory (``--cache DIR`` to keep one):

* the start system (monodromy + trace test): wall time, loops, root count, trace residual;
* the same start system for a new model object (as in another process): read from disk;
* ``assembly_modes`` at each motor value of ``--thetas`` (start system in memory): median
  wall time per query over ``--repeat`` runs, real count, ``certified``, root count.

    python benchmarks/modes_robot_delta.py [--repeat 5] [--thetas 0,0:0.3,0.4:-0.4,0.4]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

FIXTURE = Path(__file__).resolve().parents[1] / "tests" / "fixtures" / "gepetto" / "robot_delta"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs per median")
    parser.add_argument("--thetas", default="0,0:0.3,0.4:-0.4,0.4", help="motor values [rad]")
    parser.add_argument("--cache", default=None, help="cache directory (default: a fresh one)")
    args = parser.parse_args()
    os.environ["SCDK_CACHE_DIR"] = args.cache or tempfile.mkdtemp(prefix="scdk-delta-")

    import scdk_sym as sc
    from scdk_sym.algebraic import algebraic_form
    from scdk_sym.algebraic.scaled import scaled_form
    from scdk_sym.solvers.start_system import model_start_system

    def start_of(model):
        form = scaled_form(algebraic_form(model, "compiled"))
        t = time.perf_counter()
        start = model_start_system(form, 0)
        return start, time.perf_counter() - t

    model = sc.load_model(FIXTURE, frame="effector")
    start, t_start = start_of(model)
    print(
        f"start system: {start.root_count} roots, {start.loops} loops, trace residual "
        f"{start.trace_residual:.1e}, passed {start.trace_passed}, {t_start:.1f} s"
    )
    again, t_again = start_of(sc.load_model(FIXTURE, frame="effector"))
    same = np.array_equal(again.solutions, start.solutions)
    print(f"new model object: start system read from disk in {t_again:.2f} s (same {same})")
    for text in args.thetas.split(":"):
        theta = [float(v) for v in text.split(",")]
        times = []
        for _ in range(args.repeat):
            t = time.perf_counter()
            sols = sc.assembly_modes(model, theta)
            times.append(time.perf_counter() - t)
        print(
            f"theta {theta}: {len(sols)} real of {sols.root_count}, certified {sols.certified}: "
            f"{1e3 * float(np.median(times)):.0f} ms per query (median of {args.repeat})"
        )


if __name__ == "__main__":
    main()
