"""Result types: immutable configurations and solver outputs."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

if TYPE_CHECKING:
    from .model.model import Model

_T = TypeVar("_T")


def frozen_array(a: np.ndarray) -> np.ndarray:
    """A read-only float copy of ``a``; ``a`` itself when it is already a read-only float
    array whose memory nothing can write (its base, if any, read-only too)."""
    if (
        isinstance(a, np.ndarray)
        and a.dtype == np.float64
        and not a.flags.writeable
        and (a.base is None or (isinstance(a.base, np.ndarray) and not a.base.flags.writeable))
    ):
        return a
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def frozen_joints(joints: Mapping[str, Any]) -> Mapping[str, Any]:
    """A read-only joint map: ``joints`` itself when it is read-only already (a
    :class:`JointValues`, a model read from MJCF's joints), else a read-only copy."""
    if isinstance(joints, JointValues) or hasattr(joints, "qpos"):
        return joints
    return MappingProxyType(dict(joints))


class JointValues(Mapping[str, float]):
    """A read-only joint name -> value map over one row of a read-only array: the joints of
    many configurations held as one table, a value read only when asked for.

    Args:
        columns: joint name -> column of ``row`` (iteration order: the joints' order).
        row: (C,) read-only values [rad or model length unit].
    """

    __slots__ = ("_columns", "_row")

    def __init__(self, columns: Mapping[str, int], row: np.ndarray) -> None:
        self._columns, self._row = columns, frozen_array(row)

    def __getitem__(self, name: str) -> float:
        return float(self._row[self._columns[name]])

    def __iter__(self) -> Iterator[str]:
        return iter(self._columns)

    def __len__(self) -> int:
        return len(self._columns)

    def __repr__(self) -> str:
        return f"JointValues({dict(self)!r})"

    @classmethod
    def rows(cls, columns: Mapping[str, int], table: np.ndarray) -> list[JointValues]:
        """One map per row of ``table`` (N, C), a read-only array whose memory nothing writes
        (the rows are views, not checked again)."""
        out = [object.__new__(cls) for _ in range(len(table))]
        for obj, row in zip(out, table, strict=True):
            obj._columns, obj._row = columns, row
        return out


def unchecked_many(cls: type[_T], count: int, **columns: Iterable[object]) -> list[_T]:
    """``count`` instances of the frozen dataclass ``cls``, field ``name`` of instance ``i``
    the ``i``-th item of ``columns[name]`` (each column: at least ``count`` items, e.g. the
    rows of an array, a list or ``itertools.repeat``), every field in its final form
    (read-only float arrays whose memory nothing writes, immutable maps, Python scalars):
    ``__init__`` and the copies and checks of ``__post_init__`` skipped, the fields set one
    by one over all instances. For the package's batch paths, which build many results from
    arrays they own."""
    out: list[_T] = [object.__new__(cls) for _ in range(count)]
    put = object.__setattr__
    for name, column in columns.items():
        for obj, value in zip(out, column, strict=False):
            put(obj, name, value)
    return out


@dataclass(frozen=True)
class Configuration:
    """An assembled configuration of a closed-chain model.

    Attributes:
        theta: (k,) actuated joint values [rad or model length unit].
        y: (m,) unknown joint values.
        x: (n,) workspace coordinates of the platform (or reported) frame.
        platform_pose: (4, 4) homogeneous placement of that frame in the base frame.
        joints: every movable URDF joint name -> value (locked idle joints included).
        residual: max |closure row| at this configuration [model length unit].
    """

    theta: np.ndarray
    y: np.ndarray
    x: np.ndarray
    platform_pose: np.ndarray
    joints: Mapping[str, float]
    residual: float = 0.0

    def __post_init__(self) -> None:
        for name in ("theta", "y", "x", "platform_pose"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        object.__setattr__(self, "joints", frozen_joints(self.joints))

    @property
    def qpos(self) -> np.ndarray | None:
        """(nq,) MuJoCo's whole ``qpos`` of a model read from MJCF (``data.qpos[:] =
        cfg.qpos``), else ``None``."""
        return getattr(self.joints, "qpos", None)

    @property
    def coordinates(self) -> Mapping[str, float]:
        """Every joint coordinate of the model's tree -> value (:attr:`joints` itself, but
        for a model read from MJCF, whose :attr:`joints` are by MJCF name)."""
        return getattr(self.joints, "coordinates", self.joints)

    def to_dict(self) -> dict:
        out = {
            "x": self.x.tolist(),
            "y": self.y.tolist(),
            "theta": self.theta.tolist(),
            "platform_pose": self.platform_pose.tolist(),
            "joints": dict(self.joints),
            "residual": float(self.residual),
        }
        if self.qpos is not None:
            out["qpos"] = self.qpos.tolist()
        return out


def mode_order(cfg: Configuration) -> tuple[float, ...]:
    """The sort key of assembly modes: ``x``, then ``y``, each rounded to 1e-8."""
    return mode_orders(cfg.x[None], cfg.y[None])[0]


def mode_orders(xs: np.ndarray, ys: np.ndarray) -> list[tuple[float, ...]]:
    """:func:`mode_order` of several configurations from their stacked ``x`` (N, n) and
    ``y`` (N, m): the keys Python's ``round(v, 8)`` gives, bit for bit.

    ``round(v, 8)`` is the double nearest to ``k 1e-8``, ``k`` the integer nearest to
    ``v 1e8``; so is ``rint(v * 1e8) / 1e8`` (one correctly rounded division of two exact
    doubles) wherever ``rint`` finds the same ``k``: when ``|v| < 1000`` (``v * 1e8`` then
    within 1e-5 of the exact product) and ``v * 1e8`` is not within 1e-3 of a half-integer;
    ``round`` itself rounds the other entries.
    """
    v = np.hstack([xs, ys])
    s = v * 1e8
    r = np.rint(s) / 1e8
    with np.errstate(invalid="ignore"):
        slow = ~((np.abs(v) < 1000.0) & (np.abs(s - np.floor(s) - 0.5) > 1e-3))
    if slow.any():
        r[slow] = [round(x, 8) for x in v[slow].tolist()]
    return [tuple(row) for row in r.tolist()]


#: Kinds of singular points met along a path.
CROSSING_KINDS = ("fold", "bifurcation")


@dataclass(frozen=True)
class Crossing:
    """A crossing of the singular manifold (``det J_p`` changes sign) along a path.

    Attributes:
        s: path parameter at the crossing (theta = theta1 + s (theta0 - theta1)).
        x: (n,) workspace coordinates at the crossing.
        y: (m,) unknown joint values at the crossing.
        theta: (k,) actuated joint values at the crossing.
        index: for tracks, the sample index after which the crossing occurs (-1 before the
            first sample, and for solves).
        kind: "fold" (the solution curve turns: ``s'`` and ``det J_p`` change sign together)
            or "bifurcation" (two solution branches cross: ``H = [J_p, -j_s]`` drops rank,
            ``det J_p`` changes sign while ``s`` keeps its direction).
    """

    s: float
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    index: int = -1
    kind: str = "fold"

    def __post_init__(self) -> None:
        for name in ("x", "y", "theta"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        object.__setattr__(self, "index", int(self.index))
        if self.kind not in CROSSING_KINDS:
            raise ValueError(f"unknown crossing kind {self.kind!r}; kinds: fold, bifurcation")

    def to_dict(self) -> dict:
        return {
            "s": float(self.s),
            "x": self.x.tolist(),
            "y": self.y.tolist(),
            "theta": self.theta.tolist(),
            "index": self.index,
            "kind": self.kind,
        }


@dataclass(frozen=True)
class PathSamples:
    """The sampled SC solution curve of a solve, for plots.

    Attributes:
        s: (N,) path parameter.
        y: (N, m) unknowns.
        x: (N, n) workspace coordinates.
        det_jp: (N,) ``det J_p``.
        sdot: (N,) ``s' = b det J_p`` (the paper's unnormalised field, b = +-1).
        arc: (N,) arc length along the curve (metric |dy|^2 + (|dtheta| ds)^2).
    """

    s: np.ndarray
    y: np.ndarray
    x: np.ndarray
    det_jp: np.ndarray
    sdot: np.ndarray
    arc: np.ndarray


@dataclass(frozen=True)
class SolveResult:
    """A verified direct-kinematics solution found by the SC method.

    Attributes:
        x: (n,) workspace coordinates of the solution.
        y: (m,) unknown joint values.
        theta: (k,) actuated joint values (= theta0).
        platform_pose: (4, 4) placement of the platform frame.
        joints: every movable joint -> value.
        residual: max |closure row| [model length unit] (verified <= tolerance).
        crossings: singular-manifold crossings along the path, in order.
        status: "converged".
        branch: "convergent" or "divergent" (sign of b det J_p at the start).
        b: the signed scalar of the field (+1 or -1 relative to nu).
        start: the start configuration.
        path: the sampled solution curve.
        backend: the backend that computed it ("cvodes", "compiled" or "c").
        fallback: why it was computed by ``backend`` rather than the one asked for (e.g. the
            generated C follower met a singular path and handed over to "compiled"); empty
            when the backend asked for answered.
        strategy: the divergent branch's way that answered
            (:data:`scdk_sym.solvers.divergent.DIVERGENT_STRATEGIES`: ``"paper"``, ``"nearest"``,
            ...); empty on the convergent branch.
    """

    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    platform_pose: np.ndarray
    joints: Mapping[str, float]
    residual: float
    crossings: tuple[Crossing, ...]
    status: str
    branch: str
    b: float
    start: Configuration
    path: PathSamples | None = field(default=None, repr=False)
    backend: str = ""
    fallback: str = ""
    strategy: str = ""

    @property
    def qpos(self) -> np.ndarray | None:
        """(nq,) MuJoCo's whole ``qpos`` of a model read from MJCF, else ``None``."""
        return getattr(self.joints, "qpos", None)

    @property
    def configuration(self) -> Configuration:
        return Configuration(
            self.theta, self.y, self.x, self.platform_pose, self.joints, self.residual
        )

    def to_dict(self) -> dict:
        d = self.configuration.to_dict()
        d.update(
            crossings=[c.to_dict() for c in self.crossings],
            status=self.status,
            branch=self.branch,
            backend=self.backend,
        )
        if self.fallback:
            d["fallback"] = self.fallback
        if self.strategy:
            d["strategy"] = self.strategy
        return d


@dataclass(frozen=True)
class TrackResult:
    """Direct kinematics along a sequence of joint readings.

    Attributes:
        x: (N, n) workspace coordinates at each sample.
        y: (N, m) unknowns at each sample (canonical).
        theta: (N, k) actuated values (the input).
        residual: (N,) max |closure row| at each sample [model length unit].
        crossings: singular-manifold crossings, each with ``index`` = the sample after which
            it occurs (between samples ``index`` and ``index + 1``).
        status: "converged".
        backend: the backend that computed it ("cvodes" or "c").
    """

    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    residual: np.ndarray
    crossings: tuple[Crossing, ...]
    status: str = "converged"
    backend: str = "cvodes"

    def __post_init__(self) -> None:
        for name in ("x", "y", "theta", "residual"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))

    def configurations(self, model: Model) -> tuple[Configuration, ...]:
        """Each sample as a :class:`Configuration` (platform pose and joint values included).

        Args:
            model: the :class:`~scdk_sym.model.model.Model` that was tracked.
        """
        return tuple(
            model.configuration(y, theta) for y, theta in zip(self.y, self.theta, strict=True)
        )

    def to_dict(self, model: Model | None = None) -> dict:
        """JSON-ready: ``x``, ``y``, ``theta``, ``residual`` per sample, ``crossings``,
        ``status``, ``backend``; with ``model``, also ``platform_pose`` (N, 4, 4) and
        ``joints`` (one name -> value object per sample) from :meth:`configurations`."""
        d = {
            "x": self.x.tolist(),
            "y": self.y.tolist(),
            "theta": self.theta.tolist(),
            "residual": self.residual.tolist(),
            "crossings": [c.to_dict() for c in self.crossings],
            "status": self.status,
            "backend": self.backend,
        }
        if model is not None:
            configs = self.configurations(model)
            d["platform_pose"] = [c.platform_pose.tolist() for c in configs]
            d["joints"] = [dict(c.joints) for c in configs]
        return d


@dataclass(frozen=True, eq=False)
class AssemblyModes(Sequence):
    """The real assembly modes at one ``theta``: a sequence of :class:`Configuration`.

    Behaves like the tuple of its configurations (``len``, iteration, indexing, slicing).

    Attributes:
        solutions: the configurations, sorted by ``x`` then ``y``; for a model whose blocks
            fall in independent groups (a biped's legs), a
            :class:`~scdk_sym.solvers.block_modes.ModeProduct` of the groups' sorted sets,
            whose configurations are built and verified when read (see ``groups``).
        certified: the set is proven complete and every member certified: the start system
            passed its trace test, every path reached ``t = 1`` at a regular endpoint or at
            infinity, and every real solution has a Krawczyk certificate, the boxes pairwise
            disjoint. Always False for the real-curve search.
        root_count: complex solutions tracked (the start system's size; 0 for the curve search).
        report: one line: what was proven, or why the set is not certified.
        certificates: one :class:`~scdk_sym.algebraic.certify.Certificate` per solution (in the
            order of ``solutions``); empty when none were computed.
        method: ``"homotopy"`` or ``"curves"``.
        blocks: for a model solved one block at a time
            (:mod:`scdk_sym.solvers.block_modes`), each block's sets: one
            :class:`~scdk_sym.solvers.block_modes.BlockModes` per value of its inputs, with
            their own certificates; empty otherwise.
        groups: the sizes of the independent groups' sets whose product ``solutions`` is
            (e.g. ``(8, 8)`` for a biped with 8 assemblies per leg); empty when ``solutions``
            is a plain tuple.
    """

    solutions: Sequence[Configuration] = ()
    certified: bool = False
    root_count: int = 0
    report: str = ""
    certificates: tuple = ()
    method: str = "homotopy"
    blocks: tuple = ()
    groups: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if not self.groups:
            object.__setattr__(self, "solutions", tuple(self.solutions))
        object.__setattr__(self, "groups", tuple(int(g) for g in self.groups))
        object.__setattr__(self, "certificates", tuple(self.certificates))
        object.__setattr__(self, "blocks", tuple(self.blocks))

    def __len__(self) -> int:
        return len(self.solutions)

    def __getitem__(self, index):
        return self.solutions[index]

    def __iter__(self):
        return iter(self.solutions)

    def to_dict(self) -> dict:
        """JSON-ready: ``solutions`` (each with its ``certified`` flag: its certificate's, or
        for a set certified block by block the set's), ``count``, ``certified``,
        ``root_count``, ``report``, ``method``, and ``groups`` for a product of groups' sets
        (every combination is listed)."""
        sols = []
        for i, s in enumerate(self.solutions):
            d = dict(s.to_dict(), crossings=[], status="converged")
            if self.blocks and not self.certificates:  # certified block by block
                d["certified"] = bool(self.certified)
            else:
                d["certified"] = bool(i < len(self.certificates) and self.certificates[i].proven)
            sols.append(d)
        return {
            "solutions": sols,
            "count": len(sols),
            "certified": bool(self.certified),
            "root_count": int(self.root_count),
            "report": self.report,
            "method": self.method,
            **({"groups": list(self.groups)} if self.groups else {}),
        }
