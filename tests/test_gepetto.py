"""Closed-chain models published by Gepetto (example-parallel-robots), loaded as they are.

The fixtures (tests/fixtures/gepetto, BSD-3-Clause, see the LICENSE there) only carry
``closed_loop`` / ``type`` / ``name_mot``: no home, no platform. Two are not square as written
and must be reduced at load. Every direct-kinematics solution is checked by Pinocchio (closure
residuals through its constraint models, frame placements) and against an independent
Gauss-Newton solve written here on Pinocchio alone (Gepetto's own residuals: 3d = difference of
the frame origins, 6d = log6 of the relative placement).
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

import scdk_sym as sc
from scdk_sym.cli import main
from scdk_sym.errors import NonSquareSystemError, UnknownNameError
from scdk_sym.solvers.solve import solve
from scdk_sym.verify.pinocchio import closure_residuals, pin_configuration, placement_error

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "gepetto"
NAMES = ("5bar_linkage_iso3d", "5bar_linkage_iso6d", "5bar_linkage", "robot_delta")
N_SOLVES = 200
#: name -> (rows, unknowns, rank, redundant rows, idle joints) of a system that is not square
REDUCED = {"5bar_linkage": (6, 4, 3, 3, 1), "robot_delta": (18, 12, 9, 9, 3)}


@cache
def model(name: str) -> sc.Model:
    return sc.load_model(FIXTURES / name, frame="effector")


class PinocchioReference:
    """Direct kinematics with Pinocchio only: Gauss-Newton (minimum-norm steps) on the closures."""

    def __init__(self, name: str) -> None:
        self.pm = pin.buildModelFromUrdf(str(FIXTURES / name / "robot.urdf"))
        self.data = self.pm.createData()
        spec = yaml.safe_load((FIXTURES / name / "robot.yaml").read_text())
        self.pairs = [
            (self.pm.getFrameId(a), self.pm.getFrameId(b), t)
            for (a, b), t in zip(spec["closed_loop"], spec["type"], strict=True)
        ]
        self.motors = [self.pm.joints[self.pm.getJointId(n)].idx_q for n in spec["name_mot"]]
        self.free = [i for i in range(self.pm.nq) if i not in self.motors]
        self.effector = self.pm.getFrameId("effector")

    def residual(self, q: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(self.pm, self.data, q)
        out = []
        for a, b, kind in self.pairs:
            Ma, Mb = self.data.oMf[a], self.data.oMf[b]
            if kind == "3d":
                out.append(Ma.translation - Mb.translation)
            else:
                out.append(pin.log6(Ma.inverse() * Mb).vector)
        return np.concatenate(out)

    def solve(self, theta: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, float]:
        """(effector placement 4x4, max |residual|) from the start q0 with motors at theta."""
        q = q0.copy()
        q[self.motors] = theta
        for _ in range(50):
            r = self.residual(q)
            if np.abs(r).max() < 1e-14:
                break
            J = np.zeros((r.size, len(self.free)))
            for k, i in enumerate(self.free):
                dq = np.zeros_like(q)
                dq[i] = 1e-7
                J[:, k] = (self.residual(q + dq) - self.residual(q - dq)) / 2e-7
            q[self.free] -= np.linalg.lstsq(J, r, rcond=None)[0]
        res = float(np.abs(self.residual(q)).max())
        return self.data.oMf[self.effector].homogeneous.copy(), res


def test_fixtures_keep_their_licence() -> None:
    assert "BSD 3-Clause" in (FIXTURES / "LICENSE").read_text()
    for name in NAMES:
        data = yaml.safe_load((FIXTURES / name / "robot.yaml").read_text())
        assert set(data) == {"closed_loop", "type", "name_mot"}  # as published


@pytest.mark.parametrize("name", NAMES)
def test_loads_as_is_and_reduces_what_is_not_square(name: str) -> None:
    m = model(name)
    assert m.frame == "effector"
    assert m.home.residual <= 1e-12
    assert closure_residuals(m, m.home.joints).max() <= 1e-12
    assert m.m == len(m.unknowns) == len(m.rows)
    if name not in REDUCED:
        assert m.reduction is None and not m.locked
        return
    rows, unknowns, rank, redundant, idle = REDUCED[name]
    note = m.reduction
    assert "\n" not in note
    assert f"{rows} rows x {unknowns} unknowns, rank {rank}" in note
    assert f"dropped {redundant} redundant row(s)" in note
    assert len(m.locked) == idle and m.m == rank
    for joint in m.locked:
        assert joint in note


def test_idle_joints_are_locked_where_rounding_cannot_move_them(monkeypatch) -> None:
    """robot_delta has no home: it is projected from the neutral configuration, and its three
    idle joints are locked there. A start moved by 1e-13 rad (seeded) must lock them within
    1e-10 of the unmoved one: a projection stepping along the idle directions moved them by
    1e-4, so the model depended on the floating-point library it ran on."""
    from scdk_sym.robot.model import Model

    project = Model._project
    locked = [np.array(list(model("robot_delta").locked.values()))]
    for seed in range(2):
        rng = np.random.default_rng(seed)

        def moved(f_all, y, theta, rng=rng):
            return project(f_all, y + 1e-13 * rng.standard_normal(len(y)), theta)

        monkeypatch.setattr(Model, "_project", staticmethod(moved))
        m = sc.load_model(FIXTURES / "robot_delta", frame="effector")
        assert m.home.residual <= 1e-12
        locked.append(np.array(list(m.locked.values())))
    assert float(np.ptp(np.array(locked), axis=0).max()) <= 1e-10


def test_neutral_assembly_matches_the_published_figure() -> None:
    # README of the fixtures: least squares from the neutral configuration, mot1 = mot2 = 0
    m = model("5bar_linkage_iso3d")
    np.testing.assert_allclose(m.home.x, [0.139968, -0.2, -0.616625], rtol=0, atol=1e-6)


@cache
def solutions(name: str) -> list[tuple[np.ndarray, sc.SolveResult]]:
    m = model(name)
    rng = np.random.default_rng(100 + NAMES.index(name))
    out = []
    for _ in range(N_SOLVES):
        theta = m.home.theta + rng.uniform(-0.2, 0.2, m.k)
        out.append((theta, solve(m, theta, record_path=False)))
    return out


@pytest.mark.parametrize("name", NAMES)
def test_direct_kinematics_checked_by_pinocchio(name: str) -> None:
    m = model(name)
    sols = solutions(name)
    assert len(sols) >= 200
    assert max(r.residual for _, r in sols) <= 1e-12
    assert max(closure_residuals(m, r.joints).max() for _, r in sols) <= 1e-12
    assert max(placement_error(m, r.y, r.theta) for _, r in sols[:20]) <= 1e-12


@pytest.mark.parametrize("name", NAMES)
def test_direct_kinematics_matches_an_independent_pinocchio_solve(name: str) -> None:
    m = model(name)
    ref = PinocchioReference(name)
    q0 = pin_configuration(m, m.home.joints)
    worst = 0.0
    for theta, r in solutions(name):
        T, res = ref.solve(theta, q0)
        assert res <= 1e-13
        worst = max(worst, float(np.abs(T - r.platform_pose).max()))
    assert worst <= 1e-9, worst


def test_warm_solves_stay_exact() -> None:
    # a control loop: each solve starts from the previous solution
    m = model("5bar_linkage_iso3d")
    rng = np.random.default_rng(7)
    cfg = m.home
    for _ in range(100):
        theta = cfg.theta + rng.uniform(-0.02, 0.02, m.k)
        res = solve(m, theta, start=cfg, record_path=False)
        assert res.residual <= 1e-12
        assert closure_residuals(m, res.joints).max() <= 1e-12
        cfg = m.configuration(res.y, res.theta)


# ---------------------------------------------------------------------------- CLI


@pytest.mark.parametrize("name", NAMES)
def test_cli_solve_with_frame_effector(name: str, capsys) -> None:
    m = model(name)
    theta = m.home.theta + np.array([0.1, -0.1])
    argv = ["solve", str(FIXTURES / name), "--theta", ",".join(repr(float(v)) for v in theta)]
    assert main([*argv, "--frame", "effector", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["residual"] <= 1e-12
    # Pinocchio places the effector where the solver says, and the closures hold there
    placements = PinocchioReference(name)
    q = pin_configuration(m, out["joints"])
    assert np.abs(placements.residual(q)).max() <= 1e-12
    pin.framesForwardKinematics(placements.pm, placements.data, q)
    T = placements.data.oMf[placements.effector].homogeneous
    np.testing.assert_allclose(out["platform_pose"], T, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["x"], T[:3, 3], rtol=0, atol=1e-12)
    # the reduction is stated in one line on stderr with --verbose, not on every call
    assert main([*argv, "--frame", "effector"]) == 0
    assert "note:" not in capsys.readouterr().err
    assert main([*argv, "--frame", "effector", "--verbose"]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if line.startswith("note: reduced")]
    assert len(notes) == (1 if name in REDUCED else 0)


# ---------------------------------------------------------------------------- errors


def test_irreducible_system_names_joints_and_rows(tmp_path: Path) -> None:
    # one motor fewer: the other one is free and moves the effector, nothing can be reduced
    d = tmp_path / "one_motor"
    d.mkdir()
    (d / "robot.urdf").write_text((FIXTURES / "5bar_linkage" / "robot.urdf").read_text())
    (d / "robot.yaml").write_text(
        "closed_loop: [['closedloop1_A', 'closedloop1_B']]\ntype: ['6d']\nname_mot: ['mot1']\n"
    )
    with pytest.raises(NonSquareSystemError) as info:
        sc.load_model(d)
    msg = str(info.value)
    assert (info.value.rows, info.value.unknowns, info.value.rank) == (6, 5, 3)
    for word in ("mot2", "free1", "6d(closedloop1_A,closedloop1_B).x", "effector"):
        assert word in msg
    assert "\n" not in msg
    assert main(["solve", str(d), "--theta", "0.1"]) == 1


def test_unknown_frame_lists_links_and_joint_frames() -> None:
    with pytest.raises(UnknownNameError) as info:
        sc.load_model(FIXTURES / "5bar_linkage", frame="no_such_frame")
    assert "closedloop1_A" in info.value.valid and "effector" in info.value.valid
