"""Cold first compiled use of models/stewart_gough: the C tracker built from an empty cache.

Runs ``sc.track(model, thetas, backend="c")`` on a few readings in a fresh process whose
``$SCDK_CACHE_DIR`` is an empty folder (so the kernels are generated and compiled), and prints
the time of that first call (the model load is timed apart) with the CPU time it took (the
process and its compilers: less sensitive to the load of the machine than the wall time), the
stderr line it printed; then where the time goes: each source of the library (size, CPU time
of its compiler at the library's flags, one at a time); and, as the baseline measured in the
same run, the same kernels in one source compiled by one compiler process at -O2.

    python benchmarks/compile_hexapod.py
"""

from __future__ import annotations

import importlib
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


def compiler_cpu(args: list, cwd: Path) -> float:
    """CPU time [s] of one compiler run (user + system of the child processes)."""
    before = os.times()
    run_compiler(args, cwd=cwd)
    after = os.times()
    return (after.children_user - before.children_user) + (
        after.children_system - before.children_system
    )


def main() -> None:
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
