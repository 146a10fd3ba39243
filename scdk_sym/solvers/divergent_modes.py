"""The divergent answer chosen among every real solution at ``theta0``.

The ``"modes"`` way of the divergent branch (:mod:`scdk_sym.solvers.divergent`): where the
paths from the start miss it, the answer across the nearest singular configuration is picked
from the certified assembly modes (:func:`scdk_sym.solvers.modes.assembly_modes`), and the
singular surface crossed is located between it and the start's side.
"""

from __future__ import annotations

from ..errors import ScdkError
from ..follower.surface import det_sign
from ..results import SolveResult
from .result import on_path, solve_result


def across_by_modes(
    model, theta0, start, sign, fold, convergent, backend, tried
) -> SolveResult | None:
    """The ``modes`` way of :func:`~scdk_sym.solvers.divergent.divergent`: the real solution at
    ``theta0`` on the other side of ``fold`` nearest to it, chosen among every real solution
    (certified assembly modes).

    Where no singular configuration was found near the start (``fold`` None: the descent
    stopped at a local minimum of ``sigma_min``), the candidate is the solution with
    ``det J_p`` of the other sign nearest to the start, and the singular surface crossed is
    located from the configuration midway between it and the convergent answer (or the
    start): near a fold the two sheets are mirror images, so the midpoint lies next to it;
    where ``sigma_min`` has no singular minimum near it either, by Gauss-Newton onto the
    singular manifold from the midpoint (:func:`~scdk_sym.follower.nearest.singular_from`:
    a singular configuration, not necessarily the nearest).
    """
    from ..follower.nearest import nearest_singular, singular_from
    from ..follower.other_sheet import nearest_across
    from ..robot.rods import rod_reduction, seat
    from .modes import assembly_modes

    try:
        # the default (generated C where a compiler is found) whatever the solve's kernels:
        # the first call per model computes its start system (seconds: about 9 s for
        # Gepetto's robot_delta), cached on disk, proven or not
        sols = assembly_modes(model, theta0, certified_only=True)
    except ScdkError as exc:
        tried.append(f"every real solution at theta0: {exc}")
        return None
    if not sols.certified:
        tried.append("every real solution at theta0: the set is not certified complete")
        return None
    conv = convergent()
    anchor = start if fold is None else fold
    candidates = [cfg.y for cfg in sols]
    rods, _ = rod_reduction(model)
    if rods:  # one configuration per assembly: its balls' angles as the anchor's continue
        seated = [seat(model, rods, y, theta0, anchor.y) for y in candidates]
        candidates = [y if s is None else s for y, s in zip(candidates, seated, strict=True)]
    best = nearest_across(
        model,
        anchor.y,
        theta0,
        [(y, []) for y in candidates],
        det_sign(model, start),
        any_sign=fold is not None and fold.kind != "fold",
        exclude=None if conv is None else conv.configuration,
    )
    if best is None:
        tried.append(
            f"every real solution at theta0 ({len(sols)}, certified): none on the other side"
        )
        return None
    if fold is None:
        near = conv if conv is not None else start
        mid = model.configuration(0.5 * (near.y + best[0].y), 0.5 * (near.theta + theta0))
        for seed in (mid, best[0]):
            fold = nearest_singular(model, seed, backend)
            if fold is not None:
                break
        else:  # sigma_min has a non-singular local minimum there (the Delta near home)
            fold = singular_from(model, mid, backend)
        if fold is None:
            tried.append("every real solution at theta0: no singular surface located between")
            return None
    crossing = on_path(fold, start, theta0)
    return solve_result(model, best[0].y, theta0, (crossing,), "divergent", -sign, start, None)
