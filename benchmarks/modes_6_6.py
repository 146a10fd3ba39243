"""Assembly modes of 6-6 Stewart-Gough platforms: certified homotopy, curve search, LM.

For Dietmaier's 40-mode platform and ``--platforms`` random general 6-6 platforms
(tests/stewart.py ``random_platform``, seeds 1, 2, ...) prints, in one run:

* the start system of each platform (monodromy + trace test): wall time, loops, root count
  (loaded from the disk cache on a second run: ``loops`` is then the stored count);
* ``assembly_modes`` (method "homotopy", start system in memory): median wall time per query
  over ``--repeat`` runs with the paths tracked in C (the default) and in numpy (the
  reference tracker), split into the parameter homotopy (all root-count paths), polishing in
  the model and the Krawczyk certificates, the real count, ``certified`` and whether the real
  set equals the LM reference (rotation and translation within 1e-6); CPU-time medians too
  (``time.process_time``: on a shared machine the wall time also counts the waits);
* the curve search (method "curves", compiled kernels) on the same legs: median time, count;
* the baseline: random-start Levenberg-Marquardt (tests/stewart.py, ``--lm-starts``
  starts), median time and count;
* with ``--fksgp DIR`` (a checkout of the published all-solution numpy solver fkSGP, MIT, not
  shipped here): its general 6-6 solver on the same legs in the same run, median time of
  ``--repeat`` calls, its real set against the certified one, and the ratio of the certified
  query's median to it per platform (the summary gives the worst platform's ratio).

BLAS is pinned to one thread (both sides), unless the environment says otherwise.

    python benchmarks/modes_6_6.py [--platforms 2] [--repeat 5] [--lm-starts 3000] [--fksgp DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
import time
import types
from pathlib import Path

from common import pin_blas_threads, test_references

pin_blas_threads()  # before numpy is imported

import numpy as np  # noqa: E402

import scdk_sym as sc  # noqa: E402
from scdk_sym.algebraic import algebraic_form, certify_configurations, solve_homotopy  # noqa: E402
from scdk_sym.algebraic import homotopy as homotopy_module  # noqa: E402
from scdk_sym.algebraic.scaled import scaled_form  # noqa: E402
from scdk_sym.solvers.start_system import model_start_system  # noqa: E402

stewart = test_references("stewart")  # the references shared with the tests


def same_set(found, reference, tol: float = 1e-6) -> bool:
    poses = [(c.platform_pose[:3, 3], c.platform_pose[:3, :3]) for c in found]
    return len(poses) == len(reference) and all(
        min(max(np.abs(p - q).max(), np.abs(R - S).max()) for q, S in poses) < tol
        for p, R in reference
    )


#: CPU-time medians [s] of the last median_time call of each label (the machine may be shared).
CPU: dict[str, float] = {}


def median_time(fn, repeat: int, label: str = ""):
    """Median wall time [s] of ``repeat`` calls and the last result; the median CPU time
    (``time.process_time``) is kept in ``CPU[label]``."""
    times, cpu, out = [], [], None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    CPU[label] = float(np.median(cpu))
    return float(np.median(times)), out


def load_fksgp(checkout: Path):
    """fkSGP's general 6-6 solver ``solver66(X, x, L2, realOnly)`` from a checkout (its
    ``python/`` package is imported without running its ``__init__``)."""
    folder = Path(checkout) / "python"
    if not (folder / "solver66.py").is_file():
        raise SystemExit(f"--fksgp {checkout}: no python/solver66.py there (a fkSGP checkout?)")
    package = types.ModuleType("fksgp_checkout")
    package.__path__ = [str(folder)]
    sys.modules["fksgp_checkout"] = package
    return importlib.import_module("fksgp_checkout.solver66").solver66


def fksgp_solve(solver66, A, B, legs):
    """fkSGP's postures (k, 3, 4) ``[R | t]`` for the platform with anchor 0 of base and
    platform as origins (its input convention); all k of them, complex."""
    Rt, _ = solver66(A - A[0], B - B[0], np.asarray(legs) ** 2, 0)
    return Rt


def fksgp_real_poses(Rt, A, B):
    """The real postures (imaginary parts below 1e-8) of :func:`fksgp_solve`, as (position,
    rotation) of the platform frame in the base frame."""
    poses = []
    for T in Rt:
        if np.abs(T.imag).max() <= 1e-8:
            R = T[:, :3].real
            poses.append((A[0] + T[:, 3].real - R @ B[0], R))
    return poses


@contextlib.contextmanager
def numpy_tracker():
    """Queries inside track their paths with the numpy tracker (the C one is skipped)."""
    saved = homotopy_module.c_tracker
    homotopy_module.c_tracker = lambda system, tracker="auto": None
    try:
        yield
    finally:
        homotopy_module.c_tracker = saved


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--platforms", type=int, default=2, help="random platforms")
    parser.add_argument("--repeat", type=int, default=5, help="runs per median")
    parser.add_argument("--lm-starts", type=int, default=3000, help="LM random starts")
    parser.add_argument("--fksgp", type=Path, help="a checkout of fkSGP: same-run baseline")
    args = parser.parse_args()
    solver66 = load_fksgp(args.fksgp) if args.fksgp else None
    np.random.seed(0)  # noqa: NPY002  (fkSGP draws its frame rotations from the global generator)
    platforms = {
        "Dietmaier 1998": (
            stewart.DIETMAIER_BASE,
            stewart.DIETMAIER_PLATFORM,
            stewart.DIETMAIER_LENGTHS,
        )
    }
    for seed in range(1, args.platforms + 1):
        platforms[f"random #{seed}"] = stewart.random_platform(seed)
    summary = []
    print("load average (1, 5, 15 min): {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))
    for name, (A, B, legs) in platforms.items():
        model = sc.builders.stewart_gough(A, B)
        form = scaled_form(algebraic_form(model, "compiled"))
        t = time.perf_counter()
        start = model_start_system(form, 0)
        t_start = time.perf_counter() - t
        print(
            f"{name}: start system {start.root_count} roots, {start.loops} loops, trace "
            f"residual {start.trace_residual:.1e}, {t_start:.1f} s"
        )
        p0 = form.params(legs)
        t_query, sols = median_time(
            lambda m=model, lg=legs: sc.assembly_modes(m, lg), args.repeat, "query"
        )
        with numpy_tracker():
            t_query_py, sols_py = median_time(
                lambda m=model, lg=legs: sc.assembly_modes(m, lg), args.repeat, "query_py"
            )
        t_track, res = median_time(
            lambda f=form, s=start, p=p0: solve_homotopy(f, s, p), 3, "track"
        )
        t_track_py, _ = median_time(
            lambda f=form, s=start, p=p0: solve_homotopy(f, s, p, tracker="python"), 3, "track_py"
        )
        ys = np.vstack([c.y for c in sols]) if len(sols) else np.zeros((0, model.m))
        t_cert, _ = median_time(lambda m=model, y=ys, lg=legs: certify_configurations(m, y, lg), 3)
        t_lm, ref = median_time(
            lambda a=A, b=B, lg=legs: stewart.stewart_reference(a, b, lg, args.lm_starts, 0), 3
        )
        t_curves, curves = median_time(
            lambda m=model, lg=legs: sc.assembly_modes(m, lg, method="curves", backend="compiled"),
            3,
        )
        match = same_set(list(sols), ref)
        match_py = same_set(list(sols_py), ref)
        steps = int(np.median(res.steps))
        print(
            f"  homotopy  {len(sols):>3} real of {sols.root_count}, certified {sols.certified}, "
            f"= LM set {match}: {1e3 * t_query:8.1f} ms per query, C tracker (median of "
            f"{args.repeat}); tracking {1e3 * t_track:.1f} ms ({len(res.status)} paths, median "
            f"{steps} steps), certificates {1e3 * t_cert:.1f} ms, rest (polish, configurations) "
            f"{1e3 * max(0.0, t_query - t_track - t_cert):.1f} ms; CPU time: query "
            f"{1e3 * CPU['query']:.1f} ms, tracking {1e3 * CPU['track']:.1f} ms"
        )
        print(
            f"  homotopy  {len(sols_py):>3} real, certified {sols_py.certified}, = LM set "
            f"{match_py}: {1e3 * t_query_py:8.1f} ms per query, numpy tracker; tracking "
            f"{1e3 * t_track_py:.1f} ms; C / numpy: query {t_query / t_query_py:.2f}, "
            f"tracking {t_track / t_track_py:.2f}; CPU time: query {1e3 * CPU['query_py']:.1f} ms, "
            f"tracking {1e3 * CPU['track_py']:.1f} ms"
        )
        print(f"  curves    {len(curves):>3} real: {1e3 * t_curves:8.1f} ms (median of 3)")
        print(
            f"  LM        {len(ref):>3} real: {1e3 * t_lm:8.1f} ms "
            f"({args.lm_starts} starts, median of 3)"
        )
        ratio = np.nan
        if solver66 is not None:
            t_fk, Rt = median_time(
                lambda a=A, b=B, lg=legs: fksgp_solve(solver66, a, b, lg), args.repeat
            )
            fk_real = fksgp_real_poses(Rt, A, B)  # converted outside the clock
            ratio = t_query / t_fk
            print(
                f"  fkSGP     {len(fk_real):>3} real of {len(Rt)}, = certified set "
                f"{same_set(list(sols), fk_real, 1e-5)}: {1e3 * t_fk:8.1f} ms (median of "
                f"{args.repeat}); certified query / fkSGP {ratio:.2f}"
            )
        summary.append(
            (sols.root_count == 40, sols.certified, match, t_query, t_query_py, t_lm, ratio)
        )
    n = len(summary)
    print(
        f"{n} platforms: root count 40 in {sum(s[0] for s in summary)}, certified in "
        f"{sum(s[1] for s in summary)}, real set = LM in {sum(s[2] for s in summary)}; "
        f"median query {1e3 * float(np.median([s[3] for s in summary])):.1f} ms (C tracker), "
        f"{1e3 * float(np.median([s[4] for s in summary])):.1f} ms (numpy tracker), LM "
        f"{1e3 * float(np.median([s[5] for s in summary])):.1f} ms"
    )
    if solver66 is not None:
        ratios = [s[6] for s in summary]
        print(
            f"certified query / fkSGP (same run, medians): worst platform {max(ratios):.2f}, "
            f"median {float(np.median(ratios)):.2f}"
        )
    print("load average (1, 5, 15 min): {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))


if __name__ == "__main__":
    main()
