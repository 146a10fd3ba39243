"""Fuzz of the direct-kinematics solver and tracker against independent references.

Every model (the shipped ones and the Gepetto fixtures) gets the same number of seeded
scenarios: a start (home, the package's inverse kinematics of a pose near home, or an
assembled configuration) and a target ``theta0`` with a known solution (closed-form inverse
kinematics of a drawn pose; Gepetto fixtures: a configuration walked on the closure manifold),
in four kinds: small steps in the start's assembly mode, large steps, targets just across a
singular surface and targets just before one. Each is solved on both branches and classified
by tests/references.py (closure from the geometry or Pinocchio, never the package's residual;
crossing parity against finite-difference det signs): ok, silently wrong, refused (ScdkError
although a solution exists), crash (any other exception), timeout. Then commanded motions
(smooth, and through a singular surface) are tracked with ``backend="cvodes"`` and ``"c"``
and each sample is compared with the commanded pose.

    python benchmarks/fuzz.py [--count 100000] [--seed 0] [--models NAME ...]
        [--backend cvodes|compiled] [--tracks 20] [--workers 1] [--limit 60] [--out DIR]

With ``--out DIR`` every finished work unit is saved there (a pickle per unit, named by its
model, seed, backend, limit and chunk); a run interrupted and started again with the same
arguments and ``--out`` solves only the missing units and reports on all of them.

``--count`` is the total number of solves (two per scenario, split evenly over the models).
Prints progress every ``--every`` solves, then a table per model and branch, the refusals
per scenario kind, the track figures and one reproducer per class of non-ok outcome.
"""

from __future__ import annotations

import argparse
import math
import pickle
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from references import (  # noqa: E402  (references shared with the tests)
    ALL_NAMES,
    NAMES,
    Report,
    draw_scenarios,
    draw_tracks,
    run_solves,
    run_tracks,
    warm_up,
)

#: Scenarios per work unit (one seeded draw + solve in one process).
CHUNK = 50


def solve_chunk(name: str, chunk: int, size: int, seed: int, backend: str, limit: float):
    scen = draw_scenarios(name, size, seed * 100003 + chunk)
    return run_solves(scen, backend=backend, limit=limit)


