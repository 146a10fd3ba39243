"""Independent direct-kinematics references and a seeded fuzz driver (tests and benchmarks).

The references use none of the package's kinematics (of the package only its loaded model's
home configuration and locked joint names, to start from). Each shipped model gets a
closed-form reference written from its geometry, read from the URDF text and the YAML:

* ``stewart_gough``, ``planar_3rpr`` (prismatic legs): ``|p + R b_i - a_i| - L_i``;
* ``planar_hexa``, ``planar_hexa_reduced``, ``five_bar``, ``delta``, ``hexa`` (rotary arms and
  rods of fixed length): ``|C_i(x) - E_i(theta_i)| - rod``, with the elbow ``E_i`` on the circle
  of arm ``i`` about its axis and ``C_i`` the platform anchor (a circle intersection in the
  plane, a sphere constraint in space);

with the closed-form inverse kinematics ``ik(x)`` (the working modes of the model's home) and
the sign of ``det d(closure)/dx`` by central finite differences (``det_sign``), the
direct-kinematic singularity test. Orientations are perturbed by a rotation vector in the base
frame, so no Euler-angle singularity is ever mistaken for a singular mechanism. The Gepetto
fixtures (``frame="effector"``) are checked with Pinocchio alone: ``3d`` closures as the
difference of the frame origins, ``6d`` as ``log6`` of the relative placement, on the
Pinocchio ``q`` of a result's ``joints``; they have no closed-form inverse kinematics, so their
assembled configurations come from a walk on the closure manifold (tangent steps and
minimum-norm Gauss-Newton corrections). The MJCF fixtures of :data:`MJCF_NAMES` are walked
the same way on MuJoCo's own kinematics (compiled by MuJoCo, the closure the equality rows of
``efc_pos``, on MuJoCo's ``qpos``).

The fuzz driver (:func:`draw_scenarios`, :func:`run_solves`, :func:`draw_tracks`,
:func:`run_tracks`, :func:`fuzz`) draws, seeded, a start and a target ``theta0`` with a known
solution (the generating pose) per model, solves it on both branches and classifies every
outcome against the reference (see :data:`OUTCOMES`).
"""

from __future__ import annotations

import math
import re
import signal
import time
import traceback
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
GEPETTO = Path(__file__).resolve().parent / "fixtures" / "gepetto"
MJCF = Path(__file__).resolve().parent / "fixtures" / "mjcf"
#: Shipped models (models/<name>).
SHIPPED = (
    "planar_hexa",
    "planar_hexa_reduced",
    "stewart_gough",
    "planar_3rpr",
    "delta",
    "hexa",
    "five_bar",
)
#: Gepetto fixtures (tests/fixtures/gepetto/<name>, loaded with frame="effector").
GEPETTO_NAMES = ("5bar_linkage", "5bar_linkage_iso3d", "5bar_linkage_iso6d", "robot_delta")
#: Legged robots of the Gepetto collection whose URDF needs no joint edit (every joint one
#: coordinate in Pinocchio), loaded with no option: the pose reported is the model's frame.
GEPETTO_LEGGED = ("cassie_like", "digit_like", "disney_like", "talos_like", "wl16_like")
#: The models fuzzed by default.
NAMES = SHIPPED + GEPETTO_NAMES
#: MJCF fixtures (tests/fixtures/mjcf/<name>.xml) whose joints are all hinges or slides and
#: whose actuators drive joints directly, loaded with no option (the pose reported is the
#: model's frame, an MJCF body); checked against MuJoCo itself (:class:`MjcfReference`).
MJCF_NAMES = ("planar_fourbar", "fourbar_sites", "weld_loop")
#: Models with no direct-kinematic singularity on their closure manifold, so no scenario or
#: track across (or next to) a singular surface can be drawn: the two Grashof crank-rocker
#: four-bars, whose transmission angle stays within (52, 93) and (42, 93) degrees over the
#: whole crank turn (coupler and rocker are never aligned) in either assembly mode.
NO_SINGULAR = frozenset({"planar_fourbar", "fourbar_sites"})
#: Scenario kinds that need a singular surface (not drawn for :data:`NO_SINGULAR`).
SINGULAR_KINDS = ("across", "near_singular")
#: Every model the fuzz can draw for; a new name goes last (each model's draws are seeded by
#: its index here).
ALL_NAMES = NAMES + GEPETTO_LEGGED + MJCF_NAMES

#: Closure residual accepted as a solution [model length unit or rad].
RESIDUAL_TOL = 1e-7
#: Pose / joint-consistency error accepted between the parts of one result.
CONSISTENCY_TOL = 1e-7
#: Normalised |det| (Hadamard ratio) below which the sign of det is not trusted.
TINY_DET = 1e-6
#: Max pose error of a track sample against the commanded motion.
TRACK_TOL = 1e-6


