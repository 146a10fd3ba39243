"""Gepetto's legged robots: first solve cold, and the tracker's cost per step against a plain C
Newton on the same blocks, in one run.

- **First solve, cold** (each in a fresh process with an empty cache: loading, assembly,
  symbolic build and the solve at home + 0.05 rad on every motor): a biped solved one leg at
  a time (``model.blocks``, the default) against the same solve on the whole 36 x 36 system.
- **Tracking**: on a 400-sample motion of one motor through a fold of the leg (the arc-length
  continuation of ``examples/biped_ankle_singularity.py``) and on a smooth 2000-sample
  motion of every motor (one sine period, 0.1 rad), microseconds per sample of
  ``sc.track(backend="c")`` (every block, the answer assembled and verified on the model)
  against a plain warm-started Newton in C (``benchmarks/newton_c/newton_blocks.c``) on the
  same blocks with their CasADi-generated closure kernels, compiled with ``-O3``; both timed
  in turn within each repeat, medians printed with their ratio. The blocks are those
  ``track`` runs (``model.stages``: a leg's knee four-bar, then its ankle mechanism, each leg
  in turn); ``track(c)`` with one block per leg (``model.blocks``) is timed beside, as it
  was before the block-triangular split. The Newton tracker has no
  branch control: it is the cost floor, not an equivalent (it returns to the wrong assembly
  after the fold).

    python benchmarks/gepetto_legs.py [--repeat 15] [--models digit_like digit_like_2legs]
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import casadi as ca
import numpy as np

import scdk_sym as sc
from scdk_sym.errors import ModelWarning

ROOT = Path(__file__).resolve().parents[1]
FIXTURES = ROOT / "tests" / "fixtures" / "gepetto"
NEWTON = Path(__file__).resolve().parent / "newton_c" / "newton_blocks.c"
sys.path.insert(0, str(ROOT / "examples"))
from biped_ankle_singularity import closure_curve  # noqa: E402  (the example's motion)

COLD = r"""
import json, sys, time, warnings
warnings.simplefilter("ignore")
t0 = time.perf_counter()
import scdk_sym as sc
m = sc.load_model(sys.argv[1])
if sys.argv[2] == "dense":
    m.blocks = (m,)
