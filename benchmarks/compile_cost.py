"""Cold compile cost of the compiled backends on every shipped and Gepetto model.

For each model of ``tests/fixtures/gepetto`` (every folder holding a model) and ``models/``,
each part runs in a fresh process with an empty cache (``$SCDK_CACHE_DIR`` a new temporary
folder, so that the kernels are generated and compiled):

- ``solve``: the first ``sc.solve(model, home.theta + 0.05, backend="compiled")`` (the reading
  of the tests), with every C source its compilers built: generated lines, the compiler's wall
  and CPU seconds and its optimisation flags;
- ``track``: the first ``sc.track(model, thetas, backend="c")`` on the tests' motion (400
  samples, one sine period of ``--amplitude`` rad, 0.1 by default, spread over the motors),
  with its sources likewise;
- ``cvodes``: the baseline measured in the same run, the first
  ``sc.solve(model, home.theta + 0.05)`` (CasADi's virtual machine: nothing compiled), and the
  ratio of each first compiled call to it.

Each first call is timed apart from the model's loading, with the CPU time of the process and
its compilers (less sensitive to the load of the machine than the wall time). A model that
does not load, or a call that raises, is reported with its error (the time to the error is
still the cost paid).

    python benchmarks/compile_cost.py [--models wl16_like,digit_like_2legs]
                                      [--parts solve,track,cvodes] [--amplitude 0.1]
                                      [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = (ROOT / "tests" / "fixtures" / "gepetto", ROOT / "models")
PARTS = ("solve", "track", "cvodes")

CHILD = r"""
import json, os, resource, shlex, subprocess, sys, time, warnings
warnings.simplefilter("ignore")
import numpy as np
import scdk_sym as sc
from scdk_sym.errors import BuildError
from scdk_sym.kernels import compile as comp

sources = []


def timed_compiler(args, cwd=None):
    # the package's compiler run, with the compiler's own wall and CPU time (os.wait4)
    cmd = [*comp.compiler_command(), *map(str, args)]
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    err = proc.stderr.read().decode(errors="replace")
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise BuildError(f"C compilation failed ({shlex.join(cmd)}): {err.strip()[:200]}")
    src = [a for a in map(str, args) if a.endswith(".c")]
    lines = sum(sum(1 for _ in open(a, errors="replace")) for a in src)
    sources.append(dict(
        source=os.path.basename(src[0]) if src else "link",
        lines=lines, wall=wall, cpu=usage.ru_utime + usage.ru_stime,
        flags=" ".join(a for a in map(str, args) if a.startswith("-O")),
    ))


comp.run_compiler = timed_compiler


def cpu():
    own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


path, part, amplitude = sys.argv[1], sys.argv[2], float(sys.argv[3])
out = dict(part=part)
t = time.perf_counter()
try:
    model = sc.load_model(path)
except Exception as exc:
    print(json.dumps(dict(out, error=f"load: {type(exc).__name__}: {str(exc)[:120]}")))
    sys.exit(0)
out.update(load=time.perf_counter() - t, m=model.m, k=model.k,
           blocks=[b.m for b in model.blocks], stages=[b.m for b in model.stages])
theta = model.home.theta + 0.05
c0, t = cpu(), time.perf_counter()
try:
    if part == "track":
        s = np.linspace(0.0, 1.0, 400)
        thetas = model.home.theta + amplitude * np.sin(2 * np.pi * s)[:, None] * np.linspace(
            1, -1, model.k)
        result = sc.track(model, thetas, backend="c")
        out["answer"] = np.asarray(result.y[-1]).tolist()
    else:
        backend = "compiled" if part == "solve" else "cvodes"
        result = sc.solve(model, theta, backend=backend)
        out["answer"] = np.asarray(result.y).tolist()
except Exception as exc:
    out["error"] = f"{type(exc).__name__}: {str(exc)[:120]}"
out.update(first=time.perf_counter() - t, cpu=cpu() - c0, sources=sources)
print(json.dumps(out))
"""


def model_folders(names: set[str] | None) -> list[Path]:
    """The model folders (a ``robot.yaml`` or an MJCF file in it), those of ``names`` only
    when given."""
    found = []
    for folder in FOLDERS:
        for d in sorted(p for p in folder.iterdir() if p.is_dir()):
            has_model = (d / "robot.yaml").exists() or any(d.glob("*.xml"))
            if has_model and (names is None or d.name in names):
                found.append(d)
    return found


def cold(path: Path, part: str, amplitude: float) -> dict:
    """One part on one model in a fresh process with an empty cache (``amplitude``: of the
    tracked motion, rad)."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, SCDK_CACHE_DIR=cache, OMP_NUM_THREADS="1")
        proc = subprocess.run(
            [sys.executable, "-c", CHILD, str(path), part, repr(amplitude)],
            capture_output=True, text=True, env=env,
        )  # fmt: skip
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or not lines:
        tail = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return dict(part=part, error=f"process failed: {tail[:120]}")
    return json.loads(lines[-1])


def report(name: str, runs: dict[str, dict]) -> None:
    """Print one model's figures."""
    first = next(iter(runs.values()))
    if "m" not in first:
        print(f"{name}: {first.get('error')}")
        return
    print(f"{name}: m={first['m']} k={first['k']} blocks={first['blocks']} "
          f"stages={first['stages']}")  # fmt: skip
    base = runs.get("cvodes", {}).get("first")
    for part, run in runs.items():
        ratio = f"  x{run['first'] / base:.2f} of cvodes" if base and part != "cvodes" else ""
        error = f"  ERROR {run['error']}" if "error" in run else ""
        print(f"  {part:7s} first call {run.get('first', float('nan')):7.2f} s  "
              f"(CPU {run.get('cpu', float('nan')):6.2f} s){ratio}{error}")  # fmt: skip
        for src in run.get("sources", []):
            if src["source"] == "link":
                continue
            print(f"      {src['source']:24s} {src['lines']:8d} lines  {src['wall']:6.2f} s wall  "
                  f"{src['cpu']:6.2f} s CPU  {src['flags']}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", help="comma-separated folder names (default: every model)")
    ap.add_argument("--parts", default=",".join(PARTS), help="of solve,track,cvodes")
    ap.add_argument("--amplitude", type=float, default=0.1, help="of the tracked motion [rad]")
    ap.add_argument("--json", type=Path, help="also write every figure to this file")
    args = ap.parse_args()
    names = set(args.models.split(",")) if args.models else None
    parts = [p for p in args.parts.split(",") if p]
    unknown = set(parts) - set(PARTS)
    if unknown:
        ap.error(f"unknown parts {sorted(unknown)}; choose from {PARTS}")
    everything = {}
    for path in model_folders(names):
        runs = {part: cold(path, part, args.amplitude) for part in parts}
        report(path.name, runs)
        everything[path.name] = runs
        sys.stdout.flush()
    if args.json:
        args.json.write_text(json.dumps(everything, indent=1))


if __name__ == "__main__":
    main()
