"""The singularity-consistent (SC) direct-kinematics solver.

Direct kinematics as path tracking (Bhattacharya, Nenchev & Uchiyama): from an assembled
start ``(y1, theta1)``, follow the solution curve of ``g(y, theta1 + s (theta0 - theta1)) = 0``
in ``q = (y, s)`` along the SC field until ``s = 1``. The field is integrated with CasADi's
CVODES in chunks of arc length; every crossing of the singular manifold (``det J_p`` changes
sign, ``s`` turns) is located by Newton on ``[g; t_s] = 0``; the ``s = 1`` crossing is finished
with ``dy/ds = J_p^{-1} j_s`` and a Newton polish, then verified.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..errors import InputError, NotAssembledError, PathError, SolveError, VerificationError
from ..model.model import Model, as_vector
from ..results import Configuration, Crossing, PathSamples, SolveResult

#: Output samples per integrated chunk.
GRID = 8
#: Stabilisation gain K (g decays as exp(-K tau) over one chunk).
GAIN = 5.0
CVODES_OPTIONS = {
    "linear_multistep_method": "adams",
    "nonlinear_solver_iteration": "functional",
    "abstol": 1e-11,
    "reltol": 1e-10,
    "max_num_steps": 20000,
}


@dataclass
class Engine:
    """Per-model numeric machinery of the SC solver (integrator, mapped probes)."""

    model: Model
    kernels: object
    integrator: ca.Function
    probe: ca.Function
    m: int
    k: int
    cache: dict = field(default_factory=dict)


def engine(model: Model, backend: str = "casadi") -> Engine:
    """The (cached) SC engine of a model.

    Args:
        model: the model.
        backend: "casadi" (SX Functions) or "compiled" (generated C, cached on disk).
    """
    store = model.__dict__.setdefault("_engines", {})
    if backend in store:
        return store[backend]
    if backend == "casadi":
        kern = model.kernels
    elif backend == "compiled":
        from ..kernels.compile import compiled_kernels

        kern = compiled_kernels(model)
    else:
        raise InputError(f"unknown backend {backend!r}; backends: casadi, compiled")
    m, k = model.m, model.k
    q = ca.MX.sym("q", m + 1)
    p = ca.MX.sym("p", 2 * k + m + 3)
    c = ca.MX.sym("c", model.chart.size)
    dae = {"x": q, "p": ca.vertcat(p, c), "ode": kern.field(q, p, c)}
    grid = np.linspace(0.0, 1.0, GRID + 1)[1:]
    integ = ca.integrator("sc_chunk", "cvodes", dae, 0.0, grid, CVODES_OPTIONS)
    eng = Engine(model, kern, integ, kern.probe.map(GRID + 1), m, k)
    store[backend] = eng
    return eng


def _null_direction(Jp: np.ndarray, js: np.ndarray) -> np.ndarray:
    """Unit vector along nu = [adj(J_p) j_s; det J_p] (generalised cross product of H's rows)."""
    H = np.hstack([Jp, -js[:, None]])
    _, _, Vt = np.linalg.svd(H)
    t = Vt[-1]
    if np.linalg.det(np.vstack([H, t])) < 0:
        t = -t
    return t


def _wnorm(v: np.ndarray, w: float) -> float:
    return float(math.sqrt(float(v[:-1] @ v[:-1]) + (w * v[-1]) ** 2))


def validate_start(model: Model, start: Configuration | None) -> Configuration:
    if start is None:
        return model.home
    if not isinstance(start, Configuration):
        raise InputError(
            f"start must be a Configuration (e.g. model.inverse_kinematics(x)), got {start!r}"
        )
    as_vector(start.y, model.m, "start.y")
    as_vector(start.theta, model.k, "start.theta")
    res = model.residual(start.y, start.theta)
    if res > model.tolerance:
        raise NotAssembledError(
            f"start configuration is not assembled (residual {res:.3g} > {model.tolerance:.1e})",
            res,
        )
    return start


def solve(
    model: Model,
    theta0: Sequence[float],
    start: Configuration | None = None,
    branch: str = "convergent",
    b: float | None = None,
    *,
    backend: str = "casadi",
    max_arc: float | None = None,
    record_path: bool = True,
) -> SolveResult:
    """Solve the direct kinematics at ``theta0`` by the singularity-consistent method.

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        start: assembled start configuration (default: ``model.home``).
        branch: "convergent" (``b det J_p > 0`` at the start: stays in the start's
            compartment) or "divergent" (moves away, crosses the singular manifold).
        b: the paper's signed scalar; when given, its sign selects the direction of
            ``nu`` and overrides ``branch``.
        backend: "casadi" or "compiled" kernels.
        max_arc: arc-length budget of the path (default: 60 times the linear prediction).
        record_path: keep the sampled curve in ``result.path``.

    Returns:
        A verified :class:`SolveResult`.

    Raises:
        InputError: bad shapes, NaN, unknown branch.
        PathError: the curve never reached ``s = 1`` within the budget (e.g. theta0 is not
            reachable along this curve, or it closed on itself).
        VerificationError: the final configuration failed its residual check.
    """
    theta0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
    start = validate_start(model, start)
    if b is None and branch not in ("convergent", "divergent"):
        raise InputError(f"unknown branch {branch!r}; branches: convergent, divergent")
    if b is not None and (not math.isfinite(b) or b == 0):
        raise InputError(f"b must be a non-zero finite number, got {b!r}")
    eng = engine(model, backend)
    kern = eng.kernels
    m, k = eng.m, eng.k
    theta1 = np.array(start.theta, dtype=float)
    dtheta = theta0 - theta1
    w = float(np.linalg.norm(dtheta))
    if w <= 1e-14 * max(1.0, float(np.linalg.norm(theta0))):
        return _result(model, start.y, theta0, (), "convergent", 1.0, start, None)
    y_loc, c = model.chart.to_local(start.y)
    floating = bool(model.chart.rotations)
    Jp, Js = (np.array(a) for a in kern.jac(y_loc, theta1, c))
    js = Js @ dtheta
    nu = _null_direction(Jp, js)
    det0 = float(np.linalg.det(Jp))
    if b is None:
        if abs(nu[-1]) < 1e-10:
            raise SolveError(
                "the start configuration is singular (det J_p ~ 0): the branch is undefined; "
                "pass b=+1 or b=-1"
            )
        sign = 1.0 if nu[-1] > 0 else -1.0
        direction = sign if branch == "convergent" else -sign
    else:
        direction = 1.0 if b > 0 else -1.0
    name = "convergent" if direction * det0 > 0 else "divergent"
    tangent = direction * nu / _wnorm(nu, w)
    ell0 = 1.0 / max(abs(tangent[-1]) * w / max(w, 1e-300), 1e-6)  # arc length per unit s
    ell0 = min(ell0, 1e3 * max(1.0, model.length_scale))
    budget = max_arc if max_arc is not None else 60.0 * ell0 + 20.0 * max(1.0, model.length_scale)
    scale = 0.5 * ell0
    q = np.concatenate([y_loc, [0.0]])
    q_start = q.copy()
    arc = 0.0
    crossings: list[Crossing] = []
    rec_q, rec_t, rec_J, rec_x, rec_arc = [], [], [], [], []
    chunks = 0
    while True:
        chunks += 1
        if arc > budget or chunks > 4000:
            raise PathError(
                f"the solution curve did not reach s = 1 for theta0={theta0.tolist()} within arc "
                f"length {budget:.3g} (s ranged over [{min(r[-1] for r in rec_q):.3g}, "
                f"{max(r[-1] for r in rec_q):.3g}]): theta0 may be unreachable from this start"
            )
        p = np.concatenate([theta1, dtheta, tangent, [scale, GAIN]])
        try:
            xf = np.array(eng.integrator(x0=q, p=np.concatenate([p, c]))["xf"])
        except RuntimeError:
            xf = np.full((m + 1, GRID), np.nan)
        Q = np.hstack([q[:, None], xf])
        if not np.all(np.isfinite(Q)):
            scale /= 4
            if scale < 1e-12 * ell0:
                raise PathError(f"integration of the SC field failed near q={q.tolist()}")
            continue
        T, Jv, X = (
            np.array(a)
            for a in eng.probe(
                Q, np.tile(p[:, None], (1, GRID + 1)), np.tile(c[:, None], (1, GRID + 1))
            )
        )
        t_end = T[:, -1]
        cosine = float(t_end[:-1] @ tangent[:-1] + w * w * t_end[-1] * tangent[-1])
        if cosine < 0.8:
            scale /= 2
            if scale < 1e-12 * ell0:
                raise PathError(f"the SC field turned too sharply near q={q.tolist()}")
            continue
        s_vals = Q[-1]
        ts = T[-1]
        done = None
        for i in range(GRID):
            if ts[i] * ts[i + 1] < 0:  # s' changes sign: a crossing of the singular manifold
                crossings.append(
                    _locate_crossing(eng, Q[:, i], Q[:, i + 1], ts[i], ts[i + 1], p, c)
                )
            if (s_vals[i] - 1.0) * (s_vals[i + 1] - 1.0) <= 0 and s_vals[i] != s_vals[i + 1]:
                done = i
                break
        if record_path:
            upto = GRID + 1 if done is None else done + 1
            Qc = Q[:, :upto].T
            if floating:
                Qc = np.array([np.append(model.chart.to_canonical(r[:-1], c), r[-1]) for r in Qc])
            rec_q.extend(Qc)
            rec_t.extend(T[:, :upto].T)
            rec_J.extend(Jv[:, :upto].T)
            rec_x.extend(X[:, :upto].T)
            rec_arc.extend(arc + scale * np.arange(upto) / GRID)
        else:
            rec_q.append(Q[:, -1])
        if done is not None:
            ya, sa = Q[:-1, done], Q[-1, done]
            if abs(sa - 1.0) < 1e-15:
                y_end = ya
            else:
                y_end, _ = kern.finish(ya, sa, theta1, dtheta, c)
                y_end = np.array(y_end).ravel()
            seg = np.linalg.norm(Q[:-1, done + 1] - ya) + 1e-12
            if not np.all(np.isfinite(y_end)) or np.linalg.norm(y_end - ya) > 3 * seg + 1e-9:
                # the finishing step left the curve: retry this chunk with finer samples
                if record_path:
                    del rec_q[-(done + 1) :], rec_t[-(done + 1) :], rec_J[-(done + 1) :]
                    del rec_x[-(done + 1) :], rec_arc[-(done + 1) :]
                crossings = [c for c in crossings if c.s is not None and c.index != chunks]
                scale /= 4
                if scale < 1e-12 * ell0:
                    raise PathError("could not finish the path at s = 1")
                continue
            path = None
            if record_path:
                path = _samples(
                    rec_q, rec_t, rec_J, rec_x, rec_arc, direction, y_end, model, theta0
                )
            return _result(model, y_end, theta0, tuple(crossings), name, direction, start, path, c)
        arc += scale
        q = Q[:, -1]
        tangent = t_end / _wnorm(t_end, w)
        if floating:  # re-centre the orientation chart on the current rotation
            y_new, c = model.chart.recentre(q[:-1], c)
            q = np.append(y_new, q[-1])
            pn = np.concatenate([theta1, dtheta, tangent, [scale, GAIN]])
            tangent = np.array(kern.probe(q, pn, c)[0]).ravel()
        if not floating and arc > 2 * scale and np.linalg.norm(q - q_start) < 0.05 * scale:
            raise PathError(
                f"the solution curve through the start closed on itself without reaching s = 1 "
                f"for theta0={theta0.tolist()}: theta0 is not reachable along it"
            )
        if cosine > 0.995:
            scale = min(scale * 1.6, 2.0 * ell0)


def _locate_crossing(eng: Engine, qa, qb, ta, tb, p, c) -> Crossing:
    alpha = ta / (ta - tb)
    q0 = qa + alpha * (qb - qa)
    q1 = np.array(eng.kernels.cross(q0, p, c)).ravel()
    seg = np.linalg.norm(qb - qa)
    if not np.all(np.isfinite(q1)) or np.linalg.norm(q1 - q0) > 2 * seg + 1e-12:
        q1 = q0  # fall back on the interpolated point (accurate to the sample spacing)
    m, k = eng.m, eng.k
    theta = p[:k] + q1[-1] * p[k : 2 * k]
    cfg = eng.model.configuration(q1[:m], theta, c)
    return Crossing(float(q1[-1]), cfg.x, cfg.y, cfg.theta)


def _samples(rec_q, rec_t, rec_J, rec_x, rec_arc, direction, y_end, model, theta0) -> PathSamples:
    Q = np.array(rec_q)
    m = model.m
    J = np.array(rec_J).reshape(len(rec_J), m, m).transpose(0, 2, 1)  # CasADi vec is column-major
    det = np.linalg.det(J)
    return PathSamples(
        s=Q[:, -1],
        y=Q[:, :-1],
        x=np.array(rec_x),
        det_jp=det,
        sdot=direction * det,
        arc=np.array(rec_arc),
    )


def _result(model, y, theta0, crossings, branch, direction, start, path, c=None) -> SolveResult:
    cfg = model.configuration(y, theta0, c)
    if not cfg.residual <= model.tolerance:
        raise VerificationError(
            f"solution at theta0={np.asarray(theta0).tolist()} failed verification: residual "
            f"{cfg.residual:.3g} > {model.tolerance:.1e}",
            cfg.residual,
        )
    return SolveResult(
        x=cfg.x,
        y=cfg.y,
        theta=cfg.theta,
        platform_pose=cfg.platform_pose,
        joints=cfg.joints,
        residual=cfg.residual,
        crossings=crossings,
        status="converged",
        branch=branch,
        b=direction,
        start=start,
        path=path,
    )
