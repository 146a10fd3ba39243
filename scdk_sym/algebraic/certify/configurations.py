"""Krawczyk certificates of a loaded model's configurations: the closure system
``g(y, theta) = 0`` as a square system (unknowns ``y`` in the local chart of the floating
joints; ``theta`` and the chart as exact parameters), one solution or several in one common
chart."""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from ...errors import InputError
from ...model.rotations import gibbs, rot_exp
from ...products import CLOSURE_FUNCTION
from .certificate import Certificate, CertificateSet
from .inputs import check_settings, real_array, real_vector
from .krawczyk_arb import TIGHTEN, TRIES
from .points import certify_batch, certify_sets, krawczyk
from .square import square_system

if TYPE_CHECKING:
    from ...robot import Model


def closure_function(model: Model) -> ca.Function:
    """The closure rows of ``model`` as a square system for :func:`krawczyk`.

    Args:
        model: a loaded model (``m`` unknowns, ``k`` actuated joints, ``f`` floating joints).

    Returns:
        The SX Function ``(y[m], q[k + 9 f]) -> g[m]`` of ``model.symbolic``, with the
        parameters ``q = [theta; c]`` (actuated values, then the chart: the reference rotations
        of the floating joints, column-major). Built once per model (``model.products``).
    """

    def build() -> ca.Function:
        s = model.symbolic
        q = ca.vertcat(s.theta, s.c)
        return ca.Function("closure", [s.y, q], [s.g], ["y", "q"], ["g"])

    return model.products.get(CLOSURE_FUNCTION, build)


def certify_solution(
    model: Model,
    y: ArrayLike,
    theta: ArrayLike,
    c: ArrayLike | None = None,
    *,
    tries: int = TRIES,
) -> Certificate:
    """Krawczyk certificate of one solution of the closure system of ``model``.

    Args:
        model: a loaded model.
        y: (m,) unknowns: canonical (``c`` None, e.g. ``SolveResult.y``) or local in the
            chart ``c``.
        theta: (k,) actuated values [rad or model length unit], exact.
        c: (9 f,) chart of the floating joints, or None to centre one on ``y``.
        tries: boxes tried.

    Returns:
        The certificate; its boxes are in the local chart coordinates of ``y`` (for models
        without floating joints, the joint coordinates themselves).
    """
    y = real_vector(y, model.m, "y")
    theta = real_vector(theta, model.k, "theta")
    if c is None:
        y, c = model.chart.to_local(y)
    c = real_vector(c, model.chart.size, "chart c")
    return krawczyk(closure_function(model), y, np.concatenate([theta, c]), tries=tries)


