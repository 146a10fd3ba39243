"""A compiled MJCF model (``MjModel``) read into a spanning tree, closures and inputs: one
pass over MuJoCo's arrays (see :mod:`scdk_sym.model.mjcf` for what each element becomes)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ModelError
from .mjcf_compile import require_mujoco
from .qpos import QposEntry
from .rotations import quaternion_matrix, rot_exp, rot_log
from .spec import Closure
from .urdf import Joint, Tree

#: MuJoCo's joint types (mjtJoint) and equality types (mjtEq), as numbers.
FREE, BALL, SLIDE, HINGE = 0, 1, 2, 3
CONNECT, WELD, JOINT, TENDON = 0, 1, 2, 3
#: MuJoCo's object types (mjtObj) of equality ends.
OBJ_BODY, OBJ_SITE = 1, 6
#: Transmission types (mjtTrn).
TRN_JOINT, TRN_JOINTINPARENT, TRN_TENDON = 0, 1, 3
#: Tendon wrap type of a joint (mjtWrap).
WRAP_JOINT = 1
#: Anchors shorter than this are the body's origin [m].
ANCHOR_TOL = 1e-15


def names_of(m: Any, kind: str, count: int, fallback: str) -> list[str]:
    mujoco = require_mujoco()
    obj = getattr(mujoco.mjtObj, f"mjOBJ_{kind}")
    out = []
    for i in range(count):
        name = mujoco.mj_id2name(m, obj, i)
        out.append(name if name else (f"{fallback}{i}" if fallback else ""))
    return out


def _pose(pos: Any, quat: Any = None) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = pos
    if quat is not None:
        T[:3, :3] = quaternion_matrix(np.asarray(quat, dtype=float))
    return T


def _motion(kind: int, axis: np.ndarray, q: float) -> np.ndarray:
    """4x4 motion of a hinge or slide by ``q``."""
    T = np.eye(4)
    if kind == SLIDE:
        T[:3, 3] = axis * q
    else:
        T[:3, :3] = rot_exp(axis * q)
    return T


def _tied_free_bodies(m: Any, free: list[int]) -> set[int]:
    """The bodies among ``free`` (bodies of free joints) that an active frame equality ties
    to a body outside their subtree: floating parts of a loop, not a robot's root."""
    parent = m.body_parentid

    def inside(body: int, root: int) -> bool:
        while body > 0:
            if body == root:
                return True
            body = int(parent[body])
        return False

    tied = set()
    for e in range(m.neq):
        if not m.eq_active0[e] or m.eq_type[e] not in (CONNECT, WELD):
            continue
        ends = [int(m.eq_obj1id[e]), int(m.eq_obj2id[e])]
        if m.eq_objtype[e] == OBJ_SITE:
            ends = [int(m.site_bodyid[s]) for s in ends]
        for b in free:
            if inside(ends[0], b) != inside(ends[1], b):
                tied.add(b)
    return tied


