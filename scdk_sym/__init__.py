"""scdk_sym: singularity-consistent direct kinematics of closed-chain manipulators."""

from . import builders
from .atlas import atlas
from .errors import ScdkError
from .model.model import Model, load_model
from .results import Configuration, Crossing, SolveResult, TrackResult
from .solvers.modes import assembly_modes
from .solvers.sc import solve
from .solvers.track import track

__all__ = [
    "Configuration",
    "Crossing",
    "Model",
    "ScdkError",
    "SolveResult",
    "TrackResult",
    "assembly_modes",
    "atlas",
    "builders",
    "load_model",
    "solve",
    "track",
]
