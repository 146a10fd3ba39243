"""Loaded models: a description (:mod:`scdk_sym.model`) with its symbolic system and kernels,
reduced to a square closure system and assembled at home."""

from .model import Model, as_vector, load_model, model_from_tree

__all__ = ["Model", "as_vector", "load_model", "model_from_tree"]
