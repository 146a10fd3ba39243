"""Cold first compiled use of models/stewart_gough: the C tracker built from an empty cache.

Runs ``sc.track(model, thetas, backend="c")`` on a few readings in a fresh process whose
``$SCDK_CACHE_DIR`` is an empty folder (so the kernels are generated and compiled), and prints
the time of that first call (the model load is timed apart) with the CPU time it took (the
process and its compilers: less sensitive to the load of the machine than the wall time), the
stderr line it printed; then where the time goes: each source of the library (size, CPU time
of its compiler at the library's flags, one at a time); and, as the baseline measured in the
same run, the same kernels in one source compiled by one compiler process at -O2.

Then the compiled backend the same way: in another fresh process with an empty cache, the
first ``sc.solve(model, theta0, backend="compiled")`` (convergent, by the warm kernel) and the
first divergent solve after it (which builds the curve follower's kernels), each with its CPU
time, what it printed on stderr and where its time went: the generation of each library's
sources, each compiler run (source, size, flags, wall time; the runs of one library overlap)
and the rest (loading, solving); then the second solve of each branch. ``--warm-first``: the
convergent solve without its path (``record_path=False``: the warm kernel alone, so that the
divergent solve after it is the first to build the curve follower's kernels).

    python benchmarks/compile_hexapod.py [--part c|compiled|all] [--warm-first]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import scdk_sym as sc
from scdk_sym.kernels.compile import run_compiler

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "stewart_gough"
generate = importlib.import_module("scdk_sym.codegen.generate")

COLD = f"""
import resource, time, numpy as np, scdk_sym as sc

def cpu():
    own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime

t = time.perf_counter(); model = sc.load_model({str(MODEL)!r}); load = time.perf_counter() - t
thetas = np.tile(model.home.theta, (5, 1)) + 1e-4 * np.arange(1, 6)[:, None]
c, t = cpu(), time.perf_counter()
sc.track(model, thetas, backend="c")
first, first_cpu = time.perf_counter() - t, cpu() - c
t = time.perf_counter(); sc.track(model, thetas, backend="c"); again = time.perf_counter() - t
print(load, first, first_cpu, again)
"""

SOLVES = f"""
import json, resource, sys, time
import numpy as np, scdk_sym as sc
from scdk_sym.kernels import compile as comp

events = []
run_compiler, write_c_parts = comp.run_compiler, comp.write_c_parts
compile_parallel = comp.compile_parallel


def timed_compiler(args, cwd=None):
    t = time.perf_counter()
    run_compiler(args, cwd=cwd)
    src = [a for a in map(str, args) if a.endswith(".c")]
    size = sum(__import__("os").path.getsize(a) for a in src)
    what = src[0].rsplit("/", 1)[-1] if src else "link"
    opt = [a for a in map(str, args) if a.startswith("-O")]
    events.append(("gcc " + what + " " + " ".join(opt), size, time.perf_counter() - t))


def timed_write(functions, name, directory):
    t = time.perf_counter()
    out = write_c_parts(functions, name, directory)
    size = sum(p.stat().st_size for p in out[0])
    what = "generate " + name + " (%d sources)" % len(out[0])
    events.append((what, size, time.perf_counter() - t))
    return out


def timed_library(sources, target, *args, **kwargs):
    t = time.perf_counter()
    out = compile_parallel(sources, target, *args, **kwargs)
    size = sum(__import__("os").path.getsize(a) for a in sources)
    events.append(("library (compile + link, wall)", size, time.perf_counter() - t))
    return out


comp.run_compiler, comp.write_c_parts = timed_compiler, timed_write
comp.compile_parallel = timed_library


def cpu():
    own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


model = sc.load_model({str(MODEL)!r})
theta0 = model.home.theta + 0.003 * np.arange(1, model.k + 1)
out = {{}}
for branch in ("convergent", "divergent"):
    events.clear()
    c, t = cpu(), time.perf_counter()
    kw = dict(record_path=False) if WARM_FIRST and branch == "convergent" else {{}}
    res = sc.solve(model, theta0, branch=branch, backend="compiled", **kw)
    first, first_cpu = time.perf_counter() - t, cpu() - c
    print(branch, file=sys.stderr, flush=True)
    t = time.perf_counter()
    sc.solve(model, theta0, branch=branch, backend="compiled", **kw)
    again = time.perf_counter() - t
    out[branch] = dict(first=first, cpu=first_cpu, again=again, events=list(events),
                       x=res.x.tolist(), crossings=len(res.crossings))