# ---------------------------------------------------------------------------- rotations


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF roll-pitch-yaw: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def rpy_of(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw [rad] of a rotation matrix (pitch in [-pi/2, pi/2])."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    return np.array([math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])])


def axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


def exp_so3(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector ``w`` [rad]."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-300:
        return np.eye(3)
    return axis_angle(w / angle, angle)


def wrap(a):
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


# ---------------------------------------------------------------------------- URDF text


@dataclass(frozen=True)
class Joint:
    """One URDF joint as written: type, parent and child links, origin, axis."""

    name: str
    type: str
    parent: str
    child: str
    xyz: np.ndarray
    rpy: np.ndarray
    axis: np.ndarray


def read_urdf(path: Path) -> dict[str, Joint]:
    """Joints of a URDF file by name (origin xyz / rpy and axis default as in the spec)."""
    root = ET.parse(path).getroot()
    joints = {}
    for j in root.findall("joint"):
        origin = j.find("origin")
        axis = j.find("axis")

        def vec(el, key, default):
            if el is None or el.get(key) is None:
                return np.array(default, dtype=float)
            return np.array([float(v) for v in el.get(key).split()])

        joints[j.get("name")] = Joint(
            j.get("name"),
            j.get("type"),
            j.find("parent").get("link"),
            j.find("child").get("link"),
            vec(origin, "xyz", [0.0, 0.0, 0.0]),
            vec(origin, "rpy", [0.0, 0.0, 0.0]),
            vec(axis, "xyz", [1.0, 0.0, 0.0]),
        )
    return joints


def link_placements(joints: Mapping[str, Joint], values: Mapping[str, float]) -> dict:
    """World placement (4x4) of every link from joint values, by walking the URDF tree.

    Revolute and continuous joints rotate about their axis, prismatic ones slide along it,
    a floating joint ``j`` takes ``j.x, j.y, j.z`` (position) and ``j.rx, j.ry, j.rz`` (a
    rotation vector).
    """
    by_parent: dict[str, list[Joint]] = {}
    children = set()
    for j in joints.values():
        by_parent.setdefault(j.parent, []).append(j)
        children.add(j.child)
    roots = {j.parent for j in joints.values()} - children
    out = {r: np.eye(4) for r in roots}
    stack = list(roots)
    while stack:
        parent = stack.pop()
        for j in by_parent.get(parent, []):
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = rpy(*j.rpy), j.xyz
            M = np.eye(4)
            if j.type in ("revolute", "continuous"):
                M[:3, :3] = axis_angle(j.axis, values[j.name])
            elif j.type == "prismatic":
                M[:3, 3] = j.axis / np.linalg.norm(j.axis) * values[j.name]
            elif j.type == "floating":
                M[:3, 3] = [values[f"{j.name}.{c}"] for c in "xyz"]
                M[:3, :3] = exp_so3(np.array([values[f"{j.name}.r{c}"] for c in "xyz"]))
            elif j.type != "fixed":
                raise NotImplementedError(f"joint type {j.type!r}")
            out[j.child] = out[parent] @ T @ M
            stack.append(j.child)
    return out


# ---------------------------------------------------------------------------- references


class Reference:
    """Independent closure, inverse kinematics and singularity sign of one model.

    Coordinates ``u`` are the workspace pose ``x`` (shipped models) or the Pinocchio ``q``
    (Gepetto fixtures); :meth:`coords` reads them from a package result or configuration.

    Attributes:
        name: model name.
        k: number of actuators.
        has_ik: a closed-form inverse kinematics of the pose exists.
        scale: typical length of the model [model length unit].
    """

    name: str
    k: int
    has_ik: bool = True
    scale: float = 1.0

    def coords(self, cfg) -> np.ndarray:
        """The reference coordinates of a Configuration / SolveResult."""
        raise NotImplementedError

    def closure(self, u: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Closure residual rows at ``u`` with actuators ``theta``."""
        raise NotImplementedError

    def closure_many(self, U: np.ndarray, thetas: np.ndarray) -> np.ndarray:
        """(N, rows) :meth:`closure` at N points ``U`` (N, len(u)) with ``thetas`` (N, k)."""
        return np.array([self.closure(u, t) for u, t in zip(U, thetas, strict=True)])

    def jacobian(self, u: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """(k, k) d(closure)/d(pose perturbation) by central differences (rows normalised)."""
        raise NotImplementedError

    def det_ratio(self, u: np.ndarray, theta: np.ndarray) -> float:
        """Signed |det J| / prod |J_row|: in [-1, 1], 0 on the singular manifold."""
        J = self.jacobian(u, theta)
        norms = np.linalg.norm(J, axis=1)
        if not np.all(norms > 0):
            return 0.0
        return float(np.linalg.det(J / norms[:, None]))

    def det_sign(self, u: np.ndarray, theta: np.ndarray, tiny: float = TINY_DET) -> int:
        """Sign of ``det d(closure)/dx`` (+1 / -1), 0 when ``|det|`` is too small to trust."""
        r = self.det_ratio(u, theta)
        return 0 if abs(r) < tiny else (1 if r > 0 else -1)

    def consistency(self, res) -> float:
        """Disagreement between the parts of a result (x, platform_pose, joints)."""
        raise NotImplementedError

    def distance(self, u: np.ndarray, v: np.ndarray) -> float:
        """Pose distance (max |T_u - T_v| over the 4x4 placements, angles wrapped)."""
        raise NotImplementedError

    def ik(self, x: np.ndarray, near: np.ndarray | None = None, modes=None) -> np.ndarray | None:
        """Actuators of pose ``x`` in the home working modes (or ``modes``: +-1 per arm), the
        revolute ones unwrapped to ``near`` (default home); None where ``x`` is out of reach."""
        raise NotImplementedError


class PoseReference(Reference):
    """Shipped models: coordinates are the workspace pose x."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.dir = MODELS / name
        self.joints = read_urdf(self.dir / "robot.urdf")
        self.spec = yaml.safe_load((self.dir / "robot.yaml").read_text())
        self.workspace = tuple(self.spec["workspace"])
        self.actuated = tuple(self.spec["name_mot"])
        self.k = len(self.actuated)
        self.platform = self.spec["platform"]
        self.spatial = "roll" in self.workspace
        self.planar_rot = "phi" in self.workspace
        passive = {
            j.name
            for j in self.joints.values()
            if j.type not in ("fixed",) and j.name not in self.actuated
        }
        #: the unknowns are the pose coordinates themselves (a start can be assembled from x)
        self.pose_joints = (
            {"x": "px", "y": "py", "z": "pz", "phi": "phi"}
            if passive <= {"px", "py", "pz", "phi"}
            else None
        )
        #: the arms have working modes (+-1 each) that inverse kinematics can choose
        self.has_modes = False

    # pose <-> placement ------------------------------------------------------------

    def pose(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(p, R) of workspace coordinates x."""
        x = np.asarray(x, dtype=float)
        p, R = np.zeros(3), np.eye(3)
        if self.spatial:
            p, R = x[:3].copy(), rpy(*x[3:6])
        elif self.planar_rot:
            p[:2], R = x[:2], rot_z(x[2])
        else:
            p[: len(x)] = x
        return p, R

    def placement(self, x) -> np.ndarray:
        T = np.eye(4)
        p, R = self.pose(x)
        T[:3, :3], T[:3, 3] = R, p
        return T

    def x_of(self, T: np.ndarray) -> np.ndarray:
        """Workspace coordinates of a placement."""
        if self.spatial:
            return np.concatenate([T[:3, 3], rpy_of(T[:3, :3])])
        if self.planar_rot:
            return np.array([T[0, 3], T[1, 3], math.atan2(T[1, 0], T[0, 0])])
        return T[: len(self.workspace), 3].copy()

    def perturbed(self, x, dz) -> tuple[np.ndarray, np.ndarray]:
        """(p, R) of x moved by dz (position, then a base-frame rotation vector / angle)."""
        p, R = self.pose(x)
        if self.spatial:
            return p + dz[:3], exp_so3(dz[3:]) @ R
        if self.planar_rot:
            return p + np.array([dz[0], dz[1], 0.0]), rot_z(dz[2]) @ R
        q = p.copy()
        q[: len(dz)] += dz
        return q, R

    def _steps(self) -> np.ndarray:
        n = len(self.workspace)
        h = np.full(n, 1e-6 * self.scale)
        if self.spatial:
            h[3:] = 1e-6
        elif self.planar_rot:
            h[2] = 1e-6
        return h

    def _column_scale(self) -> np.ndarray:
        s = np.ones(len(self.workspace))
        if self.spatial:
            s[3:] = self.scale
        elif self.planar_rot:
            s[2] = self.scale
        return s

    def closure_pR(self, p, R, theta) -> np.ndarray:
        raise NotImplementedError

    def closure(self, u, theta) -> np.ndarray:
        p, R = self.pose(u)
        return self.closure_pR(p, R, np.asarray(theta, dtype=float))

    def jacobian(self, u, theta) -> np.ndarray:
        theta = np.asarray(theta, dtype=float)
        h = self._steps()
        cols = []
        for i, hi in enumerate(h):
            dz = np.zeros(len(h))
            dz[i] = hi
            fp = self.closure_pR(*self.perturbed(u, dz), theta)
            fm = self.closure_pR(*self.perturbed(u, -dz), theta)
            cols.append((fp - fm) / (2 * hi))
        return np.array(cols).T * self._column_scale()[None, :]

    def coords(self, cfg) -> np.ndarray:
        return np.array(cfg.x, dtype=float)

    def distance(self, u, v) -> float:
        Tu, Tv = self.placement(u), self.placement(v)
        return float(np.max(np.abs(Tu - Tv)))

    def start_y(self, x, unknowns: Sequence[str]) -> np.ndarray | None:
        """Unknowns (in the order ``unknowns``) of pose x when they are the pose coordinates."""
        if self.pose_joints is None:
            return None
        vals = {self.pose_joints[w]: float(v) for w, v in zip(self.workspace, x, strict=True)}
        return np.array([vals[n] for n in unknowns])

    def joints_pose(self, joints: Mapping[str, float]) -> np.ndarray:
        """Platform placement from joint values (the URDF tree walked here)."""
        return link_placements(self.joints, joints)[self.platform]

    def joints_closure(self, joints: Mapping[str, float]) -> float:
        """Max closure residual computed on the joint values (0 when x says it all)."""
        return 0.0

    def consistency(self, res) -> float:
        T = self.placement(res.x)
        errs = [np.max(np.abs(T - np.asarray(res.platform_pose)))]
        errs.append(np.max(np.abs(T - self.joints_pose(res.joints))))
        errs.append(self.joints_closure(res.joints))
        return float(max(errs))

    @property
    def home_x(self) -> np.ndarray:
        """Home pose from the YAML home joints (URDF tree walked here)."""
        return self.x_of(self.joints_pose(self.home_joints))

    @property
    def home_joints(self) -> dict[str, float]:
        vals = {j.name: 0.0 for j in self.joints.values() if j.type in ("revolute", "prismatic")}
        for j in self.joints.values():
            if j.type == "floating":
                vals.update({f"{j.name}.{c}": 0.0 for c in ("x", "y", "z", "rx", "ry", "rz")})
        vals.update({k: float(v) for k, v in self.spec["home"].items()})
        return vals

    @property
    def home_theta(self) -> np.ndarray:
        return np.array([float(self.spec["home"][a]) for a in self.actuated])


class LegReference(PoseReference):
    """Prismatic legs: ``|p + R b_i - a_i| - L_i`` with ``L_i = theta_i`` (stewart, 3-RPR)."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.a = np.array([self.joints[f"base_anchor_{i}_joint"].xyz for i in range(1, self.k + 1)])
        self.b = np.array(
            [self.joints[f"platform_anchor_{i}_joint"].xyz for i in range(1, self.k + 1)]
        )
        self.scale = float(np.linalg.norm(self.a, axis=1).max())

    def closure_pR(self, p, R, theta) -> np.ndarray:
        return np.linalg.norm(p + self.b @ R.T - self.a, axis=1) - theta

    def ik(self, x, near=None, modes=None) -> np.ndarray | None:
        p, R = self.pose(x)
        return np.linalg.norm(p + self.b @ R.T - self.a, axis=1)


class RodReference(PoseReference):
    """Rotary arms and rods: ``|C_i(x) - E_i(theta_i)| - rod_i``.

    The elbow of arm ``i`` is ``E_i = P_i + R0_i Rot(axis_i, theta_i) e_i`` (``P_i``, ``R0_i``
    the actuated joint's origin, ``e_i`` the elbow's offset in the arm frame), the platform
    anchor ``C_i = p + R c_i``. Inverse kinematics per arm: ``alpha cos t + beta sin t = K``.
    """

    def __init__(self, name: str, arms, anchors, rods) -> None:
        super().__init__(name)
        self.P, self.u, self.w, self.c = [], [], [], np.array(anchors, dtype=float)
        for jname, e in zip(self.actuated, arms, strict=True):
            j = self.joints[jname]
            R0 = rpy(*j.rpy)
            a = j.axis / np.linalg.norm(j.axis)
            e = np.asarray(e, dtype=float)
            along = float(a @ e)
            self.P.append(j.xyz + R0 @ (along * a))
            self.u.append(R0 @ (e - along * a))
            self.w.append(R0 @ np.cross(a, e))
        self.P, self.u, self.w = np.array(self.P), np.array(self.u), np.array(self.w)
        self.rod = np.array(rods, dtype=float)
        self.scale = float(self.rod.max())
        # working mode of each arm: the sign of acos that gives the home angles
        self.modes = np.ones(self.k)
        x0, t0 = self.home_x, self.home_theta
        for sign in (1.0, -1.0):
            t = self._ik(x0, np.full(self.k, sign), t0)
            if t is not None:
                hit = np.abs(wrap(t - t0)) < 1e-6
                self.modes[hit] = sign
        check = self._ik(x0, self.modes, t0)
        assert check is not None and np.abs(wrap(check - t0)).max() < 1e-6, name
        self.has_modes = True

    def elbows(self, theta) -> np.ndarray:
        theta = np.asarray(theta, dtype=float)
        return self.P + np.cos(theta)[:, None] * self.u + np.sin(theta)[:, None] * self.w

    def anchors(self, p, R) -> np.ndarray:
        return p + self.c @ R.T

    def closure_pR(self, p, R, theta) -> np.ndarray:
        return np.linalg.norm(self.anchors(p, R) - self.elbows(theta), axis=1) - self.rod

    def closure_many(self, U: np.ndarray, thetas: np.ndarray) -> np.ndarray:
        """:meth:`closure` at N points in one evaluation of the arrays (the same formula)."""
        U = np.asarray(U, dtype=float)
        if self.spatial or self.planar_rot:
            poses = [self.pose(u) for u in U]
            p = np.array([a for a, _ in poses])
            R = np.array([b for _, b in poses])
            anchors = p[:, None, :] + self.c @ R.transpose(0, 2, 1)
        else:  # a translation: R = I (the same values as pose's)
            p = np.zeros((len(U), 3))
            p[:, : U.shape[1]] = U
            anchors = p[:, None, :] + self.c @ np.eye(3).T
        th = np.asarray(thetas, dtype=float)
        elbows = self.P + np.cos(th)[..., None] * self.u + np.sin(th)[..., None] * self.w
        return np.linalg.norm(anchors - elbows, axis=2) - self.rod

    def _ik(self, x, modes, near) -> np.ndarray | None:
        p, R = self.pose(x)
        d = self.anchors(p, R) - self.P
        alpha = np.einsum("ij,ij->i", d, self.u)
        beta = np.einsum("ij,ij->i", d, self.w)
        K = (np.einsum("ij,ij->i", d, d) + np.einsum("ij,ij->i", self.u, self.u) - self.rod**2) / 2
        rho = np.hypot(alpha, beta)
        if not np.all(np.abs(K) < rho * (1 - 1e-12)):
            return None
        t = np.arctan2(beta, alpha) + modes * np.arccos(K / rho)
        return near + wrap(t - near)

    def ik(self, x, near=None, modes=None) -> np.ndarray | None:
        return self._ik(
            x,
            self.modes if modes is None else np.asarray(modes, dtype=float),
            self.home_theta if near is None else np.asarray(near),
        )


class PlanarHexaReference(RodReference):
    """The seed robot with full chains: the platform hangs on leg 1, 2d closures at 2 and 3."""

    def joints_closure(self, joints) -> float:
        T = link_placements(self.joints, joints)
        gaps = [T[f"vertex_{i}"][:2, 3] - T[f"rod_end_{i}"][:2, 3] for i in (2, 3)]
        return float(np.max(np.abs(gaps)))


def _rod_reference(name: str) -> RodReference:
    d = MODELS / name
    J = read_urdf(d / "robot.urdf")
    spec = yaml.safe_load((d / "robot.yaml").read_text())
    k = len(spec["name_mot"])
    legs = range(1, k + 1)
    if name == "planar_hexa":
        arms = [J[f"elbow_{i}"].xyz for i in legs]
        rods = [np.linalg.norm(J["wrist_1"].xyz)] + [
            np.linalg.norm(J[f"rod_end_{i}_joint"].xyz) for i in (2, 3)
        ]
        o = J["platform_joint"]  # platform = vertex_1 * origin: vertex_1 in the platform frame
        anchors = [-rpy(*o.rpy).T @ o.xyz] + [J[f"vertex_{i}_joint"].xyz for i in (2, 3)]
        return PlanarHexaReference(name, arms, anchors, rods)
    arms = [J[f"elbow_{i}_joint"].xyz for i in legs]
    rods = [float(v) for v in spec["length"]]
    if name == "planar_hexa_reduced":
        anchors = [J[f"vertex_{i}_joint"].xyz for i in legs]
    elif name == "five_bar":
        anchors = [np.zeros(3) for _ in legs]
    else:
        anchors = [J[f"platform_anchor_{i}_joint"].xyz for i in legs]
    return RodReference(name, arms, anchors, rods)


#: Gepetto references whose closure Jacobians are Pinocchio's analytic ones (the others'
#: central differences keep the seeded scenarios of earlier runs): wl16_like's 36 columns of
#: differences made one scenario take minutes to draw.
ANALYTIC_JACOBIANS = frozenset({"wl16_like"})
#: Gepetto references whose det ratio is ``sign(det) sigma_min / sigma_max`` of the row-scaled
#: Jacobian: the product of the scaled singular values shrinks with the dimension (wl16_like's
#: 36: below TINY_DET at every regular point, so no scenario could be drawn); the other
#: references keep the product, and their seeded scenarios.
CONDITION_DETS = frozenset({"wl16_like"})


class GepettoReference(Reference):
    """Gepetto fixtures: Pinocchio closures on the Pinocchio q of a result's joints.

    Args:
        name: fixture name.
        locked: joints held at fixed values (the idle freedoms the model locks) -> value.

    ``det`` is taken over the free joints that are not locked, on the closure rows picked
    once at the home configuration by a pivoted QR (the rows that are not redundant there).
    """

    has_ik = False

    def __init__(
        self,
        name: str,
        home_joints: Mapping[str, float],
        locked: Iterable[str],
        frame: str = "effector",
    ):
        import pinocchio as pin

        self.pin = pin
        self.name = name
        self.dir = GEPETTO / name
        self.pm = pin.buildModelFromUrdf(str(self.dir / "robot.urdf"))
        self.data = self.pm.createData()
        spec = yaml.safe_load((self.dir / "robot.yaml").read_text())
        self.pairs = [
            (self.pm.getFrameId(a), self.pm.getFrameId(b), t)
            for (a, b), t in zip(spec["closed_loop"], spec["type"], strict=True)
        ]
        self.actuated = tuple(spec["name_mot"])
        self.k = len(self.actuated)
        self.names = [self.pm.names[j] for j in range(1, self.pm.njoints)]
        self.index = {n: self.pm.joints[self.pm.getJointId(n)].idx_q for n in self.names}
        assert all(self.pm.joints[self.pm.getJointId(n)].nq == 1 for n in self.names)
        self.motors = [self.index[n] for n in self.actuated]
        self.locked = {n: float(home_joints[n]) for n in locked}
        self.unknowns = [n for n in self.names if n not in self.actuated and n not in self.locked]
        self.free = [self.index[n] for n in self.unknowns]
        self.effector = self.pm.getFrameId(frame)
        self.scale = 1.0
        self.home_q = self.q_of(home_joints)
        self.home_theta = self.home_q[self.motors]
        self.rows = self._independent_rows()

    def _independent_rows(self) -> list[int]:
        """The closure rows that are not redundant at home: pivoted Gram-Schmidt on the rows
        of the Jacobian over the free joints and motors (as many as free joints, or raise)."""
        J = self._jac(self.home_q, self.free + self.motors)
        rows, basis = [], []
        for i in np.argsort(-np.linalg.norm(J, axis=1)):
            v = J[i].copy()
            for b in basis:
                v -= (v @ b) * b
            if np.linalg.norm(v) > 1e-8 * np.linalg.norm(J):
                rows.append(int(i))
                basis.append(v / np.linalg.norm(v))
        if len(rows) != len(self.free):
            raise ValueError(f"{self.name}: {len(rows)} independent rows, {len(self.free)} free")
        return sorted(rows)

    def q_of(self, joints: Mapping[str, float]) -> np.ndarray:
        q = np.zeros(self.pm.nq)
        for n in self.names:
            q[self.index[n]] = joints[n]
        return q

    def coords(self, cfg) -> np.ndarray:
        return self.q_of(cfg.joints)

    def _placements(self, q):
        pin = self.pin
        pin.forwardKinematics(self.pm, self.data, q)
        pin.updateFramePlacements(self.pm, self.data)
        return self.data.oMf

    def residual_q(self, q: np.ndarray) -> np.ndarray:
        oMf = self._placements(q)
        out = []
        for a, b, kind in self.pairs:
            Ma, Mb = oMf[a], oMf[b]
            if kind == "3d":
                out.append(Ma.translation - Mb.translation)
            else:
                out.append(self.pin.log6(Ma.inverse() * Mb).vector)
        return np.concatenate(out)

    def closure(self, u, theta) -> np.ndarray:
        q = np.array(u, dtype=float)
        q[self.motors] = theta
        return self.residual_q(q)

    def det_ratio(self, u: np.ndarray, theta: np.ndarray) -> float:
        """The base class's ratio, or for :data:`CONDITION_DETS` the signed inverse
        condition number of the row-scaled Jacobian (0 on the singular manifold)."""
        if self.name not in CONDITION_DETS:
            return super().det_ratio(u, theta)
        J = self.jacobian(u, theta)
        norms = np.linalg.norm(J, axis=1)
        if not np.all(norms > 0):
            return 0.0
        J = J / norms[:, None]
        sv = np.linalg.svd(J, compute_uv=False)
        return float(np.sign(np.linalg.det(J)) * sv[-1] / sv[0])

    def _jac(self, q, cols, h=1e-7) -> np.ndarray:
        if self.name in ANALYTIC_JACOBIANS:
            return self._jac_analytic(q)[:, cols]
        out = []
        for i in cols:
            dq = np.zeros_like(q)
            dq[i] = h
            out.append((self.residual_q(q + dq) - self.residual_q(q - dq)) / (2 * h))
        return np.array(out).T

    def jacobian(self, u, theta) -> np.ndarray:
        q = np.array(u, dtype=float)
        q[self.motors] = theta
        return self._jac(q, self.free, h=1e-6)[self.rows]

    def _jac_analytic(self, q) -> np.ndarray:
        """d residual_q / dq (rows, nq) from Pinocchio's frame Jacobians (every joint has one
        coordinate, so q and v index alike): a point closure's rows R_a J_a - R_b J_b
        (linear parts, LOCAL), a weld's Jlog6(M) (J_b - Ad(M^-1) J_a) with M = M_a^-1 M_b."""
        pin = self.pin
        pin.computeJointJacobians(self.pm, self.data, q)
        pin.updateFramePlacements(self.pm, self.data)
        oMf, out = self.data.oMf, []
        for a, b, kind in self.pairs:
            Ja = pin.getFrameJacobian(self.pm, self.data, a, pin.LOCAL)
            Jb = pin.getFrameJacobian(self.pm, self.data, b, pin.LOCAL)
            if kind == "3d":
                out.append(oMf[a].rotation @ Ja[:3] - oMf[b].rotation @ Jb[:3])
            else:
                M = oMf[a].inverse() * oMf[b]
                out.append(pin.Jlog6(M) @ (Jb - M.inverse().action @ Ja))
        return np.vstack(out)

    def effector_pose(self, q) -> np.ndarray:
        return self._placements(q)[self.effector].homogeneous.copy()

    def consistency(self, res) -> float:
        q = self.coords(res)
        T = self.effector_pose(q)
        errs = [np.max(np.abs(T - np.asarray(res.platform_pose)))]
        errs.append(np.max(np.abs(T[:3, 3] - np.asarray(res.x))))
        errs.append(max((abs(q[self.index[n]] - v) for n, v in self.locked.items()), default=0))
        return float(max(errs))

    def distance(self, u, v) -> float:
        return float(np.max(np.abs(wrap(np.asarray(u)[self.free] - np.asarray(v)[self.free]))))

    def ik(self, x, near=None, modes=None):
        return None

    # the closure manifold -------------------------------------------------------------

    def project(self, q: np.ndarray, iterations: int = 30) -> np.ndarray | None:
        """Minimum-norm Gauss-Newton onto the closures over free joints and motors."""
        cols = self.free + self.motors
        q = q.copy()
        for _ in range(iterations):
            r = self.residual_q(q)
            if np.abs(r).max() < 1e-13:
                return q
            J = self._jac(q, cols)[self.rows]
            q[cols] -= np.linalg.lstsq(J, r[self.rows], rcond=None)[0]
        return q if np.abs(self.residual_q(q)).max() < 1e-12 else None

    def tangent(self, q: np.ndarray) -> np.ndarray:
        """(k, m + k) orthonormal basis of the tangent space over free joints and motors."""
        J = self._jac(q, self.free + self.motors)[self.rows]
        return np.linalg.svd(J)[2][len(self.rows) :]

    def walk(
        self, q: np.ndarray, direction: np.ndarray, steps: int, h: float
    ) -> list[np.ndarray] | None:
        """Configurations along the manifold: ``steps`` tangent steps of length ``h`` [rad],
        the direction transported by projection onto each new tangent space."""
        cols = self.free + self.motors
        path = [q.copy()]
        d = np.asarray(direction, dtype=float)
        for _ in range(steps):
            B = self.tangent(q)
            d = B.T @ (B @ d)
            n = np.linalg.norm(d)
            if n < 1e-9:
                return None
            d /= n
            trial = q.copy()
            trial[cols] += h * d
            q = self.project(trial)
            if q is None:
                return None
            path.append(q)
        return path


class MjcfReference(GepettoReference):
    """MJCF fixtures: MuJoCo's own kinematics on MuJoCo's qpos (no scdk_sym).

    The file is compiled by MuJoCo (``MjModel.from_xml_path``) with contacts, limits and
    friction loss disabled, so that the only constraint rows of ``mj_forward`` are the
    equalities. ``q`` is MuJoCo's qpos (joint names from ``mj_id2name``, addresses from
    ``jnt_qposadr``); the closure is the ``efc_pos`` rows of type ``mjCNSTR_EQUALITY``, its
    Jacobian the matching ``efc_J`` rows (a weld's rotation rows signed, see
    :meth:`jacobian`); the effector pose is ``xpos`` / ``xmat`` of the body ``frame``; the
    actuated joints are the joints the MJCF actuators drive (``actuator_trnid``), in the
    actuators' order. Only hinges and slides, and actuators on joints, are accepted (every
    joint one qpos coordinate).

    Args:
        name: fixture name (tests/fixtures/mjcf/<name>.xml).
        home_joints: joint name -> qpos value of the configuration the walks start from.
        locked: joints held at fixed values -> value.
        frame: the body whose pose is reported.
    """

    def __init__(
        self,
        name: str,
        home_joints: Mapping[str, float],
        locked: Mapping[str, float],
        frame: str,
    ):
        import mujoco

        self.mj = mujoco
        self.name = name
        self.path = MJCF / f"{name}.xml"
        m = mujoco.MjModel.from_xml_path(str(self.path))
        off = mujoco.mjtDisableBit
        m.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_LIMIT | off.mjDSBL_FRICTIONLOSS
        m.opt.disableflags &= ~(off.mjDSBL_CONSTRAINT | off.mjDSBL_EQUALITY)
        m.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
        self.mm, self.md = m, mujoco.MjData(m)
        scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        if not all(int(t) in scalar for t in m.jnt_type):
            raise ValueError(f"{name}: a joint is not a hinge or a slide")
        assert np.array_equal(m.jnt_qposadr, m.jnt_dofadr)  # so efc_J's columns index q
        if not all(int(t) == int(mujoco.mjtTrn.mjTRN_JOINT) for t in m.actuator_trntype):
            raise ValueError(f"{name}: an actuator does not drive a joint")
        for e in range(m.neq):  # _row_signs reads the bodies' quaternions
            if int(m.eq_type[e]) == int(mujoco.mjtEq.mjEQ_WELD) and int(m.eq_objtype[e]) != int(
                mujoco.mjtObj.mjOBJ_BODY
            ):
                raise ValueError(f"{name}: a weld between sites")
        obj = mujoco.mjtObj.mjOBJ_JOINT
        self.names = [mujoco.mj_id2name(m, obj, j) for j in range(m.njnt)]
        self.index = {n: int(m.jnt_qposadr[j]) for j, n in enumerate(self.names)}
        self.actuated = tuple(self.names[int(m.actuator_trnid[a, 0])] for a in range(m.nu))
        self.k = len(self.actuated)
        self.motors = [self.index[n] for n in self.actuated]
        self.locked = {n: float(v) for n, v in locked.items()}
        self.unknowns = [n for n in self.names if n not in self.actuated and n not in self.locked]
        self.free = [self.index[n] for n in self.unknowns]
        self.effector = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, frame)
        if self.effector < 0:
            raise ValueError(f"{name}: no body {frame!r}")
        self.equality = int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        self.scale = 1.0
        self.home_q = self.q_of(home_joints)
        self.home_theta = self.home_q[self.motors]
        self.rows = self._independent_rows()

    def q_of(self, joints: Mapping[str, float]) -> np.ndarray:
        q = np.zeros(self.mm.nq)
        for n in self.names:
            q[self.index[n]] = joints[n]
        return q

    def _forward(self, q: np.ndarray) -> None:
        d = self.md
        d.qpos[:] = q
        d.qvel[:] = 0.0
        self.mj.mj_forward(self.mm, d)

    def residual_q(self, q: np.ndarray) -> np.ndarray:
        self._forward(q)
        d = self.md
        rows = np.asarray(d.efc_type[: d.nefc]) == self.equality
        return np.asarray(d.efc_pos[: d.nefc])[rows].copy()

    def _jac(self, q, cols, h=None) -> np.ndarray:
        """d residual_q / dq[cols]: MuJoCo's ``efc_J`` equality rows (hinges and slides only,
        so the dofs are the qpos coordinates)."""
        self._forward(q)
        d = self.md
        rows = np.asarray(d.efc_type[: d.nefc]) == self.equality
        J = np.asarray(d.efc_J[: d.nefc * self.mm.nv]).reshape(d.nefc, self.mm.nv)
        return J[rows][:, cols]

    def jacobian(self, u, theta) -> np.ndarray:
        """The Gepetto Jacobian, a weld's rotation rows times the sign of the real part of its
        error quaternion: MuJoCo's rows ``Im(conj(q2) q1 relquat)`` vanish both where that
        quaternion is +1 and where it is -1 (the same rotation, e.g. past a turn of a hinge),
        with opposite derivatives; the sign keeps ``det`` continuous on the manifold."""
        q = np.array(u, dtype=float)
        q[self.motors] = theta
        return super().jacobian(u, theta) * self._row_signs(q)[self.rows, None]

    def _row_signs(self, q: np.ndarray) -> np.ndarray:
        """+-1 per equality row: -1 on the rotation rows of a weld whose error quaternion
        ``conj(q2) q1 relquat`` has a negative real part."""
        mj, m, d = self.mj, self.mm, self.md
        self._forward(q)
        eq = np.asarray(d.efc_type[: d.nefc]) == self.equality
        ids = np.asarray(d.efc_id[: d.nefc])[eq]
        signs = np.ones(len(ids))
        for e in np.unique(ids):
            if int(m.eq_type[e]) != int(mj.mjtEq.mjEQ_WELD):
                continue
            q1, q2 = d.xquat[m.eq_obj1id[e]], d.xquat[m.eq_obj2id[e]]
            conj, tmp, err = np.zeros(4), np.zeros(4), np.zeros(4)
            mj.mju_negQuat(conj, q2)
            mj.mju_mulQuat(tmp, conj, q1)
            mj.mju_mulQuat(err, tmp, m.eq_data[e, 6:10])
            rows = np.flatnonzero(ids == e)
            signs[rows[3:]] = 1.0 if err[0] >= 0 else -1.0
        return signs

    def effector_pose(self, q) -> np.ndarray:
        self._forward(q)
        T = np.eye(4)
        T[:3, :3] = np.asarray(self.md.xmat[self.effector]).reshape(3, 3)
        T[:3, 3] = self.md.xpos[self.effector]
        return T

    def consistency(self, res) -> float:
        """The Gepetto checks, and the result's qpos against its joints at MuJoCo's addresses."""
        err = super().consistency(res)
        return max(err, float(np.max(np.abs(np.asarray(res.qpos) - self.coords(res)))))


@cache
def reference(name: str) -> Reference:
    """The independent reference of a shipped model or a Gepetto fixture."""
    if name in ("stewart_gough", "planar_3rpr"):
        return LegReference(name)
    if name in SHIPPED:
        return _rod_reference(name)
    model = load(name)
    if name in MJCF_NAMES:
        return MjcfReference(name, model.home.joints, model.locked, model.frame)
    frame = "effector" if name in GEPETTO_NAMES else model.frame
    return GepettoReference(name, model.home.joints, model.locked, frame)


@cache
def load(name: str):
    """The package's model of ``name`` (Gepetto fixtures with frame="effector")."""
    import scdk_sym as sc

    if name in SHIPPED:
        return sc.load_model(MODELS / name)
    if name in GEPETTO_LEGGED:
        return sc.load_model(GEPETTO / name)
    if name in MJCF_NAMES:
        return sc.load_model(MJCF / f"{name}.xml")
    return sc.load_model(GEPETTO / name, frame="effector")


@cache
def typical_det(name: str) -> float:
    """|det ratio| at the home configuration (starts far below it are avoided)."""
    ref, model = reference(name), load(name)
    return abs(ref.det_ratio(ref.coords(model.home), model.home.theta))


def model_expr(name: str) -> str:
    """Python expression that loads the model (for reproducers; run from the repo root)."""
    if name in SHIPPED:
        return f"sc.load_model('models/{name}')"
    if name in GEPETTO_LEGGED:
        return f"sc.load_model('tests/fixtures/gepetto/{name}')"
    if name in MJCF_NAMES:
        return f"sc.load_model('tests/fixtures/mjcf/{name}.xml')"
    return f"sc.load_model('tests/fixtures/gepetto/{name}', frame='effector')"


# ---------------------------------------------------------------------------- fuzz driver

#: Half-widths of the pose box around home per shipped model (large targets; starts are drawn
#: in half of it, small steps in 3 % of it) [model length unit, rad].
BOX = {
    "planar_hexa": [3.0, 3.0, 0.9],
    "planar_hexa_reduced": [3.0, 3.0, 0.9],
    "stewart_gough": [0.08, 0.08, 0.08, 0.35, 0.35, 1.9],
    "planar_3rpr": [0.25, 0.25, 1.2],
    "delta": [0.08, 0.08, 0.06],
    "hexa": [0.06, 0.06, 0.06, 0.3, 0.3, 0.6],
    "five_bar": [0.15, 0.12],
}
#: Wider boxes for large targets and for the search of singular surfaces.
FAR_BOX = {
    "hexa": [0.1, 0.1, 0.1, 0.6, 0.6, 1.0],
    "five_bar": [0.3, 0.25],
    "delta": [0.15, 0.15, 0.12],
}
#: Walk lengths on the closure manifold of the Gepetto fixtures [rad of joint space].
WALK = {"start": 0.4, "small": 0.02, "large": 1.2, "across": 4.0}
#: Scenario kinds and their weights.
KINDS = {"small": 0.3, "large": 0.3, "across": 0.25, "near_singular": 0.15}
BRANCHES = ("convergent", "divergent")
#: Draws tried for one scenario of a kind before giving up on it.
ATTEMPTS = 40
#: Outcome classes of a solve.
#: "off_curve": a convergent refusal where the curve through the start closes without
#: reaching ``s = 1``, confirmed by the reference (:func:`confirm_off_curve`): no answer
#: exists on that branch.
OUTCOMES = ("ok", "wrong_residual", "wrong_parity", "refused", "off_curve", "crash", "timeout")


class SolveTimeout(BaseException):
    """A solve exceeded the driver's time limit (a BaseException: solver code that catches
    ``Exception`` cannot swallow it)."""


@contextmanager
def time_limit(seconds: float | None):
    """Raise :class:`SolveTimeout` in the body after ``seconds`` of wall time, then every
    0.2 s until it gets out (native code may drop the first one). Main thread only."""
    if not seconds:
        yield
        return

    def handler(signum, frame):
        raise SolveTimeout(f"no answer within {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, seconds, 0.2)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@dataclass
class Scenario:
    """One direct-kinematics problem with a known solution.

    Attributes:
        name: model name.
        kind: "small", "large", "across" or "near_singular".
        start_x: pose handed to ``model.inverse_kinematics`` for the start (None: home).
        start_yt: (y, theta) of a start assembled by ``model.configuration`` (Gepetto).
        theta0: (k,) target actuators.
        target: reference coordinates of the generating solution.
        record_path: passed to ``sc.solve``.
    """

    name: str
    kind: str
    theta0: np.ndarray
    target: np.ndarray
    start_x: np.ndarray | None = None
    start_yt: tuple[np.ndarray, np.ndarray] | None = None
    record_path: bool = False

    def start_expr(self) -> str:
        if self.start_x is not None:
            return f"m.inverse_kinematics({_list(self.start_x)})"
        if self.start_yt is not None:
            return f"m.configuration({_list(self.start_yt[0])}, {_list(self.start_yt[1])})"
        return "None"

    def start(self, model):
        if self.start_x is not None:
            return model.inverse_kinematics(self.start_x)
        if self.start_yt is not None:
            return model.configuration(*self.start_yt)
        return model.home

    def known(self) -> str:
        """The generating solution (pose x, or the Gepetto unknowns by name)."""
        if self.name in SHIPPED:
            return f"known solution x = {_list(self.target)}"
        ref = reference(self.name)
        pairs = ", ".join(f"{n}={float(self.target[ref.index[n]])!r}" for n in ref.unknowns)
        return f"known solution {pairs}"

    def reproducer(self, branch: str, backend: str = "cvodes") -> str:
        back = "" if backend == "cvodes" else f", backend={backend!r}"
        return (
            f"import scdk_sym as sc; m = {model_expr(self.name)}; "
            f"r = sc.solve(m, {_list(self.theta0)}, start={self.start_expr()}, "
            f"branch={branch!r}, record_path={self.record_path}{back})"
        )


def _list(a) -> str:
    return "[" + ", ".join(repr(float(v)) for v in np.ravel(a)) + "]"


@dataclass
class Outcome:
    """Classified result of one solve."""

    scenario: Scenario
    branch: str
    status: str
    detail: str = ""
    residual: float = float("nan")
    parity: str = "n/a"  # "agree", "disagree", "skipped" (|det| tiny), "n/a"
    generating: bool = False  # the result is the generating solution
    seconds: float = 0.0
    strategy: str = ""  # divergent answers: the way that answered (SolveResult.strategy)


def _segment(ref: PoseReference, xa, xb, n: int, modes=None):
    """Poses, actuators and det signs at n points of the straight pose segment xa -> xb."""
    lams = np.linspace(0.0, 1.0, n)
    xs, ts, signs = [], [], []
    near = ref.ik(xa, modes=modes)
    if near is None:
        return None
    for lam in lams:
        x = xa + lam * (xb - xa)
        t = ref.ik(x, near, modes)
        if t is None:
            return None
        near = t
        xs.append(x)
        ts.append(t)
        signs.append(ref.det_sign(x, t, tiny=0.0))
    return lams, np.array(xs), np.array(ts), np.array(signs)


def singular_point(ref: PoseReference, xa, xb, modes=None) -> float | None:
    """Segment parameter of the first singular point between poses xa and xb (sign change of
    det along 25 samples, then bisection to 1e-12), or None (none, or out of reach)."""
    seg = _segment(ref, xa, xb, 25, modes)
    if seg is None:
        return None
    lams, xs, ts, signs = seg
    change = np.nonzero(signs[1:] != signs[:-1])[0]
    if not change.size:
        return None
    lo, hi = lams[change[0]], lams[change[0] + 1]
    s_lo = signs[change[0]]
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        x = xa + mid * (xb - xa)
        t = ref.ik(x, ts[change[0]], modes)
        if t is None:
            return None
        if ref.det_sign(x, t, tiny=0.0) == s_lo:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _pose_start(ref: PoseReference, model, rng, modes=None):
    """A start: home (30 %, home modes only), the package's inverse kinematics of a pose near
    home, or (other working modes) the configuration assembled at a pose: (x, y, theta, cfg)."""
    box = np.asarray(BOX[ref.name], dtype=float)
    if modes is None and rng.random() < 0.3:
        return None, None, model.home
    for _ in range(50):
        x = ref.home_x + rng.uniform(-0.5, 0.5, len(box)) * box
        t = ref.ik(x, modes=modes)
        if t is None or abs(ref.det_ratio(x, t)) < 0.01 * typical_det(ref.name):
            continue
        try:
            if modes is None:
                return x, None, model.inverse_kinematics(x)
            y = ref.start_y(x, model.unknowns)
            return None, (y, t), model.configuration(y, t)
        except Exception:  # noqa: BLE001 - not assembled by the package: try another pose
            continue
    return None


def _draw_pose(ref: PoseReference, model, rng, kind: str) -> Scenario | None:
    box = np.asarray(BOX[ref.name], dtype=float)
    far_box = np.asarray(FAR_BOX.get(ref.name, box), dtype=float)
    modes = None
    if ref.has_modes and ref.pose_joints is not None and rng.random() < 0.5:
        modes = rng.choice([-1.0, 1.0], ref.k)
    drawn = _pose_start(ref, model, rng, modes)
    if drawn is None:
        return None
    start_x, start_yt, start = drawn
    xs = np.array(start.x, dtype=float)
    ts = np.array(start.theta, dtype=float)
    if kind == "small":
        xt = xs + rng.uniform(-0.03, 0.03, len(box)) * box
        seg = _segment(ref, xs, xt, 6, modes)
        if seg is None or len(set(seg[3].tolist())) != 1:
            return None
        target = xt
    elif kind == "large":
        target = ref.home_x + rng.uniform(-1.0, 1.0, len(box)) * far_box
    else:
        far = ref.home_x + rng.uniform(-1.0, 1.0, len(box)) * far_box
        lam = singular_point(ref, xs, far, modes)
        if lam is None:
            return None
        if kind == "across":
            lt = lam + rng.uniform(0.01, 0.5) * (1 - lam)
        else:
            lt = lam * (1 - rng.uniform(0.002, 0.1))
        target = xs + lt * (far - xs)
        seg = _segment(ref, xs, target, 25, modes)
        if seg is None:
            return None
    theta0 = ref.ik(target, ts, modes)
    if theta0 is None or ref.det_sign(target, theta0) == 0:
        return None
    return Scenario(ref.name, kind, theta0, target, start_x=start_x, start_yt=start_yt)


def _walk_until(ref: GepettoReference, q, rng, length: float, stop_at_crossing: bool):
    """Walk from q in a random tangent direction; with ``stop_at_crossing`` return the
    configurations up to just after the first det sign change (else None)."""
    h = min(0.04 if stop_at_crossing else 0.02, length / 2)
    B = ref.tangent(q)
    d = B.T @ rng.normal(size=ref.k)
    path = ref.walk(q, d, max(2, int(round(length / h))), h)
    if path is None:
        return None
    if not stop_at_crossing:
        return path
    signs = [ref.det_sign(p, p[ref.motors], tiny=0.0) for p in path]
    for i in range(1, len(signs)):
        if signs[i] != signs[i - 1]:
            return path[: i + 1]
    return None


def _gepetto_start(ref: GepettoReference, model, rng):
    if rng.random() < 0.3:
        return ref.home_q, None
    path = _walk_until(ref, ref.home_q, rng, rng.uniform(0.05, WALK["start"]), False)
    if path is None or abs(ref.det_ratio(path[-1], path[-1][ref.motors])) < 0.01 * typical_det(
        ref.name
    ):
        return ref.home_q, None
    q = path[-1]
    y = np.array([q[ref.index[n]] for n in model.unknowns])
    theta = q[ref.motors]
    return q, (y, theta)


def _draw_gepetto(ref: GepettoReference, model, rng, kind: str) -> Scenario | None:
    qs, start_yt = _gepetto_start(ref, model, rng)
    if kind == "small":
        path = _walk_until(ref, qs, rng, WALK["small"] * rng.uniform(0.2, 1.0), False)
        if path is None:
            return None
        if len({ref.det_sign(p, p[ref.motors], tiny=0.0) for p in path}) != 1:
            return None
        target = path[-1]
    elif kind == "large":
        path = _walk_until(ref, qs, rng, rng.uniform(0.1, WALK["large"]), False)
        if path is None:
            return None
        target = path[-1]
    else:
        path = _walk_until(ref, qs, rng, WALK["across"], True)
        if path is None:
            return None
        if kind == "across":
            extra = _walk_until(ref, path[-1], rng, rng.uniform(0.02, 0.3), False)
            if extra is None:
                return None
            target = extra[-1]
            if ref.det_sign(target, target[ref.motors]) != ref.det_sign(
                path[-1], path[-1][ref.motors]
            ):
                return None
        else:
            target = path[-2]
    theta0 = target[ref.motors]
    if ref.det_sign(target, theta0) == 0:
        return None
    return Scenario(ref.name, kind, theta0, target, start_yt=start_yt)


def draw_scenarios(name: str, count: int, seed: int, kinds: Mapping[str, float] = KINDS):
    """``count`` seeded scenarios of model ``name`` (kinds drawn with the given weights; none
    of :data:`SINGULAR_KINDS` for a model of :data:`NO_SINGULAR`)."""
    if name in NO_SINGULAR:
        kinds = {k: w for k, w in kinds.items() if k not in SINGULAR_KINDS}
        if not kinds:
            return []
    ref, model = reference(name), load(name)
    rng = np.random.default_rng([seed, ALL_NAMES.index(name)])
    names = list(kinds)
    weights = np.array([kinds[k] for k in names], dtype=float)
    out: list[Scenario] = []
    misses = 0
    draw = _draw_pose if isinstance(ref, PoseReference) else _draw_gepetto
    while len(out) < count and misses < 5 * count + 10:
        kind = names[int(rng.choice(len(names), p=weights / weights.sum()))]
        for _ in range(ATTEMPTS):
            s = draw(ref, model, rng, kind)
            if s is not None:
                s.record_path = bool(rng.random() < 0.5)
                out.append(s)
                break
        else:
            misses += 1
    return out


def classify(ref: Reference, scen: Scenario, start, res) -> Outcome:
    """Check a solve result against the reference."""
    u = ref.coords(res)
    residual = float(np.abs(ref.closure(u, scen.theta0)).max())
    consistency = max(ref.consistency(res), float(np.abs(res.theta - scen.theta0).max()))
    out = Outcome(scen, res.branch, "ok", residual=residual, strategy=res.strategy)
    out.generating = ref.distance(u, scen.target) < 1e-6
    if not (residual <= RESIDUAL_TOL and consistency <= CONSISTENCY_TOL):
        out.status = "wrong_residual"
        out.detail = f"closure {residual:.3g}, consistency {consistency:.3g}"
        return out
    s0 = ref.det_sign(ref.coords(start), start.theta)
    s1 = ref.det_sign(u, scen.theta0)
    # a divergent solve across crossing branches switches branch at the first point: det J_p
    # may keep or change its sign there, so the parity says nothing
    switched = res.branch == "divergent" and res.crossings and res.crossings[0].kind != "fold"
    if s0 == 0 or s1 == 0 or switched:
        out.parity = "skipped"
    elif (-1) ** len(res.crossings) == s0 * s1:
        out.parity = "agree"
    else:
        out.parity = "disagree"
        out.status = "wrong_parity"
        where = ", ".join(f"{c.kind} at s={c.s:.4g}" for c in res.crossings) or "none"
        past = any(c.s > 1 for c in res.crossings)
        out.detail = (
            f"{len(res.crossings)} crossings ({where}), det signs start {s0} result {s1}"
            + ("; a reported crossing lies past s = 1" if past else "")
        )
    return out


def run_solves(
    scenarios: Sequence[Scenario],
    backend: str = "cvodes",
    progress: Callable | None = None,
    branches: Sequence[str] = BRANCHES,
    limit: float | None = None,
) -> list[Outcome]:
    """Solve every scenario on each branch and classify each outcome.

    Args:
        scenarios: from :func:`draw_scenarios`.
        backend: ``sc.solve`` backend.
        progress: called as ``progress(done, total)`` after each scenario.
        branches: branches to solve.
        limit: wall-time limit per solve [s] (outcome "timeout"), None for none.
    """
    import scdk_sym as sc

    out = []
    for i, scen in enumerate(scenarios):
        ref, model = reference(scen.name), load(scen.name)
        warm_up(scen.name, backend)
        start = scen.start(model)
        given = None if scen.start_x is None and scen.start_yt is None else start
        for branch in branches:
            t0 = time.perf_counter()
            try:
                with time_limit(limit):
                    res = sc.solve(
                        model,
                        scen.theta0,
                        start=given,
                        branch=branch,
                        backend=backend,
                        record_path=scen.record_path,
                    )
            except sc.ScdkError as exc:
                o = Outcome(scen, branch, "refused", f"{type(exc).__name__}: {exc}")
            except SolveTimeout as exc:
                o = Outcome(scen, branch, "timeout", str(exc))
            except Exception as exc:  # noqa: BLE001 - any other exception is a defect
                o = Outcome(scen, branch, "crash", _describe(exc))
            else:
                o = classify(ref, scen, start, res)
                o.branch = branch
            o.seconds = time.perf_counter() - t0
            out.append(o)
        if progress is not None:
            progress(i + 1, len(scenarios))
    return out


def _template(message: str) -> str:
    """A message with its numbers, lists and repeated detail blanked (for grouping)."""
    text = re.sub(r"\[[^\]]*\]", "[.]", message)
    text = re.sub(r"(?<![A-Za-z_\d])[-+]?\d+(\.\d*)?([eE][-+]?\d+)?", "#", text)
    return text[:140]


#: Time given to building a model's assembly-mode start system before a fuzz [s].
MODES_WARM_UP = 180.0


@cache
def warm_up(name: str, backend: str, modes: bool = False) -> None:
    """Build (or load from the cache) what a backend compiles, outside any time limit; with
    ``modes``, also the start system of the model's assembly modes (disk-cached: the solves'
    last divergent way reads it)."""
    import scdk_sym as sc

    model = load(name)
    theta = np.array(model.home.theta, dtype=float)
    step = theta + 1e-3
    try:
        if backend == "c":
            sc.track(model, np.array([theta, step]), backend=backend)
            return
        sc.solve(model, step, backend=backend, record_path=False)
        # the follower's own kernels (fold location, nearest singular point, detours) are
        # built on first use, which a plain convergent solve may not reach
        from scdk_sym.follower.calls import follower_kernels

        follower_kernels(model, backend)
        if modes:  # the start system the divergent branch's last way reads
            with time_limit(MODES_WARM_UP):
                sc.assembly_modes(model, theta)
    except (sc.ScdkError, SolveTimeout):
        pass


def _describe(exc: BaseException) -> str:
    """Exception type, message and the innermost frame (file:line)."""
    tb = traceback.extract_tb(exc.__traceback__)
    where = f" @{Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
    return f"{type(exc).__name__}: {exc}{where}"


# ---------------------------------------------------------------------------- tracks


@dataclass
class Track:
    """A commanded motion: reference coordinates per sample and the actuators of each."""

    name: str
    kind: str  # "smooth" or "singular" (through a direct-kinematic singularity)
    targets: np.ndarray  # (N, ...) reference coordinates
    thetas: np.ndarray  # (N, k)
    start_x: np.ndarray | None = None
    start_yt: tuple[np.ndarray, np.ndarray] | None = None

    def start(self, model):
        if self.start_x is not None:
            return model.inverse_kinematics(self.start_x)
        return model.configuration(*self.start_yt)

    def reproducer(self, backend: str) -> str:
        start = (
            f"m.inverse_kinematics({_list(self.start_x)})"
            if self.start_x is not None
            else f"m.configuration({_list(self.start_yt[0])}, {_list(self.start_yt[1])})"
        )
        return (
            f"import numpy as np, scdk_sym as sc; m = {model_expr(self.name)}; "
            f"t = sc.track(m, np.array({_list(self.thetas)}).reshape(-1, {self.thetas.shape[1]}),"
            f" start={start}, backend={backend!r})"
        )


@dataclass
class TrackOutcome:
    track: Track
    backend: str
    status: str  # "ok", "refused", "deviation", "crash", "timeout"
    detail: str = ""
    error: float = float("nan")
    first_bad: int = -1
    seconds: float = 0.0


def _pose_track(ref: PoseReference, model, rng, kind: str, samples: int) -> Track | None:
    box = np.asarray(BOX[ref.name], dtype=float)
    modes = None
    if ref.has_modes and ref.pose_joints is not None and rng.random() < 0.5:
        modes = rng.choice([-1.0, 1.0], ref.k)
    if kind == "smooth":
        t = np.linspace(0.0, 1.0, samples)[:, None]
        x0 = ref.home_x + rng.uniform(-0.3, 0.3, len(box)) * box
        xs = x0.copy()[None, :].repeat(samples, 0)
        for _ in range(3):
            amp = rng.uniform(-0.25, 0.25, len(box)) * box
            xs = xs + amp * np.sin(2 * np.pi * rng.uniform(0.3, 1.5) * t + rng.uniform(0, 6.3))
    else:
        far = np.asarray(FAR_BOX.get(ref.name, box), dtype=float)
        xa = ref.home_x + rng.uniform(-0.5, 0.5, len(box)) * box
        xb = ref.home_x + rng.uniform(-1.0, 1.0, len(box)) * far
        lam = singular_point(ref, xa, xb, modes)
        if lam is None:
            return None
        half = rng.uniform(0.05, 0.3)
        lams = np.linspace(max(0.0, lam - half), min(1.0, lam + half), samples)
        xs = xa + lams[:, None] * (xb - xa)
    thetas, near = [], ref.ik(xs[0], modes=modes)
    if near is None or abs(ref.det_ratio(xs[0], near)) < 0.01 * typical_det(ref.name):
        return None
    for x in xs:
        th = ref.ik(x, near, modes)
        if th is None:
            return None
        thetas.append(th)
        near = th
    thetas = np.array(thetas)
    try:
        if modes is None:
            model.inverse_kinematics(xs[0])
            return Track(ref.name, kind, xs, thetas, start_x=xs[0])
        y = ref.start_y(xs[0], model.unknowns)
        model.configuration(y, thetas[0])
        return Track(ref.name, kind, xs, thetas, start_yt=(y, thetas[0]))
    except Exception:  # noqa: BLE001 - the package cannot start there: draw another
        return None


def _gepetto_track(ref: GepettoReference, model, rng, kind: str, samples: int) -> Track | None:
    h = rng.uniform(0.003, 0.01)
    if kind == "smooth":
        qs, _ = _gepetto_start(ref, model, rng)
        d = ref.tangent(qs).T @ rng.normal(size=ref.k)
    else:
        # find a singular surface, back off before it, cross it with small steps
        path = _walk_until(ref, ref.home_q, rng, WALK["across"], True)
        if path is None:
            return None
        back = min(len(path) - 2, int(rng.integers(1, 8)))
        qs = path[-2 - back]
        d = (path[-1 - back] - qs)[ref.free + ref.motors]
    track = ref.walk(qs, d, samples - 1, h)
    if track is None:
        return None
    signs = [ref.det_sign(p, p[ref.motors], tiny=0.0) for p in track]
    if (kind == "singular") != (len(set(signs)) > 1):
        return None
    if abs(ref.det_ratio(qs, qs[ref.motors])) < 0.01 * typical_det(ref.name):
        return None
    qs_arr = np.array(track)
    y = np.array([qs[ref.index[n]] for n in model.unknowns])
    return Track(ref.name, kind, qs_arr, qs_arr[:, ref.motors], start_yt=(y, qs[ref.motors]))


def draw_tracks(name: str, count: int, seed: int, samples: int = 100) -> list[Track]:
    """``count`` seeded commanded motions (half smooth, half through a singularity; all
    smooth for a model of :data:`NO_SINGULAR`)."""
    ref, model = reference(name), load(name)
    rng = np.random.default_rng([seed, ALL_NAMES.index(name), 7])
    out: list[Track] = []
    draw = _pose_track if isinstance(ref, PoseReference) else _gepetto_track
    for i in range(count):
        kind = "smooth" if i % 2 == 0 or name in NO_SINGULAR else "singular"
        for _ in range(3 * ATTEMPTS):
            tr = draw(ref, model, rng, kind, samples)
            if tr is not None:
                out.append(tr)
                break
    return out


def run_tracks(
    tracks: Sequence[Track], backends: Sequence[str] = ("cvodes", "c"), limit: float | None = None
) -> list[TrackOutcome]:
    """Track every motion on every backend; compare each sample with the commanded one
    (``limit``: wall-time limit per track [s], outcome "timeout")."""
    import scdk_sym as sc

    out = []
    for tr in tracks:
        ref, model = reference(tr.name), load(tr.name)
        start = tr.start(model)
        for backend in backends:
            warm_up(tr.name, backend)
            t0 = time.perf_counter()
            try:
                with time_limit(limit):
                    res = sc.track(model, tr.thetas, start=start, backend=backend)
            except SolveTimeout as exc:
                out.append(TrackOutcome(tr, backend, "timeout", str(exc)))
                out[-1].seconds = time.perf_counter() - t0
                continue
            except sc.ScdkError as exc:
                out.append(TrackOutcome(tr, backend, "refused", f"{type(exc).__name__}: {exc}"))
                out[-1].seconds = time.perf_counter() - t0
                continue
            except Exception as exc:  # noqa: BLE001 - any other exception is a defect
                out.append(TrackOutcome(tr, backend, "crash", _describe(exc)))
                out[-1].seconds = time.perf_counter() - t0
                continue
            dt = time.perf_counter() - t0
            errs = _track_errors(ref, model, tr, res)
            bad = np.nonzero(errs > TRACK_TOL)[0]
            o = TrackOutcome(tr, backend, "ok", error=float(errs.max()), seconds=dt)
            if bad.size:
                o.status, o.first_bad = "deviation", int(bad[0])
                o.detail = f"max error {errs.max():.3g} from sample {bad[0]} of {len(errs)}"
            out.append(o)
    return out


def _track_errors(ref: Reference, model, tr: Track, res) -> np.ndarray:
    errs = []
    for i in range(len(tr.thetas)):
        if isinstance(ref, PoseReference):
            e = ref.distance(res.x[i], tr.targets[i])
            e = max(e, float(np.abs(ref.closure(res.x[i], tr.thetas[i])).max()))
        else:
            target = tr.targets[i]
            y_ref = np.array([target[ref.index[n]] for n in model.unknowns])
            e = float(np.max(np.abs(wrap(np.asarray(res.y[i]) - y_ref))))
            e = max(e, float(np.max(np.abs(res.x[i] - ref.effector_pose(target)[:3, 3]))))
        errs.append(e)
    return np.array(errs)


# ------------------------------------------------------- the curve of a convergent solve

#: Budgets of :func:`line_curve_reaches`: steps and arc length [reference coordinates, s].
LINE_STEPS = 100000
LINE_ARC = 1000.0
#: Largest corrector move of :func:`line_curve_reaches`, relative to the step.
LINE_CORRECTION = 0.05
#: Largest step of :func:`line_curve_reaches` [reference coordinates and s], and the finer
#: one of the second look that confirms a refusal (a fold sharper than a step is jumped by
#: it: the step lands on the neighbouring sheet within the corrector's tolerance).
LINE_H_MAX = 0.05
LINE_H_FINE = 0.002
#: A step that crosses ``s = 1`` counts only when it is at most this long; a longer one is
#: taken again at a quarter (a fold just short of 1 would otherwise be jumped).
LINE_CROSS = 1e-4


def _free(ref: Reference, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(indices of the unknown coordinates of ``u``, 1 where they are angles)."""
    if isinstance(ref, GepettoReference):
        return np.array(ref.free), np.ones(len(ref.free))
    return np.arange(len(u)), np.zeros(len(u))


def line_curve_reaches(
    ref: Reference,
    u0,
    theta1,
    theta0,
    h_max: float = LINE_H_MAX,
    direction: float = 1.0,
    turns: list[float] | None = None,
) -> bool | None:
    """Whether the solution curve of the closures along the line ``theta1 + s (theta0 -
    theta1)`` through the start ``u0`` (at ``s = 0``) reaches ``s = 1``, followed from the
    start towards increasing ``s`` (the convergent branch's first direction).

    Pseudo-arclength continuation on the reference's own closures (finite-difference
    Jacobians, bordered Newton corrector, step halving and growth): True when ``s`` crosses
    1, False when the curve comes back to the start (closed without reaching it), None
    when a budget ran out or the corrector failed (undecided), and None too for a closed
    curve on which ``s`` turned inside a step within :data:`GRAZE` of 1 (a fold just past
    1 crosses it twice within one step: the check of the step's ends would not see it).
    Steps are at most ``h_max`` long; one that crosses 1 counts only when at most
    :data:`LINE_CROSS` long (a longer one is taken again shorter). ``direction=-1`` follows
    the curve towards decreasing ``s`` first (the paper's divergent direction); ``turns``,
    if given, receives the ``s`` of every step inside which ``s`` turned (a fold), and
    ``inf`` last where a budget (steps or arc) ran out, not the corrector.
    """
    theta1 = np.asarray(theta1, dtype=float)
    dth = np.asarray(theta0, dtype=float) - theta1
    u0 = np.array(u0, dtype=float)
    idx, angle = _free(ref, u0)
    rows = ref.rows if isinstance(ref, GepettoReference) else slice(None)

    def F(v):
        u = u0.copy()
        u[idx] = v[:-1]
        return np.asarray(ref.closure(u, theta1 + v[-1] * dth))[rows]

    def J(v, h=1e-7):  # central differences, the 2 len(v) points in one evaluation
        n = len(v)
        V = np.concatenate([v + h * np.eye(n), v - h * np.eye(n)])
        U = np.tile(u0, (2 * n, 1))
        U[:, idx] = V[:, :-1]
        G = ref.closure_many(U, theta1 + V[:, -1:] * dth)[:, rows]
        return ((G[:n] - G[n:]) / (2 * h)).T

    def tangent(v, prev):
        t = np.linalg.svd(J(v))[2][-1]
        return t if float(t @ prev) > 0 else -t

    v = np.append(u0[idx], 0.0)
    start = v.copy()
    if not float(np.abs(F(v)).max()) <= 1e-8:
        return None
    e_s = np.zeros(len(v))
    e_s[-1] = 1.0
    t = tangent(v, direction * e_s)
    t_start = t.copy()
    h, arc, far, grazed = 1e-3, 0.0, False, False
    for _ in range(LINE_STEPS):
        w = v + h * t
        for _it in range(8):  # Newton on [F; t . (w - v) - h] = 0
            r = np.append(F(w), float(t @ (w - v)) - h)
            if float(np.abs(r).max()) <= 1e-11:
                break
            w = w - np.linalg.solve(np.vstack([J(w), t]), r)
        # the corrector moved little from the prediction: still on the curve followed (a
        # larger move may land on another curve passing near, e.g. past a fold)
        ok = (
            float(np.abs(F(w)).max()) <= 1e-10
            and float(np.linalg.norm(w - (v + h * t))) <= LINE_CORRECTION * h
        )
        if not ok:
            h *= 0.5
            if h < 1e-9:
                return None
            continue
        t_new = tangent(w, t)
        if float(t_new @ t) < 0.9:  # turned too sharply for the step: halve it
            h *= 0.5
            continue
        if (v[-1] - 1.0) * (w[-1] - 1.0) <= 0:
            if h > LINE_CROSS:  # approach the level in short steps: a fold may be next to it
                h *= 0.25
                continue
            return True
        if turns is not None and t[-1] * t_new[-1] < 0:
            turns.append(float(w[-1]))
        if t[-1] * t_new[-1] < 0 and _turn_near(v[-1], w[-1], h * t[-1], h * t_new[-1], 1.0):
            grazed = True  # s turned inside the step next to 1: it may cross 1 twice there
        arc += h
        v, t = w, t_new
        d = np.where(np.append(angle, 0.0) > 0, wrap(v - start), v - start)
        d[-1] = v[-1] - start[-1]
        dist = float(np.linalg.norm(d))
        if dist > 10 * h:
            far = True
        elif far and dist <= 2 * h and float(t @ t_start) > 0:
            # back at the start, in the direction it left: the curve is closed (undecided
            # where it turned next to s = 1)
            return None if grazed else False
        if arc > LINE_ARC:
            if turns is not None:
                turns.append(math.inf)  # the arc budget ran out (not a failed corrector)
            return None
        h = min(1.5 * h, h_max)
    if turns is not None:
        turns.append(math.inf)  # the step budget ran out
    return None


#: A turn of ``s`` inside a step whose cubic estimate comes this close to a level leaves the
#: reference undecided about the level (two crossings may hide inside the step).
GRAZE = 1e-4


def _turn_near(sa: float, sb: float, da: float, db: float, level: float) -> bool:
    """Whether the cubic Hermite of ``s`` over a step (ends ``sa``, ``sb``, end derivatives
    times the step ``da``, ``db``) comes within :data:`GRAZE` of ``level`` or passes it."""
    u = np.linspace(0.0, 1.0, 257)
    u2, u3 = u * u, u * u * u
    s = (2 * u3 - 3 * u2 + 1) * sa + (u3 - 2 * u2 + u) * da + (-2 * u3 + 3 * u2) * sb
    s = s + (u3 - u2) * db
    side = np.sign(sa - level)
    return bool(np.any(side * (s - level) <= GRAZE))


#: What a refusal says when the curve through the start gave no answer: the convergent
#: branch's, and the divergent branch's after every way failed.
_NO_ANSWER = {
    "convergent": "did not reach s = 1",
    "divergent": "no solution across a singular surface was reached",
}


def confirm_off_curve(o: Outcome) -> bool:
    """A refusal confirmed by the reference: the curve through the start closes without
    reaching ``s = 1`` (:func:`line_curve_reaches`). Convergent: no answer on that branch.
    Divergent: the paper's divergent path runs along the same closed curve the other way,
    so it has no answer either (the branch's further ways are searches beyond the path);
    and a divergent refusal is confirmed too where the curve has no singular point at all:
    ``s`` never turns, from the start to ``s = 1`` and the other way over a whole budget
    (:data:`LINE_STEPS` steps or :data:`LINE_ARC`; :func:`line_curve_monotone`).
    Where the continuation with its usual steps does not find the curve closed, it is run
    again with steps of at most :data:`LINE_H_FINE` (a fold sharper than a step is jumped)."""
    if o.status != "refused" or _NO_ANSWER.get(o.branch, "\0") not in o.detail:
        return False
    scen = o.scenario
    ref, model = reference(scen.name), load(scen.name)
    start = scen.start(model)
    u0 = ref.coords(start)
    for h_max in (LINE_H_MAX, LINE_H_FINE):
        if line_curve_reaches(ref, u0, start.theta, scen.theta0, h_max) is False:
            return True
    return o.branch == "divergent" and line_curve_monotone(ref, u0, start.theta, scen.theta0)


def line_curve_monotone(ref: Reference, u0, theta1, theta0) -> bool:
    """Whether ``s`` never turns on the line's solution curve through the start
    (:func:`line_curve_reaches`, steps of at most :data:`LINE_H_FINE`): followed forwards
    it reaches ``s = 1`` and backwards it runs through a whole budget, with no fold
    on either side; so the paper's divergent path meets no singular point."""
    ahead: list[float] = []
    behind: list[float] = []
    fwd = line_curve_reaches(ref, u0, theta1, theta0, LINE_H_FINE, turns=ahead)
    if fwd is not True or ahead:
        return False
    back = line_curve_reaches(ref, u0, theta1, theta0, LINE_H_FINE, -1.0, behind)
    return back is None and behind == [math.inf]


# ---------------------------------------------------------------------------- summaries


@dataclass
class Report:
    solves: list[Outcome] = field(default_factory=list)
    tracks: list[TrackOutcome] = field(default_factory=list)

    def counts(self, name: str | None = None, branch: str | None = None, kind: str | None = None):
        """Outcome class -> count (filtered)."""
        sel = [
            o
            for o in self.solves
            if (name is None or o.scenario.name == name)
            and (branch is None or o.branch == branch)
            and (kind is None or o.scenario.kind == kind)
        ]
        c = {k: 0 for k in OUTCOMES}
        for o in sel:
            c[o.status] += 1
        c["solves"] = len(sel)
        c["parity_skipped"] = sum(o.parity == "skipped" for o in sel)
        c["generating"] = sum(o.generating for o in sel)
        c["median_ms"] = float(np.median([o.seconds for o in sel]) * 1e3) if sel else float("nan")
        return c

    def both_refused(self, name: str | None = None, kind: str | None = None) -> int:
        by: dict[int, list[Outcome]] = {}
        for o in self.solves:
            if (name is None or o.scenario.name == name) and (
                kind is None or o.scenario.kind == kind
            ):
                by.setdefault(id(o.scenario), []).append(o)
        no = ("refused", "off_curve")  # no answer on either branch
        return sum(len(v) == 2 and all(o.status in no for o in v) for v in by.values())

    def confirm_refusals(self) -> int:
        """Relabel the refusals that the reference confirms (the curve through the start
        closes without reaching ``s = 1``: :func:`confirm_off_curve`) as "off_curve"; returns
        their number."""
        n = 0
        for o in self.solves:
            if confirm_off_curve(o):
                o.status = "off_curve"
                n += 1
        return n

    def failures(self, statuses=("wrong_residual", "wrong_parity", "crash")) -> list[Outcome]:
        return [o for o in self.solves if o.status in statuses]

    def classes(
        self,
        statuses=("wrong_residual", "wrong_parity", "crash", "refused", "off_curve", "timeout"),
    ):
        """Non-ok solves grouped by (status, model, branch, kind, message with numbers
        blanked): key -> (count, first outcome)."""
        groups: dict[tuple, list] = {}
        for o in self.solves:
            if o.status not in statuses:
                continue
            key = (o.status, o.scenario.name, o.branch, o.scenario.kind, _template(o.detail))
            groups.setdefault(key, [0, o])[0] += 1
        return {k: tuple(v) for k, v in sorted(groups.items(), key=lambda kv: -kv[1][0])}

    def table(self) -> str:
        """Per model and branch: solves, ok, silently wrong (of which parity), refused (both
        branches refused, per scenario), refusals confirmed off the start's curve, crashes,
        timeouts, parity checks skipped, results equal to the generating solution, median wall
        time per solve."""
        names = list(dict.fromkeys(o.scenario.name for o in self.solves))
        head = (
            f"{'model':<20} {'branch':<10} {'solves':>6} {'ok':>6} {'wrong':>5} {'(par)':>5} "
            f"{'refused':>7} {'(both)':>6} {'off':>4} {'crash':>5} {'t/o':>4} {'par.skip':>8} "
            f"{'gen':>5} "
            f"{'ms/solve':>9}"
        )
        lines = [head, "-" * len(head)]
        for name in [*names, None]:
            for branch in BRANCHES:
                c = self.counts(name, branch)
                if not c["solves"]:
                    continue
                wrong = c["wrong_residual"] + c["wrong_parity"]
                both = self.both_refused(name) if branch == "convergent" else ""
                lines.append(
                    f"{name or 'all':<20} {branch:<10} {c['solves']:>6} {c['ok']:>6} {wrong:>5} "
                    f"{c['wrong_parity']:>5} {c['refused']:>7} {both!s:>6} {c['off_curve']:>4} "
                    f"{c['crash']:>5} "
                    f"{c['timeout']:>4} {c['parity_skipped']:>8} {c['generating']:>5} "
                    f"{c['median_ms']:>9.2f}"
                )
        return "\n".join(lines)

    def kind_table(self) -> str:
        names = list(dict.fromkeys(o.scenario.name for o in self.solves))
        head = f"{'model':<20} " + " ".join(f"{k:>22}" for k in KINDS)
        lines = [
            "refused convergent / divergent / both, of scenarios, per kind",
            head,
            "-" * len(head),
        ]
        for name in [*names, None]:
            cells = []
            for kind in KINDS:
                cv = self.counts(name, "convergent", kind)
                dv = self.counts(name, "divergent", kind)
                cell = (
                    f"{cv['refused']}/{dv['refused']}/{self.both_refused(name, kind)} of "
                    f"{cv['solves']}"
                )
                cells.append(f"{cell:>22}")
            lines.append(f"{name or 'all':<20} " + " ".join(cells))
        return "\n".join(lines)

    def track_table(self) -> str:
        head = (
            f"{'model':<20} {'backend':<7} {'kind':<9} {'tracks':>6} {'ok':>4} {'refused':>7} "
            f"{'deviation':>9} {'crash':>5} {'t/o':>4} {'max err (ok)':>12} {'ms/track':>8}"
        )
        lines = [head, "-" * len(head)]
        keys = list(dict.fromkeys((o.track.name, o.backend, o.track.kind) for o in self.tracks))
        for name, backend, kind in keys:
            sel = [
                o
                for o in self.tracks
                if (o.track.name, o.backend, o.track.kind) == (name, backend, kind)
            ]
            st = [o.status for o in sel]
            ok_err = [o.error for o in sel if o.status == "ok"]
            lines.append(
                f"{name:<20} {backend:<7} {kind:<9} {len(sel):>6} {st.count('ok'):>4} "
                f"{st.count('refused'):>7} {st.count('deviation'):>9} {st.count('crash'):>5} "
                f"{st.count('timeout'):>4} "
                f"{(max(ok_err) if ok_err else float('nan')):>12.2e} "
                f"{np.median([o.seconds for o in sel]) * 1e3:>8.1f}"
            )
        return "\n".join(lines)


def fuzz(
    names: Iterable[str] = NAMES,
    count: int = 20,
    seed: int = 0,
    backend: str = "cvodes",
    tracks: int = 0,
    samples: int = 100,
    progress: Callable | None = None,
) -> Report:
    """Seeded fuzz: ``count`` scenarios (2 solves each) and ``tracks`` motions per model."""
    report = Report()
    for name in names:
        report.solves += run_solves(draw_scenarios(name, count, seed), backend, progress)
        if tracks:
            report.tracks += run_tracks(draw_tracks(name, tracks, seed, samples))
    return report
