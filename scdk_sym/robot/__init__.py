"""Loaded models: a description (:mod:`scdk_sym.model`) with its symbolic system and kernels,
reduced to a square closure system and assembled at home."""

from .loading import load_model, model_from_tree
from .model import Model
from .validation import as_vector

__all__ = ["Model", "as_vector", "load_model", "model_from_tree"]
