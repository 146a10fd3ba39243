"""The compiled sweep: the convergent branch of many ``theta0`` from one start in one C call.

Where ``det J_p`` keeps its sign along the straight path from the start, the SC solution
curve is the graph of ``y(s)`` over ``s`` in [0, 1] (``s' = b det J_p`` never vanishes: no
fold), so the first ``s = 1`` crossing of :func:`scdk_sym.solve`'s convergent branch is
``y(1)``, the end of the initial-value problem ``dy/ds = J_p^{-1} j_s``. The sweep integrates
it with :data:`STEPS` RK4 steps, each followed by Newton corrections, and returns what decides
whether the answer is that solution:

* ``det J_p`` at every RK stage and step end, divided by its value at the start (all must
  be positive: the path stayed on the start's side);
* the largest Newton correction of a step relative to that step's motion (small: each
  corrector landed on the curve it was predicted on, not on another sheet);
* the residual and ``J_p`` at the end (verification; well conditioned, or the point is left
  to :func:`scdk_sym.solve`, which names singular solutions).

A point the sweep cannot vouch for is solved by :func:`scdk_sym.solve` itself; both give the
same root to rounding (the test suite compares them to 1e-12).

The steps are the curve follower's: :func:`scdk_sym.kernels.curve.rk4_in_s` (whose stage
``J_p`` gives the ``det J_p`` checks) and :func:`scdk_sym.kernels.curve.newton_correction`.
The kernel is generated, compiled once per model into the disk cache (keyed by the model's
kernel hash and the sources it is built from) and loaded with ``casadi.external``; mapped
over a chunk of points it is one call per chunk.
"""

from __future__ import annotations

import hashlib
import tempfile
from pathlib import Path

import casadi as ca

#: RK4 steps in s from the start to theta0 of the two passes (the second for the points the
#: first cannot vouch for).
STEPS = (8, 32)
#: Newton corrections after each RK4 step, and at the end.
NEWTON = 1
POLISH = 2


def build_sweep(model, steps: int) -> ca.Function:
    """The sweep Function of a model, on the curve follower's kernels.

    Each step is one :func:`~scdk_sym.kernels.curve.rk4_in_s` step followed by
    :data:`NEWTON` :func:`~scdk_sym.kernels.curve.newton_correction` steps; ``det J_p`` is
    taken at every RK stage from the ``J_p`` the stage's slope is solved with. The answer is
    re-centred with :meth:`scdk_sym.model.chart.Chart.recentred`.

    Signature: ``(y1[m], theta1[k], theta0[k], c) -> (y0[m], det_ratio_min, correction,
    residual, J_p0[m*m], x0[n])`` with ``y`` in the local chart ``c`` of the start;
    ``det_ratio_min`` the smallest ``det J_p / det J_p(start)`` met, ``correction`` the
    largest Newton correction of a step divided by that step's ``max |dy|`` (plus 1e-300),
    ``residual`` the largest verification row at the end, ``J_p0`` in the chart centred on
    the solution (as :func:`scdk_sym.solve` checks it).
    """
    from ..kernels.curve import newton_correction, rk4_in_s

    sym = model.symbolic
    y, theta, c = sym.y, sym.theta, sym.c
    m, k = sym.m, sym.k
    jp = ca.Function("jp", [y, theta, c], [sym.J_p])
    det = ca.Function("det", [y, theta, c], [ca.det(sym.J_p)])
    newton = newton_correction(sym)
    check = ca.Function("check", [y, theta, c], [ca.norm_inf(sym.g_check)])
    pose = ca.Function("pose", [y, theta, c], [sym.x])
    recentre = ca.Function("recentre", [y, c], list(model.chart.recentred(y, c)))

    th1 = ca.SX.sym("theta1", k)
    dth = ca.SX.sym("dtheta", k)
    d1 = ca.SX.sym("det1")
    h = 1.0 / steps

    # one RK4 step and Newton corrections; state = (y, s, det ratio, worst correction)
    state = ca.SX.sym("state", m + 3)
    yk, s, ratio, worst = state[:m], state[m], state[m + 1], state[m + 2]
    stages: list = []
    pred = rk4_in_s(sym, yk, s, s + h, th1, dth, 1, stage_jp=stages)
    for Jp in stages:
        ratio = ca.fmin(ratio, ca.det(Jp) / d1)
    yn = pred
    for _ in range(NEWTON):
        yn = yn - newton(yn, th1 + (s + h) * dth, c)
    worst = ca.fmax(worst, ca.norm_inf(yn - pred) / (ca.norm_inf(yn - yk) + 1e-300))
    step = ca.Function(
        f"scdk_atlas_step_{steps}",
        [state, th1, dth, d1, c],
        [ca.vertcat(yn, s + h, ratio, worst)],
    )
    fold = step.fold(steps)

    y1 = ca.MX.sym("y1", m)
    t1 = ca.MX.sym("theta1", k)
    t0 = ca.MX.sym("theta0", k)
    cm = ca.MX.sym("c", c.numel())
    end = fold(ca.vertcat(y1, 0, 1, 0), t1, t0 - t1, det(y1, t1, cm), cm)
    y_end = end[:m]
    for _ in range(POLISH):
        y_end = y_end - newton(y_end, t0, cm)
    ratio_min = ca.fmin(end[m + 1], det(y_end, t0, cm) / det(y1, t1, cm))
    y_sol, c_sol = recentre(y_end, cm)
    jp_sol = ca.vec(jp(y_sol, t0, c_sol))
    outs: list[ca.MX] = [y_end, ratio_min, end[m + 2], check(y_end, t0, cm), jp_sol,
                         pose(y_end, t0, cm)]  # fmt: skip
    return ca.Function(
        f"scdk_atlas_sweep_{steps}",
        [y1, t1, t0, cm],
        [ca.densify(e) for e in outs],
        ["y1", "theta1", "theta0", "c"],
        ["y0", "det_ratio_min", "correction", "residual", "J_p0", "x0"],
    )


def sweep_key(model) -> str:
    """Cache key of a model's sweep library: its kernel hash (which covers the kernel sources,
    the follower's kernels, the chart and rotations), this module and the compiler."""
    from ..kernels.compile import cache_key, compiler_tag, source_digest

    h = hashlib.sha256(cache_key(model).encode())
    h.update(source_digest(("atlases/sweep.py",)))
    h.update(compiler_tag().encode())
    return h.hexdigest()[:24]


def sweep_library(model) -> Path:
    """The compiled sweep of a model, built into the disk cache on first use (seconds)."""
    from ..kernels.cache import cache_dir, cached_file
    from ..kernels.compile import compile_shared, write_c

    def build(path: Path) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            funcs = [build_sweep(model, n) for n in STEPS]
            src = write_c(funcs, "scdk_atlas_sweep", Path(tmp), with_header=False)
            compile_shared(src, path)

    target = cache_dir() / f"atlas_sweep_{sweep_key(model)}.so"
    return cached_file(target, build, "atlas sweep library")


def load_sweeps(model) -> tuple[ca.Function, ...]:
    """The cached compiled sweeps of a model, one per entry of :data:`STEPS`."""
    lib = str(sweep_library(model))
    return tuple(ca.external(f"scdk_atlas_sweep_{n}", lib) for n in STEPS)
