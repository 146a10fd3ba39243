"""Polynomial maps of the roots of a model's algebraic form, evaluated at complex points.

What the certified modes evaluate on complex roots besides the form itself: the placements of
the model's frame and closure frames (the functions a start system's trace test traces:
:func:`frame_trace_map`), and the traces of ``R_a^T R_b`` of its 6d closures, which tell the
roots that close a weld with a half turn (:func:`weld_traces`).
"""

from __future__ import annotations

import casadi as ca
import numpy as np


def _complex_map(form, p: np.ndarray, name: str, entries):
    """``f(z (N, n)) -> (N, E)`` complex: ``entries(T)`` (SX, a function of the links' world
    placements ``T``, link name -> (4, 4) SX, polynomial in ``z``) at fixed parameters ``p``."""
    from ..algebraic.pairs import complexify
    from ..algebraic.polynomial import polynomial_joint_values, polynomial_motion

    model = form.model
    z, ps = ca.SX.sym("z", form.n), ca.SX.sym("p", form.n_params)
    values, _ = polynomial_joint_values(model, form.rows.slots, z, ps)
    T = {model.tree.root: ca.SX.eye(4)}
    for j in model.tree.joints:
        M = T[j.parent] @ ca.DM(j.origin)
        if j.movable:
            M = M @ polynomial_motion(j.type, j.axis, values[j.name])
        T[j.child] = M
    F = complexify(ca.Function(name, [z, ps], [entries(T)]), f"{name}_c")
    p = np.asarray(p, dtype=complex)

    def evaluate(Z: np.ndarray) -> np.ndarray:
        Z = np.atleast_2d(Z)
        N = len(Z)
        out = F.map(N)(Z.real.T, Z.imag.T, np.tile(p.real[:, None], (1, N)),
                       np.tile(p.imag[:, None], (1, N)))  # fmt: skip
        return (np.array(out[0]) + 1j * np.array(out[1])).T

    return evaluate


def frame_trace_map(form, p: np.ndarray):
    """The traced functions of a form: placements of the model frame and the closure frames.

    The closure rows are polynomials in these placements (linear for point closures), so
    their trace along an offset pencil is a polynomial of low degree where a plain chart
    coordinate would have poles.

    Args:
        form: an :class:`~scdk_sym.algebraic.form.AlgebraicForm`.
        p: (n_params,) complex parameters held fixed along the trace pencil.

    Returns:
        ``f(z) -> (N, 12 F)`` complex: translation and rotation entries of the ``F`` frames,
        polynomial in ``z``.
    """
    model = form.model
    frames = [model.frame] + [f for cl in model.closures for f in (cl.frame_a, cl.frame_b)]

    def entries(T):
        out = ca.vertcat(*[ca.vec(T[f][:3, :]) for f in dict.fromkeys(frames)])
        return out / model.length_scale

    return _complex_map(form, p, "frames", entries)


def weld_traces(form, p: np.ndarray):
    """The traces of ``R_a^T R_b`` of the model's 6d closures, as polynomial maps of ``z``.

    A 6d closure's rotation rows ``vee(R_a^T R_b) = 0`` hold exactly where ``R_a^T R_b`` is
    symmetric, i.e. (an orthogonal matrix, complex or real) the identity, of trace 3, or a
    half turn, of trace -1. Trace being continuous and two valued on that set, a connected
    set of roots of the form keeps one trace: a component on which it is -1 holds no closure
    of the model, real or complex.

    Args:
        form: an :class:`~scdk_sym.algebraic.form.AlgebraicForm` (scaled or not).
        p: (n_params,) complex parameters.

    Returns:
        ``f(z (N, n)) -> (N, W)`` complex traces, one column per 6d closure (``W`` may be 0).
    """
    welds = [cl for cl in form.model.closures if cl.type == "6d"]

    def entries(T):
        traces = [ca.trace(T[cl.frame_a][:3, :3].T @ T[cl.frame_b][:3, :3]) for cl in welds]
        return ca.vertcat(*traces, 0)

    f = _complex_map(form, p, "welds", entries)
    return lambda Z: f(Z)[:, : len(welds)]
