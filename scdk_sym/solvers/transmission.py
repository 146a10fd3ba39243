"""Motor <-> joint maps of a closed-chain leg, as a controller needs them.

A leg is controlled in the joint space of its serial equivalent (knee angle, ankle pitch and
roll) while the motors sit elsewhere. :func:`transmission` makes, from a model whose inputs
are the motors, a :class:`Transmission` to a chosen set of output joints (as many as the
motors; a motor may be its own output):

- ``forward(theta)``: the outputs at motor values, the continuing solution from the last call
  (the singularity-consistent tracker over the last readings: through a singular
  configuration, never a silent jump to another assembly);
- ``inverse(q_out)``: the motors that give the outputs (the same machinery on the model with
  the roles swapped, ``load_model(path, inputs=outputs)``);
- ``jacobian(theta)``: ``d outputs / d theta`` by the implicit function theorem on ``J_p``,
  ``J_s``; ``velocities`` and ``torques`` (``J^T tau_out``: the motor torques that hold output
  torques, frictionless and static) and the inverse directions;
- ``margin(theta)``: how far from singular the map is, per block of the leg (its knee loop,
  its ankle loop): a :class:`~scdk_sym.errors.SingularTransmissionError` with that figure
  where it is singular.

Units: rad for revolute joints and motors, the model's length unit for prismatic ones;
torques in N m (or N for prismatic joints) when velocities are in rad/s (m/s).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError, SingularTransmissionError, UnknownNameError
from ..kernels.fastcall import model_calls
from ..results import Configuration
from ..robot import Model
from ..robot.blocks import triangular_blocks
from ..robot.validation import as_vector
from .track import track
from .transmission_range import RangeCertificate, certify_range

#: A map is singular where its margin is below this (relative smallest singular value).
SINGULAR_MARGIN = 1e-8
#: Readings the forward and inverse maps keep to judge the continuing solution.
HISTORY = 3


@dataclass(frozen=True)
class Margin:
    """How far from singular a transmission is at one configuration.

    Attributes:
        value: the smallest of ``blocks`` [1].
        blocks: per block of the map, the smallest singular value of its motor -> output
            Jacobian and of its inverse's, each relative to the largest [1]; 0 where a block
            is singular.
        block_outputs: the outputs of each block.
        worst: index of the block with the smallest margin.
    """

    value: float
    blocks: tuple[float, ...]
    block_outputs: tuple[tuple[str, ...], ...]
    worst: int


class _Follower:
    """The continuing solution of one model along its readings: each call tracks the last
    :data:`HISTORY` readings again with the new ones, from the configuration before them, so
    the tracker's rule sees the motion (the readings at a steady rate)."""

    def __init__(self, model: Model, backend: str) -> None:
        self.model, self.backend = model, backend
        self.reset()

    def reset(self, start: Configuration | None = None) -> None:
        self.anchor = start or self.model.home
        self.window: list[np.ndarray] = []
        self.last: Configuration = self.anchor

    def many(self, thetas: np.ndarray, keep: bool = True) -> list[Configuration]:
        """The configurations at ``thetas`` (N, k), continuing from the last call (which
        they become unless ``keep`` is False)."""
        readings = [*self.window, *np.asarray(thetas, dtype=float)]
        res = track(self.model, np.array(readings), start=self.anchor, backend=self.backend)
        cfgs = list(res.configurations(self.model))
        if keep:
            cut = max(0, len(readings) - HISTORY)
            if cut:
                self.anchor = cfgs[cut - 1]
            self.window = [np.array(r) for r in readings[cut:]]
            self.last = cfgs[-1]
        return cfgs[-len(thetas) :]


