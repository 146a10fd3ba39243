"""Closed-chain models: URDF spanning tree + loop closures, loaded and reduced to a square system.

Loading validates every name, assembles the home configuration, and reduces a closure system
that is not square as written (redundant rows, idle freedoms) to an independent square one.
The description (URDF tree, closure YAML, charts) comes from :mod:`scdk_sym.model`; the
closure system is built by :mod:`scdk_sym.symbolic` and evaluated by :mod:`scdk_sym.kernels`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import replace
from functools import cached_property
from os import PathLike
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from ..errors import (
    InputError,
    ModelError,
    NonSquareSystemError,
    NotAssembledError,
    OutputError,
    UnknownNameError,
    UnreachableError,
)
from ..kernels.fastcall import model_calls
from ..kernels.functions import build_kernels
from ..model.chart import Chart
from ..model.edits import apply_joint_edits, ball_to_universal
from ..model.files import read_description
from ..model.qpos import MjcfJoints, QposLayout
from ..model.rotations import rot_exp, rot_log, rpy_matrix
from ..model.spec import Spec
from ..model.urdf import Tree, slides_along_carrier, tree_to_urdf
from ..products import Products
from ..results import Configuration, JointValues, unchecked_many
from ..symbolic.kinematics import link_placements
from ..symbolic.system import Symbolic, build_symbolic
from . import assembly
from .assembly import assemble, closure_rows, least_squares
from .diagnosis import weld_diagnosis
from .home import settle as settle_home

#: Workspace coordinates that are angles [rad].
ANGLE_COORDINATES = ("phi", "roll", "pitch", "yaw")
#: Relative tolerance of the assembled-configuration checks (scaled by the model size).
RESIDUAL_TOL = 1e-9
#: Redundant closure rows may disagree with the others by this much of the model's size (a
#: file's rounding) and be left out of the verification; more is an over-constraint.
REDUNDANT_TOL = 1e-5
#: A freedom the actuators leave undetermined is idle when it moves every joint by less than
#: this fraction of the model's size per unit of motion (a spin in place; CAD exports leave
#: offsets of a few 1e-4 m between axes meant to meet) [length unit / (rad or length unit)].
IDLE_TOL = 1e-3


def as_vector(value, size: int, what: str) -> np.ndarray:
    """Validate a finite 1-D array of a given size (raises :class:`InputError`)."""
    if value is None or isinstance(value, (str, bytes, dict)):
        raise InputError(f"{what} must be {size} numbers, got {value!r}")
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what} must be {size} numbers, got {value!r}") from exc
    if arr.size != size:
        raise InputError(f"{what} must have {size} values, got {arr.size}: {arr.tolist()}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{what} must be finite, got {arr.tolist()}")
    return arr


def distal_link(tree: Tree, closures, actuated: Sequence[str] = ()) -> str:
    """The default reported link of a model without ``platform``: the leaf link with the most
    movable joints between it and the root (a leg's foot), closure frames excluded, among the
    leaves that a joint the closures determine moves (not an arm or a gripper whose joints
    are all actuated, on a whole humanoid) when there are such; the first in URDF order among
    equals (the first leg's foot on a biped)."""
    parents = {j.child: j for j in tree.joints}
    ends = {f for c in closures for f in (c.frame_a, c.frame_b)}
    inner = {j.parent for j in tree.joints}
    best, rank = tree.links[-1], (False, -1)
    for link in tree.links:
        if link in inner or link in ends:
            continue
        n, passive, at = 0, False, link
        while at in parents:
            joint = parents[at]
            n += joint.movable
            passive = passive or (joint.movable and joint.name not in actuated)
            at = joint.parent
        if (passive, n) > rank:
            best, rank = link, (passive, n)
    return best


def _pivoted_selection(M: np.ndarray, count: int) -> list[int]:
    """Indices of ``count`` columns of M chosen by Gram-Schmidt with column pivoting."""
    A = np.array(M, dtype=float)
    chosen: list[int] = []
    for _ in range(count):
        norms = np.linalg.norm(A, axis=0)
        norms[chosen] = -1
        # the first of the columns tied with the largest (to rounding): the two revolutes on
        # one axis at a cut have equal columns, and argmax alone picks one by rounding
        i = int(np.flatnonzero(norms >= norms.max() * (1 - 1e-9))[0])
        chosen.append(i)
        u = A[:, i] / norms[i]
        A = A - np.outer(u, u @ A)
    return sorted(chosen)


def _closure_function(full: Symbolic, c0: np.ndarray) -> ca.Function:
    """(y, theta) -> (g_all, dg_all/dy, g_check, dg_check/dy, dg_all/dtheta,
    dg_check/dtheta) of the unreduced closures, in the chart ``c0``."""
    return ca.Function(
        "all",
        [full.y, full.theta],
        [
            ca.substitute(e, full.c, ca.DM(c0))
            for e in (
                full.g_all,
                ca.jacobian(full.g_all, full.y),
                full.g_check,
                ca.jacobian(full.g_check, full.y),
                ca.jacobian(full.g_all, full.theta),
                ca.jacobian(full.g_check, full.theta),
            )
        ],
    )


def _check_names(tree: Tree, spec: Spec, joint_frames: dict[str, str], path: str | None) -> None:
    """Every name of the spec exists in the tree: closure frames (links or joints), actuated
    joints (movable, one coordinate), length joints, home coordinates."""
    links, movable, single = tree.links, tree.coordinates, tree.single_coordinate_joints
    frames = (*links, *joint_frames)
    for c in spec.closures:
        if c.type == "coupling":
            for j in c.joints:
                if j not in single:
                    raise UnknownNameError(
                        "joint",
                        j,
                        single,
                        path,
                        None if j not in movable else "in a coupling is not a one-coordinate joint",
                    )
            continue
        for f in (c.frame_a, c.frame_b):
            if f not in links and f not in joint_frames:
                raise UnknownNameError("frame", f, frames, path)
    kinds = {j.name: j.type for j in tree.joints}
    for a in spec.actuated:
        if a not in single:
            if kinds.get(a) in ("fixed", "floating", "spherical"):
                reason = (
                    f"in 'name_mot' is a {kinds[a]} joint: only a movable joint with one "
                    "coordinate can be actuated"
                )
                raise UnknownNameError("movable joint", a, single, path, reason)
            raise UnknownNameError("joint", a, single, path)
    for c in spec.closures:
        if c.length_joint is not None and c.length_joint not in single:
            raise UnknownNameError("joint", c.length_joint, single, path)
    for j in spec.home:
        if j not in movable:
            raise UnknownNameError("joint", j, movable, path)


def _names_list(value: Any, what: str, path: str | None) -> tuple[str, ...]:
    """A list of distinct joint names (``inputs=``)."""
    if isinstance(value, str) or not all(isinstance(v, str) for v in value):
        raise InputError(f"{what} must be a list of joint names, got {value!r}")
    names = tuple(value)
    if not names:
        raise InputError(f"{what} is empty: at least one input joint is needed")
    if len(set(names)) != len(names):
        raise InputError(f"{what} has duplicates: {list(names)}")
    return names


def _held(
    tree: Tree, spec: Spec, locked: Mapping[str, float] | None, path: str | None
) -> dict[str, float]:
    """``locked=``: one-coordinate joints, not inputs, each with a finite value."""
    if locked is None:
        return {}
    if not isinstance(locked, Mapping):
        raise InputError(f"locked must map joint names to values, got {locked!r}")
    single = tree.single_coordinate_joints
    out = {}
    for name, value in locked.items():
        if name not in single:
            raise UnknownNameError("joint", name, single, path,
                                   None if name not in tree.coordinates
                                   else "in locked= is not a one-coordinate joint")  # fmt: skip
        if name in spec.actuated:
            raise InputError(f"joint {name!r} is both an input and locked; choose one")
        try:
            v = float(value)
        except (TypeError, ValueError):
            v = float("nan")
        if not np.isfinite(v):
            raise InputError(f"locked value of {name!r} must be a finite number, got {value!r}")
        out[name] = v
    return out


def _reported_frame(
    tree: Tree, spec: Spec, joint_frames: dict[str, str], frame: str | None, path: str | None
) -> str:
    """The link whose pose is reported: ``frame``, else the spec's platform, else a link
    named ``effector``, else the distal link of the closures (a joint stands for its child)."""
    chosen = frame or spec.platform
    if chosen is None:
        chosen = (
            "effector"
            if "effector" in tree.links
            else distal_link(tree, spec.closures, spec.actuated)
        )
    if chosen not in tree.links and chosen not in joint_frames:
        raise UnknownNameError("frame", chosen, (*tree.links, *joint_frames), path)
    return joint_frames.get(chosen, chosen)


def _workspace(spec: Spec, path: str | None) -> tuple[str, ...]:
    """The spec's workspace coordinates, else the pose (with a platform) or the position."""
    if spec.workspace is not None:
        workspace = spec.workspace
    elif spec.platform is not None:
        workspace = ("x", "y", "z", "roll", "pitch", "yaw")
    else:
        workspace = ("x", "y", "z")
    rot = {"roll", "pitch", "yaw"} & set(workspace)
    if rot and rot != {"yaw"} and rot != {"roll", "pitch", "yaw"}:
        raise ModelError(
            f"workspace {list(workspace)}: give all of roll, pitch, yaw or only yaw", path
        )
    return tuple(workspace)


class Model:
    """A closed-chain manipulator: spanning tree, closures, actuated and unknown joints.

    Use :func:`load_model` or a builder of :mod:`scdk_sym.builders` to make one.

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

    #: (index, :class:`~scdk_sym.robot.blocks.Block`) of a block model, ``None`` otherwise.
    block: tuple[int, Any] | None = None
    #: What distinguishes a block model's cache key from its parent's (empty otherwise).
    _restriction: tuple[str, ...] = ()
    #: Rows of the full closure system left out of the verification: redundant rows that a
    #: file's rounding makes slightly inconsistent with the others (see
    #: :meth:`_inconsistent_rows`); their residual is reported in :attr:`reduction`.
    unchecked: tuple[int, ...] = ()

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
            spec = replace(spec, actuated=_names_list(inputs, "inputs", path))
        self.tree = tree
        self.spec = spec
        self.path = path
        self.name = tree.name
        #: where the model came from when not URDF + YAML (an MJCF file: its qpos layout,
        #: what loading decided), else ``None``
        self.source = source
        # a frame is a link, or a joint (as in Pinocchio: the joint frame is its child link's)
        joint_frames = {j.name: j.child for j in tree.joints if j.name not in tree.links}
        _check_names(tree, spec, joint_frames, path)
        #: joints held at given values (``locked=``, an MJCF file's springs) -> value
        self.held = _held(tree, spec, locked, path)
        self.frame = _reported_frame(tree, spec, joint_frames, frame, path)
        workspace = _workspace(spec, path)
        self.workspace = tuple(workspace)
        self.actuated = tuple(spec.actuated)
        self.closures = tuple(
            replace(
                c,
                frame_a=joint_frames.get(c.frame_a, c.frame_a),
                frame_b=joint_frames.get(c.frame_b, c.frame_b),
            )
            for c in spec.closures
        )
        candidates = tuple(
            j for j in tree.coordinates if j not in self.actuated and j not in self.held
        )
        if not candidates:
            raise ModelError("no unknown joints: every movable joint is actuated", path)
        if not spec.closures:
            raise ModelError("no loop closures: 'closed_loop' is empty", path)
        self.length_scale = self._size()
        self.tolerance = RESIDUAL_TOL * max(1.0, self.length_scale)
        self._candidates = candidates
        self.assembly: str | None = None
        #: ball joint -> (rotation at home (3, 3), spin axis (3,)) of the balls turned into
        #: universal joints to lock a rod's spin (see :meth:`_lock_spins`)
        self.spins: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._preferred: tuple[int, ...] | None = None
        self._reduce(candidates)
        if source is not None:
            self.unchecked = self._inconsistent_rows()

    # ------------------------------------------------------------------ loading helpers

    def _size(self) -> float:
        # a numeric forward pass with every joint at zero
        T = link_placements(self.tree, dict.fromkeys(self.tree.coordinates, 0.0))
        pos = np.array([np.array(ca.DM(t[:3, 3])).ravel() for t in T.values()])
        return float(np.max(np.linalg.norm(pos - pos[0], axis=1)))

    def _reduce(self, candidates: tuple[str, ...], start: dict[str, float] | None = None) -> None:
        """Reduce the closures over ``candidates`` to a square system at home (or at
        ``start``, projected): redundant rows dropped, idle joints locked (rod spins turned
        into universal joints), the assembled home kept."""
        full = build_symbolic(
            self.tree,
            self.closures,
            self.actuated,
            candidates,
            self.held,
            None,
            self.frame,
            self.workspace,
        )
        chart = Chart.for_unknowns(candidates, self.tree.rotation_joints)
        given = self.spec.home if start is None else start
        y0 = np.array([given.get(j, 0.0) for j in candidates])
        th0 = np.array([given.get(j, 0.0) for j in self.actuated])
        y0, c0 = chart.to_local(y0)
        f_all = _closure_function(full, c0)
        y0, th0 = self._assembled(full, c0, f_all, y0, th0, start is not None)
        G = np.array(f_all(y0, th0)[1])
        nrows, ncols = G.shape
        rows, keep, rank, note = self._square_selection(full, f_all, G, y0, th0, c0, candidates)
        self.rows = tuple(rows)
        self.unknowns = tuple(candidates[c] for c in keep)
        floating_locked = [
            candidates[c] for c in range(ncols) if c not in keep and "." in candidates[c]
        ]
        balls = sorted({n.partition(".")[0] for n in floating_locked})
        if (
            floating_locked
            and start is None
            and all(self.tree.joint(b).type == "spherical" for b in balls)
        ):
            self._lock_spins(balls, candidates, G, rank, y0, c0, th0, chart)
            return
        if floating_locked:
            raise NonSquareSystemError(
                f"{ncols} unknown joints, {nrows} closure rows, rank {rank}: the reduction would "
                f"lock floating coordinates {floating_locked}; cannot reduce to a square system",
                nrows,
                ncols,
                rank,
                self.path,
            )
        self.locked = {
            **self.held,
            **{candidates[c]: float(y0[c]) for c in range(ncols) if c not in keep},
        }
        self.reduction = note
        self.chart = Chart.for_unknowns(self.unknowns, self.tree.rotation_joints)
        self._home_y = chart.to_canonical(y0, c0)[keep]
        self._home_theta = th0

    def _assembled(self, full, c0, f_all, y0, th0, projected: bool):
        """The start ``(y0, th0)`` assembled: projected (``projected``), the spec's home as
        given (refused when it does not close), or assembled from the neutral configuration
        when the spec has no home."""
        check = np.abs(np.array(f_all(y0, th0)[2])).ravel()
        if projected:
            return self._project(f_all, y0, th0), th0
        if getattr(self.source, "settle_home", False):
            return self._settled(f_all, y0, th0)
        if self.spec.home:
            if check.max() > self.tolerance:
                raise NotAssembledError(
                    f"'home' is not assembled: {self._worst(check)} "
                    f"(tolerance {self.tolerance:.1e})",
                    float(check.max()),
                    self.path,
                )
            return y0, th0
        y0 = self._project(f_all, y0, th0)
        check = np.abs(np.array(f_all(y0, th0)[2])).ravel()
        if check.max() > self.tolerance:
            y0, th0 = self._assemble(full, c0, f_all, y0, th0, check)
        return y0, th0

    def _settled(self, f_all, y0, th0):
        """A stated home projected onto the closures and moved off a singular configuration
        (see :mod:`scdk_sym.robot.home`); what was done goes into :attr:`assembly`."""

        def rows(y, th):
            g, Gy, _, _, Gt, _ = (np.array(v) for v in f_all(y, th))
            return g.ravel(), Gy, Gt

        names = (*self._candidates, *self.actuated)
        done = settle_home(rows, y0, th0, names, 1e-2 * self.tolerance)
        check = np.abs(np.array(f_all(done.y, done.theta)[2])).ravel()
        if done.subset is not None:  # the rows home closes; the others within rounding
            g = np.abs(rows(done.y, done.theta)[0])
            rest = float(np.delete(g, list(done.subset)).max(initial=0.0))
            self._preferred = done.subset
            check = g[list(done.subset)] if rest <= REDUNDANT_TOL * self.length_scale else g
        if check.max() > self.tolerance:
            raise NotAssembledError(
                f"home does not assemble: {self._worst(check)} after a least-change projection "
                f"over every joint (tolerance {self.tolerance:.1e}); {self.source.home_hint}",
                float(check.max()),
                self.path,
            )
        if not done.regular:
            raise NotAssembledError(
                f"{done.note}: a start must be regular; give a regular home (MJCF: a keyframe "
                "named 'home') or other inputs (inputs=[...])",
                float(check.max()),
                self.path,
            )
        self.assembly = done.note or None
        return done.y, done.theta

    def _inconsistent_rows(self, samples: int = 6, spread: float = 0.5) -> tuple[int, ...]:
        """The dropped redundant rows that disagree with the kept ones by more than the
        tolerance, but within rounding (:data:`REDUNDANT_TOL` of the model size), at home or
        along continuations of the kept rows to seeded inputs up to ``spread`` away; what they
        do is said in :attr:`reduction`. Disagreeing beyond rounding is refused.

        Raises:
            NonSquareSystemError: a dropped row disagrees beyond rounding.
        """
        dropped = [r for r in range(int(self.row_offsets[-1])) if r not in self.rows]
        if not dropped:
            return ()
        sym = build_symbolic(self.tree, self.closures, self.actuated, self.unknowns,
                             self.locked, self.rows, self.frame, self.workspace)  # fmt: skip
        f = ca.Function("redundant", [sym.y, sym.theta, sym.c], [sym.g, sym.J_p, sym.g_all])
        y0, c = self.chart.to_local(self._home_y)
        rng = np.random.default_rng(0)
        worst = np.abs(np.array(f(y0, self._home_theta, c)[2])).ravel()
        for _ in range(samples):  # a continuation in 10 steps to a random nearby input
            step = spread * rng.standard_normal(self.k) / 10
            y = y0.copy()
            for i in range(1, 11):
                theta = self._home_theta + i * step
                for _ in range(12):
                    g, J, _ = (np.array(v) for v in f(y, theta, c))
                    if np.abs(g).max() < 1e-14 * max(1.0, self.length_scale):
                        break
                    y = y - np.linalg.lstsq(J, g.ravel(), rcond=1e-12)[0]
                else:
                    break  # no solution of the kept rows on the way: nothing to compare
                worst = np.maximum(worst, np.abs(np.array(f(y, theta, c)[2])).ravel())
        bad = [r for r in dropped if worst[r] > self.tolerance]
        if not bad:
            return ()
        labels = self.row_labels()
        big = [labels[r] for r in bad if worst[r] > REDUNDANT_TOL * self.length_scale]
        if big:
            raise NonSquareSystemError(
                f"redundant closure row(s) {big} disagree with the others by up to "
                f"{worst[bad].max():.2g} away from home: the closures over-constrain the "
                "mechanism beyond rounding; check the file's geometry or lock a joint",
                int(self.row_offsets[-1]),
                len(self._candidates),
                len(self.rows),
                self.path,
            )
        self.reduction = (self.reduction or "reduced to a square system") + (
            f"; redundant row(s) {[labels[r] for r in bad]} disagree with the others by up to "
            f"{worst[bad].max():.2g} (the file's rounding): solved on an independent subset, "
            "those rows left out of the verification"
        )
        return tuple(bad)

    def _square_selection(self, full, f_all, G, y0, th0, c0, candidates):
        """``(rows, keep, rank, note)``: the closure rows and unknowns of a square system of
        full rank at the start (pivoted selections; chart coordinates of floating and ball
        joints kept first), idle freedoms judged by what they move, and a note saying what
        was dropped and locked (``None`` when nothing was)."""
        nrows, ncols = G.shape
        sv = np.linalg.svd(G, compute_uv=False)
        rank = int(np.sum(sv > 1e-8 * max(1.0, sv[0] if sv.size else 1.0)))
        if rank == 0:
            raise NonSquareSystemError(
                f"the closures do not constrain any unknown joint ({', '.join(candidates)})",
                nrows,
                ncols,
                rank,
                self.path,
            )
        labels = self.row_labels()
        self._check_actuation(G, np.array(f_all(y0, th0)[4]), rank, labels)
        if rank == nrows == ncols:
            return list(range(nrows)), list(range(ncols)), rank, None
        weight = np.ones(nrows)
        if self._preferred is not None:  # rows home closes first (see :meth:`_settled`)
            weight[[r for r in range(nrows) if r not in self._preferred]] = 1e-6
        rows = _pivoted_selection((G * weight[:, None]).T, rank)
        keep = _pivoted_selection(G[rows], rank)
        if any("." in candidates[c] for c in range(ncols) if c not in keep):
            # lock single-coordinate joints: weigh the chart coordinates up so that the
            # pivoting keeps them (a spin is locked at a revolute of its chain)
            weight = np.array([1e3 if "." in n else 1.0 for n in candidates])
            keep = _pivoted_selection(G[rows] * weight, rank)
        idle = [c for c in range(ncols) if c not in keep]
        dropped = [labels[r] for r in range(nrows) if r not in rows]
        if idle:
            self._judge_idle(full, y0, th0, c0, G, rank, candidates, dropped)
        parts = [f"{nrows} rows x {ncols} unknowns, rank {rank}"]
        if dropped:
            parts.append(f"dropped {len(dropped)} redundant row(s) {dropped}")
        if idle:
            parts.append(f"locked idle joint(s) {[candidates[c] for c in idle]} at home")
        return rows, keep, rank, "reduced to a square system: " + "; ".join(parts)

    def _lock_spins(
        self,
        balls: list[str],
        candidates: tuple[str, ...],
        G: np.ndarray,
        rank: int,
        y0: np.ndarray,
        c0: np.ndarray,
        th0: np.ndarray,
        chart: Chart,
    ) -> None:
        """Lock the spins of rods between two ball joints: each ball joint whose coordinates
        the reduction would lock becomes a universal joint without the spin (its rotation at
        home folded into its origin), then the model is reduced again from the same home."""
        _, _, Vt = np.linalg.svd(G)
        null = Vt[rank:].T
        canonical = chart.to_canonical(y0, c0)
        values = dict(zip(candidates, canonical.tolist(), strict=True))
        values.update(zip(self.actuated, th0.tolist(), strict=True))
        tree = self.tree
        for ball in balls:
            idx = [candidates.index(f"{ball}.{c}") for c in ("rx", "ry", "rz")]
            u, _, _ = np.linalg.svd(null[idx])
            rotation = rot_exp(canonical[idx])
            tree = ball_to_universal(tree, ball, rotation, u[:, 0])
            self.spins[ball] = (rotation, u[:, 0])
        self.tree = tree
        candidates = tuple(
            j for j in tree.coordinates if j not in self.actuated and j not in self.held
        )
        self._candidates = candidates
        self._reduce(candidates, values)
        turned = ", ".join(balls)
        self.reduction = (self.reduction or "reduced to a square system") + (
            f"; ball joint(s) {turned} turned into universal joints (the spin of a rod between "
            "two ball joints locked at home)"
        )

    def _judge_idle(
        self,
        full: Symbolic,
        y0: np.ndarray,
        th0: np.ndarray,
        c0: np.ndarray,
        G: np.ndarray,
        rank: int,
        candidates: tuple[str, ...],
        dropped: list[str],
    ) -> None:
        """Refuse freedoms the actuators leave undetermined unless they are idle.

        A null direction of the closure Jacobian ``G`` (actuators fixed) is idle when it moves
        no joint of the mechanism: the bodies it turns spin in place about axes through all
        their joints (a rod between two ball joints turning about its own axis, two revolutes
        on one axis at a cut), and so move nothing but themselves. Every joint of the tree is
        judged (the origin of its child link), not one frame. A freedom that moves a joint is a
        real lack of actuation: refused, naming the links it moves. The reported frame must
        not turn either when the workspace has orientations.
        """
        nrows, ncols = G.shape
        _, _, Vt = np.linalg.svd(G)
        null = Vt[rank:].T
        links = [j.child for j in self.tree.joints if j.movable]
        origins = ca.vertcat(*[full.placements[lk][:3, 3] for lk in links])
        turn = ca.vec(full.pose[:3, :3])
        jac = ca.Function(
            "idle", [full.y, full.theta, full.c], [ca.jacobian(ca.vertcat(origins, turn), full.y)]
        )
        J = np.array(jac(y0, th0, c0))
        V = (J @ null)[: 3 * len(links)].reshape(len(links), 3, -1)
        speed = np.abs(V).max(axis=(1, 2))
        tol = IDLE_TOL * self.length_scale
        moved = [lk for lk, v in zip(links, speed, strict=True) if v > tol]
        if moved:  # the reported frame first when the freedom moves it
            jx = ca.Function(
                "frame", [full.y, full.theta, full.c], [ca.jacobian(full.pose[:3, 3], full.y)]
            )
            if np.abs(np.array(jx(y0, th0, c0)) @ null).max() > tol:
                moved = [self.frame, *(lk for lk in moved if lk != self.frame)]
        names = [candidates[c] for c in range(ncols) if np.abs(null[c]).max() > 1e-6]
        if moved:
            sv = np.linalg.svd(V.reshape(-1, V.shape[-1]), compute_uv=False)
            real = int(np.sum(sv > tol))
            shown = moved if len(moved) <= 8 else [*moved[:8], f"... {len(moved) - 8} more"]
            raise NonSquareSystemError(
                f"{ncols} unknown joints, {nrows} closure rows, rank {rank}: {real} freedom(s) "
                f"left undetermined by the actuators {list(self.actuated)} move links {shown} "
                f"(joints {names}; dependent rows {dropped}); the mechanism is under-actuated: "
                "add the missing actuators to 'name_mot' (or inputs=[...]), hold joints "
                "(locked={...}), or add a closure that fixes them",
                nrows,
                ncols,
                rank,
                self.path,
            )
        rotations = {"roll", "pitch", "yaw", "phi"} & set(self.workspace)
        if rotations and np.abs(J[3 * len(links) :] @ null).max() > IDLE_TOL:
            raise NonSquareSystemError(
                f"frame {self.frame!r} turns with idle joints {names} (it spins in place): its "
                f"orientation {sorted(rotations)} is not determined; report another link "
                "(frame=...) or a workspace of positions only",
                nrows,
                ncols,
                rank,
                self.path,
            )

    def _assemble(
        self,
        full: Symbolic,
        c0: np.ndarray,
        f_all: ca.Function,
        y: np.ndarray,
        theta: np.ndarray,
        check: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Assemble from the neutral configuration over every joint (actuators too), where a
        least-squares projection with the actuators at zero does not close the loops.

        Returns:
            (y, theta): the assembled unknowns (chart centred at neutral) and actuators.

        Raises:
            NotAssembledError: no seed assembles (says how far the projection got).
        """

        m = y.size
        z0 = np.zeros(m + self.k)
        found = assemble(
            lambda start: closure_rows(full, self.closures, c0, start),
            z0,
            1e-2 * self.tolerance,
            np.concatenate([y, theta]),
        )
        worst = np.inf
        if found is not None:
            worst = float(np.abs(np.array(f_all(found.z[:m], found.z[m:])[2])).max())
        if found is None or worst > self.tolerance:
            suspects = slides_along_carrier(self.tree, self.actuated)
            hint = "add 'home' to the YAML"
            welds = self._weld_diagnosis(c0, np.concatenate([y, theta]))
            if welds:
                hint = welds
            elif suspects:
                listed = ", ".join(f"{p} along the axis of revolute {r}" for p, r in suspects)
                hint = (
                    f"linear actuators that slide only along their own hinge axis ({listed}) "
                    "cannot drive a loop: check those joint axes in the URDF, or add 'home'"
                )
            raise NotAssembledError(
                "no 'home' given, and the neutral configuration does not assemble (least "
                f"squares: {self._worst(check)}; continuation from a relaxed closure over "
                f"every joint failed from {assembly.SEEDS + 1} starts); {hint}",
                float(check.max()),
                self.path,
            )
        names = (*self._candidates, *self.actuated)
        found = self._nearest_turns(found, names)
        far = int(np.argmax(np.abs(found.z)))
        start = "the neutral configuration" if found.seed == 0 else f"perturbed seed {found.seed}"
        self.assembly = (
            f"assembled from {start} by continuation from a relaxed closure over every joint "
            f"({found.steps} steps, residual {found.residual:.1e}); largest change from neutral "
            f"{found.change:.3g} ({names[far]}); write it as 'home' with `scdk assemble --write`"
        )
        return found.z[:m], found.z[m:]

    def _weld_diagnosis(self, c0: np.ndarray, z: np.ndarray) -> str:
        """A sentence when the welds are what keeps the model from assembling, else empty
        (see :mod:`scdk_sym.robot.diagnosis`)."""

        def build(closures):
            return build_symbolic(self.tree, closures, self.actuated, self._candidates,
                                  self.held, None, self.frame, self.workspace)  # fmt: skip

        return weld_diagnosis(build, self.closures, c0, z, self.tolerance)

    def _nearest_turns(self, found: assembly.Assembly, names: Sequence[str]) -> assembly.Assembly:
        """``found`` with each revolute angle replaced by the equivalent one (a whole number
        of turns away) nearest to neutral within the joint's limits (a continuation may wind a
        joint past a turn: -6.08 rad where 0.20 rad is the same configuration and the only one
        within the URDF's limits)."""
        z = found.z.copy()
        joints = {j.name: j for j in self.tree.joints}
        for i, name in enumerate(names):
            joint = joints.get(name)
            if joint is None or joint.type not in ("revolute", "continuous"):
                continue
            turns = z[i] + 2.0 * np.pi * np.arange(-3, 4)
            inside = turns[(turns >= joint.lower) & (turns <= joint.upper)]
            if inside.size:
                z[i] = inside[np.argmin(np.abs(inside))]
        return replace(found, z=z, change=float(np.abs(z).max()))

    def _check_actuation(self, G: np.ndarray, G_theta: np.ndarray, rank: int, labels) -> None:
        """Refuse more actuators than the mechanism has freedoms (rows that bind theta alone).

        With ``rank [G, G_theta] > rank G`` at home, some closure rows constrain the actuated
        joints whatever the unknowns: the actuators cannot be set independently and almost
        every ``theta`` has no assembly.
        """
        both = np.hstack([G, G_theta])
        sv = np.linalg.svd(both, compute_uv=False)
        full = int(np.sum(sv > 1e-8 * max(1.0, sv[0] if sv.size else 1.0)))
        if full <= rank:
            return
        nrows, ncols = G.shape
        dof = ncols + self.k - full
        # the rows outside the span of G's rows that involve theta
        U, _, _ = np.linalg.svd(G)
        left = U[:, rank:]  # combinations of rows free of y
        bound = [labels[r] for r in range(nrows) if np.abs(left[r]).max() > 1e-6]
        raise NonSquareSystemError(
            f"over-actuated: {self.k} actuated joints {list(self.actuated)} but the mechanism "
            f"has {dof} degree(s) of freedom ({ncols} unknown + {self.k} actuated coordinates, "
            f"{full} independent closure rows, {full - rank} binding the actuators alone: "
            f"{bound}); remove {full - rank} joint(s) from 'name_mot', or check the joint "
            "types (a ball joint written as one revolute over-constrains its loop)",
            nrows,
            ncols,
            rank,
            self.path,
        )

    def row_labels(self) -> list[str]:
        """A label per closure row of the full (unreduced) system, ``"<closure>.<row>"``
        (``x``, ``y``, ``z``, ``rx``, ``ry``, ``rz`` or ``d``)."""
        labels: list[str] = []
        for c in self.spec.closures:
            comps = {
                "3d": "xyz",
                "2d": "xy",
                "distance": ["d"],
                "6d": ["x", "y", "z", "rx", "ry", "rz"],
                "coupling": ["q"],
            }
            labels.extend(f"{c.label}.{k}" for k in comps[c.type])
        return labels

    def _worst(self, check: np.ndarray) -> str:
        sizes = [c.rows + (9 if c.type == "6d" else 0) for c in self.spec.closures]
        i = int(np.argmax(check))
        start = 0
        for c, n in zip(self.spec.closures, sizes, strict=True):
            if i < start + n:
                return f"closure {c.label} violated by {check[i]:.3g}"
            start += n
        return f"residual {check.max():.3g}"

    @staticmethod
    def _project(f_all: ca.Function, y: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Levenberg-Marquardt least squares on the closures over y (theta fixed).

        The verification rows are minimised (for 6d closures the whole ``R_a^T R_b - I``):
        the skew part alone also vanishes at a half turn, a false minimum.

        Every step is a minimum-norm one: it has no component along the directions the
        closures do not see (singular values below ``1e-10`` of the largest). Where the
        closures leave idle freedoms (joints locked at the result), a step along them would be
        driven by rounding alone, and the locked values would depend on the floating-point
        library; this way the result is the same on every machine to rounding.
        """

        def rows(yv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            _, _, g, J, *_ = (np.array(v) for v in f_all(yv, theta))
            return g.ravel(), J

        return least_squares(rows, y)[0]

    @cached_property
    def row_offsets(self) -> np.ndarray:
        """(closures + 1,) int: closure ``i``'s rows of the full closure system are
        ``row_offsets[i]`` to ``row_offsets[i + 1] - 1`` (``rows`` indexes that system)."""
        offsets = np.cumsum([0, *[c.rows for c in self.closures]])
        offsets.flags.writeable = False
        return offsets

    # ------------------------------------------------------------------ products

    @cached_property
    def products(self) -> Products:
        """The solver products built for this model (:class:`~scdk_sym.products.Products`:
        kernels, compiled libraries, algebraic forms...; declared in :mod:`scdk_sym.products`)."""
        return Products()

    @cached_property
    def symbolic(self):
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
    def blocks(self) -> tuple[Model, ...]:
        """One model per independent block of the closure system (the legs of a biped; see
        :mod:`scdk_sym.robot.blocks`), or ``(self,)`` when it does not split (or for a block
        model). Assign ``(model,)`` to solve the whole system at once."""
        if self.block is not None:
            return (self,)
        from .blocks import block_models

        return block_models(self)

    @cached_property
    def stages(self) -> tuple[Model, ...]:
        """One model per block of the block-triangular decomposition of the closure system,
        dependencies first (a leg's knee four-bar, then its ankle mechanism, whose model takes
        the knee's unknowns as extra actuators; see
        :func:`~scdk_sym.robot.blocks.triangular_models`): what ``track`` runs, one block
        after the other, each sample of a block read from the samples of the blocks before it.
        :attr:`blocks` below :data:`~scdk_sym.robot.blocks.BLOCK_MIN_UNKNOWNS` unknowns, or
        when the decomposition refines nothing (or an input is not a one-coordinate joint).
        Assign ``(model,)`` to track the whole system at once."""
        from .blocks import BLOCK_MIN_UNKNOWNS, triangular_models

        if self.block is not None or self.m < BLOCK_MIN_UNKNOWNS:
            return self.blocks
        stages = triangular_models(self)
        return stages if len(stages) > 1 else self.blocks

    @cached_property
    def kernels(self):
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
        (see :meth:`restricted`), also of its unknowns, actuators and rows."""
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

    @classmethod
    def restricted(
        cls,
        parent: Model,
        unknowns: tuple[str, ...],
        actuated: tuple[str, ...],
        closures: tuple,
        rows: tuple[int, ...],
        held: dict[str, float],
        block: tuple[int, object],
        unchecked: tuple[int, ...] = (),
    ) -> Model:
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
        sub._candidates = unknowns
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

    # ------------------------------------------------------------------ configurations

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
        row = JointValues(self._joint_columns, self._joint_table(y[None], theta[None])[0])
        if self.qpos_layout is not None:
            return MjcfJoints(row, self.qpos_layout)
        return dict(row)

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

    def _joint_table(self, ys: np.ndarray, thetas: np.ndarray) -> np.ndarray:
        """(N, C) read-only joint values of canonical ``ys`` (N, m) and ``thetas`` (N, k),
        columns as :attr:`_joint_columns` says."""
        locked = np.broadcast_to(np.array(list(self.locked.values()), dtype=float),
                                 (len(ys), len(self.locked)))  # fmt: skip
        out = np.hstack([locked, ys, thetas])
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

    def inverse_kinematics(self, x: ArrayLike) -> Configuration:
        """An assembled configuration whose platform has workspace coordinates ``x``.

        Continuation from the home configuration along a straight line in position and a
        geodesic in orientation, with Newton corrections on ``[g; pose error]`` over all
        joints: the result stays in the working modes of ``home``.

        Args:
            x: (n,) workspace coordinates, in the order of ``model.workspace``.

        Raises:
            InputError: wrong size or non-finite values.
            UnreachableError: no configuration in the home working mode reaches ``x``.
        """
        if len(self.workspace) != self.k:
            raise InputError(
                f"inverse kinematics needs as many workspace coordinates as actuators: "
                f"workspace {list(self.workspace)} vs actuated {list(self.actuated)}"
            )
        T_goal = self.target_pose(x)
        T0 = np.array(self.home.platform_pose)
        dp = T_goal[:3, 3] - T0[:3, 3]
        w = rot_log(T0[:3, :3].T @ T_goal[:3, :3])
        y_loc, c = self.chart.to_local(self.home.y)
        z = np.concatenate([y_loc, self.home.theta])
        lam, step = 0.0, 1.0
        tol = self.tolerance * 1e-2
        scale = max(1.0, self.length_scale)
        while lam < 1.0:
            trial = min(1.0, lam + step)
            T = np.eye(4)
            T[:3, 3] = T0[:3, 3] + trial * dp
            T[:3, :3] = T0[:3, :3] @ rot_exp(trial * w)
            zk, ok = z.copy(), False
            for _ in range(12):
                zn, res = self.kernels.ik_step(zk, T, c)
                zn = np.array(zn).ravel()
                if not np.all(np.isfinite(zn)) or np.linalg.norm(zn - z, np.inf) > 0.5 * scale:
                    break
                zk = zn
                if float(res) < tol:
                    ok = True
                    break
            if ok:
                z, lam = zk, trial
                step = min(1.0, step * 2)
                y_loc, c = self.chart.recentre(z[: self.m], c)
                z = np.concatenate([y_loc, z[self.m :]])
            else:
                step /= 2
                if step < 1e-5:
                    raise UnreachableError(
                        f"pose x={list(map(float, as_vector(x, len(self.workspace), 'x')))} "
                        f"is not reachable in the home working mode (continuation stalled at "
                        f"{lam:.3f} of the way from home)"
                    )
        cfg = self.configuration(z[: self.m], z[self.m :], c)
        if cfg.residual > self.tolerance:
            raise UnreachableError(
                f"inverse kinematics did not assemble (residual {cfg.residual:.2e})"
            )
        return cfg

    # ------------------------------------------------------------------ saving

    def save(self, directory: str | Path) -> Path:
        """Write ``robot.urdf`` and ``robot.yaml`` into ``directory`` (created if needed).

        Raises:
            OutputError: ``directory`` is a file or cannot be written.
        """
        d = Path(directory)
        if d.exists() and not d.is_dir():
            raise OutputError("is a file, not a folder; choose a folder to save the model in", d)
        try:
            d.mkdir(parents=True, exist_ok=True)
            (d / "robot.urdf").write_text(self._urdf_text)
            (d / "robot.yaml").write_text(self.spec.to_yaml())
        except OSError as exc:
            raise OutputError(f"cannot save the model: {exc.strerror or exc}", d) from exc
        return d

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
        from .info import describe

        return describe(self)

    def __repr__(self) -> str:
        return (
            f"Model({self.name!r}, actuated={list(self.actuated)}, unknowns={list(self.unknowns)}, "
            f"workspace={list(self.workspace)}, frame={self.frame!r})"
        )


def load_model(
    path: str | Path,
    frame: str | None = None,
    *,
    inputs: Sequence[str] | None = None,
    locked: Mapping[str, float] | None = None,
) -> Model:
    """Load a model: a directory holding ``robot.urdf`` + ``robot.yaml`` (or the YAML path),
    or an MJCF file (``.xml``, read by MuJoCo's compiler: ``pip install "scdk_sym[mjcf]"``).

    Args:
        path: model directory, the path of its YAML file (the URDF is ``robot.urdf`` beside
            it, or the YAML's name with ``.urdf``), or an MJCF ``.xml`` file.
        frame: link whose pose is reported as x, or a joint (its child link's frame, as in
            Pinocchio) (default: the YAML's ``platform``, else ``effector`` if present).
        inputs: the joints given to the solvers (theta), instead of the YAML's ``name_mot``
            or the MJCF actuators' joints: motors plus measured spring joints, or a leg's
            output joints so that the motors become unknowns.
        locked: joints held at given values [rad or length unit]; of an MJCF file, added to
            its springs (held at ``springref``), whose values it overrides.

    Raises:
        ModelError: missing files, malformed URDF/YAML/MJCF, unknown names, non-square
            systems (a choice of inputs that leaves freedoms undetermined, or binds inputs).
        DependencyError: an MJCF file without ``mujoco`` installed.
    """
    if isinstance(path, (str, PathLike)) and Path(path).suffix.lower() == ".xml":
        from ..model.mjcf import read_mjcf

        tree, spec, source = read_mjcf(path)
        chosen = set(inputs) if inputs is not None and not isinstance(inputs, str) else set()
        chosen |= set(locked or {})
        held = {k: v for k, v in source.springs.items() if k not in chosen}
        preloaded = [label for k, label in source.preloaded.items() if k not in chosen]
        if preloaded:
            _refuse_preloaded(tree, spec, str(path), source, preloaded, held, inputs)
        held.update(locked or {})
        try:
            return Model(tree, spec, str(path), frame or source.frame, inputs=inputs,
                         locked=held, source=source)  # fmt: skip
        except NonSquareSystemError as exc:
            _name_passive_tendons(exc, source, held)
            raise
    tree, spec, yaml_path, urdf_text = read_description(path)
    return Model(tree, spec, yaml_path, frame, urdf_text, inputs=inputs, locked=locked)


def _name_passive_tendons(exc: NonSquareSystemError, source: Any, held: Mapping) -> None:
    """Raise ``exc`` again naming the passive tendons whose limits alone would hold the
    freedoms it reports (limits are inequalities, not closures), if there are such."""
    text = str(exc)
    named = {t: [j for j in joints if repr(j) in text and j not in held]
             for t, joints in source.passive_tendons.items()}  # fmt: skip
    named = {t: js for t, js in named.items() if js}
    if not named:
        return
    listed = "; ".join(f"tendon {t!r}: {', '.join(js)}" for t, js in named.items())
    raise NonSquareSystemError(
        f"{text.removeprefix(str(exc.path) + ': ')}; joints held only by the limits of a "
        f"passive tendon ({listed}), an inequality, not a closure: lock them (locked={{...}}) "
        "or make them inputs (inputs=[...])",
        exc.rows,
        exc.unknowns,
        exc.rank,
        exc.path,
    ) from exc


def _refuse_preloaded(tree, spec, path, source, preloaded, held, inputs) -> None:
    """Refuse springs that cannot be held at their springref, naming the freedoms they hold
    (the reduction's message with them free)."""
    free = {k: v for k, v in held.items() if k not in source.preloaded}
    names = ", ".join(preloaded)
    fix = "lock them at values that assemble (locked={...}) or give them as inputs (inputs=[...])"
    try:
        Model(tree, spec, path, source.frame, inputs=inputs, locked=free, source=source)
    except ModelError as exc:
        raise ModelError(
            f"springs {names} cannot be held at springref, and without them: "
            f"{str(exc).removeprefix(path + ': ')}; {fix}",
            path,
        ) from exc
    raise ModelError(f"springs {names} cannot be held at springref; {fix}", path)


def model_from_tree(tree: Tree, spec: Spec, frame: str | None = None) -> Model:
    """Make a model from an in-memory tree and spec (used by the builders)."""
    return Model(tree, spec, None, frame)
