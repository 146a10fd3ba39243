"""What a point's homotopy proves, and its :class:`~scdk_sym.results.AssemblyModes`.

The links of the certified chain that fail are collected as reasons: a start system not
proven complete, paths that failed or ended singular or nearly real; the report of a point
says what was proven, or each reason it was not. Singular endpoints on roots of the form that
close a weld with a half turn are no closures, and set apart
(:func:`~scdk_sym.solvers.form_maps.weld_traces`).
"""

from __future__ import annotations

import numpy as np

from ..results import AssemblyModes
from .form_maps import weld_traces

#: Largest relative imaginary part of a real endpoint (as ``solve_homotopy`` selects them).
REAL_TOL = 1e-8
#: Endpoints with a relative imaginary part in (REAL_TOL, UNDECIDED_TOL] leave the set
#: uncertified: a real solution computed with that much error would be missed.
UNDECIDED_TOL = 1e-5
#: A singular endpoint at which a weld's ``tr(R_a^T R_b)`` is within this of -1 lies on a
#: set of roots of the form closing that weld with a half turn (the trace is -1 or 3 there,
#: constant on a connected set): none of its points is a closure
#: (:func:`~scdk_sym.solvers.form_maps.weld_traces`).
HALF_TURN = 1.0


def point_modes(start, found, certs, reasons, half_turns, continued) -> AssemblyModes:
    """The :class:`AssemblyModes` of one point from its chain's outcomes."""
    cfgs, spurious, _ = found
    certified = not reasons
    if certified:
        source = (
            f"tracked from a neighbouring point's complete set to {start.root_count} distinct "
            "regular ends"
            if continued
            else f"start system complete: {start.certificate}"
        )
        report = (
            f"certified complete: {len(cfgs)} real of {start.root_count} complex solutions "
            f"({source}); each real one proven unique in its Krawczyk box, boxes pairwise "
            "disjoint"
        )
        if spurious:
            report += (
                f"; {spurious} real root(s) of the algebraic form are no closures of the model"
            )
    else:
        report = "not certified: " + "; ".join(reasons)
    if half_turns:
        report += (
            f"; {half_turns} path(s) ended on roots of the form that close a weld with a half "
            "turn (tr R_a^T R_b = -1 on all of them): no closures"
        )
    return AssemblyModes(
        solutions=tuple(cfgs),
        certified=certified,
        root_count=int(start.root_count),
        report=report,
        certificates=certs,
        method="homotopy",
    )


def path_reasons_many(form, results: list, thetas: np.ndarray, reasons: list[list[str]]) -> list:
    """:func:`_path_reasons` of each point: the points of one path count screened at once,
    the function itself run only where some path failed, ended singular or nearly real."""
    out = [0] * len(results)
    by_paths: dict[tuple, list[int]] = {}
    for w, res in enumerate(results):
        by_paths.setdefault(res.endpoints.shape, []).append(w)
    for group in by_paths.values():
        S = np.stack([results[w].status for w in group])  # (G, R)
        Z = np.stack([results[w].endpoints for w in group])  # (G, R, n)
        ok = S == "success"
        with np.errstate(invalid="ignore"):
            imag = np.abs(Z.imag).max(axis=2) / np.maximum(1.0, np.abs(Z).max(axis=2))
        undecided = ok & (imag > REAL_TOL) & (imag <= UNDECIDED_TOL)
        look = (S == "failed").any(axis=1) | (S == "singular").any(axis=1) | undecided.any(axis=1)
        for w in np.asarray(group)[look].tolist():
            out[w] = _path_reasons(form, results[w], thetas[w], reasons[w])
    return out


def _path_reasons(form, res, theta0: np.ndarray, reasons: list[str]) -> int:
    """What the homotopy's paths leave unproven (appended to ``reasons``); the number of
    singular endpoints that close a weld with a half turn (no closures, set apart)."""
    n_failed = int((res.status == "failed").sum())
    if n_failed:
        reasons.append(f"{n_failed} of {len(res.status)} paths failed before t = 1")
    singular = res.endpoints[res.status == "singular"]
    half_turns = 0
    if len(singular):
        # roots on a set where a weld's rotation rows close with a half turn: no closures
        p0 = form.params(theta0)
        traces = weld_traces(form, p0)(singular)
        G, _, _ = form.evaluate(singular, np.broadcast_to(p0, (len(singular), form.n_params)))
        near = np.abs(G).max(axis=1) <= 1e-6 * (1.0 + np.abs(singular).max(axis=1))
        on_half_turn = near & (np.abs(traces + 1.0) < HALF_TURN).any(axis=1)
        half_turns = int(on_half_turn.sum())
        singular = singular[~on_half_turn]
    if len(singular):
        n_real = int(np.sum(form.is_real(singular, 1e-6)))
        reasons.append(
            f"{len(singular)} path(s) ended at singular points ({n_real} real): multiple or "
            "non-isolated solutions (e.g. a positive-dimensional set), whose real points are "
            "not all listed"
        )
    ok = res.endpoints[res.status == "success"]
    imag = np.abs(ok.imag).max(axis=1) / np.maximum(1.0, np.abs(ok).max(axis=1))
    undecided = int(np.sum((imag > REAL_TOL) & (imag <= UNDECIDED_TOL)))
    if undecided:
        reasons.append(
            f"{undecided} endpoint(s) nearly real (imaginary part between {REAL_TOL:.0e} and "
            f"{UNDECIDED_TOL:.0e}): real or complex undecided"
        )
    return half_turns


def unproven_start(start, reasons: list[list[str]], certified_only: bool) -> AssemblyModes | None:
    """A start system not proven complete: the reason appended to every point's ``reasons``;
    with ``certified_only``, the (empty, not certified) modes each point answers at once,
    else None (its paths are tracked all the same)."""
    why = start.reason or (
        f"trace residual {start.trace_residual:.1e} after {start.loops} monodromy loops"
    )
    for r in reasons:
        r.append(f"start system not proven complete: {why} (rebuild=True recomputes it)")
    if not certified_only:
        return None
    note = f"not certified: {reasons[0][0]}; its paths not tracked (certified_only)"
    return AssemblyModes(
        solutions=(),
        certified=False,
        root_count=int(start.root_count),
        report=note,
        certificates=(),
        method="homotopy",
    )
