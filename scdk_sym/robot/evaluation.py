"""A model's configurations: home, one or many configurations assembled from unknowns and
inputs, link placements, residuals, joint values in the model files' terms, target poses;
and the models of part of its closure system (:meth:`ModelEvaluation.restricted`)."""

from __future__ import annotations

from collections.abc import Mapping
from functools import cached_property
from typing import Any, TypeVar

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from ..errors import UnknownNameError
from ..kernels.fastcall import model_calls
from ..model.chart import Chart
from ..model.qpos import MjcfJoints, QposLayout
from ..model.rotations import rot_exp, rot_log, rpy_matrix
from ..results import Configuration, JointValues, unchecked_many
from .data import ModelData
from .validation import as_vector

#: A model class (a model of part of a model's system is of its class).
ModelT = TypeVar("ModelT", bound="ModelEvaluation")


class ModelEvaluation(ModelData):
    """A model's configurations (see :class:`~scdk_sym.robot.model.Model`)."""

    @cached_property
    def home(self) -> Configuration:
        """The assembled home configuration (fixes the working modes)."""
        return self.configuration(self._home_y, self._home_theta)

    def residual(self, y: np.ndarray, theta: np.ndarray, c: np.ndarray | None = None) -> float:
        """Max |closure row| including the dropped redundant rows [model length unit].

        Args:
            y: (m,) unknowns, canonical (``c is None``) or in the local chart ``c``.
            theta: (k,) actuated values.
            c: chart of ``y`` (see :mod:`scdk_sym.model.chart`), ``None`` for canonical ``y``.
        """
        if c is None:
            y, c = self.chart.to_local(y)
        return float(np.abs(model_calls(self).check(y, theta, c)).max())

    def configuration(
        self, y: ArrayLike, theta: ArrayLike, c: np.ndarray | None = None
    ) -> Configuration:
        """Assemble a :class:`Configuration` from unknowns ``y`` (m,) and actuated ``theta`` (k,).

        Args:
            y: unknowns, canonical or (with ``c``) in a local chart.
            theta: actuated joint values.
            c: chart of ``y``; ``None`` when ``y`` is canonical.
        """
        y = as_vector(y, self.m, "y")
        theta = as_vector(theta, self.k, "theta")
        if c is None:
            y_loc, c = self.chart.to_local(y)
        else:
            y_loc, y = y, self.chart.to_canonical(y, c)
        calls = model_calls(self)
        T, x = calls.pose(y_loc, theta, c)
        residual = float(np.abs(calls.check(y_loc, theta, c)).max())
        return Configuration(theta, y, x.ravel(), T, self.joint_values(y, theta), residual)

    def configurations(
        self,
        ys: np.ndarray,
        theta: ArrayLike,
        cs: np.ndarray,
        residuals: np.ndarray | None = None,
    ) -> list[Configuration]:
        """:meth:`configuration` of several points, the kernels evaluated over all of them
        in one call.

        Args:
            ys: (N, m) unknowns in the local charts ``cs``.
            theta: (k,) actuated joint values of every point, or (N, k) one row per point.
            cs: (N, chart size) the chart of each row of ``ys``.
            residuals: (N,) each point's :meth:`residual` when already known.
        """
        return self.configuration_table(ys, theta, cs, residuals)[0]

    def configuration_table(
        self,
        ys: np.ndarray,
        theta: ArrayLike,
        cs: np.ndarray,
        residuals: np.ndarray | None = None,
    ) -> tuple[list[Configuration], np.ndarray, np.ndarray]:
        """:meth:`configurations` and their stacked fields.

        Returns:
            ``(configurations, y, x)``: the N configurations, their canonical unknowns
            (N, m) and workspace coordinates (N, n), read-only arrays whose rows the
            configurations hold.
        """
        ys = np.asarray(ys, dtype=float).reshape(-1, self.m)
        N = len(ys)
        if np.ndim(theta) == 2:
            thetas = np.asarray(theta, dtype=float).reshape(N, self.k)
            for bad in thetas[~np.isfinite(thetas).all(axis=1)][:1]:  # its error says what
                as_vector(bad, self.k, "theta")
            arg = thetas.T
        else:
            arg = as_vector(theta, self.k, "theta")
            thetas = np.broadcast_to(arg, (N, self.k))
        if not N:
            return [], np.zeros((0, self.m)), np.zeros((0, len(self.workspace)))
        cs = np.asarray(cs, dtype=float).reshape(N, self.chart.size)
        canonical = self.chart.to_canonical_many(ys, cs)
        calls = model_calls(self)
        T, x = calls.mapped("pose", N)(ys.T, arg, cs.T)
        if residuals is None:
            residuals = np.abs(calls.mapped("check", N)(ys.T, arg, cs.T)).max(axis=0)
        # owned read-only arrays: the configurations take their rows without copies
        ths = np.array(thetas)
        xs = np.array(np.asarray(x).T)
        poses = np.array(np.asarray(T).reshape(4, N, 4).transpose(1, 0, 2))
        ys_c = np.array(canonical)
        for a in (ths, xs, poses, ys_c):
            a.setflags(write=False)
        joints: list = JointValues.rows(self._joint_columns, self._joint_table(ys_c, ths))
        if self.qpos_layout is not None:
            joints = [MjcfJoints(j, self.qpos_layout) for j in joints]
        cfgs = unchecked_many(
            Configuration, N, theta=ths, y=ys_c, x=xs, platform_pose=poses, joints=joints,
            residual=np.asarray(residuals, dtype=float).tolist(),
        )  # fmt: skip
        return cfgs, ys_c, xs

    @cached_property
    def _placements(self) -> ca.Function:
        sym = self.symbolic
        return ca.Function(
            "placements", [sym.y, sym.theta, sym.c], [ca.vertcat(*sym.placements.values())]
        )

    def placements(self, cfg: Configuration) -> dict[str, np.ndarray]:
        """World placement of every link of a configuration.

        Args:
            cfg: a configuration of this model (a solution, ``home``, a track sample).

        Returns:
            Link name -> (4, 4) homogeneous placement in the base frame [model length unit].
        """
        y_loc, c = self.chart.to_local(cfg.y)
        out = np.array(self._placements(y_loc, cfg.theta, c))
        links = self.symbolic.placements
        return {n: out[4 * i : 4 * i + 4] for i, n in enumerate(links)}

    def evaluate(
        self, ys: np.ndarray, thetas: np.ndarray, residual: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Workspace coordinates and residuals of many configurations in one mapped call.

        Args:
            ys: (N, m) canonical unknowns.
            thetas: (N, k) actuated values.
            residual: False to skip the residuals (``None`` is returned for them).

        Returns:
            (x (N, n), residual (N,)): what :meth:`configuration` gives for each row.
        """
        ys, thetas = np.atleast_2d(ys), np.atleast_2d(thetas)
        N = ys.shape[0]
        loc, charts = np.array(ys, dtype=float), np.zeros((N, self.chart.size))
        for i, idx in enumerate(self.chart.rotations):
            R = rot_exp(ys[:, list(idx)])  # (N, 3, 3)
            charts[:, 9 * i : 9 * i + 9] = R.transpose(0, 2, 1).reshape(N, 9)
            loc[:, list(idx)] = 0.0
        pose, check = self.kernels.pose.map(N), self.kernels.check.map(N)
        x = np.array(pose(loc.T, thetas.T, charts.T)[1]).T
        if not residual:
            return x, None
        rows = np.abs(np.array(check(loc.T, thetas.T, charts.T)))
        return x, rows.max(axis=0)

    def placement(self, cfg: Configuration, link: str) -> np.ndarray:
        """World placement (4, 4) of one link (or joint frame) of a configuration.

        Raises:
            UnknownNameError: ``link`` is not a link or joint of the model.
        """
        frames = {j.name: j.child for j in self.tree.joints}
        name = link if link in self.tree.links else frames.get(link)
        if name is None:
            raise UnknownNameError("link", link, self.tree.links, self.path)
        return self.placements(cfg)[name]

    def file_joints(self, cfg: Configuration) -> dict[str, float]:
        """The joint coordinates of ``cfg`` in the model files' terms (``home`` of the YAML):
        a ball joint whose rod spin was locked gives its rotation vector again."""
        joints = {k: v for k, v in cfg.coordinates.items() if not k.endswith(("_U1", "_U2"))}
        if not self.spins:
            return joints
        T = self.placements(cfg)
        for ball in self.spins:
            first = self.tree.joint(f"{ball}_U1")
            second = self.tree.joint(f"{ball}_U2")
            rotation, _ = self.spins[ball]
            frame = T[first.parent] @ first.origin
            w = rot_log(rotation @ frame[:3, :3].T @ T[second.child][:3, :3])
            joints.update(
                {f"{ball}.{c}": float(v) for c, v in zip(("rx", "ry", "rz"), w, strict=True)}
            )
        return joints

    def joint_values(self, y: np.ndarray, theta: np.ndarray) -> Mapping[str, Any]:
        """Every joint coordinate (URDF order, locked ones included) from canonical y, theta;
        of a model read from MJCF, the joints by MJCF name (:class:`MjcfJoints`: hinge and
        slide ``qpos``, ball quaternions, and the whole ``qpos``)."""
        y, theta = np.asarray(y, dtype=float), np.asarray(theta, dtype=float)
        values = self._joint_table(y[None], theta[None])[0]
        if self.qpos_layout is not None:
            return MjcfJoints(JointValues(self._joint_columns, values), self.qpos_layout)
        listed = values.tolist()  # the same floats as the row's items
        return {j: listed[i] for j, i in self._joint_columns.items()}

    @cached_property
    def qpos_layout(self) -> QposLayout | None:
        """Where MuJoCo's ``qpos`` takes each joint, for a model read from MJCF (``None``
        otherwise)."""
        layout = getattr(self.source, "layout", None)
        return None if layout is None else layout.with_spins(self.spins)

    @cached_property
    def _joint_columns(self) -> dict[str, int]:
        """Joint coordinate (URDF order) -> its column of :meth:`_joint_table`'s rows (the
        locked joints' values, then y, then theta; a name in two takes the later column)."""
        L, m = len(self.locked), self.m
        source = {j: i for i, j in enumerate(self.locked)}
        source.update({j: L + i for i, j in enumerate(self.unknowns)})
        source.update({j: L + m + i for i, j in enumerate(self.actuated)})
        return {j: source[j] for j in self._coordinates}

    @cached_property
    def _locked_values(self) -> np.ndarray:
        """(L,) the locked joints' values, in :attr:`locked`'s order (read-only)."""
        values = np.array(list(self.locked.values()), dtype=float)
        values.setflags(write=False)
        return values

    def _joint_table(self, ys: np.ndarray, thetas: np.ndarray) -> np.ndarray:
        """(N, C) read-only joint values of canonical ``ys`` (N, m) and ``thetas`` (N, k),
        columns as :attr:`_joint_columns` says."""
        locked = self._locked_values
        if len(ys) == 1:  # one configuration: one concatenation (the same values)
            out = np.concatenate([locked, ys[0], thetas[0]])[None]
        else:
            out = np.hstack([np.broadcast_to(locked, (len(ys), len(locked))), ys, thetas])
        out.setflags(write=False)
        return out

    def target_pose(self, x: ArrayLike) -> np.ndarray:
        """The 4x4 placement with workspace coordinates ``x`` (other components from home)."""
        x = as_vector(x, len(self.workspace), f"x ({', '.join(self.workspace)})")
        T = np.array(self.home.platform_pose)
        vals = dict(zip(self.workspace, x, strict=True))
        for i, axis in enumerate("xyz"):
            if axis in vals:
                T[i, 3] = vals[axis]
        if "phi" in vals or set(vals) & {"roll", "pitch", "yaw"}:
            yaw = vals.get("phi", vals.get("yaw", 0.0))
            T[:3, :3] = rpy_matrix(vals.get("roll", 0.0), vals.get("pitch", 0.0), yaw)
        return T

    @classmethod
    def restricted(
        cls: type[ModelT],
        parent: ModelEvaluation,
        unknowns: tuple[str, ...],
        actuated: tuple[str, ...],
        closures: tuple,
        rows: tuple[int, ...],
        held: dict[str, float],
        block: tuple[int, object],
        unchecked: tuple[int, ...] = (),
    ) -> ModelT:
        """A model of part of ``parent``'s closure system (one independent block): its own
        unknowns, actuators, closures and rows of those closures, every other joint held at
        the given value; built without a reduction (the parent's rows and locks are kept).

        Args:
            parent: the whole model.
            unknowns: the block's unknowns (canonical, in the parent's order).
            actuated: the actuators the block's rows involve (and, for a block of a
                triangular decomposition, the unknowns of earlier blocks they involve).
            closures: the block's closures (frames resolved to links).
            rows: indices of the kept rows in the block's closure rows.
            held: every other joint coordinate -> value [rad or length unit].
            block: (index, :class:`~scdk_sym.robot.blocks.Block`) of the block.
            unchecked: rows of the block's closure rows left out of the verification.
        """
        sub = cls.__new__(cls)
        for name in ("tree", "spec", "path", "name", "_urdf_text", "frame", "workspace", "held"):
            setattr(sub, name, getattr(parent, name))
        for name in ("length_scale", "tolerance", "reduction", "assembly", "spins", "source"):
            setattr(sub, name, getattr(parent, name))
        sub.closures, sub.unknowns, sub.actuated, sub.rows = closures, unknowns, actuated, rows
        sub.unchecked = unchecked
        sub.locked = dict(held)
        sub.chart = Chart.for_unknowns(unknowns, parent.tree.rotation_joints)
        home = parent.home
        sub._home_y = np.array([home.y[parent.unknowns.index(n)] for n in unknowns])
        sub._home_theta = np.array(
            [
                home.theta[parent.actuated.index(n)]
                if n in parent.actuated
                else home.y[parent.unknowns.index(n)]  # an earlier block's unknown as input
                for n in actuated
            ]
        )
        sub.block = block
        sub._restriction = ("block", *unknowns, "|", *actuated, "|", *map(str, rows))
        return sub
