"""Algebraic (polynomial) forms of closure systems, for complete solution by homotopy."""

from .form import AlgebraicForm, algebraic_form

__all__ = [
    "AlgebraicForm",
    "algebraic_form",
]
