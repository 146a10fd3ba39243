"""Assembly modes of a model with rods between ball joints, from its distance model.

The distance model (:func:`scdk_sym.robot.rods.distance_model`) has the model's unknowns but
the rods' angles, and one distance row per rod: its real solutions are the assemblies of the
model's links, each once, where the model's own unknowns count every assembly once per
representation of its balls' angles (two per revolute triple). Its modes are solved and
certified as any model's; each is lifted to the model (:func:`scdk_sym.robot.rods.lift`),
verified on the model's rows and certified again there by the caller.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..results import AssemblyModes, Configuration
from ..robot import Model
from ..robot.rods import Rod, lift


def lifted_modes(
    model: Model,
    rods: tuple[Rod, ...],
    reduced: Model,
    found: AssemblyModes,
    theta0: np.ndarray,
    certify: Callable[[list[Configuration], list[str]], tuple],
) -> AssemblyModes:
    """The model's modes from its distance model's.

    Args:
        model: the model.
        rods: its rods.
        reduced: its distance model.
        found: the distance model's modes at ``theta0``.
        theta0: (k,) actuated values [rad or model length unit].
        certify: ``(configurations, reasons) -> certificates`` on the model (a failure
            appended to ``reasons``).

    Returns:
        The lifted configurations sorted as ``found``'s, certified when ``found`` is, every
        lift closes and every lifted configuration is certified on the model.
    """
    cfgs: list[Configuration] = []
    reasons: list[str] = []
    for cfg in found:
        y = lift(model, rods, reduced, cfg.y, theta0)
        if y is None or model.residual(y, theta0) > model.tolerance:
            reasons.append(f"the rods of the solution {np.round(cfg.y, 6).tolist()} do not close")
            continue
        cfgs.append(model.configuration(y, theta0))
    certs = certify(cfgs, reasons) if found.certified and not reasons else ()
    what = (
        f"{len(rods)} rod(s) between ball joints solved as distances (each assembly once, its "
        "rods' angles lifted from home)"
    )
    certified = found.certified and not reasons
    report = f"{what}; " + (found.report if certified else "not certified: " + "; ".join(
        reasons or [found.report.removeprefix("not certified: ")]))  # fmt: skip
    return AssemblyModes(
        solutions=tuple(cfgs),
        certified=certified,
        root_count=found.root_count,
        report=report,
        certificates=certs,
        method="homotopy",
    )
