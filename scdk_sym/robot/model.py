"""Closed-chain models: URDF spanning tree + loop closures, reduced to a square system.

Making a model checks every name of its description (:mod:`scdk_sym.robot.mechanism`),
assembles the home configuration (:mod:`scdk_sym.robot.home_assembly`) and reduces a closure
system that is not square as written (redundant rows, idle freedoms) to an independent square
one (:mod:`scdk_sym.robot.reduction`, :mod:`scdk_sym.robot.locking`). The description (URDF
tree, closure YAML, charts) comes from :mod:`scdk_sym.model`; the closure system is built by
:mod:`scdk_sym.symbolic` and evaluated by :mod:`scdk_sym.kernels`; models are read from files
by :mod:`scdk_sym.robot.loading`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from numpy.typing import ArrayLike

from ..model.edits import apply_joint_edits
from ..model.spec import Spec
from ..model.urdf import Tree, tree_to_urdf
from ..results import Configuration
from . import ik, saving
from .assembly import Assembly
from .home_assembly import nearest_turns, project
from .info import describe
from .mechanism import resolve
from .parts import ModelParts
from .reduction import inconsistent_rows, reduce_closures
from .validation import names_list


class Model(ModelParts):
    """A closed-chain manipulator: spanning tree, closures, actuated and unknown joints.

    Use :func:`~scdk_sym.robot.loading.load_model` or a builder of :mod:`scdk_sym.builders`
    to make one. Its data and what is built from it once (symbolic system, kernels, products,
    content hash) are :class:`~scdk_sym.robot.data.ModelData`'s; its configurations (home,
    configurations, placements, residuals, joint values)
    :class:`~scdk_sym.robot.evaluation.ModelEvaluation`'s; its blocks and stages
    :class:`~scdk_sym.robot.parts.ModelParts`'.

    Attributes:
        name: robot name.
        tree: the URDF spanning tree.
        spec: the parsed loop-closure side file.
        actuated: actuated joint names (theta order).
        unknowns: unknown joint names (y order), after the square reduction.
        locked: idle joints held at their home value -> value.
        rows: indices of the closure rows kept by the reduction.
        workspace: names of the workspace coordinates x.
        frame: link whose pose is x (the platform).
        reduction: one line describing the square reduction, or ``None``.
        assembly: one line saying how home was assembled when the YAML gives no ``home`` and
            the neutral configuration does not close, else ``None``.
        length_scale: characteristic size of the model [model length unit].
    """

    #: The least-squares projection onto the closures that the reduction uses (see
    #: :func:`~scdk_sym.robot.home_assembly.project`).
    _project = staticmethod(project)

    def __init__(
        self,
        tree: Tree,
        spec: Spec,
        path: str | None = None,
        frame: str | None = None,
        urdf_text: str | None = None,
        *,
        inputs: Sequence[str] | None = None,
        locked: Mapping[str, float] | None = None,
        source: Any = None,
    ) -> None:
        self._urdf_text = urdf_text if urdf_text is not None else tree_to_urdf(tree)
        #: what the model was made from: (tree, spec, frame) before edits and reduction
        self._made_from = (tree, spec, frame)
        tree = apply_joint_edits(tree, spec.joint_edits, path)
        if inputs is not None:
            spec = replace(spec, actuated=names_list(inputs, "inputs", path))
        self.tree = tree
        self.spec = spec
        self.path = path
        self.name = tree.name
        #: where the model came from when not URDF + YAML (an MJCF file: its qpos layout,
        #: what loading decided), else ``None``
        self.source = source
        mechanism = resolve(tree, spec, path, frame, locked, source, self._project)
        #: joints held at given values (``locked=``, an MJCF file's springs) -> value
        self.held = mechanism.held
        self.frame, self.workspace = mechanism.frame, mechanism.workspace
        self.actuated, self.closures = mechanism.actuated, mechanism.closures
        self.length_scale, self.tolerance = mechanism.length_scale, mechanism.tolerance
        reduced = reduce_closures(mechanism)
        self.tree = reduced.mechanism.tree
        self.rows, self.unknowns, self.locked = reduced.rows, reduced.unknowns, reduced.locked
        self.reduction, self.assembly = reduced.note, reduced.assembly
        #: ball joint -> (rotation at home (3, 3), spin axis (3,)) of the balls turned into
        #: universal joints to lock a rod's spin
        self.spins = reduced.spins
        self.chart = reduced.chart
        self._home_y, self._home_theta = reduced.home_y, reduced.home_theta
        if source is not None:
            self.unchecked, self.reduction = inconsistent_rows(reduced)

    def _nearest_turns(self, found: Assembly, names: Sequence[str]) -> Assembly:
        """:func:`~scdk_sym.robot.home_assembly.nearest_turns` in this model's tree."""
        return nearest_turns(self.tree, found, names)

    def inverse_kinematics(self, x: ArrayLike) -> Configuration:
        """An assembled configuration whose platform has workspace coordinates ``x``.

        Continuation from the home configuration along a straight line in position and a
        geodesic in orientation, with Newton corrections on ``[g; pose error]`` over all
        joints: the result stays in the working modes of ``home``
        (:func:`~scdk_sym.robot.ik.inverse_kinematics`).

        Args:
            x: (n,) workspace coordinates, in the order of ``model.workspace``.

        Raises:
            InputError: wrong size or non-finite values.
            UnreachableError: no configuration in the home working mode reaches ``x``.
        """
        return ik.inverse_kinematics(self, x)

    def save(self, directory: str | Path) -> Path:
        """Write ``robot.urdf`` and ``robot.yaml`` into ``directory`` (created if needed).

        Raises:
            OutputError: ``directory`` is a file or cannot be written.
        """
        return saving.save(directory, self._urdf_text, self.spec)

    def with_inputs(self, inputs: Sequence[str]) -> Model:
        """The same mechanism with other joints as inputs (the motors becoming unknowns when
        the inputs are output joints), its home this model's home.

        Raises:
            NonSquareSystemError: the inputs leave freedoms undetermined or bind each other.
        """
        tree, spec, frame = self._made_from
        spec = replace(spec, home=dict(self.file_joints(self.home)))
        source = self.source
        if source is not None:  # home is assembled and regular already
            source = replace(source, settle_home=False)
        held = {k: v for k, v in self.held.items() if k not in inputs}
        return Model(tree, spec, self.path, frame, self._urdf_text, inputs=inputs,
                     locked=held, source=source)  # fmt: skip

    def info(self) -> str:
        """What the model is made of, as text (``scdk info``): inputs, unknowns, closures,
        held joints and springs, home, joint ranges, blocks, the reduction made."""
        return describe(self)

    def __repr__(self) -> str:
        return (
            f"Model({self.name!r}, actuated={list(self.actuated)}, unknowns={list(self.unknowns)}, "
            f"workspace={list(self.workspace)}, frame={self.frame!r})"
        )
