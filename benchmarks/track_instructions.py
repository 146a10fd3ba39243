"""Instructions per sample of the generated C tracker and of the plain-C Newton (callgrind).

On the smooth 3000-sample path of ``benchmarks/track_hexapod.py`` (models/stewart_gough), a
small C driver runs the generated tracker (``scdk_tracker_track_res``, the whole path in one
call, as Python calls it) and the plain warm-started Newton (``benchmarks/newton_c/newton.c``)
over the same samples. The tracker's sources (those of the library Python loads) and newton.c
are compiled with the library's flags (:data:`scdk_sym.codegen.generate.COMPILE_FLAGS`) and
linked into one program, which ``valgrind --tool=callgrind`` runs once per tracker, counting
only inside that tracker's call (``--toggle-collect``): instruction counts do not depend on
the load of the machine. Prints the instructions of each call, per sample and their ratio, and
where the tracker's go (the functions with the most instructions of their own, with calls).

    python benchmarks/track_instructions.py [--samples 3000] [--top 12] [--keep DIR]
"""

from __future__ import annotations

import argparse
import importlib
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import scdk_sym as sc
from scdk_sym.kernels.compile import compiler, run_compiler

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))
from stewart import anchors, leg_lengths  # noqa: E402  (shared with the tests)
from track_hexapod import MODEL, NEWTON_C, smooth_path  # noqa: E402

generate = importlib.import_module("scdk_sym.codegen.generate")

DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include "scdk_tracker.h"

long newton_track(const double *A, const double *B, const double *x0, long n,
                  const double *thetas, double *out, double tol, int max_iter);

static double *take(FILE *f, long count) {
    double *a = malloc(sizeof(double) * (count > 0 ? count : 1));
    if (!a || fread(a, sizeof(double), count, f) != (size_t)count) exit(3);
    return a;
}

/* driver DATA tracker|newton: one call over every sample of DATA (n, then y0, c0, theta0, A,
 * B, x0 and the n readings, as doubles); prints the status and a checksum of the answers */
