"""scdk_sym: singularity-consistent direct kinematics of closed-chain manipulators.

The public names are imported on first use, so that importing a lower layer (for instance
:mod:`scdk_sym.model`, the description without CasADi) does not load the whole package.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from . import builders
    from .atlases import atlas, open_atlas
    from .errors import ScdkError
    from .results import Configuration, Crossing, SolveResult, TrackResult
    from .robot import Model, load_model
    from .solvers.batch import SolveBatch, solve_many
    from .solvers.modes import assembly_modes
    from .solvers.solve import solve
    from .solvers.track import track
    from .solvers.transmission import Transmission, transmission
    from .verify.report import VerifyReport, verify_model

#: Public name -> (module, attribute; ``None`` for the module itself).
_PUBLIC: dict[str, tuple[str, str | None]] = {
    "Configuration": (".results", "Configuration"),
    "Crossing": (".results", "Crossing"),
    "Model": (".robot", "Model"),
    "ScdkError": (".errors", "ScdkError"),
    "SolveResult": (".results", "SolveResult"),
    "TrackResult": (".results", "TrackResult"),
    "assembly_modes": (".solvers.modes", "assembly_modes"),
    "atlas": (".atlases", "atlas"),
    "builders": (".builders", None),
    "load_model": (".robot", "load_model"),
    "open_atlas": (".atlases", "open_atlas"),
    "solve": (".solvers.solve", "solve"),
    "solve_many": (".solvers.batch", "solve_many"),
    "SolveBatch": (".solvers.batch", "SolveBatch"),
    "track": (".solvers.track", "track"),
    "Transmission": (".solvers.transmission", "Transmission"),
    "transmission": (".solvers.transmission", "transmission"),
    "VerifyReport": (".verify.report", "VerifyReport"),
    "verify_model": (".verify.report", "verify_model"),
}

__all__ = [
    "Configuration",
    "Crossing",
    "Model",
    "ScdkError",
    "SolveResult",
    "TrackResult",
    "VerifyReport",
    "assembly_modes",
    "atlas",
    "builders",
    "load_model",
    "open_atlas",
    "solve",
    "solve_many",
    "SolveBatch",
    "track",
    "transmission",
    "Transmission",
    "verify_model",
]


def __getattr__(name: str) -> Any:
    try:
        module, attr = _PUBLIC[name]
    except KeyError:
        raise AttributeError(f"module 'scdk_sym' has no attribute {name!r}") from None
    mod = importlib.import_module(module, __name__)
    value = mod if attr is None else getattr(mod, attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
