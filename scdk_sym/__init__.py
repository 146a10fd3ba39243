"""scdk_sym: singularity-consistent direct kinematics of closed-chain manipulators.

The public names are imported on first use, so that importing a lower layer (for instance
:mod:`scdk_sym.model`, the description without CasADi) does not load the whole package.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from . import builders
    from .atlas import atlas
    from .errors import ScdkError
    from .results import Configuration, Crossing, SolveResult, TrackResult
    from .robot import Model, load_model
    from .solvers.modes import assembly_modes
    from .solvers.sc import solve
    from .solvers.track import track
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
    "atlas": (".atlas", "atlas"),
    "builders": (".builders", None),
    "load_model": (".robot", "load_model"),
    "solve": (".solvers.sc", "solve"),
    "track": (".solvers.track", "track"),
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
    "solve",
    "track",
    "verify_model",
]


class _Package(types.ModuleType):
    """The package module: a subpackage named like a public function (``atlas``) stays the
    function when the import system binds the subpackage on its first import."""

    def __setattr__(self, name: str, value: Any) -> None:
        module, attr = _PUBLIC.get(name, ("", None))
        if attr is not None and getattr(value, "__name__", "") == f"{__name__}{module}":
            value = getattr(value, attr)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


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
