"""Time to certify one solution (Krawczyk test) against one float Newton step.

For models/stewart_gough (a pose from inverse kinematics) and models/planar_hexa (the
paper's example, convergent branch), prints the median time of:

- ``krawczyk`` on the closure system at the solution (replay translated once, then cached;
  the first call, which translates, is printed apart), with ``arithmetic="auto"`` (binary64
  intervals in C for rows of ``+ - * /``, sin and cos: both models') and ``"arb"`` (Arb balls
  only);
- its parts: the interval replay of ``g`` at the point and of ``J`` over the box;
- the baseline in the same run: one float evaluation of ``g`` and ``J`` (CasADi, through
  preallocated buffers) and one LU solve ``J \\ g`` (numpy),

and the ratio certificate / baseline: CPU time per call (median over repeats of batches),
and in brackets the median wall time of single calls.

    python benchmarks/certify.py [--repeat 15] [--number 20]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import casadi as ca
import numpy as np

import scdk_sym as sc
from scdk_sym.algebraic.certify import closure_function, krawczyk
from scdk_sym.algebraic.certify import square as certify_module
from scdk_sym.algebraic.interval import balls, interval_function
from scdk_sym.kernels.fastcall import Buffered

ROOT = Path(__file__).resolve().parents[1]


def median_time(call, repeat: int, number: int) -> float:
    """Median over ``repeat`` runs of the mean CPU time of ``number`` calls [s].

    Process CPU time, not wall time: on a shared machine a batch of calls is descheduled now
    and then, which inflates wall-clock means several-fold (single calls mostly fit in one
    time slice, so :func:`median_wall` stays close to this).
    """
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        for _ in range(number):
            call()
        times.append((time.process_time() - t0) / number)
    return statistics.median(times)


def median_wall(call, calls: int) -> float:
    """Median wall-clock time of single calls [s]."""
    times = []
    for _ in range(calls):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def solution(name: str) -> tuple[sc.Model, np.ndarray, np.ndarray]:
    """A model, a solution y (local chart) and its parameters q = [theta; c]."""
    model = sc.load_model(ROOT / "models" / name)
    if name == "planar_hexa":
        theta = np.array([1.292, -0.802, -2.896])
        start = model.inverse_kinematics([0.0, 0.0, 0.4])
        y = sc.solve(model, theta, start=start, branch="convergent").y
    else:
        rng = np.random.default_rng(1)
        pose = model.home.x + np.r_[rng.uniform(-0.03, 0.03, 3), rng.uniform(-0.1, 0.1, 3)]
        cfg = model.inverse_kinematics(pose)
        y, theta = cfg.y, cfg.theta
    y, c = model.chart.to_local(y)
    return model, y, np.concatenate([theta, c])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--number", type=int, default=20)
    a = ap.parse_args()
    print(f"median over {a.repeat} repeats of {a.number} calls")
    for name in ("stewart_gough", "planar_hexa"):
        model, y, q = solution(name)
        f = closure_function(model)
        t0 = time.perf_counter()
        cert = krawczyk(f, y, q)
        first = time.perf_counter() - t0
        assert cert.proven, cert.reason
        t_cert = median_time(lambda f=f, y=y, q=q: krawczyk(f, y, q), a.repeat, a.number)
        w_cert = median_wall(lambda f=f, y=y, q=q: krawczyk(f, y, q), a.repeat * a.number)
        t_arb = median_time(
            lambda f=f, y=y, q=q: krawczyk(f, y, q, arithmetic="arb"), a.repeat, a.number
        )
        fast = certify_module._SQUARES(f).fast is not None

        s = model.symbolic
        qs = ca.vertcat(s.theta, s.c)
        J = ca.densify(ca.jacobian(s.g, s.y))
        newton = Buffered(ca.Function("newton", [s.y, qs], [s.g, J]))
        m = model.m

        def float_step(newton=newton, y=y, q=q, m=m):
            g, Jv = newton(y, q)
            return np.linalg.solve(Jv.reshape(m, m, order="F"), g)

        t_float = median_time(float_step, a.repeat, a.number)
        w_float = median_wall(float_step, a.repeat * a.number)

        g_replay = interval_function(ca.Function("g", [s.y, qs], [s.g]))
        J_replay = interval_function(ca.Function("J", [s.y, qs], [J.T]))
        M, Y, Q = balls(y), balls(y, 1e-12), balls(q)
        t_g = median_time(lambda r=g_replay, M=M, Q=Q: r(M, Q), a.repeat, a.number)
        t_J = median_time(lambda r=J_replay, Y=Y, Q=Q: r(Y, Q), a.repeat, a.number)

        print(
            f"{name}: m = {m}, {g_replay.function.n_instructions()} + "
            f"{J_replay.function.n_instructions()} instructions (g, J); box radius "
            f"{cert.radius:.1e}\n"
            f"  (CPU time per call; in brackets the median wall time of single calls)\n"
            f"  certificate      {t_cert * 1e3:8.3f} ms  [{w_cert * 1e3:.3f}]  (first call, "
            f"translating: {first * 1e3:.1f} ms wall; "
            f"{'binary64 intervals in C' if fast else 'Arb: not rational'})\n"
            f"  certificate, Arb {t_arb * 1e3:8.3f} ms\n"
            f"    replay g(m)    {t_g * 1e3:8.3f} ms\n"
            f"    replay J(X)    {t_J * 1e3:8.3f} ms\n"
            f"  float g, J + LU  {t_float * 1e3:8.4f} ms  [{w_float * 1e3:.4f}]\n"
            f"  ratio            {t_cert / t_float:8.0f} x  [{w_cert / w_float:.0f}]; Arb "
            f"{t_arb / t_float:.0f} x"
        )


if __name__ == "__main__":
    main()