class Transmission:
    """Motor <-> output maps of a model (see the module docstring); made by
    :func:`transmission`.

    Attributes:
        model: the model whose inputs are the motors.
        inverse_model: the same mechanism with the outputs as inputs.
        motors: the motor names (theta order).
        outputs: the output joint names.
    """

    def __init__(self, model: Model, outputs: Sequence[str], backend: str = "cvodes") -> None:
        if isinstance(outputs, str) or not all(isinstance(o, str) for o in outputs):
            raise InputError(f"outputs must be a list of joint names, got {outputs!r}")
        outputs = tuple(outputs)
        single = model.tree.single_coordinate_joints
        for o in outputs:
            if o not in single:
                raise UnknownNameError("output joint", o, single, model.path)
        if len(outputs) != model.k or len(set(outputs)) != len(outputs):
            raise InputError(
                f"a transmission needs as many distinct outputs as motors ({model.k}: "
                f"{list(model.actuated)}), got {list(outputs)}"
            )
        self.model = model
        self.motors = model.actuated
        self.outputs = outputs
        self.inverse_model = model.with_inputs(outputs)
        self._stages = triangular_blocks(model)
        self._forward = _Follower(model, backend)
        self._inverse = _Follower(self.inverse_model, backend)

    # ------------------------------------------------------------------ positions

    def forward(self, theta: ArrayLike) -> np.ndarray:
        """(n,) outputs at motor values ``theta`` (k,), continuing from the last call (or
        from home) [rad or length unit].

        Raises:
            TrackError: the readings jump too far, or leave the reachable set.
        """
        theta = as_vector(theta, self.model.k, "theta (motors)")
        return self._values(self._forward.many(theta[None])[-1])

    def forward_many(self, thetas: ArrayLike) -> np.ndarray:
        """(N, n) outputs along motor readings ``thetas`` (N, k), in time order, continuing
        from the last call."""
        thetas = _rows(thetas, self.model.k, "thetas (motors)")
        return np.array([self._values(c) for c in self._forward.many(thetas)])

    def inverse(self, q_out: ArrayLike) -> np.ndarray:
        """(k,) motor values that give the outputs ``q_out`` (n,), continuing from the last
        call (or from home)."""
        q_out = as_vector(q_out, len(self.outputs), "q_out (outputs)")
        return self._motor_values(self._inverse.many(q_out[None])[-1])

    def inverse_many(self, q_outs: ArrayLike) -> np.ndarray:
        """(N, k) motor values along output readings ``q_outs`` (N, n)."""
        q_outs = _rows(q_outs, len(self.outputs), "q_outs (outputs)")
        return np.array([self._motor_values(c) for c in self._inverse.many(q_outs)])

    def reset(self) -> None:
        """Forget the readings: the next calls continue from home."""
        self._forward.reset()
        self._inverse.reset()

    def configuration(self) -> Configuration:
        """The forward map's last configuration (home before the first call)."""
        return self._forward.last

    def _values(self, cfg: Configuration) -> np.ndarray:
        joints = cfg.coordinates
        return np.array([joints[o] for o in self.outputs])

    def _motor_values(self, cfg: Configuration) -> np.ndarray:
        joints = cfg.coordinates
        return np.array([joints[m] for m in self.motors])

    # ------------------------------------------------------------------ derivatives

    def _at(self, theta: ArrayLike | None) -> Configuration:
        """The configuration at ``theta`` continuing from the last call (which it does not
        change), or the last one."""
        if theta is None:
            return self._forward.last
        theta = as_vector(theta, self.model.k, "theta (motors)")
        if np.array_equal(self._forward.last.theta, theta):
            return self._forward.last
        return self._forward.many(theta[None], keep=False)[-1]

    def _parts(self, cfg: Configuration) -> tuple[np.ndarray, np.ndarray]:
        """``(J_p, J_s)`` of the forward model at ``cfg``."""
        y, c = self.model.chart.to_local(cfg.y)
        J_p, J_s = model_calls(self.model).jac(y, cfg.theta, c)
        return np.array(J_p, dtype=float), np.array(J_s, dtype=float)

    def _output_rows(self, J_p: np.ndarray, J_s: np.ndarray) -> np.ndarray:
        """(n, k) d outputs / d theta from ``J_p dy = J_s dtheta``."""
        dy = np.linalg.solve(J_p, J_s)
        rows = []
        for o in self.outputs:
            if o in self.model.unknowns:
                rows.append(dy[self.model.unknowns.index(o)])
            else:  # a motor as its own output
                rows.append(np.eye(self.model.k)[self.model.actuated.index(o)])
        return np.array(rows)

    def jacobian(self, theta: ArrayLike | None = None) -> np.ndarray:
        """(n, k) ``d outputs / d theta`` at the motor values ``theta`` (default: the last
        call's), on the continuing solution.

        Raises:
            SingularTransmissionError: the map is singular there (the margin says how).
        """
        cfg = self._at(theta)
        self._check(cfg)
        return self._output_rows(*self._parts(cfg))

    def inverse_jacobian(self, theta: ArrayLike | None = None) -> np.ndarray:
        """(k, n) ``d theta / d outputs``: the inverse of :meth:`jacobian`."""
        return np.linalg.inv(self.jacobian(theta))

    def velocities(self, theta: ArrayLike | None, dtheta: ArrayLike) -> np.ndarray:
        """(n,) output velocities of motor velocities ``dtheta`` (k,) [rad/s or unit/s]."""
        return self.jacobian(theta) @ as_vector(dtheta, self.model.k, "dtheta")

    def inverse_velocities(self, theta: ArrayLike | None, dq_out: ArrayLike) -> np.ndarray:
        """(k,) motor velocities that give output velocities ``dq_out`` (n,)."""
        return np.linalg.solve(self.jacobian(theta), as_vector(dq_out, len(self.outputs), "dq_out"))

    def torques(self, theta: ArrayLike | None, tau_out: ArrayLike) -> np.ndarray:
        """(k,) motor torques that hold output torques ``tau_out`` (n,): ``J^T tau_out``
        (frictionless, static; virtual work ``tau_motor . dtheta = tau_out . dq_out``)
        [N m, or N for prismatic joints]."""
        return self.jacobian(theta).T @ as_vector(tau_out, len(self.outputs), "tau_out")

    def inverse_torques(self, theta: ArrayLike | None, tau_motor: ArrayLike) -> np.ndarray:
        """(n,) output torques that motor torques ``tau_motor`` (k,) hold: ``J^-T tau``."""
        return np.linalg.solve(
            self.jacobian(theta).T, as_vector(tau_motor, self.model.k, "tau_motor")
        )

    # ------------------------------------------------------------------ margin

    def certify_range(self, lower: ArrayLike, upper: ArrayLike, **options) -> RangeCertificate:
        """Prove the map invertible with no singular configuration over the box of outputs
        ``[lower, upper]`` (see :func:`~scdk_sym.solvers.transmission_range.certify_range`,
        which takes ``depth`` and ``max_boxes``)."""
        return certify_range(self, lower, upper, **options)

    def blocks(self) -> tuple[tuple[tuple[str, ...], tuple[str, ...]], ...]:
        """``(motors, outputs)`` of each independent block of the map at home (a leg's knee
        loop, its ankle loop; a motor that is its own output is a block of its own)."""
        return self._blocks

    @cached_property
    def _blocks(self) -> tuple[tuple[tuple[str, ...], tuple[str, ...]], ...]:
        J = np.abs(self._output_rows(*self._parts(self.model.home))) > 1e-12
        n = len(self.outputs)
        # connected components of the bipartite graph outputs - motors
        seen: set[int] = set()
        out = []
        for start in range(n):
            if start in seen:
                continue
            outs, mots, todo = {start}, set(), [start]
            while todo:
                i = todo.pop()
                for k in np.flatnonzero(J[i]):
                    if k not in mots:
                        mots.add(int(k))
                        for i2 in np.flatnonzero(J[:, k]):
                            if int(i2) not in outs:
                                outs.add(int(i2))
                                todo.append(int(i2))
            seen |= outs
            out.append((tuple(self.motors[k] for k in sorted(mots)),
                        tuple(self.outputs[i] for i in sorted(outs))))  # fmt: skip
        return tuple(out)

    def margin(self, theta: ArrayLike | None = None) -> Margin:
        """How far from singular the map is at ``theta`` (default: the last call's): per
        block, the smallest singular value of its part of ``J_p`` (the closure rows and
        unknowns its motors move: motors -> joints) and of its ``d outputs / d theta``
        (outputs -> motors), each relative to the largest."""
        return self._margin(self._at(theta))

    def _stages_of(self, outs: Sequence[str]) -> list[tuple[list[int], list[int]]]:
        """``(rows, unknowns)`` of the stages of the closure system (the block-triangular
        decomposition: a knee four-bar, then the ankle it carries) that the outputs ``outs``
        depend on."""
        stages = self._stages
        want = {self.model.unknowns.index(o) for o in outs if o in self.model.unknowns}
        chosen: list[int] = []
        for i in reversed(range(len(stages))):  # dependencies come first
            if want & set(stages[i].unknowns):
                chosen.append(i)
                want |= set(stages[i].inputs)
        return [(list(stages[i].rows), list(stages[i].unknowns)) for i in sorted(chosen)]

    def _margin(self, cfg: Configuration) -> Margin:
        J_p, J_s = self._parts(cfg)
        values: list[float] = []
        blocks = self.blocks()
        J: np.ndarray | None = None  # d outputs / d theta, once a block needs it
        for motors, outs in blocks:
            parts = [_relative_min(J_p[np.ix_(r, u)]) for r, u in self._stages_of(outs)]
            value = min(parts, default=1.0)
            if value > SINGULAR_MARGIN:
                J = self._output_rows(J_p, J_s) if J is None else J
                sub = J[np.ix_([self.outputs.index(o) for o in outs],
                               [self.motors.index(mo) for mo in motors])]  # fmt: skip
                value = min(value, _relative_min(sub))
            values.append(value)
        worst = int(np.argmin(values))
        return Margin(values[worst], tuple(values), tuple(o for _, o in blocks), worst)

    def _check(self, cfg: Configuration) -> None:
        m = self._margin(cfg)
        if m.value <= SINGULAR_MARGIN:
            raise SingularTransmissionError(
                f"the transmission is singular at theta={cfg.theta.tolist()}: margin "
                f"{m.value:.2e} in the block of outputs {list(m.block_outputs[m.worst])}; its "
                "velocities and torques are not defined there: move away from it, or choose "
                "other outputs",
                m.value,
                cfg.theta,
            )


def _relative_min(A: np.ndarray) -> float:
    """Smallest singular value of ``A`` relative to its largest (0 for a zero matrix)."""
    sv = np.linalg.svd(A, compute_uv=False)
    return float(sv[-1] / sv[0]) if sv.size and sv[0] > 0 else 0.0


def _rows(values: ArrayLike, size: int, what: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != size or not np.all(np.isfinite(arr)):
        raise InputError(f"{what} must be a finite (N, {size}) array, got shape {arr.shape}")
    return arr


def transmission(model: Model, outputs: Sequence[str], backend: str = "cvodes") -> Transmission:
    """The motor <-> output maps of ``model`` (see :class:`Transmission`).

    Args:
        model: a model whose inputs are the motors.
        outputs: the output joints, as many as the motors (a motor may be its own output).
        backend: the tracker's backend ("cvodes" or "c").

    Raises:
        UnknownNameError: an output is not a one-coordinate joint.
        InputError: not as many distinct outputs as motors.
        NonSquareSystemError: the outputs do not determine the mechanism (or bind each other).
    """
    return Transmission(model, outputs, backend)
