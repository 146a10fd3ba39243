"""A model's algebraic form with its closure rows in units of the model's size.

Monodromy loops and trace pencils offset the closure rows by amounts of the order of one; on a
model a few centimetres across, rows in metres are of the order of 0.01 and such offsets
throw the solutions far out of the model's scale, where paths fail. Dividing point rows by the
model's length scale ``L`` and distance rows (``|d|^2 - L_0^2``) by ``L^2`` makes every row
dimensionless and of the order of one; rotation and structural rows stay. The solutions are
those of the form.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .form import AlgebraicForm


def row_weights(form) -> np.ndarray:
    """(n,) weights of the rows of ``form``: 1/L on point rows, 1/L^2 on distance rows."""
    L = float(form.model.length_scale) or 1.0
    w = np.ones(form.n)
    for i, label in enumerate(form.rows.labels):
        part = label.rsplit(".", 1)[-1]
        if not form.offset_rows[i]:
            continue
        if part in ("x", "y", "z"):
            w[i] = 1.0 / L
        elif part == "d":
            w[i] = 1.0 / (L * L)
    return w


@dataclass(frozen=True, eq=False)
class ScaledForm:
    """``W G(z, p)`` for the row weights ``W`` of :func:`row_weights`: a polynomial system
    (the engine's protocol) with the form's unknowns, parameters and mapping to the model.

    Attributes:
        form: the :class:`~scdk_sym.algebraic.form.AlgebraicForm`.
        weights: (n,) row weights.
    """

    form: AlgebraicForm
    weights: np.ndarray = field(repr=False)

    @property
    def n(self) -> int:
        return self.form.n

    @property
    def n_params(self) -> int:
        return self.form.n_params

    @property
    def offset_rows(self) -> np.ndarray:
        return self.form.offset_rows

    @property
    def model(self):
        return self.form.model

    @property
    def backend(self) -> str:
        return self.form.backend

    @property
    def rows(self):
        return self.form.rows

    def evaluate(self, z: np.ndarray, p: np.ndarray):
        """``W G``, ``W dG/dz``, ``W dG/dp`` (see the form's ``evaluate``)."""
        G, Jz, Jp = self.form.evaluate(z, p)
        w = self.weights
        return G * w, Jz * w[:, None], Jp * w[:, None]

    @property
    def param_widths(self) -> np.ndarray:
        """The form's loop steps in its parameters."""
        return self.form.param_widths

    def random_point(self, rng: np.random.Generator):
        """The form's random point."""
        return self.form.random_point(rng)

    def content_hash(self) -> str:
        """The form's hash and the weights."""
        h = hashlib.sha256(self.form.content_hash().encode())
        h.update(np.asarray(self.weights, dtype=float).tobytes())
        return h.hexdigest()

    def params(self, theta) -> np.ndarray:
        return self.form.params(theta)

    def to_model(self, z, reference=None, tol: float = 1e-8):
        return self.form.to_model(z, reference, tol)

    def is_real(self, z, tol: float = 1e-8):
        return self.form.is_real(z, tol)


def scaled_form(form) -> ScaledForm:
    """The form with dimensionless closure rows (see the module documentation)."""
    return ScaledForm(form, row_weights(form))
