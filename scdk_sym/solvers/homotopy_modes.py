"""All real assembly modes with a proof: parameter homotopy from a certified start system.

The pipeline of :func:`homotopy_modes`:

1. the model's algebraic form ``G(z, p) = 0`` (:func:`scdk_sym.algebraic.algebraic_form`,
   generated C when a C compiler is present);
2. its start system: every complex solution at one random complex parameter point, by
   monodromy, proven complete (cached on disk under the form's content hash) when the
   number of distinct regular roots found equals the form's BKK root bound
   (:mod:`scdk_sym.algebraic.rootbound`), or else by a trace test
   (:func:`scdk_sym.algebraic.trace_test`). The traced functions are the entries of
   the placement of the model's frame (translation and rotation), which stay finite where a
   quaternion chart does not;
3. the parameter homotopy from there to ``params(theta0)``
   (:func:`scdk_sym.algebraic.solve_homotopy`): every isolated solution at ``theta0`` is an
   endpoint;
4. real endpoints -> the model's unknowns, Newton-polished on the model's own closure rows
   ``g`` (max |g| <= :data:`~scdk_sym.solvers.mode_polish.RESIDUAL` verified), deduplicated
   and sorted as the curve search sorts them;
5. each one certified by a Krawczyk test on ``g`` in one common chart, the boxes pairwise
   disjoint (:func:`scdk_sym.algebraic.certify_configurations`).

The steps are modules of their own: the start system and its disk cache
(:mod:`~scdk_sym.solvers.start_system`, its traced maps in :mod:`~scdk_sym.solvers.form_maps`),
the continuation from a neighbour's root set (:mod:`~scdk_sym.solvers.mode_neighbours`), the
polish (:mod:`~scdk_sym.solvers.mode_polish`), the certificates
(:mod:`~scdk_sym.solvers.mode_certify`) and the report (:mod:`~scdk_sym.solvers.mode_report`);
this module runs them for one point or a batch.

The result is certified only when every link of that chain holds; otherwise its ``report``
names the first one that does not. All work is bounded (monodromy loops, tracker steps,
homotopy attempts, Newton steps).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..backends import resolve
from ..errors import InputError
from ..results import AssemblyModes
from ..robot import Model, as_vector
from ..robot.rods import rod_reduction
from .mode_certify import certificates_many, certifier
from .mode_neighbours import ModeSeed, complete_set, from_neighbours
from .mode_polish import real_modes
from .mode_report import REAL_TOL, path_reasons_many, point_modes, unproven_start
from .query import target
from .rod_modes import lifted_modes
from .start_system import MAX_LOOPS, model_start_system


@dataclass(frozen=True)
class ModesOptions:
    """The options of a batch of certified mode queries (see :func:`homotopy_modes`).

    Attributes:
        seed: seed of the start system and of the gammas of the homotopy's retries.
        progress: progress bar while the start system is computed.
        backend: the kernels of the algebraic form (see :mod:`scdk_sym.backends`).
        max_loops: bound on the monodromy loops of the start system.
        cache: read and write the start system's disk cache.
        rebuild: compute the start system again even if one is cached.
        certified_only: when the start system is not proven complete, answer at once (no
            solutions, not certified) instead of tracking its paths.
        seeds: test each point's set for completeness, to pass it on to a neighbour.
    """

    seed: int = 0
    progress: bool = False
    backend: str = "auto"
    max_loops: int = MAX_LOOPS
    cache: bool = True
    rebuild: bool = False
    certified_only: bool = False
    seeds: bool = True


def homotopy_modes(
    model: Model,
    theta0: ArrayLike,
    *,
    seed: int = 0,
    progress: bool = False,
    backend: str = "auto",
    max_loops: int = MAX_LOOPS,
    cache: bool = True,
    rebuild: bool = False,
    certified_only: bool = False,
) -> AssemblyModes:
    """Every real assembly mode at ``theta0``, with a certificate of completeness.

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        seed: seed of the start system and of the gammas of the homotopy's retries.
        progress: progress bar while the start system is computed (first call per model).
        backend: ``"auto"`` (generated C when a C compiler is found), ``"cvodes"`` (SX
            kernels) or ``"compiled"``; see :mod:`scdk_sym.backends`.
        max_loops: bound on the monodromy loops of the start system.
        cache: read and write the start system's disk cache.
        rebuild: compute the start system again even if one (proven or failed) is cached.
        certified_only: for callers that use only a certified set: when the start system is
            not proven complete, return at once (no solutions, not certified, the report
            saying why) instead of tracking its paths.

    Returns:
        :class:`~scdk_sym.results.AssemblyModes` (see the module documentation).

    Raises:
        InputError: bad ``theta0`` or backend.
        AlgebraicFormError: a joint type with no algebraic form.
    """
    theta0 = target(model, theta0)
    options = ModesOptions(seed, progress, backend, max_loops, cache, rebuild, certified_only,
                           seeds=False)  # fmt: skip
    modes, _, _ = modes_many(model, theta0[None], [None], options)[0]
    return modes


def modes_from_neighbour(
    model: Model, theta0: ArrayLike, neighbour: ModeSeed | None, *, backend: str = "compiled"
) -> tuple[AssemblyModes, ModeSeed | None, bool]:
    """The certified assembly modes at ``theta0`` from a neighbouring point's complete root
    set: one step of a mode map.

    The neighbour's R roots (R the start system's root count, every one regular and distinct:
    its set is complete) are tracked to ``params(theta0)`` along an arc through complex
    parameters (:data:`NEIGHBOUR_GAMMA`). When every path ends regular and the R ends are
    pairwise distinct, they are all the isolated roots at ``theta0`` (R bounds their number),
    and the rest is :func:`homotopy_modes`' chain (real ends polished on the model's rows,
    each proven by a Krawczyk test). Otherwise (or without a neighbour) the homotopy runs from
    the start system, as :func:`homotopy_modes` does.

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        neighbour: the complete root set of a neighbouring point, or None.
        backend: as for :func:`homotopy_modes`.

    Returns:
        ``(modes, seed, continued)``: the :class:`~scdk_sym.results.AssemblyModes` at
        ``theta0``; its complete root set for the next point (None when the ends are not R
        distinct regular roots); whether the neighbour's set was used.
    """
    theta0 = target(model, theta0)
    return modes_many(model, theta0[None], [neighbour], ModesOptions(backend=backend))[0]


def modes_from_neighbours(
    model: Model,
    thetas: ArrayLike,
    neighbours: list[ModeSeed | None],
    *,
    backend: str = "compiled",
) -> list[tuple[AssemblyModes, ModeSeed | None, bool]]:
    """:func:`modes_from_neighbour` at several points at once (e.g. one front of a mode map):
    the paths of all points tracked in one batch, the real ends of all polished and
    certified in batches. Every point's answer is the one :func:`modes_from_neighbour` gives.

    Args:
        model: the model.
        thetas: (W, k) actuated joint values [rad or model length unit].
        neighbours: W complete root sets of neighbouring points (None where there is none).
        backend: as for :func:`homotopy_modes`.

    Returns:
        W ``(modes, seed, continued)`` as :func:`modes_from_neighbour` returns them.

    Raises:
        InputError: ``thetas`` is not (W, k) finite values, or not one neighbour per point.
    """
    th = np.asarray(thetas, dtype=float)
    if th.ndim != 2 or th.shape[1] != model.k or len(neighbours) != len(th):
        raise InputError(
            f"thetas must be (W, {model.k}) actuated values with one neighbour each, got shape "
            f"{th.shape} and {len(neighbours)} neighbours"
        )
    for bad in th[~np.isfinite(th).all(axis=1)][:1]:  # its error says what is wrong
        as_vector(bad, model.k, f"theta ({', '.join(model.actuated)})")
    return modes_many(model, th, list(neighbours), ModesOptions(backend=backend))


def modes_many(
    model: Model, thetas: np.ndarray, neighbours: list[ModeSeed | None], options: ModesOptions
) -> list[tuple[AssemblyModes, ModeSeed | None, bool]]:
    """The modes at each of W points (W, k): from its neighbour's set where that gives a
    complete set (all such points in one batch), else from the start system; with
    ``options.seeds`` False no point's set is tested for completeness, and only those from a
    neighbour are returned as seeds (a single query does not pass its set on)."""
    from ..algebraic import algebraic_form, solve_homotopy
    from ..algebraic.scaled import scaled_form

    rods, reduced = rod_reduction(model)
    if reduced is not None:  # rods between balls: the distance model's modes, lifted
        distances = modes_many(reduced, thetas, neighbours, options)
        return [
            (
                lifted_modes(model, rods, reduced, modes, th, certifier(model, th)),
                seed_out,
                used,
            )  # fmt: skip
            for (modes, seed_out, used), th in zip(distances, thetas, strict=True)
        ]
    seed = options.seed
    form = scaled_form(algebraic_form(model, resolve(options.backend, "modes")))
    start = model_start_system(
        form, seed, progress=options.progress, max_loops=options.max_loops, cache=options.cache,
        rebuild=options.rebuild,
    )  # fmt: skip
    W = len(thetas)
    reasons: list[list[str]] = [[] for _ in range(W)]
    if not start.trace_passed:
        skipped = unproven_start(start, reasons, options.certified_only)
        if skipped is not None:
            return [(skipped, None, False)] * W
    P0 = np.stack([form.params(th) for th in thetas])
    results, continued = from_neighbours(form, start, neighbours, P0)
    complete = list(continued)
    for w in range(W):
        if results[w] is None:
            results[w] = solve_homotopy(form, start, P0[w], seed=seed, real_tol=REAL_TOL)
            complete[w] = (
                options.seeds and start.trace_passed and complete_set(results[w], start.root_count)
            )
    half_turns = path_reasons_many(form, results, thetas, reasons)
    found = real_modes(model, form, results, thetas, reasons)
    certs = certificates_many(model, [ys for _, _, ys in found], thetas, reasons)
    out = []
    for w in range(W):
        modes = point_modes(start, found[w], certs[w], reasons[w], half_turns[w],
                            continued[w])  # fmt: skip
        out.append((modes, ModeSeed(P0[w], results[w].endpoints) if complete[w] else None,
                    continued[w]))  # fmt: skip
    return out