def certify_configurations(
    model: Model,
    ys: ArrayLike,
    theta: ArrayLike,
    c: ArrayLike | None = None,
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> CertificateSet:
    """Certify several solutions of the closure system of ``model`` at one ``theta``.

    Every solution is expressed in one chart (so that their boxes are comparable): the
    rotation of each floating joint in Rodrigues parameters relative to the chart ``c``.

    Args:
        model: a loaded model.
        ys: (N, m) canonical unknowns (e.g. ``[cfg.y for cfg in sc.assembly_modes(...)]``).
        theta: (k,) actuated values, exact.
        c: (9 f,) common chart; None: the chart centred on ``ys[0]``. No solution may be
            turned by a half turn relative to it.
        tries: boxes tried per solution.
        tighten: Krawczyk steps that shrink each proven enclosure.
        arithmetic: see :func:`krawczyk`.

    Returns:
        The :class:`CertificateSet` (boxes in the local coordinates of the common chart).
    """
    return certify_configuration_sets(
        model, [(ys, theta, c)], tries=tries, tighten=tighten, arithmetic=arithmetic
    )[0]


def certify_configuration_sets(
    model: Model,
    sets: list,
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> list[CertificateSet]:
    """:func:`certify_configurations` of several sets, e.g. the modes of several points of a
    map, the first boxes of all in one C call (the certificates are those of separate calls).

    Args:
        model: a loaded model.
        sets: S tuples ``(ys, theta, c)``, each as :func:`certify_configurations` takes them.
        tries: as :func:`certify_configurations`.
        tighten: as :func:`certify_configurations`.
        arithmetic: as :func:`certify_configurations`.

    Returns:
        S :class:`CertificateSet`.

    Raises:
        InputError: a set as :func:`certify_configurations` raises it.
    """
    check_settings(tries, tighten, arithmetic)
    batch = _local_sets(model, sets)
    if batch is not None:
        sq = square_system(closure_function(model))
        local, qs, sizes = batch
        params = [(q, np.stack([q, q], axis=1), True) for q in qs]
        bounds = np.repeat(np.stack([qs, qs], axis=2), sizes, axis=0)
        return certify_batch(sq, local, sizes, params, bounds, tries, tighten, arithmetic)
    xs_list, q_list = [], []  # one set after the other: the first bad one says what is wrong
    for ys, theta, c in sets:
        local, q = _local(model, ys, theta, c)
        xs_list.append(local)
        q_list.append(q)
    return certify_sets(
        closure_function(model), xs_list, q_list, tries=tries, tighten=tighten,
        arithmetic=arithmetic,
    )  # fmt: skip


def _local_sets(model: Model, sets: list) -> tuple | None:
    """:func:`_local` of every set at once, as it makes them set by set: the local
    coordinates of all configurations (N, m), each set's parameters (S, k + chart size) and
    sizes; ``None`` where some set is not plain valid input (:func:`_local` says why)."""
    if not sets:
        return None
    ys_list, thetas, charts = [], [], []
    for ys, theta, c in sets:
        if not (isinstance(ys, np.ndarray) and isinstance(theta, np.ndarray)):
            return None
        if ys.dtype != np.float64 or ys.ndim != 2 or ys.shape[1] != model.m:
            return None
        if theta.dtype != np.float64 or theta.shape != (model.k,):
            return None
        ys_list.append(ys)
        thetas.append(theta)
        charts.append(c)
    sizes = [len(ys) for ys in ys_list]
    Y = np.concatenate(ys_list)
    T = np.stack(thetas)
    if not (np.isfinite(Y).all() and np.isfinite(T).all()):
        return None
    size = model.chart.size
    C = np.zeros((len(sets), size))
    for i, (ys, c) in enumerate(zip(ys_list, charts, strict=True)):
        if c is None:
            C[i] = model.chart.to_local(ys[0])[1] if len(ys) else np.zeros(size)
        elif isinstance(c, np.ndarray) and c.dtype == np.float64 and c.shape == (size,):
            C[i] = c
        else:
            return None
    if not np.isfinite(C).all():
        return None
    local = _in_charts(model, Y, np.repeat(C, sizes, axis=0))
    if not np.all(np.abs(local) < 1e8):
        return None
    return local, np.concatenate([T, C], axis=1), sizes


def _in_charts(model: Model, ys: np.ndarray, charts: np.ndarray) -> np.ndarray:
    """Canonical unknowns ``ys`` (N, m) in the local coordinates of the charts (N, chart
    size), one per row: each floating joint's rotation in Rodrigues parameters relative to
    its reference rotation (all rows at once)."""
    local = ys.copy()
    for i, idx in enumerate(model.chart.rotations):
        ref = charts[:, 9 * i : 9 * i + 9].reshape(-1, 3, 3, order="F")
        local[:, list(idx)] = gibbs(ref.transpose(0, 2, 1) @ rot_exp(local[:, list(idx)]))
    return local


def _local(model: Model, ys: ArrayLike, theta: ArrayLike, c: ArrayLike | None) -> tuple:
    """Configurations ``ys`` in the common chart ``c`` and the closure's parameters
    ``[theta; c]`` (see :func:`certify_configurations`)."""
    ys = real_array(ys, "ys")
    if ys.ndim != 2 or ys.shape[1] != model.m or not np.all(np.isfinite(ys)):
        raise InputError(
            f"ys must be (N, {model.m}) finite canonical unknowns, got shape {ys.shape}; "
            f"pass one row per configuration"
        )
    theta = real_vector(theta, model.k, "theta")
    if c is None:
        c = model.chart.to_local(ys[0])[1] if len(ys) else np.zeros(model.chart.size)
    c = real_vector(c, model.chart.size, "chart c")
    local = _in_charts(model, ys, np.broadcast_to(c, (len(ys), len(c))))
    far = np.flatnonzero(~np.all(np.abs(local) < 1e8, axis=1))
    if far.size:
        raise InputError(
            f"configurations {far.tolist()} are turned by about a half turn from the chart; "
            f"pass a chart c nearer to them (e.g. certify them in separate sets)"
        )
    return local, np.concatenate([theta, c])