int main(int argc, char **argv) {
    FILE *f = argc == 3 ? fopen(argv[1], "rb") : NULL;
    double *nn, *y0, *c0, *theta0, *A, *B, *x0, *thetas, *ys, *cs, *xs, *dets, *res, sum = 0;
    long n, i, failed = -1;
    int *codes, status;
    if (!f) return 2;
    nn = take(f, 1);
    n = (long)nn[0];
    y0 = take(f, SCDK_NY);
    c0 = take(f, SCDK_NC);
    theta0 = take(f, SCDK_NTHETA);
    A = take(f, 18);
    B = take(f, 18);
    x0 = take(f, 6);
    thetas = take(f, n * SCDK_NTHETA);
    ys = malloc(sizeof(double) * n * SCDK_NY);
    cs = malloc(sizeof(double) * n * SCDK_NC_ALLOC);
    xs = malloc(sizeof(double) * n * SCDK_NX);
    dets = malloc(sizeof(double) * n);
    res = malloc(sizeof(double) * n);
    codes = malloc(sizeof(int) * n);
    if (argv[2][0] == 't') {
        status = scdk_tracker_track_res(y0, SCDK_NY, c0, SCDK_NC, theta0, SCDK_NTHETA, NULL, n,
                                        thetas, ys, cs, xs, dets, res, codes, &failed, NULL);
    } else {
        status = newton_track(A, B, x0, n, thetas, xs, 1e-12, 20) < 0 ? -1 : 0;
    }
    for (i = 0; i < n * SCDK_NX; ++i) sum += xs[i];
    printf("%s status %d failed %ld checksum %.17g\n", argv[2], status, failed, sum);
    return 0;
}
"""


def build(model, directory: Path, n: int) -> tuple[Path, Path]:
    """Write the data and compile the driver; returns (program, data file)."""
    A, B = anchors(MODEL)
    X = smooth_path(model.home.x, n)
    thetas = leg_lengths(X, A, B)
    y0, c0 = model.chart.to_local(model.home.y)
    data = directory / "path.bin"
    parts = [[float(n)], y0, c0, model.home.theta, A.ravel(), B.ravel(), model.home.x, thetas]
    np.concatenate([np.asarray(p, dtype=float).ravel() for p in parts]).tofile(data)
    src = generate.generate(model, directory, "scdk", split=True, inverse_kinematics=False)
    (directory / "driver.c").write_text(DRIVER)
    sources = [*src.sources, NEWTON_C, directory / "driver.c"]
    objects = []
    for source in sources:
        obj = directory / (Path(source).stem + ".o")
        run_compiler([*generate.COMPILE_FLAGS, "-c", str(source), "-o", str(obj)], cwd=directory)
        objects.append(obj)
    program = directory / "driver"
    subprocess.run([compiler(), *map(str, objects), "-o", str(program), "-lm"], check=True)
    return program, data


def callgrind(program: Path, data: Path, which: str, function: str, out: Path) -> str:
    """Run the driver under callgrind counting inside ``function`` only; returns its stdout."""
    run = subprocess.run(
        ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", "--collect-atstart=no",
         f"--toggle-collect={function}", str(program), str(data), which],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return run.stdout.strip()


def annotate(out: Path, inclusive: bool) -> str:
    run = subprocess.run(
        ["callgrind_annotate", f"--inclusive={'yes' if inclusive else 'no'}", str(out)],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return run.stdout


def total(report: str) -> int:
    """The program total of a callgrind_annotate report [instructions]."""
    m = re.search(r"^\s*([\d,]+)(?: \([^)]*\))?\s+\(?PROGRAM TOTALS", report, re.M)
    if not m:
        raise RuntimeError(f"no PROGRAM TOTALS in callgrind_annotate output:\n{report[:2000]}")
    return int(m.group(1).replace(",", ""))


def rows(report: str, top: int) -> list[tuple[int, str]]:
    """The first ``top`` function rows (instructions, name) of a callgrind_annotate report."""
    out = []
    for line in report.splitlines():
        m = re.match(r"^\s*([\d,]+)\s+(?:\([^)]*\)\s+)?\S*:(\S+)", line)
        if m and not m.group(2).startswith(("(", "0x", "__libc_start", "main")):
            out.append((int(m.group(1).replace(",", "")), m.group(2)))
    return out[:top]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=3000, help="poses on the smooth path")
    parser.add_argument("--top", type=int, default=12, help="functions listed per tracker")
    parser.add_argument("--keep", default="", help="write the sources and profiles here")
    args = parser.parse_args()
    if shutil.which("valgrind") is None:
        raise SystemExit("valgrind not found: install it (apt-get install valgrind)")

    model = sc.load_model(MODEL)
    tmp = None if args.keep else tempfile.TemporaryDirectory()
    directory = Path(args.keep or tmp.name)
    directory.mkdir(exist_ok=True)
    program, data = build(model, directory, args.samples)
    n = args.samples
    counts = {}
    for which, function in (("tracker", "scdk_tracker_track_res"), ("newton", "newton_track")):
        out = directory / f"callgrind.{which}"
        print(callgrind(program, data, which, function, out))
        counts[which] = total(annotate(out, inclusive=False))
    print(f"\nmodels/stewart_gough, smooth path of {n} samples, flags "
          f"{' '.join(generate.COMPILE_FLAGS)} (valgrind --tool=callgrind):")  # fmt: skip
    for which, count in counts.items():
        print(f"  {which:<8} {count / 1e6:8.2f} million instructions, {count / n:8.0f} per sample")
    print(f"  tracker / Newton: {counts['tracker'] / counts['newton']:.3f}x")
    out = directory / "callgrind.tracker"
    for inclusive in (False, True):
        kind = "with calls" if inclusive else "own"
        print(f"\nthe tracker's instructions per sample by function ({kind}):")
        for count, name in rows(annotate(out, inclusive), args.top):
            print(f"  {count / n:9.0f}  {name}")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
