"""All assembly modes: every real direct-kinematics solution at one joint reading.

:func:`assembly_modes` runs one of two methods: the parameter homotopy with its proof
(:mod:`scdk_sym.solvers.homotopy_modes`, the default) or the real-curve search
(:mod:`scdk_sym.solvers.curve_modes`, never certified).
"""

from __future__ import annotations

from typing import Any

from numpy.typing import ArrayLike

from ..backends import DEFAULTS, resolve
from ..errors import InputError
from ..results import AssemblyModes
from ..robot import Model
from .curve_modes import (  # noqa: F401  (the curve search's names, also importable from here)
    Curve,
    CurveOptions,
    ModeSearch,
    RandomStarts,
    StoppingRule,
    curve_kernels,
    curves_result,
    explore,
    follow_curve,
)
from .query import target

#: Methods of :func:`assembly_modes`.
METHODS = ("homotopy", "curves")
_CURVE_DEFAULTS = {"time_budget": None, "start": None, "patience": 8, "cover": 2, "max_curves": 400}


def assembly_modes(
    model: Model,
    theta0: ArrayLike,
    *,
    method: str = "homotopy",
    seed: int = 0,
    progress: bool = False,
    backend: str | None = None,
    **options: Any,
) -> AssemblyModes:
    """All real direct-kinematics solutions (assembly modes) at ``theta0``.

    ``method="homotopy"`` (default) lists every real solution with a proof
    (:func:`scdk_sym.solvers.homotopy_modes.homotopy_modes`): a parameter homotopy on the
    model's algebraic form from a start system proven complete by a trace test, every real
    endpoint polished on the model's rows and certified by a Krawczyk test, the boxes pairwise
    disjoint. ``sols.certified`` says whether all of it held; ``sols.report`` says what was
    proven or why not. The first call per model computes the start system (seconds to a
    minute; cached on disk), later calls only track its paths.

    ``method="curves"`` is the real-curve search
    (:func:`~scdk_sym.solvers.curve_modes.explore`): it follows singularity-consistent
    solution curves from the start configuration and from random starts until a heuristic
    stopping rule holds. It can miss solutions on curves it never
    enters and cannot know it missed them: its result is never ``certified``.

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        method: ``"homotopy"`` or ``"curves"``.
        seed: seed of the random choices (start system and retry gammas; curve directions and
            starts).
        progress: show a progress bar (tqdm) on stderr (the monodromy's loops; the curves).
        backend: a name of :mod:`scdk_sym.backends`: ``"auto"``, ``"cvodes"`` or
            ``"compiled"``; default (``None``): ``"auto"`` for the homotopy (generated C when
            a C compiler is found), ``"cvodes"`` for the curves.
        **options: curves only: ``time_budget`` (wall-time limit [s]), ``start`` (assembled
            start configuration(s), default ``model.home``), ``patience`` (curves of each kind
            in a row without a new solution before stopping, 8), ``cover`` (times each known
            solution must be met again, 2), ``max_curves`` (400). Homotopy only:
            ``max_loops`` (bound on the monodromy loops), ``cache`` (disk cache of the start
            system, True), ``rebuild`` (compute the start system again even if a proven or a
            failed one is cached, False), ``certified_only`` (return at once, with no
            solutions, when a start system is not proven complete, False).

    Returns:
        :class:`~scdk_sym.results.AssemblyModes`: a sequence of
        :class:`~scdk_sym.results.Configuration` (``theta = theta0``), each verified, distinct
        and sorted by ``x`` then ``y`` (rounded to 1e-8), with ``certified``, ``root_count``,
        ``report`` and ``certificates``.

    Raises:
        InputError: bad ``theta0``, method, option, budget, counts or backend.
        NotAssembledError: a start configuration of the curve search is not assembled.
        AlgebraicFormError: (homotopy) a joint type with no algebraic form.
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; methods: {', '.join(METHODS)}")
    if method == "homotopy":
        from .homotopy_modes import homotopy_modes

        extra = set(options) - {"max_loops", "cache", "rebuild", "certified_only"}
        if extra:
            raise InputError(
                f"option(s) {', '.join(sorted(extra))} belong to method='curves'; the homotopy "
                "takes seed, progress, backend, max_loops, cache, rebuild, certified_only"
            )
        from .block_modes import block_modes, split

        chosen = resolve(backend or DEFAULTS["modes"], "modes")
        parts = split(model)
        if parts is not None:
            theta = target(model, theta0)
            return block_modes(
                model, theta, parts[0], parts[1], seed=seed, progress=progress, backend=chosen,
                **options,
            )  # fmt: skip
        return homotopy_modes(
            model, theta0, seed=seed, progress=progress, backend=chosen, **options
        )
    extra = set(options) - set(_CURVE_DEFAULTS)
    if extra:
        raise InputError(
            f"unknown option(s) {', '.join(sorted(extra))} for method='curves'; "
            f"options: {', '.join(_CURVE_DEFAULTS)}"
        )
    given = {**_CURVE_DEFAULTS, **options}
    search = explore(
        model,
        theta0,
        seed=seed,
        progress=progress,
        backend=resolve(backend or DEFAULTS["curves"], "curves"),
        start=given["start"],
        time_budget=given["time_budget"],
        rule=StoppingRule(given["patience"], given["cover"], given["max_curves"]),
    )
    return curves_result(search)