print(json.dumps(out))
"""


def compiled_backend(warm_first: bool = False) -> None:
    """The cold first compiled solves (convergent, then divergent) in a fresh process;
    ``warm_first``: the convergent one with ``record_path=False``."""
    print(f"compiled backend; load average {os.getloadavg()[0]:.2f} (2 cores)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, SCDK_CACHE_DIR=cache)
        code = f"WARM_FIRST = {warm_first!r}\n{SOLVES}"
        proc = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
    out = json.loads(proc.stdout)
    stderr = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    before = stderr[: stderr.index("convergent")]
    print(f"stderr of the first solve: {before}")
    for branch, r in out.items():
        path = ", record_path=False" if warm_first and branch == "convergent" else ""
        print(f"first sc.solve(branch={branch!r}, backend='compiled'{path}) {r['first']:.2f} s "
              f"(CPU {r['cpu']:.2f} s; {r['crossings']} crossings); second "
              f"{1e3 * r['again']:.1f} ms")  # fmt: skip
        spent = 0.0
        for what, size, wall in r["events"]:
            spent += wall if what.startswith(("generate", "library")) else 0.0
            print(f"  {what:<44}{size / 1e3:8.1f} kB {wall:6.2f} s")
        print(f"  {'the rest (build, load, solve)':<55}{r['first'] - spent:6.2f} s")
    print(f"load average {os.getloadavg()[0]:.2f}")


def compiler_cpu(args: list, cwd: Path) -> float:
    """CPU time [s] of one compiler run (user + system of the child processes)."""
    before = os.times()
    run_compiler(args, cwd=cwd)
    after = os.times()
    return (after.children_user - before.children_user) + (
        after.children_system - before.children_system
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("c", "compiled", "all"), default="all")
    parser.add_argument("--warm-first", action="store_true", help="convergent solve without path")
    args = parser.parse_args()
    if args.part in ("c", "all"):
        c_tracker()
    if args.part in ("compiled", "all"):
        compiled_backend(args.warm_first)


def c_tracker() -> None:
    """The cold first ``sc.track(backend="c")`` and its sources."""
    print(f"load average {os.getloadavg()[0]:.2f} (2 cores)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, SCDK_CACHE_DIR=cache)
        proc = subprocess.run(
            [sys.executable, "-c", COLD], env=env, capture_output=True, text=True, check=True
        )
    load, first, first_cpu, again = map(float, proc.stdout.split())
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    print(f"model load {load:.2f} s; first sc.track(backend='c') {first:.2f} s (generate + "
          f"compile; CPU {first_cpu:.2f} s); second {1e3 * again:.1f} ms")  # fmt: skip
    print(f"stderr: {lines}")
    model = sc.load_model(MODEL)
    with tempfile.TemporaryDirectory() as tmp:
        src = generate.generate(model, Path(tmp), "scdk", split=True, inverse_kinematics=False)
        print("the library's sources, each compiled alone at its flags:")
        for path in src.sources:
            flags = [*generate.COMPILE_FLAGS, *(["-O0"] if path in src.unoptimised else [])]
            cpu = compiler_cpu([*flags, "-c", path, "-o", path.with_suffix(".o")], Path(tmp))
            print(f"  {path.name:<22}{path.stat().st_size / 1e3:7.1f} kB  {cpu:5.2f} s CPU")
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        src = generate.generate(model, Path(tmp), "scdk", split=False, inverse_kinematics=False)
        args = ["-std=c99", "-O2", "-Wall", "-shared", "-fPIC", "-Wl,-Bsymbolic"]
        run_compiler([*args, *src.sources, "-o", Path(tmp) / "one.so", "-lm"], cwd=Path(tmp))
        one = time.perf_counter() - t
    print(f"baseline: generate + one source, one process at -O2: {one:.2f} s "
          f"(first use / baseline = {first / one:.2f})")  # fmt: skip
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
