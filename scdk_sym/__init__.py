"""scdk_sym: singularity-consistent direct kinematics of closed-chain manipulators."""

from . import builders
from .errors import ScdkError
from .model.model import Model, load_model
from .results import Configuration, Crossing, SolveResult

__all__ = [
    "Configuration",
    "Crossing",
    "Model",
    "ScdkError",
    "SolveResult",
    "builders",
    "load_model",
]
