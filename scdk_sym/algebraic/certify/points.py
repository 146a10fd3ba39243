"""Krawczyk certificates of points of one square CasADi system: one point (:func:`krawczyk`),
one set (:func:`certify_all`), several sets at their own parameters (:func:`certify_sets`).

The first box of every point is tested in binary64 intervals in C when the system is rational
(:mod:`scdk_sym.algebraic.certify.krawczyk_c`: all points in one call); the points it does not
prove go through the Arb test (:mod:`scdk_sym.algebraic.certify.krawczyk_arb`), which alone
tries more boxes and says why a test fails.
"""

from __future__ import annotations

from itertools import repeat

import casadi as ca
import numpy as np
from flint import ctx
from numpy.typing import ArrayLike

from ...errors import InputError
from ...results import unchecked_many
from .certificate import Certificate, CertificateSet
from .disjoint import certificate_set, sets_meeting
from .inputs import check_settings, parameter_balls, parameters, real_array, real_vector
from .krawczyk_arb import MAX_CONDITION, TIGHTEN, TINY, TRIES, arb_krawczyk
from .square import Square, square_system


def first_boxes(
    sq: Square, ms: np.ndarray, bounds: np.ndarray, tighten: int, arithmetic: str = "auto"
) -> list:
    """The first box of each point tested in binary64 intervals in C, all points in one call.

    Args:
        sq: the square system.
        ms: (N, n) points.
        bounds: (k, 2) or (N, k, 2) ``[lo, hi]`` of the parameters.
        tighten: most Krawczyk steps that shrink a proven enclosure.
        arithmetic: ``"auto"`` (the C test where it applies) or ``"arb"`` (none here).

    Returns:
        N certificates of the points the test proves, ``None`` for the others (and for all
        when the test does not apply: see :mod:`.krawczyk_c`; Arb at another precision than
        binary64's 53 bits asks for its own arithmetic).
    """
    if arithmetic != "auto" or sq.fast is None or ctx.prec != 53 or not len(ms):
        return [None] * len(ms)
    proven, r, box = sq.fast.test(ms, bounds, tighten, TINY, MAX_CONDITION)
    if not sq.n:
        return [None] * len(ms)
    # every point at once, as the Arb test makes them one by one
    domain = np.stack([np.nextafter(ms - r, np.inf), np.nextafter(ms + r, -np.inf)], axis=2)
    radius = np.max((box[:, :, 1] - box[:, :, 0]) / 2, axis=1)
    radius = np.where(np.isfinite(radius), radius, np.inf)
    box, ms = np.array(box), np.array(ms)  # owned, then read-only: the rows are not copied
    for a in (box, domain, ms):
        a.setflags(write=False)
    rows = np.flatnonzero(proven).tolist()
    r_max, radius = np.max(r, axis=1).tolist(), radius.tolist()
    every = len(rows) == len(ms)  # the usual case: the arrays' rows as they are
    certs = unchecked_many(
        Certificate, len(rows), proven=repeat(True), box=box if every else [box[i] for i in rows],
        # inside X = [m - r, m + r] rounded outward
        domain=domain if every else [domain[i] for i in rows],
        radius=radius if every else [radius[i] for i in rows],
        reason=[f"K(X) lies in the interior of X (radius {r_max[i]:.1e}): exactly one zero in X"
                for i in rows],
        x=ms if every else [ms[i] for i in rows], tries=repeat(1),
    )  # fmt: skip
    if every:
        return certs
    out: list = [None] * len(ms)
    for i, cert in zip(rows, certs, strict=True):
        out[i] = cert
    return out