class Builder:
    """The tree, closures and layout of one compiled model (one pass over its arrays)."""

    def __init__(self, m: Any, path: str) -> None:
        self.m, self.path = m, path
        self.bodies = names_of(m, "BODY", m.nbody, "body")
        self.bodies[0] = "world"
        self.jnames = names_of(m, "JOINT", m.njnt, "joint")
        self.sites = names_of(m, "SITE", m.nsite, "site")
        keys = names_of(m, "KEY", m.nkey, "key")
        if "home" in keys:
            self.home_name = "keyframe 'home'"
            self.qhome = np.array(m.key_qpos[keys.index("home")], dtype=float)
        else:
            self.home_name = "qpos0"
            self.qhome = np.array(m.qpos0, dtype=float)
        self.links: list[str] = ["world"]
        self.joints: list[Joint] = []
        self.entries: list[QposEntry] = []
        self.home: dict[str, float] = {}
        self.notes: list[str] = []
        free = [int(m.jnt_bodyid[j]) for j in range(m.njnt) if m.jnt_type[j] == FREE]
        self.floating = _tied_free_bodies(m, free)

    def _add(self, joint: Joint) -> None:
        if joint.child in self.links:
            raise ModelError(f"name {joint.child!r} is used twice in the tree", self.path)
        self.links.append(joint.child)
        self.joints.append(joint)

    def add_bodies(self) -> None:
        """Every body's links and joints, in body order."""
        for b in range(1, self.m.nbody):
            self._body(b)

    def spanning_tree(self) -> Tree:
        """The tree of the links and joints added so far (bodies, closure frames, inputs)."""
        return Tree(self.modelname(), "world", tuple(self.links), tuple(self.joints))

    def modelname(self) -> str:
        """The ``<mujoco model=...>`` name, else the file's stem."""
        raw = bytes(self.m.names)
        name = raw[: raw.find(b"\0")].decode() if raw else ""
        return name or Path(self.path).stem

    def _body(self, b: int) -> None:
        m, name = self.m, self.bodies[b]
        parent = self.bodies[int(m.body_parentid[b])]
        T = _pose(m.body_pos[b], m.body_quat[b])
        adr, num = int(m.body_jntadr[b]), int(m.body_jntnum[b])
        if num == 0:
            self._add(Joint(f"{name}~fixed", "fixed", parent, name, T, np.array([0, 0, 1.0])))
            return
        prev = np.zeros(3)
        for i, j in enumerate(range(adr, adr + num)):
            kind, jname = int(m.jnt_type[j]), self.jnames[j]
            qadr = int(m.jnt_qposadr[j])
            pos = np.array(m.jnt_pos[j], dtype=float)
            last = i == num - 1
            child = name if last and (kind == FREE or not np.any(pos)) else f"{name}~{jname}"
            origin = T @ _pose(pos - prev)
            axis = np.array(m.jnt_axis[j], dtype=float)
            if kind == FREE:
                self._free(b, j, jname, parent, child, qadr)
                pos = np.zeros(3)
            elif kind == BALL:
                self._add(Joint(jname, "spherical", parent, child, origin, np.array([0, 0, 1.0])))
                self.entries.append(QposEntry(jname, "ball", qadr))
                w = rot_log(quaternion_matrix(self.qhome[qadr : qadr + 4]))
                self.home.update({f"{jname}.r{c}": float(v) for c, v in zip("xyz", w, strict=True)})
            else:
                ref = float(m.qpos0[qadr])
                origin = origin @ _motion(kind, axis, -ref)
                lo, hi = m.jnt_range[j] if m.jnt_limited[j] else (-np.inf, np.inf)
                utype = "prismatic" if kind == SLIDE else (
                    "revolute" if m.jnt_limited[j] else "continuous")  # fmt: skip
                self._add(Joint(jname, utype, parent, child, origin, axis, float(lo), float(hi)))
                self.entries.append(QposEntry(jname, "slide" if kind == SLIDE else "hinge", qadr))
                self.home[jname] = float(self.qhome[qadr])
            T, parent, prev = np.eye(4), child, pos
        if parent != name:
            self._add(Joint(f"{name}~frame", "fixed", parent, name, _pose(-prev), np.eye(3)[2]))

    def _free(self, b: int, j: int, jname: str, parent: str, child: str, qadr: int) -> None:
        q = self.qhome[qadr : qadr + 7]
        if b not in self.floating:
            self._add(Joint(jname, "fixed", parent, child, _pose(q[:3], q[3:]), np.eye(3)[2]))
            self.entries.append(QposEntry(jname, "free", qadr, tuple(map(float, q))))
            self.notes.append(f"free joint {jname!r} of body {self.bodies[b]!r} held at home")
            return
        self._add(Joint(jname, "floating", parent, child, np.eye(4), np.eye(3)[2]))
        self.entries.append(QposEntry(jname, "free", qadr))
        w = rot_log(quaternion_matrix(q[3:]))
        self.home.update({f"{jname}.{c}": float(v) for c, v in zip("xyz", q[:3], strict=True)})
        self.home.update({f"{jname}.r{c}": float(v) for c, v in zip("xyz", w, strict=True)})

    # ------------------------------------------------------------------ closures

    def _frame(self, body: int, anchor: np.ndarray, tag: str, quat: Any = None) -> str:
        """A link at ``anchor`` (and ``quat``) of ``body``: the body itself at its origin."""
        name = self.bodies[body]
        if np.linalg.norm(anchor) <= ANCHOR_TOL and quat is None:
            return name
        link = f"{name}@{tag}"
        self._add(Joint(link, "fixed", name, link, _pose(anchor, quat), np.eye(3)[2]))
        return link

    def _site(self, s: int) -> str:
        m = self.m
        link = self.sites[s]
        if link in self.links:
            return link
        if link in self.bodies:
            link = f"{link}~site"
        body = self.bodies[int(m.site_bodyid[s])]
        T = _pose(m.site_pos[s], m.site_quat[s])
        self._add(Joint(link, "fixed", body, link, T, np.eye(3)[2]))
        return link

    def closures(self) -> tuple[list[Closure], list[str]]:
        """The active equalities as closures (frames first, couplings last) and the labels
        of the inactive ones."""
        m = self.m
        eqnames = names_of(m, "EQUALITY", m.neq, "")  # unnamed: labelled by their ends
        frames: list[Closure] = []
        couplings: list[Closure] = []
        skipped: list[str] = []
        order: list[tuple[str, int]] = []  # each active equality: (frames|couplings, index)
        for e in range(m.neq):
            kind, name = int(m.eq_type[e]), eqnames[e]
            tag = name or f"eq{e}"
            data = np.array(m.eq_data[e], dtype=float)
            o1, o2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
            if not m.eq_active0[e]:
                skipped.append(name or f"equality {e}")
                continue
            if kind in (CONNECT, WELD):
                order.append(("f", len(frames)))
                frames.append(self._frame_closure(e, kind, name, tag, data, o1, o2))
            elif kind == JOINT:
                order.append(("c", len(couplings)))
                couplings.append(self._joint_coupling(name, data, o1, o2))
            elif kind == TENDON:
                order.append(("c", len(couplings)))
                couplings.append(self._tendon_coupling(name, data, o1, o2))
            else:
                raise ModelError(
                    f"equality {tag!r} is of a kind with no kinematic closure here (MuJoCo "
                    f"type {kind}); supported: connect, weld, joint, tendon",
                    self.path,
                )
        self.equalities = tuple(i if k == "f" else len(frames) + i for k, i in order)
        return frames + couplings, skipped

    def _frame_closure(
        self, e: int, kind: int, name: str, tag: str, data, o1: int, o2: int
    ) -> Closure:
        m = self.m
        if m.eq_objtype[e] == OBJ_SITE:
            a, b = self._site(o1), self._site(o2)
            return Closure(a, b, "3d" if kind == CONNECT else "6d", name=name)
        if kind == CONNECT:
            a = self._frame(o1, data[0:3], f"{tag}.1")
            b = self._frame(o2, data[3:6], f"{tag}.2")
            return Closure(a, b, "3d", name=name)
        # weld: body1's frame moved by relpose against body2's at its anchor
        a = self._frame(o1, data[3:6], f"{tag}.1", data[6:10])
        b = self._frame(o2, data[0:3], f"{tag}.2")
        return Closure(a, b, "6d", name=name)

    def _joint_coupling(self, name: str, data, o1: int, o2: int) -> Closure:
        m = self.m
        for j in (o1, o2):
            if j >= 0 and m.jnt_type[j] not in (HINGE, SLIDE):
                raise ModelError(
                    f"joint equality {name!r} names {self.jnames[j]!r}, not a hinge or slide",
                    self.path,
                )
        a = ((self.jnames[o1], 1.0),)
        b = ((self.jnames[o2], 1.0),) if o2 >= 0 else ()
        a0 = float(m.qpos0[m.jnt_qposadr[o1]])
        b0 = float(m.qpos0[m.jnt_qposadr[o2]]) if o2 >= 0 else 0.0
        return Closure(a[0][0], (b or a)[0][0], "coupling", terms_a=a, offset_a=a0,
                       terms_b=b, offset_b=b0, polycoef=tuple(map(float, data[:5])),
                       name=name)  # fmt: skip

    def tendon_terms(self, t: int, what: str) -> tuple[tuple[str, float], ...]:
        """(joint, coefficient) of fixed tendon ``t``."""
        m = self.m
        adr, num = int(m.tendon_adr[t]), int(m.tendon_num[t])
        terms = []
        for w in range(adr, adr + num):
            if m.wrap_type[w] != WRAP_JOINT:
                raise ModelError(f"{what}: tendon {t} is spatial; only fixed tendons are "
                                 "kinematic closures here", self.path)  # fmt: skip
            terms.append((self.jnames[int(m.wrap_objid[w])], float(m.wrap_prm[w])))
        return tuple(terms)

    def _tendon_coupling(self, name: str, data, o1: int, o2: int) -> Closure:
        m = self.m
        a = self.tendon_terms(o1, f"equality {name!r}")
        b = self.tendon_terms(o2, f"equality {name!r}") if o2 >= 0 else ()
        a0 = float(m.tendon_length0[o1])
        b0 = float(m.tendon_length0[o2]) if o2 >= 0 else 0.0
        return Closure(a[0][0], (b or a)[0][0], "coupling", terms_a=a, offset_a=a0,
                       terms_b=b, offset_b=b0, polycoef=tuple(map(float, data[:5])),
                       name=name)  # fmt: skip

    # ------------------------------------------------------------------ inputs

    def inputs(self) -> tuple[list[str], list[Closure]]:
        """The actuated joints, and the coupling rows of inputs on fixed tendons (each such
        actuator an input joint of its own name, on a link of no body)."""
        m = self.m
        names = names_of(m, "ACTUATOR", m.nu, "actuator")
        inputs, rows = [], []
        for a in range(m.nu):
            trn, target = int(m.actuator_trntype[a]), int(m.actuator_trnid[a][0])
            if trn in (TRN_JOINT, TRN_JOINTINPARENT):
                if m.jnt_type[target] not in (HINGE, SLIDE):
                    raise ModelError(
                        f"actuator {names[a]!r} drives {self.jnames[target]!r}, a ball or "
                        "free joint: only a hinge or slide is an input here",
                        self.path,
                    )
                name = self.jnames[target]
            elif trn == TRN_TENDON:
                terms = self.tendon_terms(target, f"actuator {names[a]!r}")
                name = names[a]
                if name in self.links or name in self.jnames:
                    name = f"{name}~input"
                slide = any(m.jnt_type[self.jnames.index(j)] == SLIDE for j, _ in terms)
                self._add(Joint(name, "prismatic" if slide else "continuous", "world",
                                f"{name}~link", np.eye(4), np.eye(3)[2]))  # fmt: skip
                length0 = float(np.dot([c for _, c in terms],
                                       [self.qhome[m.jnt_qposadr[self.jnames.index(j)]]
                                        for j, _ in terms]))  # fmt: skip
                self.home[name] = length0
                self.entries.append(QposEntry(name, "input", -1))
                rows.append(Closure(terms[0][0], name, "coupling", terms_a=terms,
                                    terms_b=((name, 1.0),), polycoef=(0.0, 1.0),
                                    name=f"{names[a]}.tendon"))  # fmt: skip
            else:
                raise ModelError(
                    f"actuator {names[a]!r} acts through a site, body or slider-crank; "
                    "only joint and fixed-tendon actuators are inputs here",
                    self.path,
                )
            if name not in inputs:
                inputs.append(name)
        return inputs, rows

    def limited_tendons(self, inputs: Sequence[str]) -> dict[str, tuple[str, ...]]:
        """Fixed tendons with limits that no actuator or equality uses -> their joints: what
        holds those joints in a simulation is an inequality, not a closure."""
        m = self.m
        used = {int(m.actuator_trnid[a][0]) for a in range(m.nu)
                if m.actuator_trntype[a] == TRN_TENDON}  # fmt: skip
        used |= {int(m.eq_obj1id[e]) for e in range(m.neq) if m.eq_type[e] == TENDON}
        used |= {int(m.eq_obj2id[e]) for e in range(m.neq) if m.eq_type[e] == TENDON}
        names = names_of(m, "TENDON", m.ntendon, "tendon")
        out = {}
        for t in range(m.ntendon):
            if t in used or not m.tendon_limited[t]:
                continue
            adr, num = int(m.tendon_adr[t]), int(m.tendon_num[t])
            if all(m.wrap_type[w] == WRAP_JOINT for w in range(adr, adr + num)):
                joints = tuple(self.jnames[int(m.wrap_objid[w])] for w in range(adr, adr + num))
                out[names[t]] = tuple(j for j in joints if j not in inputs)
        return out

    def springs(self, inputs: Sequence[str]) -> tuple[dict[str, float], dict[str, str]]:
        """Hinges and slides with ``stiffness > 0`` that no actuator drives -> springref, and
        those whose springref lies outside their range -> why they cannot be held there (a
        preloaded spring pressing its joint against a limit or a contact: what holds that
        freedom is an inequality, not a closure)."""
        m = self.m
        out, outside = {}, {}
        for j in range(m.njnt):
            name = self.jnames[j]
            if m.jnt_type[j] in (HINGE, SLIDE) and m.jnt_stiffness[j] > 0 and name not in inputs:
                ref = float(m.qpos_spring[m.jnt_qposadr[j]])
                out[name] = ref
                lo, hi = m.jnt_range[j]
                if m.jnt_limited[j] and not lo <= ref <= hi:
                    outside[name] = f"{name} (springref {ref:g} outside its range [{lo:g}, {hi:g}])"
        return out, outside
