"""The singularity-consistent (SC) direct-kinematics solver.

Direct kinematics as path tracking (Bhattacharya, Nenchev & Uchiyama): from an assembled
start ``(y1, theta1)``, follow the solution curve of ``g(y, theta1 + s (theta0 - theta1)) = 0``
in ``q = (y, s)`` along the SC field until ``s = 1``. The field is integrated with CasADi's
CVODES in chunks of arc length; every crossing of the singular manifold (``det J_p`` changes
sign, ``s`` turns) is located by Newton on ``[g; t_s] = 0``; each ``s = 1`` crossing is finished
with ``dy/ds = J_p^{-1} j_s`` and a Newton polish, then verified.

:func:`trace` follows the curve and reports every ``s = 1`` crossing it meets (used by the
tracker and the assembly-mode search); :func:`solve` returns the first one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..errors import InputError, NotAssembledError, PathError, SolveError, VerificationError
from ..kernels.fastcall import Buffered
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
    "max_num_steps": 5000,
    "disable_internal_warnings": True,
}
BACKENDS = ("casadi", "compiled")


@dataclass
class Engine:
    """Per-model numeric machinery of the SC solver (kernels, integrator, mapped probe).

    ``integrator``, ``probe`` and ``warm`` are called through zero-copy buffers (see
    :mod:`scdk_sym.kernels.fastcall`): use :meth:`integrate` and :meth:`probe_samples`.
    """

    model: Model
    kernels: object
    integrator: Buffered
    probe: Buffered
    m: int
    k: int
    warm: Buffered

    def integrate(self, q: np.ndarray, p: np.ndarray) -> np.ndarray:
        """(m+1, GRID) samples of one chunk of the SC field from ``q``; p = (params, chart)."""
        f = self.integrator
        out = f(
            *[
                q if n == "x0" else p if n == "p" else a
                for n, a in zip(f.names, f.args, strict=True)
            ]
        )
        return out[0].reshape(self.m + 1, GRID, order="F").copy()

    def probe_samples(self, Q: np.ndarray, p: np.ndarray, c: np.ndarray):
        """(tangents (m+1, N), vec J_p (m*m, N), x (n, N)) at the N = GRID + 1 samples Q."""
        n = GRID + 1
        T, J, X = self.probe(Q.ravel(order="F"), np.tile(p, n), np.tile(c, n))
        return (
            T.reshape(-1, n, order="F").copy(),
            J.reshape(-1, n, order="F").copy(),
            X.reshape(-1, n, order="F").copy(),
        )


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
        raise InputError(f"unknown backend {backend!r}; backends: {', '.join(BACKENDS)}")
    m, k = model.m, model.k
    q = ca.MX.sym("q", m + 1)
    p = ca.MX.sym("p", 2 * k + m + 3)
    c = ca.MX.sym("c", model.chart.size)
    dae = {"x": q, "p": ca.vertcat(p, c), "ode": kern.field(q, p, c)}
    grid = np.linspace(0.0, 1.0, GRID + 1)[1:]
    integ = ca.integrator("sc_chunk", "cvodes", dae, 0.0, grid, CVODES_OPTIONS)
    eng = Engine(
        model, kern, Buffered(integ), Buffered(kern.probe.map(GRID + 1)), m, k, Buffered(kern.warm)
    )
    store[backend] = eng
    return eng


def null_direction(Jp: np.ndarray, js: np.ndarray) -> np.ndarray:
    """Unit vector along nu = [adj(J_p) j_s; det J_p] (generalised cross product of H's rows)."""
    H = np.hstack([Jp, -js[:, None]])
    _, _, Vt = np.linalg.svd(H)
    t = Vt[-1]
    if np.linalg.det(np.vstack([H, t])) < 0:
        t = -t
    return t


def _wnorm(v: np.ndarray, w: float) -> float:
    return float(math.sqrt(float(v[:-1] @ v[:-1]) + (w * v[-1]) ** 2))


def validate_start(
    model: Model, start: Configuration | None, check_residual: bool = True
) -> Configuration:
    """The start configuration (default home), checked to be assembled."""
    if start is None:
        return model.home
    if not isinstance(start, Configuration):
        raise InputError(
            f"start must be a Configuration (e.g. model.inverse_kinematics(x)), got {start!r}"
        )
    as_vector(start.y, model.m, "start.y")
    as_vector(start.theta, model.k, "start.theta")
    if not check_residual:
        return start
    res = model.residual(start.y, start.theta)
    if res > model.tolerance:
        raise NotAssembledError(
            f"start configuration is not assembled (residual {res:.3g} > {model.tolerance:.1e})",
            res,
        )
    return start


@dataclass(frozen=True)
class Hit:
    """A point where the traced curve meets ``s = 1``: a direct-kinematics solution.

    Attributes:
        y: (m,) canonical unknowns of the solution.
        arc: arc length from the start at which it was met.
        crossings: number of singular-manifold crossings before it.
        arriving: +1 if ``s`` was increasing through 1 there, -1 if decreasing.
    """

    y: np.ndarray
    arc: float
    crossings: int
    arriving: float


@dataclass
class Trace:
    """What :func:`trace` met along the solution curve through the start.

    Attributes:
        hits: ``s = 1`` crossings, in order of arc length.
        crossings: singular-manifold crossings, in order.
        crossing_arcs: arc length of each crossing.
        direction: +1 / -1, the sign of b relative to nu.
        det0: ``det J_p`` at the start.
        arc: arc length travelled.
        closed: the curve came back to its start (it was followed entirely).
        path: sampled curve (when recorded).
    """

    hits: list[Hit] = field(default_factory=list)
    crossings: list[Crossing] = field(default_factory=list)
    crossing_arcs: list[float] = field(default_factory=list)
    direction: float = 1.0
    det0: float = 0.0
    arc: float = 0.0
    closed: bool = False
    path: PathSamples | None = None
    s_range: tuple[float, float] = (0.0, 0.0)


def start_direction(
    model: Model, theta0: np.ndarray, start: Configuration, backend: str = "casadi"
):
    """(nu unit vector, det J_p) at the start of the path towards ``theta0``."""
    eng = engine(model, backend)
    y_loc, c = model.chart.to_local(start.y)
    Jp, Js = (np.array(a) for a in eng.kernels.jac(y_loc, start.theta, c))
    return null_direction(Jp, Js @ (theta0 - start.theta)), float(np.linalg.det(Jp))


def trace(
    model: Model,
    theta0: np.ndarray,
    start: Configuration,
    direction: float,
    *,
    max_hits: int = 1,
    max_arc: float | None = None,
    backend: str = "casadi",
    record_path: bool = False,
) -> Trace:
    """Follow the SC solution curve from ``start`` towards ``theta0`` and collect what it meets.

    Args:
        model: the model.
        theta0: (k,) target actuated values (must differ from ``start.theta``).
        start: assembled start configuration.
        direction: +1 to follow ``nu``, -1 to follow ``-nu`` (the sign of the paper's b).
        max_hits: stop after this many ``s = 1`` crossings.
        max_arc: arc-length budget (default: 60 times the linear prediction of the distance
            to ``s = 1`` plus 20 model sizes).
        backend: kernel backend.
        record_path: keep the sampled curve.

    Raises:
        PathError: the integration itself failed (the field turned too sharply).
    """
    eng = engine(model, backend)
    kern = eng.kernels
    m, _k = eng.m, eng.k
    theta1 = np.array(start.theta, dtype=float)
    dtheta = np.asarray(theta0, float) - theta1
    w = float(np.linalg.norm(dtheta))
    y_loc, c = model.chart.to_local(start.y)
    floating = bool(model.chart.rotations)
    Jp, Js = (np.array(a) for a in kern.jac(y_loc, theta1, c))
    nu = null_direction(Jp, Js @ dtheta)
    out = Trace(direction=direction, det0=float(np.linalg.det(Jp)))
    tangent = direction * nu / _wnorm(nu, w)
    ell0 = 1.0 / max(abs(tangent[-1]), 1e-6)  # arc length per unit s at the start
    ell0 = min(ell0, 1e3 * max(1.0, model.length_scale))
    budget = max_arc if max_arc is not None else 60.0 * ell0 + 20.0 * max(1.0, model.length_scale)
    scale = 0.5 * ell0
    q = np.concatenate([y_loc, [0.0]])
    q_start = q.copy()
    s_lo = s_hi = 0.0
    rec: dict[str, list] = {"q": [], "J": [], "x": [], "arc": []}
    chunks = 0
    while out.arc < budget and chunks < 4000:
        chunks += 1
        p = np.concatenate([theta1, dtheta, tangent, [scale, GAIN]])
        try:
            xf = eng.integrate(q, np.concatenate([p, c]))
        except RuntimeError:
            xf = np.full((m + 1, GRID), np.nan)
        Q = np.hstack([q[:, None], xf])
        if not np.all(np.isfinite(Q)):
            scale /= 4
            if scale < 1e-12 * ell0:
                raise PathError(f"integration of the SC field failed near q={q.tolist()}")
            continue
        T, Jv, X = eng.probe_samples(Q, p, c)
        t_end = T[:, -1]
        cosine = float(t_end[:-1] @ tangent[:-1] + w * w * t_end[-1] * tangent[-1])
        if cosine < 0.8:
            scale /= 2
            if scale < 1e-12 * ell0:
                raise PathError(f"the SC field turned too sharply near q={q.tolist()}")
            continue
        s_vals, ts = Q[-1], T[-1]
        bad_finish = False
        new_hits: list[Hit] = []
        new_cross: list[tuple[Crossing, float]] = []
        for i in range(GRID):
            seg_arc = out.arc + scale * i / GRID
            if ts[i] * ts[i + 1] < 0:  # s' changes sign: a crossing of the singular manifold
                cr = _locate_crossing(eng, Q[:, i], Q[:, i + 1], ts[i], ts[i + 1], p, c)
                new_cross.append((cr, seg_arc + scale * 0.5 / GRID))
            if (s_vals[i] - 1.0) * (s_vals[i + 1] - 1.0) <= 0 and s_vals[i] != s_vals[i + 1]:
                if s_vals[i + 1] == 1.0 and i + 1 < GRID:
                    continue  # counted at the next segment
                if ts[i] * ts[i + 1] < 0:  # a fold in the same segment: resolve it first
                    bad_finish = True
                    break
                hit = _finish(eng, Q[:, i], Q[:, i + 1], theta1, dtheta, c, seg_arc)
                if hit is None:
                    bad_finish = True
                    break
                y_can = model.chart.to_canonical(hit, c) if floating else hit
                arriving = 1.0 if s_vals[i + 1] > s_vals[i] else -1.0
                new_hits.append(Hit(y_can, seg_arc, len(out.crossings) + len(new_cross), arriving))
        if bad_finish:  # the finishing step left the curve: redo this chunk with finer samples
            scale /= 4
            if scale < 1e-12 * ell0:
                raise PathError("could not finish the path at s = 1")
            continue
        for cr, a in new_cross:
            out.crossings.append(cr)
            out.crossing_arcs.append(a)
        s_lo, s_hi = min(s_lo, s_vals.min()), max(s_hi, s_vals.max())
        if record_path:
            first = 1 if rec["q"] else 0  # a chunk starts where the previous one ended
            Qc = Q[:, first:].T
            if floating:
                Qc = np.array([np.append(model.chart.to_canonical(r[:-1], c), r[-1]) for r in Qc])
            rec["q"].extend(Qc)
            rec["J"].extend(Jv[:, first:].T)
            rec["x"].extend(X[:, first:].T)
            rec["arc"].extend(out.arc + scale * np.arange(first, GRID + 1) / GRID)
        out.hits.extend(new_hits)
        out.arc += scale
        if len(out.hits) >= max_hits:
            break
        q = Q[:, -1]
        tangent = t_end / _wnorm(t_end, w)
        if floating:  # re-centre the orientation chart on the current rotation
            y_new, c = model.chart.recentre(q[:-1], c)
            q = np.append(y_new, q[-1])
            pn = np.concatenate([theta1, dtheta, tangent, [scale, GAIN]])
            tangent = np.array(kern.probe(q, pn, c)[0]).ravel()
        elif out.arc > 2 * scale and _near(Q, q_start, 0.05 * scale):
            out.closed = True
            break
        if cosine > 0.995:
            scale = min(scale * 1.6, 2.0 * ell0)
    out.s_range = (float(s_lo), float(s_hi))
    if record_path and rec["q"]:
        out.path = _samples(rec, direction, model)
    return out


def _near(Q: np.ndarray, q0: np.ndarray, tol: float) -> bool:
    return bool(np.min(np.linalg.norm(Q[:, 1:] - q0[:, None], axis=0)) < tol)


def _finish(eng: Engine, qa, qb, theta1, dtheta, c, arc) -> np.ndarray | None:
    """The solution at s = 1 between samples qa and qb (or None if the finish left the curve)."""
    m = eng.m
    ya, sa = qa[:m], qa[-1]
    if sa == 1.0:
        return np.array(ya)
    y_end, res, _ = eng.kernels.finish(ya, sa, theta1, dtheta, c)
    y_end = np.array(y_end).ravel()
    seg = np.linalg.norm(qb[:m] - ya) + 1e-12
    if not np.all(np.isfinite(y_end)) or np.linalg.norm(y_end - ya) > 3 * seg + 1e-9:
        return None
    return y_end


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


def _samples(rec: dict, direction: float, model: Model) -> PathSamples:
    Q = np.array(rec["q"])
    m = model.m
    J = np.array(rec["J"]).reshape(len(rec["J"]), m, m).transpose(0, 2, 1)  # CasADi: column-major
    det = np.linalg.det(J)
    return PathSamples(
        s=Q[:, -1], y=Q[:, :-1], x=np.array(rec["x"]), det_jp=det, sdot=direction * det,
        arc=np.array(rec["arc"]),
    )  # fmt: skip


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
    fast: bool = True,
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
        max_arc: arc-length budget of the path (see :func:`trace`).
        record_path: keep the sampled curve in ``result.path`` (for plots).
        fast: for a convergent solve without ``record_path``, first try one call of the warm
            kernel (an RK4 step in s with a Newton polish); it is accepted only if the polish
            moved the prediction by less than 1e-7 (relative) and ``det J_p`` kept its sign,
            else the full CVODES path is integrated.

    Returns:
        A verified :class:`SolveResult`; ``result.crossings`` lists the singular-manifold
        crossings met on the way.

    Raises:
        InputError: bad shapes, NaN, unknown branch.
        PathError: the curve never reached ``s = 1`` within the budget (e.g. theta0 is not
            reachable along this curve, or it closed on itself).
        VerificationError: the final configuration failed its residual check.
    """
    theta0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
    if b is None and branch not in ("convergent", "divergent"):
        raise InputError(f"unknown branch {branch!r}; branches: convergent, divergent")
    if b is not None and (not math.isfinite(b) or b == 0):
        raise InputError(f"b must be a non-zero finite number, got {b!r}")
    if fast and not record_path and b is None and branch == "convergent":
        start = validate_start(model, start, check_residual=False)
        res = _fast_convergent(model, theta0, start, backend)
        if res is not None:
            return res
    start = validate_start(model, start)
    dtheta = theta0 - start.theta
    if float(np.linalg.norm(dtheta)) <= 1e-14 * max(1.0, float(np.linalg.norm(theta0))):
        return _result(model, start.y, theta0, (), "convergent", 1.0, start, None)
    nu, det0 = start_direction(model, theta0, start, backend)
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
    tr = trace(
        model, theta0, start, direction, max_arc=max_arc, backend=backend, record_path=record_path
    )
    if not tr.hits:
        why = "it closed on itself" if tr.closed else f"within arc length {tr.arc:.3g}"
        raise PathError(
            f"the solution curve from the start did not reach s = 1 for theta0={theta0.tolist()} "
            f"({why}; s stayed in [{tr.s_range[0]:.3g}, {tr.s_range[1]:.3g}]): theta0 is not "
            "reachable along this path"
        )
    hit = tr.hits[0]
    crossings = tuple(tr.crossings[: hit.crossings])
    return _result(model, hit.y, theta0, crossings, name, direction, start, tr.path)


def _fast_convergent(model, theta0, start, backend) -> SolveResult | None:
    """One call of the warm kernel (RK4 in s + Newton + checks); None when not conclusive."""
    eng = engine(model, backend)
    y1, c = model.chart.to_local(start.y)
    y0, corr, res1, res0, J1, J0, T, x = eng.warm(y1, start.theta, theta0, c)
    if not res1[0] <= model.tolerance:
        raise NotAssembledError(
            f"start configuration is not assembled (residual {res1[0]:.3g} > "
            f"{model.tolerance:.1e})",
            float(res1[0]),
        )
    m = model.m
    if not (np.all(np.isfinite(y0)) and res0[0] <= model.tolerance):
        return None
    step = float(np.max(np.abs(y0 - y1)))
    if corr[0] > 1e-7 * step + 1e-13:
        return None
    det1 = np.linalg.det(J1.reshape(m, m, order="F"))
    det0 = np.linalg.det(J0.reshape(m, m, order="F"))
    if not det1 * det0 > 0:
        return None
    y = model.chart.to_canonical(y0, c)
    theta = theta0.copy()
    return SolveResult(
        x=x.copy(),
        y=y,
        theta=theta,
        platform_pose=T.reshape(4, 4, order="F").copy(),
        joints=model.joint_values(y, theta),
        residual=float(res0[0]),
        crossings=(),
        status="converged",
        branch="convergent",
        b=1.0 if det1 > 0 else -1.0,
        start=start,
        path=None,
    )


def _result(model, y, theta0, crossings, branch, direction, start, path) -> SolveResult:
    cfg = model.configuration(y, theta0)
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
