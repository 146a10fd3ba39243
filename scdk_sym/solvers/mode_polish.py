"""The real endpoints of a homotopy as distinct configurations of the model.

Each real endpoint is mapped to the model's unknowns, Newton-polished on the model's own
closure rows ``g`` (all endpoints of all points in common kernel calls), kept where max
``|g| <= RESIDUAL``, set apart as a spurious root of the form where it does not close at all,
and merged with the images of one configuration only; the configurations are sorted as the
curve search sorts them.
"""

from __future__ import annotations

import numpy as np

from ..follower.geometry import features
from ..kernels.fastcall import model_calls
from ..results import mode_orders
from ..robot import Model

#: Largest max |g| of a polished real solution [model length unit].
RESIDUAL = 1e-9
#: A real root of the form with max |g| above this many model sizes, before and after Newton,
#: is no solution of the model (e.g. a weld closed with a half turn in its rotation rows).
SPURIOUS = 1e-3
#: Real endpoints whose polished configurations agree to this many model sizes (chart-free
#: features) are one solution.
DUPLICATE = 1e-10
#: Newton steps on the model's rows per real endpoint.
NEWTON_STEPS = 8


def real_modes(model, form, results, thetas: np.ndarray, reasons: list[list[str]]) -> list:
    """Each point's real endpoints as distinct model configurations polished on ``g``, sorted,
    the number of real roots of the form that are no closures of the model and the
    configurations' canonical unknowns (N_w, m) (all points' kernels in common calls; a
    failure appended to the point's ``reasons``)."""
    scale = max(1.0, model.length_scale)
    Zs = [np.asarray(res.real_solutions, dtype=float) for res in results]
    finite = [np.isfinite(Z).all(axis=1) for Z in Zs]
    dropped = [int((~f).sum()) for f in finite]
    spurious = [0] * len(Zs)
    owner = np.repeat(np.arange(len(Zs)), [int(f.sum()) for f in finite])
    # real endpoints -> model unknowns, polished on g
    Y0, C = form.to_model(  # (K, m), (K, chart size)
        np.concatenate([Z[f] for Z, f in zip(Zs, finite, strict=True)] or [np.zeros((0, form.n))]),
        reference=model.home.y,
    )
    Th = thetas[owner]
    Y, R = _polish(model, Y0, C, Th)
    good = R <= RESIDUAL
    for i in np.flatnonzero(~good).tolist():
        w = int(owner[i])
        if R[i] > SPURIOUS * scale and model.residual(Y0[i], thetas[w], C[i]) > SPURIOUS * scale:
            spurious[w] += 1  # a root of the form that is no closure of the model
        else:
            dropped[w] += 1
    polished, ys, xs = model.configuration_table(Y[good], Th[good], C[good], R[good])
    # distinct endpoints of the homotopy are distinct roots; only images of one configuration
    # (polished to the same point) are merged: two real solutions next to a singular surface
    # may lie 1e-5 model sizes apart, and the Krawczyk boxes below decide (they must be
    # pairwise disjoint)
    feats = features(model, ys)
    keys = mode_orders(xs if len(xs) else np.zeros((0, 0)), ys)
    per_point: list[list[int]] = [[] for _ in Zs]
    for i, w in enumerate(owner[good].tolist()):
        per_point[w].append(i)
    out = []
    for w, rows in enumerate(per_point):
        kept = [rows[j] for j in _first_of_images(feats[rows], DUPLICATE * scale)]
        if dropped[w]:
            reasons[w].append(
                f"{dropped[w]} real endpoint(s) did not polish to max |g| <= {RESIDUAL:.0e}"
            )
        kept.sort(key=keys.__getitem__)  # stable, as sorting the configurations by mode_order
        out.append(([polished[i] for i in kept], spurious[w], ys[kept]))
    return out


def _first_of_images(feats: np.ndarray, tol: float) -> list[int]:
    """The rows of ``feats`` (R, d) kept in order, each unless some kept row lies within
    ``tol`` of it (max-norm): all pairs compared at once (by their first coordinate, then,
    where two may meet, by all), the in-order rule run only where two rows meet."""
    from ..algebraic.distinct import pairs_apart

    R = len(feats)
    if R < 2 or pairs_apart(feats[None], tol):  # no two rows meet
        return list(range(R))
    dist = np.abs(feats[:, None] - feats[None]).max(axis=2)
    near = dist <= tol
    if np.count_nonzero(near) == np.count_nonzero(near.diagonal()):  # no two rows meet
        return list(range(R))
    kept: list[int] = []
    for i in range(R):
        d = dist[kept, i]
        if kept and not np.isnan(d).any() and d.min() <= tol:  # as min() of the column
            continue
        kept.append(i)
    return kept


def _polish(model: Model, ys: np.ndarray, cs: np.ndarray, theta: np.ndarray):
    """Newton on the model's rows, each point (N, m) in its chart (N, chart size) at its
    actuated values (``theta`` (k,) for all or (N, k)), all points in each kernel call; a
    point stops when ``max |g| <= RESIDUAL / 100``, after ``NEWTON_STEPS``, or when its
    Jacobian is singular. Returns ``(ys, residuals)``, the residual
    :meth:`~scdk_sym.robot.Model.residual` (``inf`` where ``g`` went non-finite)."""
    calls = model_calls(model)
    N = len(ys)
    ys = np.array(ys, dtype=float).reshape(N, model.m)
    cs = np.asarray(cs, dtype=float).reshape(N, model.chart.size)
    if not N:
        return ys, np.zeros(0)
    g_all, jac_all = calls.mapped("g", N), calls.mapped("jac", N)
    theta = np.asarray(theta, dtype=float)
    theta = theta.T if theta.ndim == 2 else theta  # one column per point
    lost = np.zeros(N, dtype=bool)  # g went non-finite
    active = np.ones(N, dtype=bool)
    for _ in range(NEWTON_STEPS):
        G = np.asarray(g_all(ys.T, theta, cs.T)).reshape(-1, N).T  # (N, rows)
        r = np.abs(G).max(axis=1) if G.shape[1] else np.zeros(N)
        lost |= active & ~np.isfinite(r)
        active &= np.isfinite(r) & ~(r <= 0.01 * RESIDUAL)
        rows = np.flatnonzero(active)
        if not rows.size:
            break
        J = jac_all(ys.T, theta, cs.T)[0].reshape(model.m, N, model.m).transpose(1, 0, 2)
        try:
            ys[rows] -= np.linalg.solve(J[rows], G[rows][..., None])[..., 0]
        except np.linalg.LinAlgError:  # a singular one: those stop, the others step
            for i in rows:
                try:
                    ys[i] -= np.linalg.solve(J[i], G[i])
                except np.linalg.LinAlgError:
                    active[i] = False
    check = np.asarray(calls.mapped("check", N)(ys.T, theta, cs.T)).reshape(-1, N)
    residuals = np.abs(check).max(axis=0)
    residuals[lost] = np.inf
    return ys, residuals
