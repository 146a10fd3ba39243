"""Direct kinematics of Gepetto's ``robot_delta`` written on Pinocchio alone.

An independent reference for the package: nothing here calls scdk_sym. The fixture URDF is
loaded by ``pin.buildModelFromUrdf``, the closures are the YAML ``closed_loop`` frame pairs and
Gepetto's residuals (``6d``: ``log6`` of the relative placement, ``3d``: difference of the
frame origins), differentiated analytically (frame Jacobians and ``Jlog6``).

The robot is planar (every joint axis is along the base x axis): a five-bar (two motors,
two connecting rods, the effector at their common tip) carries two parallelograms. Loop 1:
``rod2`` and ``transmission_rod`` (both 40 mm, grounded 8 mm apart) with the coupler
``transmission``; loop 3: ``connecting_rod2`` and ``transmission_connecting_rod`` (60 mm)
with the couplers ``transmission`` and ``effector`` (10 mm). Every motor value has 8 real
assemblies: 2 five-bar modes x (parallelogram or crossed parallelogram) in each loop. A
parallelogram passes flat (its sides collinear) where its two solution branches cross
transversally; the physical motion keeps the parallelogram there. Where the two rod ends
coincide (an isolated point of the motor plane, ``mot1_rod2 = asin(1/4)``,
``mot1_rod1 = -asin(1/4) - 0.0211706``) the tip may turn freely about them; near it the tip
swings fast, and loop 3 is flat on a curve through it.

Each weld closes a loop cut between two revolute joints on one axis, so the pair can spin
together without moving anything (3 idle freedoms: 12 free joints, rank 9). The reference
holds the joint of the first frame of each pair at its start value and solves the 9 others
(18 rows, full column rank 9 away from flat parallelograms).

Units: metres and radians.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

FIXTURE = Path(__file__).resolve().parent / "fixtures" / "gepetto" / "robot_delta"
#: Continuation step along the motor line [rad] (infinity norm of the motor increment).
STEP = 0.01
#: Converged: max |closure row| below this [m or rad].
TOL = 1e-14


def wrap(a: np.ndarray | float) -> np.ndarray | float:
    """Angle(s) mapped to [-pi, pi) [rad]."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True)
class Assembly:
    """Which branch an assembly is on.

    Attributes:
        mode: five-bar mode: +1 as at home, -1 with the tip mirrored across the line through
            the rod ends.
        crossed: (loop 1, loop 3), True where that loop is a crossed parallelogram.
    """

    mode: int
    crossed: tuple[bool, bool]


@dataclass(frozen=True)
class ContinuationResult:
    """End point of a continuation along the motor line.

    Attributes:
        q: (nq,) Pinocchio configuration at the target motor values.
        placement: (4, 4) effector placement in the base frame [m].
        residual: max |closure row| at ``q`` [m or rad].
        flat: motor values (k,) [rad] where a parallelogram passed flat, with the loop (1 or 3):
            sign changes of :meth:`DeltaReference.flatness`, located by bisection of the step.
        max_correction: largest corrector move over the predictor, over all steps [rad].
        steps: number of continuation steps.
    """

    q: np.ndarray
    placement: np.ndarray
    residual: float
    flat: tuple[tuple[int, np.ndarray], ...]
    max_correction: float
    steps: int