t1 = time.perf_counter()
r = sc.solve(m, m.home.theta + 0.05)
t2 = time.perf_counter()
print(json.dumps({"load": t1 - t0, "solve": t2 - t1, "residual": r.residual}))
"""


def cold_first_solve(name: str, how: str) -> dict:
    env = dict(os.environ, SCDK_CACHE_DIR=tempfile.mkdtemp(), OMP_NUM_THREADS="1")
    out = subprocess.run(
        [sys.executable, "-c", COLD, str(FIXTURES / name), how],
        capture_output=True, text=True, env=env, check=True,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


class NewtonBlocks:
    """The plain C Newton tracker of every block of a model (one shared library)."""

    def __init__(self, model: sc.Model, work: Path) -> None:
        self.blocks = model.stages
        gen = ca.CodeGenerator("closures.c", {"with_header": False})
        self.functions = []
        for i, b in enumerate(self.blocks):
            sym = b.symbolic
            f = ca.Function(f"blk{i}", [sym.y, sym.theta, sym.c], [sym.g, ca.densify(sym.J_p)])
            gen.add(f)
            self.functions.append(f)
        gen.generate(str(work) + "/")
        lib = work / "newton_blocks.so"
        subprocess.run(
            ["gcc", "-O3", "-march=native", "-shared", "-fPIC", "-o", str(lib),
             str(work / "closures.c"), str(NEWTON), "-lm"],
            check=True,
        )  # fmt: skip
        self.lib = ctypes.CDLL(str(lib))
        self.lib.newton_block.restype = ctypes.c_int
        self.m = model.m

    def track(self, thetas: np.ndarray) -> tuple[np.ndarray, int]:
        N = len(thetas)
        ys = np.zeros((N, self.m))
        total = 0
        for i, (b, f) in enumerate(zip(self.blocks, self.functions, strict=True)):
            block = b.block[1] if b.block is not None else None
            cols = list(block.actuated) if block else list(range(b.k))
            inputs = list(block.inputs) if block else []  # unknowns of the blocks before
            th = np.ascontiguousarray(np.hstack([thetas[:, cols], ys[:, inputs]]))
            y, c = b.chart.to_local(b.home.y)
            y = np.ascontiguousarray(y)
            c = np.ascontiguousarray(c if c.size else np.zeros(1))
            out = np.zeros((N, b.m))
            arg = (ctypes.c_void_p * f.sz_arg())()
            res = (ctypes.c_void_p * f.sz_res())()
            iw = np.zeros(max(f.sz_iw(), 1), dtype=np.int64)
            w = np.zeros(max(f.sz_w(), 1))
            g, J = np.zeros(b.m), np.zeros(b.m * b.m)
            fn = getattr(self.lib, f"blk{i}")
            d = ctypes.POINTER(ctypes.c_double)
            n = self.lib.newton_block(
                ctypes.cast(fn, ctypes.c_void_p), b.m, b.k, c.ctypes.data_as(d),
                th.ctypes.data_as(d), N, y.ctypes.data_as(d), out.ctypes.data_as(d), 30,
                ctypes.c_double(1e-12), arg, res, iw.ctypes.data_as(ctypes.c_void_p),
                w.ctypes.data_as(d), g.ctypes.data_as(d), J.ctypes.data_as(d),
            )  # fmt: skip
            if n < 0:
                raise RuntimeError(f"plain Newton failed on block {i}")
            total += n
            ys[:, list(block.unknowns) if block else slice(None)] = out
        return ys, total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--models", nargs="+", default=["digit_like", "digit_like_2legs"])
    parser.add_argument("--cold", default="digit_like_2legs", help="biped of the cold solves")
    args = parser.parse_args()

    if args.cold:
        for how in ("blocks", "dense"):
            r = cold_first_solve(args.cold, how)
            print(
                f"{args.cold} first solve cold ({how}): load {r['load']:.2f} s, solve "
                f"{r['solve']:.2f} s, residual {r['residual']:.1e}"
            )
    for name in args.models:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ModelWarning)
            model = sc.load_model(FIXTURES / name)
        fold_ys, fold = closure_curve(model, "motor_shin1", 400, step=0.02)
        s = np.linspace(0.0, 1.0, 2000)
        wave = np.sin(2 * np.pi * s)[:, None] * np.linspace(1.0, -1.0, model.k)
        paths = {"through the ankle fold (400)": (fold, fold_ys), "smooth (2000)": (
            model.home.theta + 0.1 * wave, None)}  # fmt: skip
        with tempfile.TemporaryDirectory() as tmp:
            newton = NewtonBlocks(model, Path(tmp))
            for label, (thetas, ys) in paths.items():
                t_sc, t_bl, t_nw = [], [], []
                stages = model.stages
                for subs in (model.blocks, stages):  # builds and compiles
                    model.stages = subs
                    sc.track(model, thetas, backend="c")
                for _ in range(args.repeat):
                    t = time.perf_counter()
                    r = sc.track(model, thetas, backend="c")
                    t_sc.append(time.perf_counter() - t)
                    model.stages = model.blocks  # the legs as one block each
                    t = time.perf_counter()
                    sc.track(model, thetas, backend="c")
                    t_bl.append(time.perf_counter() - t)
                    model.stages = stages
                    t = time.perf_counter()
                    _, iters = newton.track(thetas)
                    t_nw.append(time.perf_counter() - t)
                N = len(thetas)
                a, b = np.median(t_sc) / N * 1e6, np.median(t_nw) / N * 1e6
                whole = np.median(t_bl) / N * 1e6
                follows = (
                    "" if ys is None else f", follows the motion to {np.abs(r.y - ys).max():.1e}"
                )
                print(
                    f"{name} ({len(model.stages)} block(s) of {[m.m for m in model.stages]}), "
                    f"{label}: track(c) {a:.1f} us/sample, plain C Newton on the same blocks "
                    f"{b:.1f} us/sample ({iters / N:.1f} iterations/sample), ratio {a / b:.2f}; "
                    f"track(c) one block per leg {whole:.1f} us/sample ({whole / a:.2f}x); "
                    f"{len(r.crossings)} crossing(s){follows}"
                )


if __name__ == "__main__":
    main()
