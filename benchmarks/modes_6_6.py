"""Assembly modes of 6-6 Stewart-Gough platforms: count and time against random-start LM.

For each platform (Dietmaier's 40-mode platform and two random 6-6 platforms) prints, with
the compiled kernels warm (the C library built once and cached):

* SC: ``assembly_modes`` -- solutions found and median wall time over ``--repeat`` seeds,
  with the curves followed and the predictor-corrector steps taken (the states computed);
* LM: random-start Levenberg-Marquardt on the leg equations (vectorised numpy: every start
  iterated at once; the tests' reference in tests/stewart.py), at doubling numbers of
  starts; the smallest number of starts that found all the SC solutions in every repeat,
  its median time and the ratio LM time / SC time.

    python benchmarks/modes_6_6.py [--repeat 7]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.solvers.modes import explore

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from stewart import (  # noqa: E402  (references shared with the tests)
    DIETMAIER_BASE,
    DIETMAIER_LENGTHS,
    DIETMAIER_PLATFORM,
    random_platform,
    stewart_reference,
)

DIETMAIER = (DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS)


def lm_baseline(A, B, lengths, starts: int, seed: int) -> list[np.ndarray]:
    """Random-start Levenberg-Marquardt (the tests' reference): distinct poses as 4x4."""
    poses = []
    for p, R in stewart_reference(A, B, lengths, starts, seed):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, p
        poses.append(T)
    return poses


def covered(found: list[np.ndarray], poses: list[np.ndarray]) -> bool:
    return all(any(np.abs(T - S).max() < 1e-6 for S in found) for T in poses)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="seeds per measurement")
    args = parser.parse_args()
    platforms = {
        "Dietmaier 1998": DIETMAIER,
        "random 6-6 #4": random_platform(4),
        "random 6-6 #18": random_platform(18),
    }
    print(f"{'platform':<16} {'method':<6} {'found':>5} {'median [s]':>10}  details")
    for name, (A, B, lengths) in platforms.items():
        model = sc.builders.stewart_gough(A, B)
        explore(model, lengths, backend="compiled")  # build and load the C library (cached)
        runs = [explore(model, lengths, seed=s, backend="compiled") for s in range(args.repeat)]
        sc_time = float(np.median([r.elapsed for r in runs]))
        counts = sorted({len(r.solutions) for r in runs})
        poses = [c.platform_pose for c in runs[0].solutions]
        print(
            f"{name:<16} {'SC':<6} {'/'.join(map(str, counts)):>5} {sc_time:>10.3f}  "
            f"curves {int(np.median([r.curves for r in runs]))}, "
            f"steps (states) {int(np.median([r.steps for r in runs]))} (median)"
        )
        starts = 250
        while True:
            times, complete, found = [], True, []
            for s in range(args.repeat):
                t = time.perf_counter()
                sols = lm_baseline(A, B, lengths, starts, seed=s)
                times.append(time.perf_counter() - t)
                complete &= covered(sols, poses)
                found.append(len(sols))
            lm_time = float(np.median(times))
            print(
                f"{'':<16} {'LM':<6} {int(np.median(found)):>5} {lm_time:>10.3f}  "
                f"{starts} starts, all {len(poses)} found in every repeat: {complete}"
            )
            if complete or starts >= 32000:
                break
            starts *= 2
        print(f"{'':<16} ratio LM / SC time (to find all): {lm_time / sc_time:.2f}")


if __name__ == "__main__":
    main()