class DeltaReference:
    """Closures, Jacobians, continuation and assembly search of ``robot_delta`` in Pinocchio."""

    def __init__(self, directory: Path = FIXTURE) -> None:
        self.pm = pin.buildModelFromUrdf(str(directory / "robot.urdf"))
        self.data = self.pm.createData()
        spec = yaml.safe_load((directory / "robot.yaml").read_text())
        self.pairs = [
            (self.pm.getFrameId(a), self.pm.getFrameId(b), t)
            for (a, b), t in zip(spec["closed_loop"], spec["type"], strict=True)
        ]
        self.names = [self.pm.names[j] for j in range(1, self.pm.njoints)]
        assert all(self.pm.joints[j].nq == 1 for j in range(1, self.pm.njoints))
        self.index = {n: self.pm.joints[self.pm.getJointId(n)].idx_q for n in self.names}
        self.motor_names = tuple(spec["name_mot"])
        self.motors = np.array([self.index[n] for n in self.motor_names])
        self.free = np.array([i for i in range(self.pm.nq) if i not in self.motors])
        # each weld cuts between two revolute joints on one axis (their joint frames): the pair
        # spins idly; the joint of the first frame is held
        self.cut_pairs = tuple(
            (a, b) for (a, b), t in zip(spec["closed_loop"], spec["type"], strict=True) if t == "6d"
        )
        assert all(a in self.names and b in self.names for a, b in self.cut_pairs)
        self.idle_names = tuple(a for a, _ in self.cut_pairs)
        self.idle = np.array([self.index[n] for n in self.idle_names])
        self.solved = np.array([i for i in self.free if i not in self.idle])
        self.effector = self.pm.getFrameId("effector")
        self.home = self.neutral_assembly()
        self._home_rel = self._relative_orientations(self.home)
        self._home_side = self._side(self.home)

    # ------------------------------------------------------------------ kinematics

    def q_of(self, joints: Mapping[str, float]) -> np.ndarray:
        """Pinocchio ``q`` of a joint-name mapping (every joint of the URDF)."""
        q = np.zeros(self.pm.nq)
        for n in self.names:
            q[self.index[n]] = joints[n]
        return q

    def joints_of(self, q: np.ndarray) -> dict[str, float]:
        """Joint name -> value of a Pinocchio ``q``."""
        return {n: float(q[self.index[n]]) for n in self.names}

    def residual(self, q: np.ndarray) -> np.ndarray:
        """(18,) Gepetto's closure residuals (``log6`` of each relative placement)."""
        pin.framesForwardKinematics(self.pm, self.data, q)
        out = []
        for a, b, kind in self.pairs:
            Ma, Mb = self.data.oMf[a], self.data.oMf[b]
            if kind == "3d":
                out.append(Ma.translation - Mb.translation)
            else:
                out.append(pin.log6(Ma.inverse() * Mb).vector)
        return np.concatenate(out)

    def residual_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(residual (18,), d residual / dq (18, nq)), analytic."""
        pm, d = self.pm, self.data
        pin.computeJointJacobians(pm, d, q)
        pin.updateFramePlacements(pm, d)
        rows, jac = [], []
        for a, b, kind in self.pairs:
            Ma, Mb = d.oMf[a], d.oMf[b]
            if kind == "3d":
                Ja = pin.getFrameJacobian(pm, d, a, pin.LOCAL_WORLD_ALIGNED)[:3]
                Jb = pin.getFrameJacobian(pm, d, b, pin.LOCAL_WORLD_ALIGNED)[:3]
                rows.append(Ma.translation - Mb.translation)
                jac.append(Ja - Jb)
            else:
                Ja = pin.getFrameJacobian(pm, d, a, pin.LOCAL)
                Jb = pin.getFrameJacobian(pm, d, b, pin.LOCAL)
                M = Ma.inverse() * Mb
                rows.append(pin.log6(M).vector)
                jac.append(pin.Jlog6(M) @ (Jb - M.inverse().action @ Ja))
        return np.concatenate(rows), np.vstack(jac)

    def closure(self, q: np.ndarray) -> float:
        """Max |closure row| at ``q`` [m or rad]."""
        return float(np.abs(self.residual(q)).max())

    def placement(self, q: np.ndarray) -> np.ndarray:
        """(4, 4) effector placement in the base frame [m]."""
        pin.framesForwardKinematics(self.pm, self.data, q)
        return self.data.oMf[self.effector].homogeneous.copy()

    def joint_yz(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Joint name -> (y, z) position of the joint in the base frame (the plane) [m]."""
        pin.forwardKinematics(self.pm, self.data, q)
        return {n: self.data.oMi[self.pm.getJointId(n)].translation[1:].copy() for n in self.names}

    # ------------------------------------------------------------------ branches

    def flatness(self, q: np.ndarray) -> tuple[float, float]:
        """Signed sines of the angle between the sides of each parallelogram [-].

        Loop 1: ``rod2`` (``mot1_rod2`` -> ``free1_rod2``) against the ground side
        (``mot1_rod2`` -> ``free1_rod3``); loop 3: ``connecting_rod2`` (``free1_rod2`` ->
        ``closedloop2_A``) against the coupler side (``closedloop1_A`` -> ``free3_rod3``).
        Zero where that loop is flat; a sign change along a path is a flat passage.
        """
        p = self.joint_yz(q)

        def sine(u: np.ndarray, v: np.ndarray) -> float:
            return float((u[0] * v[1] - u[1] * v[0]) / (np.linalg.norm(u) * np.linalg.norm(v)))

        f1 = sine(p["free1_rod2"] - p["mot1_rod2"], p["free1_rod3"] - p["mot1_rod2"])
        f3 = sine(p["closedloop2_A"] - p["free1_rod2"], p["free3_rod3"] - p["closedloop1_A"])
        return f1, f3

    def classify(self, q: np.ndarray | Mapping[str, float]) -> Assembly:
        """Five-bar mode and crossed loops of an assembly (joint values or Pinocchio ``q``).

        A parallelogram keeps the orientation of opposite sides equal: loop 1 is crossed where
        ``transmission_rod`` and ``rod2`` differ in orientation (``free1_rod3 != mot1_rod2``,
        both joints about the same axis), loop 3 where ``transmission`` and ``effector`` do.
        The five-bar mode is the side of the tip relative to the line through the rod ends.
        """
        if isinstance(q, Mapping):
            q = self.q_of(q)
        rel = self._relative_orientations(q) - self._home_rel
        c1, c3 = (bool(abs(wrap(r)) > 1e-6) for r in rel)
        return Assembly(mode=1 if self._side(q) == self._home_side else -1, crossed=(c1, c3))

    def _relative_orientations(self, q: np.ndarray) -> np.ndarray:
        """Rotation angles [rad] about the base x axis: rod2 -> transmission_rod and
        transmission -> effector."""
        pin.framesForwardKinematics(self.pm, self.data, q)

        def rel(a: str, b: str) -> float:
            Ra = self.data.oMf[self.pm.getFrameId(a)].rotation
            Rb = self.data.oMf[self.pm.getFrameId(b)].rotation
            return float((Ra @ pin.log3(Ra.T @ Rb))[0])

        return np.array([rel("rod2", "transmission_rod"), rel("transmission", "effector")])

    def _side(self, q: np.ndarray) -> float:
        """Side of the five-bar tip relative to the line through the rod ends (+1 or -1)."""
        p = self.joint_yz(q)
        u, v = p["free1_rod2"] - p["free1_rod1"], p["free2_rod1"] - p["free1_rod1"]
        return float(np.sign(u[0] * v[1] - u[1] * v[0]))

    def closed_form_placement(self, theta: Sequence[float]) -> np.ndarray:
        """(4, 4) effector placement of the home branch at motor values ``theta``, closed form.

        On the branch of home (both loops parallelograms, home's five-bar mode) the effector
        only translates, by the motion of the five-bar tip: each rod end turns about its motor
        axis, and the tip is the intersection of the two connecting-rod circles on home's side
        of the line through the rod ends. Valid where the rod ends do not coincide.
        """
        q = self.home
        pin.forwardKinematics(self.pm, self.data, q)
        pos = {n: pin.SE3(self.data.oMi[self.pm.getJointId(n)]) for n in self.names}
        ends = []
        for motor, end in (("mot1_rod1", "free1_rod1"), ("mot1_rod2", "free1_rod2")):
            M = pos[motor]
            i = self.motor_names.index(motor)
            R = pin.exp3(M.rotation[:, 2] * (theta[i] - q[self.motors[i]]))
            ends.append(M.translation + R @ (pos[end].translation - M.translation))
        tip0 = pos["free2_rod1"].translation
        l1 = np.linalg.norm((tip0 - pos["free1_rod1"].translation)[1:])
        l2 = np.linalg.norm((tip0 - pos["free1_rod2"].translation)[1:])
        e1, e2 = ends[0][1:], ends[1][1:]
        d = e2 - e1
        L = float(np.linalg.norm(d))
        a = (L**2 + l1**2 - l2**2) / (2 * L)
        n = np.array([-d[1], d[0]]) / L
        tip = e1 + a * d / L + self._home_side * np.sqrt(l1**2 - a**2) * n
        T = self.placement(q)
        T[1:3, 3] += tip - tip0[1:]
        return T

    # ------------------------------------------------------------------ solvers

    def lm(
        self,
        q0: np.ndarray,
        theta: Sequence[float] | None = None,
        cols: np.ndarray | None = None,
        max_iter: int = 100,
        tol: float = TOL,
    ) -> tuple[np.ndarray, float, int]:
        """Levenberg-Marquardt on the columns ``cols`` (default: the solved joints).

        Damped minimum-norm steps ``dq = -J^T (J J^T + mu I)^-1 r`` with
        ``mu = lambda 1e-3 |r|^2`` (Yamashita-Fukushima), accepted only when ``|r|`` decreases
        (else ``lambda`` grows tenfold; it shrinks threefold on success), then undamped
        minimum-norm steps (least squares) once ``|r| < 1e-9``.

        Returns:
            (q, max |closure row|, iterations).
        """
        cols = self.solved if cols is None else cols
        q = np.array(q0, dtype=float)
        if theta is not None:
            q[self.motors] = theta
        r, J = self.residual_jacobian(q)
        nr = float(r @ r)
        lam = 1.0
        it = 0
        while it < max_iter and np.abs(r).max() >= tol:
            it += 1
            A = J[:, cols]
            if nr < 1e-18:
                dq = -np.linalg.lstsq(A, r, rcond=1e-10)[0]
            else:
                mu = lam * 1e-3 * nr + 1e-16
                dq = -A.T @ np.linalg.solve(A @ A.T + mu * np.eye(len(r)), r)
            qn = q.copy()
            qn[cols] += dq
            rn, Jn = self.residual_jacobian(qn)
            nn = float(rn @ rn)
            if nn < nr or nr < 1e-18:
                q, r, J, nr = qn, rn, Jn, nn
                lam = max(lam / 3, 1e-3)
            else:
                lam *= 10
                if lam > 1e12:
                    break
        return q, float(np.abs(r).max()), it

    def neutral_assembly(self) -> np.ndarray:
        """Pinocchio's neutral configuration assembled by LM on all 12 free joints.

        Minimum-norm steps on every free joint (the idle spins included) from zero.
        """
        q, res, _ = self.lm(pin.neutral(self.pm), cols=self.free, max_iter=200)
        assert res < 1e-12, res
        return q

    def continuation(
        self, q_start: np.ndarray, theta: Sequence[float], step: float = STEP
    ) -> ContinuationResult:
        """Follow the assembly of ``q_start`` while the motors move straight to ``theta``.

        Predictor-corrector in the line parameter: a secant predictor through the last two
        solutions (a tangent from the Jacobian on the first step), then LM on the solved
        joints. Motor steps are at most ``step`` [rad] and are halved until the corrector
        converges, moves the prediction by less than a fifth of the step's joint motion and
        every joint moves by at most 0.05 rad (the tip of the five-bar swings fast near the
        motor values where its rod ends coincide). Through a flat parallelogram the
        predictor continues the incoming tangent, so the corrector lands on the branch that
        continues it (the parallelogram).

        Raises:
            RuntimeError: the step shrinks below 1e-9 of the line.
        """
        theta0 = np.asarray(q_start)[self.motors].astype(float)
        theta1 = np.asarray(theta, dtype=float)
        span = float(np.abs(theta1 - theta0).max())
        ds_max = 1.0 if span == 0 else min(1.0, step / span)
        q = np.array(q_start, dtype=float)
        q_prev, ds_prev = None, 0.0
        s, ds = 0.0, ds_max
        flat: list[tuple[int, np.ndarray]] = []
        f_last = np.array(self.flatness(q))
        worst, steps = 0.0, 0
        while s < 1.0:
            ds = min(ds, 1.0 - s)
            th = theta0 + (theta1 - theta0) * (s + ds)
            if q_prev is None:
                _, J = self.residual_jacobian(q)
                pred = q.copy()
                pred[self.motors] = th
                pred[self.solved] -= np.linalg.lstsq(
                    J[:, self.solved], J[:, self.motors] @ (th - q[self.motors]), rcond=None
                )[0]
            else:
                pred = q + (q - q_prev) * (ds / ds_prev)
            q_new, res, _ = self.lm(pred, th, max_iter=30)
            corr = float(np.abs(q_new - pred).max())
            move = float(np.abs((q_new - q)[self.solved]).max())
            if res > 1e-12 or corr > 0.2 * move + 1e-10 or move > 0.05:
                ds *= 0.5
                if ds < 1e-9:
                    raise RuntimeError(
                        f"continuation to {theta1}: stalled at s = {s:.6f} (residual "
                        f"{res:.1e}, correction {corr:.1e}, move {move:.1e})"
                    )
                continue
            worst = max(worst, corr)
            steps += 1
            f_new = np.array(self.flatness(q_new))
            for loop, j in ((1, 0), (3, 1)):
                if f_last[j] * f_new[j] < 0:
                    flat.append((loop, self._locate_flat(q, q_new, j)))
            q_prev, q, f_last, ds_prev = q, q_new, f_new, ds
            s += ds
            ds = min(1.5 * ds, ds_max)
        q[self.motors] = theta1
        q, res, _ = self.lm(q, theta1)
        return ContinuationResult(
            q=q,
            placement=self.placement(q),
            residual=self.closure(q),
            flat=tuple(flat),
            max_correction=worst,
            steps=steps,
        )

    def _locate_flat(self, qa: np.ndarray, qb: np.ndarray, j: int) -> np.ndarray:
        """Motor values where flatness ``j`` vanishes between two neighbouring solutions."""
        fa = self.flatness(qa)[j]
        for _ in range(40):
            qm = 0.5 * (qa + qb)
            qm, _, _ = self.lm(qm, qm[self.motors])
            fm = self.flatness(qm)[j]
            if fm * fa > 0:
                qa, fa = qm, fm
            else:
                qb = qm
        return 0.5 * (qa + qb)[self.motors]

    def flat_configuration(self, q_near: np.ndarray, theta: Sequence[float]) -> np.ndarray:
        """Loop 1 flat on the parallelogram branch: ``free1_rod3 = mot1_rod2`` held, LM on the rest.

        At a flat parallelogram the closure Jacobian drops rank and LM converges only
        linearly; holding the parallelogram relation makes the remaining system regular.
        """
        q = np.array(q_near, dtype=float)
        q[self.motors] = theta
        i3 = self.index["free1_rod3"]
        q[i3] = q[self.index["mot1_rod2"]]
        cols = np.array([i for i in self.solved if i != i3])
        q, res, _ = self.lm(q, cols=cols)
        assert res < 1e-13, res
        return q

    def assemblies(
        self, theta: Sequence[float], q_gauge: np.ndarray, starts: int = 400, seed: int = 0
    ) -> list[np.ndarray]:
        """Every real assembly found at motor values ``theta``, deduplicated.

        LM from ``starts`` random configurations (solved joints uniform in [-pi, pi), the
        idle joints at their values in ``q_gauge``); converged ones (residual < 1e-12)
        are compared joint by joint modulo 2 pi (1e-6 rad).
        """
        rng = np.random.default_rng(seed)
        found: list[np.ndarray] = []
        for _ in range(starts):
            q = np.array(q_gauge, dtype=float)
            q[self.motors] = theta
            q[self.solved] = rng.uniform(-np.pi, np.pi, len(self.solved))
            q, res, _ = self.lm(q, max_iter=200)
            if res > 1e-12:
                continue
            q[self.free] = q_gauge[self.free] + wrap(q[self.free] - q_gauge[self.free])
            if all(np.abs(wrap(q - p)).max() > 1e-6 for p in found):
                found.append(q)
        return found


@cache
def reference() -> DeltaReference:
    """The Pinocchio reference of the fixture (built once)."""
    return DeltaReference()
