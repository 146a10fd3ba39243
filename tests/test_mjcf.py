"""MJCF models: loaded through MuJoCo's compiler, every answer checked by MuJoCo itself.

The reference is ``tests/mjcf_reference.py`` (MuJoCo alone, no scdk_sym): an answer's ``qpos``
is put into MuJoCo's ``data.qpos`` and its equality rows (``efc_pos`` after ``mj_forward``)
must vanish; the bodies the inputs determine must sit where a continuation in MuJoCo's own
kinematics (Newton on ``efc_pos`` / ``efc_J`` as the inputs move in small steps) puts them.
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

import mjcf_reference as ref  # noqa: E402

import scdk_sym as sc  # noqa: E402
from scdk_sym.errors import (  # noqa: E402
    DependencyError,
    InputError,
    ModelError,
    NonSquareSystemError,
    UnknownNameError,
)

MJCF = Path(__file__).resolve().parent / "fixtures" / "mjcf"
CASSIE = MJCF / "menagerie" / "agility_cassie" / "cassie.xml"
ROBOTIQ = MJCF / "menagerie" / "robotiq_2f85" / "2f85.xml"
SPRINGS = ("left-shin", "left-heel-spring", "right-shin", "right-heel-spring")
ROBOTIQ_SPRINGS = ("right_spring_link_joint", "left_spring_link_joint")
#: Written from scratch (tests/fixtures/mjcf/README.md): name -> every input's change [rad].
WRITTEN = {
    "planar_fourbar": 0.05,
    "fourbar_sites": 0.05,
    "delta_ball": 0.05,
    "weld_loop": 0.05,
    "coupled": 0.05,
}


@cache
def kinematics(path: Path):
    return ref.load_kinematics(path)


@cache
def cassie(*inputs: str) -> sc.Model:
    return sc.load_model(CASSIE, inputs=list(inputs) if inputs else None)


def robotiq(value: float = 0.0) -> sc.Model:
    return sc.load_model(ROBOTIQ, locked=dict.fromkeys(ROBOTIQ_SPRINGS, value))


def mujoco_residual(path: Path, qpos: np.ndarray) -> float:
    return float(np.abs(ref.equality_residual(kinematics(path), qpos)).max())


def determined_bodies(model: sc.Model) -> list[str]:
    """The bodies whose pose the inputs determine: all but the rods between two ball points,
    whose spin about their own axis is idle (their position is still compared)."""
    m = kinematics(Path(model.path))
    out = []
    for b in range(1, m.nbody):
        j0, n = m.body_jntadr[b], m.body_jntnum[b]
        if not any(m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL for j in range(j0, j0 + n)):
            out.append(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b))
    return out


def assert_as_continuation(model: sc.Model, qpos: np.ndarray, theta, tol: float = 1e-6):
    """The answer's bodies equal a continuation in MuJoCo's kinematics from home."""
    m = kinematics(Path(model.path))
    inputs = dict(zip(model.actuated, np.asarray(theta, dtype=float).tolist(), strict=True))
    fixed = [j for j in model.held if j not in inputs]
    expected = ref.continuation(m, model.home.qpos, inputs, fixed=fixed, steps=40)
    ours, theirs = ref.body_poses(m, qpos), ref.body_poses(m, expected)
    keep = set(determined_bodies(model))
    for name, (p, R) in theirs.items():
        np.testing.assert_allclose(ours[name][0], p, rtol=0, atol=tol, err_msg=name)
        if name in keep:
            np.testing.assert_allclose(ours[name][1], R, rtol=0, atol=tol, err_msg=name)


# ---------------------------------------------------------------------------- Cassie


def test_cassie_as_published_loads_with_an_assembled_regular_home() -> None:
    model = cassie()
    assert model.k == 10 and model.m == 10
    assert set(model.held) == set(SPRINGS)  # springs held at springref
    assert model.assembly and "keyframe" not in model.assembly
    assert "projected onto the closures" in model.assembly
    # the keyframe 'home' closes only to about 1.5e-3 in MuJoCo itself
    m = kinematics(CASSIE)
    assert 1e-3 < mujoco_residual(CASSIE, np.array(m.key_qpos[0])) < 3e-3
    # our home closes in MuJoCo and is regular: J_p of full rank with a margin
    assert mujoco_residual(CASSIE, model.home.qpos) <= 1e-12
    J = ref.equality_jacobian(m, model.home.qpos)
    dofs = ref.solved_dofs(m, model.actuated, fixed=SPRINGS)
    sv = np.linalg.svd(J[:, dofs], compute_uv=False)
    # 12 rows, 14 dofs (two rod spins idle): rank 10, as MuJoCo's own Jacobian says
    assert int(np.sum(sv > 1e-8 * sv[0])) == 10 and sv[9] / sv[0] > 1e-3


def test_cassie_qpos0_is_singular_and_home_moves_off_it(tmp_path: Path) -> None:
    # without its keyframe, Cassie's home is qpos0: closed exactly, but each plantar
    # four-bar is stretched (MuJoCo's equality Jacobian over the solved dofs has rank 8)
    text = CASSIE.read_text()
    text = re.sub(r"<keyframe>.*?</keyframe>", "", text, flags=re.DOTALL)
    path = tmp_path / "cassie_qpos0.xml"
    path.write_text(text.replace('meshdir="assets"', f'meshdir="{CASSIE.parent / "assets"}"'))
    m = ref.load_kinematics(path)
    assert mujoco_residual(path, np.array(m.qpos0)) <= 1e-12
    dofs = ref.solved_dofs(m, cassie().actuated, fixed=SPRINGS)
    sv = np.linalg.svd(ref.equality_jacobian(m, np.array(m.qpos0))[:, dofs], compute_uv=False)
    assert int(np.sum(sv > 1e-8 * sv[0])) == 8
    model = sc.load_model(path)
    assert "singular" in model.assembly and "closure rank 8 where 10 is generic" in model.assembly
    qpos = model.home.qpos
    assert mujoco_residual(path, qpos) <= 1e-12
    sv = np.linalg.svd(ref.equality_jacobian(m, qpos)[:, dofs], compute_uv=False)
    assert int(np.sum(sv > 1e-8 * sv[0])) == 10
    assert np.abs(qpos - np.array(m.qpos0)).max() <= 0.2  # nearby


@pytest.mark.parametrize("branch", ["convergent", "divergent"])
def test_cassie_both_branches_close_in_mujoco(branch: str) -> None:
    model = cassie()
    theta = model.home.theta + 0.05
    res = sc.solve(model, theta, start=model.home, branch=branch)
    assert res.qpos.shape == (kinematics(CASSIE).nq,)
    assert mujoco_residual(CASSIE, res.qpos) <= 1e-9
    if branch == "convergent":
        assert_as_continuation(model, res.qpos, theta)
    else:  # another assembly: some determined body elsewhere than the continuation's
        conv = sc.solve(model, theta, start=model.home, branch="convergent")
        assert np.abs(res.qpos - conv.qpos).max() > 1e-3


def test_cassie_with_its_springs_as_measured_inputs() -> None:
    model = cassie(*cassie().actuated, *SPRINGS)
    assert model.k == 14 and not model.held
    theta = model.home.theta + np.r_[np.full(10, 0.05), np.full(4, 0.02)]
    for branch in ("convergent", "divergent"):
        res = sc.solve(model, theta, start=model.home, branch=branch)
        assert mujoco_residual(CASSIE, res.qpos) <= 1e-9
    res = sc.solve(model, theta, start=model.home, branch="convergent")
    assert_as_continuation(model, res.qpos, theta)
    for name in SPRINGS:  # an input's value is its qpos
        assert res.joints[name] == pytest.approx(theta[model.actuated.index(name)], abs=1e-15)


def test_cassie_joints_are_by_mjcf_name_with_quaternions_and_ref_included() -> None:
    model = cassie()
    res = sc.solve(model, model.home.theta + 0.05, start=model.home)
    m = kinematics(CASSIE)
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or "" for j in range(m.njnt)]
    assert [n for n in res.joints if n in names] == [n for n in names if n]
    for j, name in enumerate(names):
        adr = m.jnt_qposadr[j]
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            q = np.array(res.joints[name])
            assert q.shape == (4,) and abs(np.linalg.norm(q) - 1) <= 1e-12
            np.testing.assert_allclose(q, res.qpos[adr : adr + 4], rtol=0, atol=0)
        elif m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            assert res.joints[name] == res.qpos[adr]
    # the knee's ref is -45 degrees: qpos, not the rotation from the file's pose
    knee = res.joints["left-knee"]
    assert -2.9 < knee < -0.6


def test_cassie_track_c_along_a_motion_of_both_legs_equals_the_continuation() -> None:
    model = cassie()
    t = np.linspace(0.0, 1.0, 400)[:, None]
    amp = np.array([0.1, 0.1, 0.4, 0.5, 0.4] * 2) * np.r_[np.ones(5), -np.ones(5)]
    thetas = model.home.theta + amp * np.sin(2 * np.pi * t)
    res = sc.track(model, thetas, start=model.home, backend="c")
    cvodes = sc.track(model, thetas, start=model.home, backend="cvodes")
    np.testing.assert_allclose(res.y, cvodes.y, rtol=0, atol=1e-9)
    cfgs = res.configurations(model)
    assert max(mujoco_residual(CASSIE, c.qpos) for c in cfgs) <= 1e-9
    # no silent jump: MuJoCo's continuation sample by sample agrees everywhere
    m = kinematics(CASSIE)
    q = model.home.qpos
    for i in range(0, 400, 40):
        inputs = dict(zip(model.actuated, thetas[i], strict=True))
        q = ref.continuation(m, q, inputs, fixed=SPRINGS, steps=10)
        ours, theirs = ref.body_poses(m, cfgs[i].qpos), ref.body_poses(m, q)
        err = max(np.abs(ours[b][0] - theirs[b][0]).max() for b in theirs)
        assert err <= 1e-6, (i, err)


def test_cassie_assembly_modes_are_certified_and_close_in_mujoco() -> None:
    model = cassie()
    modes = sc.assembly_modes(model, model.home.theta + 0.05)
    assert modes.certified and len(modes) == 64  # 8 per leg, legs independent
    qs = np.array([c.qpos for c in modes])
    assert max(mujoco_residual(CASSIE, q) for q in qs) <= 1e-9
    # pairwise distinct
    d = np.abs(qs[:, None] - qs[None]).max(axis=2) + np.eye(len(qs))
    assert d.min() > 1e-6


# ---------------------------------------------------------------------------- Robotiq 2F-85


def test_robotiq_as_published_is_refused_naming_its_springs_and_finger_freedoms() -> None:
    with pytest.raises(ModelError) as info:
        sc.load_model(ROBOTIQ)
    text = str(info.value)
    for name in (*ROBOTIQ_SPRINGS, "right_follower_joint", "left_follower_joint"):
        assert name in text
    assert "2 freedom(s) left undetermined" in text and "locked=" in text
    # MuJoCo agrees: with the springs free, its equality Jacobian over the unknown joints
    # leaves two freedoms besides the input
    m = kinematics(ROBOTIQ)
    J = ref.equality_jacobian(m, np.array(m.qpos0))
    sv = np.linalg.svd(J, compute_uv=False)
    rank = int(np.sum(sv > 1e-8 * sv[0]))
    assert m.nv - rank == 3  # the tendon input + one free finger freedom per side


def test_robotiq_with_its_spring_links_locked_solves_and_closes_in_mujoco() -> None:
    model = robotiq(0.0)
    assert model.actuated == ("fingers_actuator",)
    for value in (0.2, 0.5):
        res = sc.solve(model, [value], start=model.home, branch="convergent")
        assert mujoco_residual(ROBOTIQ, res.qpos) <= 1e-9
        q = res.qpos
        m = kinematics(ROBOTIQ)
        adr = {n: m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)]
               for n in ("right_driver_joint", "left_driver_joint")}  # fmt: skip
        # the tendon (0.5 each) is at the input, the coupling holds both drivers together
        assert 0.5 * (q[adr["right_driver_joint"]] + q[adr["left_driver_joint"]]) == (
            pytest.approx(value, abs=1e-12)
        )
        assert res.joints["fingers_actuator"] == pytest.approx(value, abs=1e-15)


# ---------------------------------------------------------------------------- written here


@pytest.mark.parametrize("name", sorted(WRITTEN))
def test_written_mechanisms_close_in_mujoco_and_follow_its_continuation(name: str) -> None:
    path = MJCF / f"{name}.xml"
    model = sc.load_model(path)
    assert mujoco_residual(path, model.home.qpos) <= 1e-12
    theta = model.home.theta + WRITTEN[name]
    res = sc.solve(model, theta, start=model.home, branch="convergent")
    assert mujoco_residual(path, res.qpos) <= 1e-9
    if all(a in res.joints and isinstance(res.joints[a], float) for a in model.actuated):
        m = kinematics(path)
        if all(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, a) >= 0 for a in model.actuated):
            assert_as_continuation(model, res.qpos, theta)


@pytest.mark.parametrize("name", sorted(WRITTEN))
def test_written_mechanisms_placements_equal_mujoco_at_random_joint_values(name: str) -> None:
    path = MJCF / f"{name}.xml"
    model = sc.load_model(path)
    rng = np.random.default_rng(7)
    m = kinematics(path)
    for _ in range(3):
        y = model.home.y + 0.3 * rng.standard_normal(model.m)
        th = model.home.theta + 0.3 * rng.standard_normal(model.k)
        cfg = model.configuration(y, th)
        ours = model.placements(cfg)
        for body, (p, R) in ref.body_poses(m, cfg.qpos).items():
            if body == "world":
                continue
            np.testing.assert_allclose(ours[body][:3, 3], p, rtol=0, atol=1e-12, err_msg=body)
            np.testing.assert_allclose(ours[body][:3, :3], R, rtol=0, atol=1e-12, err_msg=body)


def test_inactive_equalities_are_skipped_and_said() -> None:
    model = sc.load_model(MJCF / "coupled.xml")
    m = kinematics(MJCF / "coupled.xml")
    inactive = int(np.sum(m.eq_active0 == 0))
    assert inactive >= 1
    assert len(model.closures) == m.neq - inactive + 1  # + the tendon input's row
    assert any("inactive equalities skipped" in n for n in model.source.notes)


def test_assembly_modes_of_a_fourbar_equal_a_random_start_least_squares_in_mujoco() -> None:
    path = MJCF / "planar_fourbar.xml"
    model = sc.load_model(path)
    theta = model.home.theta + 0.1
    modes = sc.assembly_modes(model, theta)
    assert modes.certified
    ours = sorted(tuple(np.round(c.qpos, 6)) for c in modes)
    # reference: Gauss-Newton in MuJoCo from 60 seeded random starts over the unknowns
    m = kinematics(path)
    rng = np.random.default_rng(3)
    adr = m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, model.actuated[0])]
    found = []
    for _ in range(60):
        q = rng.uniform(-np.pi, np.pi, m.nq)
        q[adr] = theta[0]
        try:
            q = ref.continuation(m, q, {model.actuated[0]: theta[0]}, steps=1)
        except RuntimeError:
            continue
        q = (q + np.pi) % (2 * np.pi) - np.pi
        found.append(tuple(np.round(q, 6)))
    theirs = sorted(set(found))
    assert len(ours) == len(theirs) == 2
    wrapped = [tuple(np.round((np.array(o) + np.pi) % (2 * np.pi) - np.pi, 6)) for o in ours]
    np.testing.assert_allclose(sorted(wrapped), theirs, rtol=0, atol=2e-6)


# ---------------------------------------------------------------------------- inputs, locks


def test_any_joints_as_inputs_urdf_round_trip() -> None:
    """A five-bar's passive joints as inputs: the motors it returns are the ones that gave
    those joints (both formats take ``inputs=``)."""
    fixtures = Path(__file__).resolve().parent / "fixtures" / "gepetto"
    base = sc.load_model(fixtures / "5bar_linkage_iso3d")
    theta = base.home.theta + np.array([0.05, -0.04])
    res = sc.solve(base, theta, start=base.home)
    outputs = [u for u in base.unknowns][:2]
    swapped = sc.load_model(fixtures / "5bar_linkage_iso3d", inputs=outputs)
    assert set(swapped.unknowns) >= set(base.actuated)
    back = sc.solve(swapped, [res.joints[o] for o in outputs], start=swapped.home)
    for a, v in zip(base.actuated, theta, strict=True):
        assert back.joints[a] == pytest.approx(v, abs=1e-9)


def test_inputs_that_leave_freedoms_or_bind_each_other_are_refused_naming_joints() -> None:
    with pytest.raises(NonSquareSystemError, match="left undetermined by the actuators"):
        sc.load_model(CASSIE, inputs=["left-hip-roll"])
    with pytest.raises(NonSquareSystemError, match="over-actuated"):
        sc.load_model(MJCF / "planar_fourbar.xml", inputs=["crank", "rocker"])


@pytest.mark.parametrize(
    ("kwargs", "error", "text"),
    [
        ({"inputs": "crank"}, InputError, "list of joint names"),
        ({"inputs": ["crank", "crank"]}, InputError, "duplicates"),
        ({"inputs": ["nope"]}, UnknownNameError, "unknown joint 'nope'"),
        ({"locked": {"nope": 0.0}}, UnknownNameError, "unknown joint 'nope'"),
        ({"locked": {"crank": 0.0}}, InputError, "both an input and locked"),
        ({"locked": {"rocker": float("nan")}}, InputError, "finite"),
    ],
)
def test_bad_inputs_and_locks_get_one_line_errors(kwargs, error, text) -> None:
    with pytest.raises(error) as info:
        sc.load_model(MJCF / "planar_fourbar.xml", **kwargs)
    assert text in str(info.value) and "\n" not in str(info.value)


def test_a_locked_joint_is_held_and_reported() -> None:
    model = sc.load_model(MJCF / "delta_ball.xml", locked={})
    assert not model.held
    model = robotiq(0.1)
    res = sc.solve(model, [0.3], start=model.home)
    for name in ROBOTIQ_SPRINGS:
        assert res.joints[name] == 0.1
    assert mujoco_residual(ROBOTIQ, res.qpos) <= 1e-9


def test_a_missing_mujoco_says_how_to_install_it(monkeypatch) -> None:
    import builtins

    real = builtins.__import__

    def fake(name, *args, **kwargs):
        if name == "mujoco":
            raise ImportError("No module named 'mujoco'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake)
    monkeypatch.delitem(__import__("sys").modules, "mujoco", raising=False)
    with pytest.raises(DependencyError, match=r"scdk_sym\[mjcf\]"):
        sc.load_model(MJCF / "planar_fourbar.xml")


def test_a_file_mujoco_cannot_compile_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><joint type='nope'/></body></worldbody></mujoco>")
    with pytest.raises(ModelError, match="MuJoCo cannot compile it") as info:
        sc.load_model(bad)
    assert "\n" not in str(info.value)


# ---------------------------------------------------------------------------- commands


def test_cli_info_verify_and_solve_on_an_mjcf_file(capsys) -> None:
    from scdk_sym.cli import main

    assert main(["info", str(ROBOTIQ), "--lock", ",".join(f"{s}=0" for s in ROBOTIQ_SPRINGS)]) == 0
    out = capsys.readouterr().out
    assert "fingers_actuator" in out and "held joints" in out and "coupling" in out
    assert main(["verify", str(MJCF / "delta_ball.xml"), "--samples", "1"]) == 0
    out = capsys.readouterr().out
    assert "vs MuJoCo" in out and "passed" in out
    code = main(["solve", str(MJCF / "planar_fourbar.xml"), "--theta", "0.1", "--json"])
    assert code == 0
    import json

    qpos = np.array(json.loads(capsys.readouterr().out)["qpos"])
    assert mujoco_residual(MJCF / "planar_fourbar.xml", qpos) <= 1e-9


def test_redundant_rows_the_file_rounds_inconsistent_are_solved_on_an_independent_subset():
    """Three parallel cranks, the third 3e-8 m longer: its redundant row disagrees with the
    others by about 1e-8 away from home; solved on the others, that row reported."""
    path = MJCF / "double_parallelogram.xml"
    model = sc.load_model(path)
    assert model.unchecked and "the file's rounding" in model.reduction
    worst = float(re.search(r"by up to ([0-9.e-]+) \(the file", model.reduction).group(1))
    assert 1e-9 < worst < 1e-7
    assert "projected onto the closures" in model.assembly  # the keyframe, rounded to 1e-9
    m = kinematics(path)
    assert np.abs(model.home.qpos - np.array(m.key_qpos[0])).max() <= 1e-7  # least change
    for backend in ("cvodes", "c"):
        res = sc.solve(model, [0.8], start=model.home, backend=backend)
        rows = np.abs(ref.equality_residual(m, res.qpos))
        assert np.sort(rows)[-2] <= 1e-12  # every row but the inconsistent one closes
        assert rows.max() <= 1e-7
        # closed form of a parallelogram: the coupler keeps its direction, the cranks turn
        # alike (the third to within its 3e-8 m of rounding)
        np.testing.assert_allclose(res.qpos, [0.8, -0.8, 0.8, 0.8], rtol=0, atol=1e-6)


def test_joints_only_a_passive_tendons_limits_hold_are_refused_and_locked_resolves_it():
    path = MJCF / "tendon_limited.xml"
    with pytest.raises(NonSquareSystemError) as info:
        sc.load_model(path)
    assert "tendon 'stop': right" in str(info.value) and "\n" not in str(info.value)
    # MuJoCo agrees: with the motor held, the equality Jacobian leaves one freedom
    m = kinematics(path)
    dofs = ref.solved_dofs(m, ["left"])
    sv = np.linalg.svd(ref.equality_jacobian(m, np.array(m.qpos0))[:, dofs], compute_uv=False)
    assert len(dofs) - int(np.sum(sv > 1e-8 * sv[0])) == 1
    for kwargs, theta in (({"locked": {"right": 0.05}}, [0.1]), ({"inputs": ["left", "right"]},
                                                                  [0.1, 0.05])):  # fmt: skip
        model = sc.load_model(path, **kwargs)
        res = sc.solve(model, theta, start=model.home)
        assert mujoco_residual(path, res.qpos) <= 1e-9
        assert res.joints["right"] == pytest.approx(0.05, abs=1e-15)


def test_atlas_and_codegen_of_an_mjcf_model(tmp_path: Path) -> None:
    """Downstream of loading, an MJCF model is a model: an atlas over its input, standalone C."""
    path = MJCF / "planar_fourbar.xml"
    model = sc.load_model(path)
    crank = float(model.home.theta[0])
    run = sc.atlas(model, {"crank": (crank - 0.1, crank + 0.1, 3)}, tmp_path / "a.zarr",
                   progress=False)  # fmt: skip
    store = sc.open_atlas(tmp_path / "a.zarr")
    assert run.points == 3 and dict(run.counts) == {0: 3}
    assert np.all(np.asarray(store["status"]) == 0)
    # each point's x is the convergent solve's, which closes in MuJoCo
    for theta, x in zip(np.linspace(crank - 0.1, crank + 0.1, 3), np.asarray(store["x"]),
                        strict=True):  # fmt: skip
        res = sc.solve(model, [theta], start=model.home)
        np.testing.assert_allclose(x, res.x, rtol=0, atol=1e-9)
        assert mujoco_residual(path, res.qpos) <= 1e-9
    from scdk_sym.cli import main

    assert main(["codegen", str(path), "--out", str(tmp_path / "c"), "--no-shared"]) == 0
    header = (tmp_path / "c" / "scdk_tracker.h").read_text()
    assert "scdk_tracker_step" in header