def track_chunk(name: str, count: int, seed: int, samples: int, limit: float):
    return run_tracks(draw_tracks(name, count, seed, samples), limit=limit)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=100_000, help="total solves")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--models",
        nargs="+",
        default=list(NAMES),
        choices=ALL_NAMES,
        help="models (default: the shipped ones and the Gepetto fixtures with an effector; "
        "the legged robots " + ", ".join(n for n in ALL_NAMES if n not in NAMES) + " on request)",
    )
    parser.add_argument("--backend", default="cvodes", choices=("cvodes", "compiled"))
    parser.add_argument("--tracks", type=int, default=20, help="commanded motions per model")
    parser.add_argument("--samples", type=int, default=100, help="samples per motion")
    parser.add_argument("--workers", type=int, default=1, help="processes")
    parser.add_argument("--limit", type=float, default=60.0, help="time limit per solve [s]")
    parser.add_argument("--every", type=int, default=2000, help="progress every N solves")
    parser.add_argument("--out", type=Path, help="directory keeping finished units (resume)")
    parser.add_argument(
        "--report",
        action="store_true",
        help="with --out: report on the units finished so far, solve nothing",
    )
    args = parser.parse_args(argv)

    per_model = max(1, math.ceil(args.count / (2 * len(args.models))))
    units = []  # interleaved over the models: a partial run covers every model evenly
    for chunk in range(math.ceil(per_model / CHUNK)):
        for name in args.models:
            size = min(CHUNK, per_model - chunk * CHUNK)
            units.append((name, chunk, size))
    total = 2 * per_model * len(args.models)
    print(
        f"{total} solves ({per_model} scenarios x 2 branches x {len(args.models)} models), "
        f"backend {args.backend}, seed {args.seed}, {args.workers} worker(s), "
        f"limit {args.limit:g} s per solve",
        flush=True,
    )
    # compiled kernels and start systems built once here (cached on disk), not in every
    # worker at once nor within a solve's time limit
    if args.report and args.out is None:
        parser.error("--report needs --out")
    if args.report:
        args.tracks = 0  # tracks are not kept on disk
    for name in [] if args.report else args.models:
        warm_up(name, args.backend, modes=True)
    report = Report()
    t0 = time.perf_counter()
    done, shown = 0, 0
    saved: dict[tuple, Path] = {}
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        for unit in units:
            name, chunk, size = unit
            saved[unit] = args.out / (
                f"{name}-s{args.seed}-{args.backend}-l{args.limit:g}-n{size}-c{chunk}.pkl"
            )
    with ProcessPoolExecutor(args.workers) as pool:
        futures = {}
        for unit in units:
            path = saved.get(unit)
            if path is not None and path.exists():
                outs = pickle.loads(path.read_bytes())
                report.solves += outs
                done += len(outs)
                continue
            if args.report:
                continue
            fut = pool.submit(solve_chunk, *unit, args.seed, args.backend, args.limit)
            futures[fut] = unit
        if done:
            print(f"  {done} solves loaded from {args.out}", flush=True)
        resumed, t0 = done, time.perf_counter()
        for fut in as_completed(futures):
            outs = fut.result()
            name, chunk, size = futures[fut]
            if len(outs) < 2 * size:  # scenarios the reference could not draw: said, not hidden
                print(
                    f"  note: {name} unit {chunk}: {len(outs) // 2} of {size} scenarios drawn",
                    file=sys.stderr,
                    flush=True,
                )
            path = saved.get(futures[fut])
            if path is not None:
                part = path.with_suffix(".part")
                part.write_bytes(pickle.dumps(outs))
                part.replace(path)
            report.solves += outs
            done += len(outs)
            if done - shown >= args.every or done == total:
                shown = done
                el = time.perf_counter() - t0
                bad = len(report.failures())
                left = el / max(1, done - resumed) * (total - done)
                print(
                    f"  {done}/{total} solves, {el:.0f} s elapsed, ~{left:.0f} s to go; "
                    f"silently wrong or crashed so far: {bad}",
                    flush=True,
                )
        solve_time = time.perf_counter() - t0
        if args.tracks:
            t1 = time.perf_counter()
            futures = [
                pool.submit(track_chunk, name, args.tracks, args.seed, args.samples, args.limit)
                for name in args.models
            ]
            for fut in as_completed(futures):
                report.tracks += fut.result()
            track_time = time.perf_counter() - t1
    off = report.confirm_refusals()
    print(f"\nsolves: {len(report.solves)} in {solve_time:.0f} s wall")
    print(
        f"{off} refusal(s) confirmed by the reference: the curve through the start closes "
        "without reaching s = 1 (column 'off'; no answer on the convergent branch, nor on the "
        "paper's divergent path along the same curve)\n"
    )
    print(report.table())
    print()
    print(report.kind_table())
    if args.tracks:
        skipped = [n for n in args.models if not any(o.track.name == n for o in report.tracks)]
        print(
            f"\ntracks: {len(report.tracks)} ({args.samples} samples each) in {track_time:.0f} s"
            f" wall{'; no motion drawn for ' + ', '.join(skipped) if skipped else ''}\n"
        )
        print(report.track_table())
    print()
    print(strategy_table(report.solves))
    classes = report.classes()
    if classes:
        print("\nnon-ok classes (count, status, model, branch, kind, message) and a reproducer:")
        for (status, name, branch, kind, text), (n, o) in classes.items():
            print(f"{n:>6} {status} {name} {branch} {kind}: {text}")
            print(f"       {o.scenario.reproducer(o.branch, args.backend)}")
            print(f"       ({o.scenario.known()})")
    bad_tracks = [o for o in report.tracks if o.status != "ok"]
    if bad_tracks:
        print("\ntracks not ok:")
        for o in bad_tracks:
            print(f"  {o.status} {o.track.name} {o.track.kind} {o.backend}: {o.detail[:200]}")
            print(f"       {o.track.reproducer(o.backend)}")
    return 0


def strategy_table(solves) -> str:
    """Divergent answers per model and per way of the divergent branch that answered
    (``?``: units saved before the way was recorded)."""
    from collections import Counter

    ways = Counter(
        (o.scenario.name, getattr(o, "strategy", "") or "?")
        for o in solves
        if o.branch == "divergent" and o.status == "ok"
    )
    names = sorted({n for n, _ in ways})
    cols = sorted({w for _, w in ways})
    lines = ["divergent answers by the way that answered",
             f"{'model':<20} " + " ".join(f"{c:>16}" for c in cols)]  # fmt: skip
    for n in names:
        lines.append(f"{n:<20} " + " ".join(f"{ways.get((n, c), 0):>16}" for c in cols))
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