def krawczyk(
    f: ca.Function,
    x: ArrayLike,
    p: ArrayLike = (),
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> Certificate:
    """Prove (or fail to prove) that one zero of ``f(., p)`` lies in a small box around ``x``.

    Args:
        f: square system, a CasADi SX Function ``(x[n]) -> f[n]`` or ``(x[n], p[k]) -> f[n]``
            (output 0; an MX Function is expanded).
        x: (n,) approximate zero: the centre of every box tried.
        p: (k,) parameter values, exact; or (k, 2) ``[lo, hi]`` bounds (the statement then
            holds for every ``p`` in the box).
        tries: boxes tried (the first from the Newton correction at ``x``, then inflated).
        tighten: at most this many Krawczyk steps shrink a proven enclosure wider than a few
            ulps (from a rough ``x``), each centred on the previous enclosure; they stop after
            a step that does not halve the enclosure's largest radius, and do not start when
            it is within twice the interval Newton point's (the rounding's floor: near a
            singular point ``cond(J) eps`` is wide, and more steps gain little).
        arithmetic: ``"auto"``: the first box in binary64 interval arithmetic in C where ``f``
            is rational (:mod:`scdk_sym.algebraic.certify.krawczyk_c`), Arb balls if it
            proves nothing; ``"arb"``: Arb balls only (see
            :data:`~scdk_sym.algebraic.certify.inputs.ARITHMETICS`).

    Returns:
        The :class:`Certificate` (``proven`` False with a ``reason`` where the test fails: a
        singular Jacobian at ``x``, or ``K(X)`` not inside ``X`` for every box tried).

    Raises:
        InputError: ``f`` is not a square system, ``x``/``p`` have the wrong size, or an
            unknown ``arithmetic``.
        IntervalError: ``f`` uses an operation without an interval counterpart.
    """
    check_settings(tries, tighten, arithmetic)
    sq = square_system(f)
    m = real_vector(x, sq.n, "x")
    p_mid, bounds, exact = parameters(p, sq.n_params)
    fast = first_boxes(sq, m[None], bounds, tighten, arithmetic)[0]
    if fast is not None:
        return fast
    return arb_krawczyk(sq, m, parameter_balls(bounds, exact), p_mid, tries, tighten)


def certify_all(
    f: ca.Function,
    xs: ArrayLike,
    p: ArrayLike = (),
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> CertificateSet:
    """Certify several approximate zeros of one system and check that they are distinct.

    Args:
        f: square system (see :func:`krawczyk`).
        xs: (N, n) approximate zeros.
        p: parameters (see :func:`krawczyk`), shared by every solution.
        tries: boxes tried per solution.
        tighten: Krawczyk steps that shrink each proven enclosure.
        arithmetic: see :func:`krawczyk` (``"auto"``: every point's first box in one C
            call).

    Returns:
        The :class:`CertificateSet`: ``proven`` when every solution is proven and every pair
        of boxes is disjoint (then ``count == N`` distinct real zeros).
    """
    return certify_sets(f, [xs], [p], tries=tries, tighten=tighten, arithmetic=arithmetic)[0]


def certify_sets(
    f: ca.Function,
    xs_list: list,
    p_list: list,
    *,
    tries: int = TRIES,
    tighten: int = TIGHTEN,
    arithmetic: str = "auto",
) -> list[CertificateSet]:
    """:func:`certify_all` of several sets of one system, each at its own parameters; the
    first box of every point of every set in one C call (the certificates are those of
    separate calls).

    Args:
        f: square system (see :func:`krawczyk`).
        xs_list: S arrays (N_s, n) of approximate zeros.
        p_list: S parameter vectors (or bounds), one per set (see :func:`krawczyk`).
        tries: as :func:`certify_all`.
        tighten: as :func:`certify_all`.
        arithmetic: as :func:`certify_all`.

    Returns:
        S :class:`CertificateSet`.

    Raises:
        InputError: not one parameter vector per set, or a set or vector as
            :func:`certify_all` refuses it.
    """
    check_settings(tries, tighten, arithmetic)
    if len(xs_list) != len(p_list):
        raise InputError(
            f"{len(xs_list)} sets of zeros and {len(p_list)} parameter vectors; pass one "
            "parameter vector per set"
        )
    sq = square_system(f)
    sets, params = [], []
    for xs, p in zip(xs_list, p_list, strict=True):
        xs = real_array(xs, "xs")
        if xs.ndim != 2:
            raise InputError(f"xs must be (N, n) approximate zeros, got shape {xs.shape}")
        if xs.shape[1] == sq.n and np.all(np.isfinite(xs)):
            ms = np.ascontiguousarray(xs)
        else:  # the first bad row says what is wrong
            ms = np.array([real_vector(x, sq.n, "x") for x in xs]).reshape(len(xs), sq.n)
        sets.append(ms)
        params.append(parameters(p, sq.n_params))
    if not sets:
        return []
    sizes = [len(ms) for ms in sets]
    bounds = np.concatenate(
        [np.broadcast_to(b, (n, *b.shape)) for (_, b, _), n in zip(params, sizes, strict=True)]
    )
    return certify_batch(sq, np.concatenate(sets), sizes, params, bounds, tries, tighten,
                         arithmetic)  # fmt: skip


def certify_batch(
    sq: Square,
    ms_all: np.ndarray,
    sizes: list[int],
    params: list,
    bounds: np.ndarray,
    tries: int,
    tighten: int,
    arithmetic: str,
) -> list[CertificateSet]:
    """:func:`certify_sets` of checked input, the first boxes of all points in one C call.

    Args:
        sq: the square system.
        ms_all: (N, n) the points of all sets, set after set.
        sizes: S points per set.
        params: S parameters of the sets, as :func:`~.inputs.parameters` returns them.
        bounds: (N, k, 2) every point's parameter bounds.
        tries: boxes tried per point.
        tighten: Krawczyk steps that shrink each proven enclosure.
        arithmetic: see :func:`krawczyk`.

    Returns:
        S :class:`~scdk_sym.algebraic.certify.certificate.CertificateSet`.
    """
    fast = first_boxes(sq, ms_all, bounds, tighten, arithmetic)  # all points in one call
    meets = sets_meeting(fast, sizes)
    out, start = [], 0
    for size, (p_mid, b, exact), meet in zip(sizes, params, meets, strict=True):
        ms = ms_all[start : start + size]
        ours = fast[start : start + size]
        P = parameter_balls(b, exact) if any(c is None for c in ours) else []
        certs = tuple(
            c if c is not None else arb_krawczyk(sq, m, P, p_mid, tries, tighten)
            for c, m in zip(ours, ms, strict=True)
        )
        start += len(ms)
        out.append(certificate_set(certs, disjoint=not meet))
    return out
