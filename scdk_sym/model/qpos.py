"""MuJoCo's ``qpos`` vector of a model read from MJCF, and its joints by MJCF name.

A configuration's joint coordinates (hinges and slides as their ``qpos``, a ball as its rotation
vector, or as the two angles of the universal joint that replaced it when its rod's spin was
locked) map to MuJoCo's whole ``qpos`` so that ``data.qpos[:] = cfg.qpos`` puts the answer
into a simulation.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from .rotations import axis_rotation, quaternion_of, rot_exp


@dataclass(frozen=True)
class QposEntry:
    """One MJCF joint.

    Attributes:
        name: joint name (an input on a fixed tendon: the actuator's).
        kind: "hinge", "slide", "ball", "free" or "input" (a tendon input, not in qpos).
        address: its first index in ``qpos`` (-1 for an input).
        held: for a free joint held at home, its 7 qpos values; else empty.
    """

    name: str
    kind: str
    address: int
    held: tuple[float, ...] = ()


@dataclass(frozen=True)
class QposLayout:
    """Where each MJCF joint sits in ``qpos``.

    Attributes:
        nq: size of ``qpos``.
        entries: the joints, in MuJoCo's order.
        home: (nq,) the file's home ``qpos``.
        spins: ball joint -> (rotation at home (3, 3), first axis (3,), second axis (3,)) of
            the balls turned into universal joints (see
            :func:`scdk_sym.model.edits.ball_to_universal`).
    """

    nq: int
    entries: tuple[QposEntry, ...]
    home: tuple[float, ...]
    spins: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)

    def with_spins(self, spins: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> QposLayout:
        """The layout of a model whose balls ``spins`` (ball -> (rotation, spin axis)) were
        turned into universal joints."""
        axes = {}
        for ball, (rotation, spin) in spins.items():
            u = np.asarray(spin, dtype=float) / np.linalg.norm(spin)
            a = np.cross(u, np.eye(3)[int(np.argmin(np.abs(u)))])
            a /= np.linalg.norm(a)
            axes[ball] = (np.asarray(rotation, dtype=float), a, np.cross(u, a))
        return QposLayout(self.nq, self.entries, self.home, axes)

    def value(self, entry: QposEntry, joints: Mapping[str, float]) -> float | tuple[float, ...]:
        """One joint's value: a number (hinge, slide, input) or its qpos (ball: quaternion
        w x y z; free: position then quaternion)."""
        n = entry.name
        if entry.kind in ("hinge", "slide", "input"):
            return float(joints[n])
        if entry.kind == "ball":
            return tuple(float(v) for v in quaternion_of(self._ball(n, joints)))
        if entry.held:
            return entry.held
        p = [float(joints[f"{n}.{c}"]) for c in "xyz"]
        R = rot_exp(np.array([joints[f"{n}.r{c}"] for c in "xyz"], dtype=float))
        return (*p, *(float(v) for v in quaternion_of(R)))

    def _ball(self, n: str, joints: Mapping[str, float]) -> np.ndarray:
        if n in self.spins:
            R0, a, b = self.spins[n]
            q1, q2 = float(joints[f"{n}_U1"]), float(joints[f"{n}_U2"])
            Ra = axis_rotation(a, np.cos(q1), np.sin(q1))
            Rb = axis_rotation(b, np.cos(q2), np.sin(q2))
            return R0 @ np.asarray(Ra) @ np.asarray(Rb)
        return rot_exp(np.array([joints[f"{n}.r{c}"] for c in "xyz"], dtype=float))

    def qpos(self, joints: Mapping[str, float]) -> np.ndarray:
        """(nq,) MuJoCo's ``qpos`` of the joint coordinates ``joints``."""
        out = np.array(self.home, dtype=float)
        for e in self.entries:
            if e.kind == "input":
                continue
            v = self.value(e, joints)
            if isinstance(v, tuple):
                out[e.address : e.address + len(v)] = v
            else:
                out[e.address] = v
        return out


class MjcfJoints(Mapping[str, object]):
    """A configuration's joints by MJCF name (hinge and slide: ``qpos``, ``ref`` included;
    ball: quaternion ``(w, x, y, z)``; free: position and quaternion; a tendon input: its
    length), and :attr:`qpos`, over the model's joint coordinates ``coordinates``.

    Args:
        coordinates: the model's joint coordinate -> value map of one configuration.
        layout: the model's qpos layout.
    """

    __slots__ = ("coordinates", "layout")

    def __init__(self, coordinates: Mapping[str, float], layout: QposLayout) -> None:
        self.coordinates, self.layout = coordinates, layout

    def __getitem__(self, name: str) -> object:
        for e in self.layout.entries:
            if e.name == name:
                return self.layout.value(e, self.coordinates)
        raise KeyError(name)

    def __iter__(self) -> Iterator[str]:
        return (e.name for e in self.layout.entries)

    def __len__(self) -> int:
        return len(self.layout.entries)

    def __repr__(self) -> str:
        return f"MjcfJoints({dict(self)!r})"

    @property
    def qpos(self) -> np.ndarray:
        """(nq,) MuJoCo's whole ``qpos`` (joints the model does not move at the file's
        home): ``data.qpos[:] = cfg.qpos``."""
        return self.layout.qpos(self.coordinates)
