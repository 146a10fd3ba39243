"""A model's data (its tree, closures, inputs, unknowns, kept rows, home) and what is built
from it once: the symbolic system, the kernels, the solver products, the content hash."""

from __future__ import annotations

import hashlib
from functools import cached_property
from typing import Any

import numpy as np

from ..kernels.functions import Kernels, build_kernels
from ..model.chart import Chart
from ..model.spec import Closure, Spec
from ..model.urdf import Tree
from ..products import Products
from ..symbolic.system import Symbolic, build_symbolic
from .mechanism import row_labels

#: Workspace coordinates that are angles [rad].
ANGLE_COORDINATES = ("phi", "roll", "pitch", "yaw")


class ModelData:
    """The data of a model and what is built from it once (the attributes are described in
    :class:`~scdk_sym.robot.model.Model`)."""

    tree: Tree
    spec: Spec
    path: str | None
    name: str
    source: Any
    held: dict[str, float]
    frame: str
    workspace: tuple[str, ...]
    actuated: tuple[str, ...]
    closures: tuple[Closure, ...]
    length_scale: float
    tolerance: float
    assembly: str | None
    spins: dict[str, tuple[np.ndarray, np.ndarray]]
    rows: tuple[int, ...]
    unknowns: tuple[str, ...]
    locked: dict[str, float]
    reduction: str | None
    chart: Chart
    _urdf_text: str
    _home_y: np.ndarray
    _home_theta: np.ndarray

    #: (index, :class:`~scdk_sym.robot.blocks.Block`) of a block model, ``None`` otherwise.
    block: tuple[int, Any] | None = None
    #: What distinguishes a block model's cache key from its parent's (empty otherwise).
    _restriction: tuple[str, ...] = ()
    #: Rows of the full closure system left out of the verification: redundant rows that a
    #: file's rounding makes slightly inconsistent with the others (see
    #: :func:`~scdk_sym.robot.reduction.inconsistent_rows`); their residual is reported in
    #: :attr:`reduction`.
    unchecked: tuple[int, ...] = ()

    def row_labels(self) -> list[str]:
        """A label per closure row of the full (unreduced) system, ``"<closure>.<row>"``
        (``x``, ``y``, ``z``, ``rx``, ``ry``, ``rz`` or ``d``)."""
        return row_labels(self.spec.closures)

    @cached_property
    def row_offsets(self) -> np.ndarray:
        """(closures + 1,) int: closure ``i``'s rows of the full closure system are
        ``row_offsets[i]`` to ``row_offsets[i + 1] - 1`` (``rows`` indexes that system)."""
        offsets = np.cumsum([0, *[c.rows for c in self.closures]])
        offsets.flags.writeable = False
        return offsets

    @cached_property
    def products(self) -> Products:
        """The solver products built for this model (:class:`~scdk_sym.products.Products`:
        kernels, compiled libraries, algebraic forms...; declared in :mod:`scdk_sym.products`)."""
        return Products()

    @cached_property
    def symbolic(self) -> Symbolic:
        """The symbolic system (:class:`~scdk_sym.symbolic.system.Symbolic`)."""
        return build_symbolic(
            self.tree,
            self.closures,
            self.actuated,
            self.unknowns,
            self.locked,
            self.rows,
            self.frame,
            self.workspace,
            self.unchecked,
        )

    @cached_property
    def kernels(self) -> Kernels:
        """CasADi Functions of this model (:class:`~scdk_sym.kernels.functions.Kernels`)."""
        return build_kernels(self.symbolic)

    @cached_property
    def _coordinates(self) -> tuple[str, ...]:
        """Every joint coordinate name of the tree (``tree.coordinates``), computed once."""
        return self.tree.coordinates

    @property
    def length_unit(self) -> str:
        """Unit of every length of the model (``length_unit`` in the YAML, default m)."""
        return self.spec.length_unit

    @property
    def units(self) -> dict[str, str]:
        """Unit of each workspace coordinate and actuated joint: rad for angles and revolute
        joints, :attr:`length_unit` for positions and prismatic joints."""
        out = {w: ("rad" if w in ANGLE_COORDINATES else self.length_unit) for w in self.workspace}
        for a in self.actuated:
            out[a] = self.length_unit if self.tree.joint(a).type == "prismatic" else "rad"
        return out

    @property
    def m(self) -> int:
        """Number of unknowns (= independent closure rows)."""
        return len(self.unknowns)

    @property
    def k(self) -> int:
        """Number of actuated joints."""
        return len(self.actuated)

    @property
    def urdf_text(self) -> str:
        """The URDF the model was built from (as read, or written from its tree)."""
        return self._urdf_text

    @cached_property
    def content_hash(self) -> str:
        """SHA-256 of the URDF, the YAML and the reported frame (cache key); of a block model
        (see :meth:`~scdk_sym.robot.model.Model.restricted`), also of its unknowns, actuators
        and rows."""
        h = hashlib.sha256()
        parts = [self._urdf_text, self.spec.to_yaml(), self.frame, "|".join(self.workspace)]
        if self.held:  # joints held by locked= (none: the hash of earlier releases)
            parts.append("held " + repr(sorted(self.held.items())))
        if self.unchecked:
            parts.append("unchecked " + repr(self.unchecked))
        for part in (*parts, *self._restriction):
            h.update(part.encode())
            h.update(b"\0")
        return h.hexdigest()
