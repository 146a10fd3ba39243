"""Self-tests of tests/mjcf_reference.py, MuJoCo's own kinematics of the MJCF fixtures.

The fixtures (tests/fixtures/mjcf, see its README.md) are assembled at home, have as many
actuators as degrees of freedom and a closure that fixes the other joints (the Delta's rods
may spin about their own axes); the residual rows and body frames follow the formulas written
down in the README; the Jacobian is the derivative of the residual; continuation on the planar
four-bar matches its closed-form solution; the two Menagerie copies compile without meshes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from mjcf_reference import (  # noqa: E402
    TOL,
    body_poses,
    continuation,
    equality_jacobian,
    equality_residual,
    home_qpos,
    load_kinematics,
    solved_dofs,
)

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "mjcf"
MECHANISMS = ["planar_fourbar", "fourbar_sites", "delta_ball", "weld_loop", "coupled"]
#: Internal motions the closure leaves free (a rod spinning between two ball points).
SPINS = {"delta_ball": 6}
MENAGERIE = {
    "cassie": FIXTURES / "menagerie" / "agility_cassie" / "cassie.xml",
    "robotiq_2f85": FIXTURES / "menagerie" / "robotiq_2f85" / "2f85.xml",
}
#: Home residual bound [m or rad].
HOME_TOL = 1e-10
#: Finite-difference step [rad] and relative tolerance of the Jacobian check.
FD_STEP = 1e-6
FD_TOL = 1e-6
#: Agreement of continuation with the closed form / with a finer continuation [rad].
SOLVE_TOL = 1e-12
#: Formula checks (residual rows, body frames) [m or rad].
FORMULA_TOL = 1e-12


def _model(name: str) -> mujoco.MjModel:
    return load_kinematics(FIXTURES / f"{name}.xml")


def _random_qpos(m: mujoco.MjModel, rng: np.random.Generator, scale: float) -> np.ndarray:
    """Home plus a random offset on every joint (unit quaternions kept unit)."""
    q = home_qpos(m)
    dq = scale * rng.standard_normal(m.nv)
    mujoco.mj_integratePos(m, q, dq, 1.0)
    return q


def _actuated_joints(m: mujoco.MjModel) -> list[str]:
    """Joints moved by the actuators: a joint transmission, or the joints of a fixed tendon."""
    joints: list[int] = []
    for a in range(m.nu):
        target = m.actuator_trnid[a, 0]
        if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT:
            joints.append(target)
        elif m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_TENDON:
            start, num = m.tendon_adr[target], m.tendon_num[target]
            assert all(m.wrap_type[start : start + num] == mujoco.mjtWrap.mjWRAP_JOINT)
            joints.extend(m.wrap_objid[start : start + num])
    return [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints]


# ------------------------------------------------------------------------ the fixtures


@pytest.mark.parametrize("name", MECHANISMS)
def test_fixture_is_assembled_at_home(name: str) -> None:
    m = _model(name)
    residual = equality_residual(m, home_qpos(m))
    assert residual.size > 0
    assert np.max(np.abs(residual)) <= HOME_TOL


@pytest.mark.parametrize("name", MECHANISMS)
def test_actuators_match_the_degrees_of_freedom(name: str) -> None:
    m = _model(name)
    q = home_qpos(m)
    actuated = _actuated_joints(m)
    assert len(actuated) == m.nu
    jac = equality_jacobian(m, q)
    passive = solved_dofs(m, actuated)
    rank = np.linalg.matrix_rank(jac[:, passive], tol=1e-9)
    assert rank == passive.size - SPINS.get(name, 0)
    mobility = solved_dofs(m, []).size - np.linalg.matrix_rank(jac, tol=1e-9)
    assert mobility == m.nu + SPINS.get(name, 0)


def test_inactive_equality_is_ignored() -> None:
    m = _model("coupled")
    assert list(m.eq_active0) == [True, True, False]
    assert equality_residual(m, home_qpos(m)).size == 3 + 1


# -------------------------------------------------------- MuJoCo's rows and frames


def _quat(mat: np.ndarray) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, mat.reshape(9))
    return quat


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, a, b)
    return out


def _expected_rows(m: mujoco.MjModel, d: mujoco.MjData, i: int) -> np.ndarray:
    """Residual of equality ``i`` from the formulas in tests/fixtures/mjcf/README.md."""
    data, o1, o2 = m.eq_data[i], m.eq_obj1id[i], m.eq_obj2id[i]
    kind, on_sites = m.eq_type[i], m.eq_objtype[i] == mujoco.mjtObj.mjOBJ_SITE
    if kind == mujoco.mjtEq.mjEQ_CONNECT and on_sites:
        return d.site_xpos[o1] - d.site_xpos[o2]
    if kind == mujoco.mjtEq.mjEQ_CONNECT:
        r1, r2 = d.xmat[o1].reshape(3, 3), d.xmat[o2].reshape(3, 3)
        return d.xpos[o1] + r1 @ data[0:3] - (d.xpos[o2] + r2 @ data[3:6])
    if kind == mujoco.mjtEq.mjEQ_WELD:
        r1, r2 = d.xmat[o1].reshape(3, 3), d.xmat[o2].reshape(3, 3)
        position = d.xpos[o1] + r1 @ data[3:6] - (d.xpos[o2] + r2 @ data[0:3])
        q2_inverse = _quat(r2) * np.array([1.0, -1.0, -1.0, -1.0])
        error = _quat_mul(q2_inverse, _quat_mul(_quat(r1), data[6:10]))
        return np.concatenate([position, data[10] * error[1:]])
    assert kind == mujoco.mjtEq.mjEQ_JOINT
    a1 = m.jnt_qposadr[o1]
    y1 = d.qpos[a1] - m.qpos0[a1]
    if o2 < 0:
        return np.array([y1 - data[0]])
    a2 = m.jnt_qposadr[o2]
    x = d.qpos[a2] - m.qpos0[a2]
    return np.array([y1 - sum(data[k] * x**k for k in range(5))])


@pytest.mark.parametrize("name", MECHANISMS)
def test_rows_follow_the_documented_formulas(name: str) -> None:
    m = _model(name)
    rng = np.random.default_rng(20240611)
    d = mujoco.MjData(m)
    for _ in range(3):
        q = _random_qpos(m, rng, 0.3)
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        active = [i for i in range(m.neq) if m.eq_active0[i]]
        expected = np.concatenate([_expected_rows(m, d, i) for i in active])
        np.testing.assert_allclose(equality_residual(m, q), expected, rtol=0, atol=FORMULA_TOL)


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_axisAngle2Quat(quat, axis, angle)
    return quat


def _rotation(quat: np.ndarray) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, quat / np.linalg.norm(quat))
    return mat.reshape(3, 3)


def _compose(m: mujoco.MjModel, q: np.ndarray, b: int, parent: tuple) -> tuple:
    """Body ``b``'s world frame: parent frame, body pos/quat, then its joints in order, each
    about its own anchor (hinge: axis-angle of qpos - qpos0; ball: the qpos quaternion;
    slide: along its axis by qpos - qpos0; free: absolute)."""
    pos = parent[0] + _rotation(parent[1]) @ m.body_pos[b]
    quat = _quat_mul(parent[1], m.body_quat[b])
    for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
        a, kind = m.jnt_qposadr[j], m.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            pos, quat = q[a : a + 3].copy(), q[a + 3 : a + 7] / np.linalg.norm(q[a + 3 : a + 7])
            continue
        if kind == mujoco.mjtJoint.mjJNT_SLIDE:
            pos = pos + _rotation(quat) @ m.jnt_axis[j] * (q[a] - m.qpos0[a])
            continue
        anchor = pos + _rotation(quat) @ m.jnt_pos[j]
        if kind == mujoco.mjtJoint.mjJNT_HINGE:
            quat = _quat_mul(quat, _axis_angle(m.jnt_axis[j], q[a] - m.qpos0[a]))
        else:
            quat = _quat_mul(quat, q[a : a + 4] / np.linalg.norm(q[a : a + 4]))
        pos = anchor - _rotation(quat) @ m.jnt_pos[j]
    return pos, quat


@pytest.mark.parametrize("name", MECHANISMS)
def test_body_frames_compose_joints_in_order(name: str) -> None:
    m = _model(name)
    rng = np.random.default_rng(7)
    q = _random_qpos(m, rng, 0.5)
    frames = {0: (np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))}
    for b in range(1, m.nbody):
        frames[b] = _compose(m, q, b, frames[m.body_parentid[b]])
    for name_b, (pos, mat) in body_poses(m, q).items():
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name_b)
        np.testing.assert_allclose(pos, frames[b][0], rtol=0, atol=FORMULA_TOL)
        np.testing.assert_allclose(mat, _rotation(frames[b][1]), rtol=0, atol=FORMULA_TOL)


def test_hinge_ref_is_qpos0_and_the_xml_pose() -> None:
    m = _model("planar_fourbar")
    crank = m.joint("crank")
    assert m.qpos0[crank.qposadr[0]] == pytest.approx(np.pi / 2, abs=1e-15)
    for angle in (np.pi / 2, 0.3, -2.0):
        q = home_qpos(m)
        q[crank.qposadr[0]] = angle
        _, mat = body_poses(m, q)["crank"]
        c, s = np.cos(angle), np.sin(angle)
        np.testing.assert_allclose(mat, [[c, -s, 0], [s, c, 0], [0, 0, 1]], atol=1e-15)


# --------------------------------------------------------------------- the Jacobian


@pytest.mark.parametrize("name", MECHANISMS)
def test_jacobian_matches_central_differences_over_hinges(name: str) -> None:
    m = _model(name)
    rng = np.random.default_rng(12345)
    q = home_qpos(m)
    hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    q[m.jnt_qposadr[hinges]] += 0.1 * rng.standard_normal(len(hinges))
    jac = equality_jacobian(m, q)
    scale = max(1.0, float(np.max(np.abs(jac))))
    for j in hinges:
        step = np.zeros(m.nq)
        step[m.jnt_qposadr[j]] = FD_STEP
        fd = (equality_residual(m, q + step) - equality_residual(m, q - step)) / (2 * FD_STEP)
        assert np.max(np.abs(fd - jac[:, m.jnt_dofadr[j]])) <= FD_TOL * scale, j


# ------------------------------------------------------------------ continuation


def _fourbar_closed_form(theta: float) -> tuple[float, float]:
    """(coupler, rocker) joint values of planar_fourbar.xml at crank angle ``theta``.

    Design: a = 0.08, b = 0.25, c = 0.35, ground pivots O = (0, 0), D = (0.36, 0); the crank
    joint value is the crank's world angle; the coupler's world angle is
    theta + atan2(-0.6, 0.8) + q_coupler; the rocker's body x axis, from D to the coupler
    tip B, has world angle atan2(0.8, -0.6) + q_rocker. B is the circle-circle intersection
    on the left of D - A (the home branch, B = (0.15, 0.28) at theta = pi/2).
    """
    a, b, c = 0.08, 0.25, 0.35
    tip_a = a * np.array([np.cos(theta), np.sin(theta)])
    ground_d = np.array([0.36, 0.0])
    v = ground_d - tip_a
    length = np.linalg.norm(v)
    e = v / length
    along = (b**2 - c**2 + length**2) / (2 * length)
    across = np.sqrt(b**2 - along**2)
    tip_b = tip_a + along * e + across * np.array([-e[1], e[0]])
    phi = np.arctan2(*(tip_b - tip_a)[::-1])
    psi = np.arctan2(*(tip_b - ground_d)[::-1])
    wrap = lambda x: (x + np.pi) % (2 * np.pi) - np.pi  # noqa: E731
    return wrap(phi - theta - np.arctan2(-0.6, 0.8)), wrap(psi - np.arctan2(0.8, -0.6))


def test_closed_form_is_home_at_ninety_degrees() -> None:
    np.testing.assert_allclose(_fourbar_closed_form(np.pi / 2), [0.0, 0.0], atol=1e-15)


def test_continuation_matches_the_closed_form_fourbar() -> None:
    m = _model("planar_fourbar")
    home = home_qpos(m)
    target = home[m.joint("crank").qposadr[0]] + 0.1
    q = continuation(m, home, {"crank": target})
    assert np.max(np.abs(equality_residual(m, q))) < TOL
    coupler, rocker = _fourbar_closed_form(target)
    np.testing.assert_allclose(q, [target, coupler, rocker], rtol=0, atol=SOLVE_TOL)
    finer = continuation(m, home, {"crank": target}, steps=200)
    np.testing.assert_allclose(finer, q, rtol=0, atol=SOLVE_TOL)
    poses = body_poses(m, q)
    tip_b = poses["coupler"][0] + poses["coupler"][1] @ [0.25, 0.0, 0.0]
    np.testing.assert_allclose(poses["rocker"][0], tip_b, rtol=0, atol=FORMULA_TOL)


def test_continuation_moves_the_floating_delta_platform() -> None:
    m = _model("delta_ball")
    home = home_qpos(m)
    q = continuation(m, home, {"arm0": 0.1, "arm1": -0.05, "arm2": 0.02}, steps=10)
    assert np.max(np.abs(equality_residual(m, q))) < TOL
    platform = m.joint("platform").qposadr[0]
    assert np.linalg.norm(q[platform : platform + 3] - home[platform : platform + 3]) > 1e-3
    # the three parallelograms keep the platform's orientation
    np.testing.assert_allclose(q[platform + 3 : platform + 7], [1, 0, 0, 0], atol=1e-12)


def test_continuation_refuses_a_ball_input() -> None:
    m = _model("delta_ball")
    with pytest.raises(ValueError, match="hinge or slide"):
        continuation(m, home_qpos(m), {"rod0a": 0.1})


# ------------------------------------------------------------------------ Menagerie


@pytest.mark.parametrize("name", sorted(MENAGERIE))
def test_menagerie_copy_loads_without_meshes(name: str) -> None:
    path = MENAGERIE[name]
    if not path.exists():
        pytest.skip(f"{path} is missing")
    m = load_kinematics(path)
    counts = {"cassie": (35, 32, 4, 10), "robotiq_2f85": (8, 8, 3, 1)}[name]
    assert (m.nq, m.nv, m.neq, m.nu) == counts
    assert m.nmesh == 0 and m.ntex == 0


def test_cassie_home_keyframe_polishes_onto_the_closure() -> None:
    path = MENAGERIE["cassie"]
    if not path.exists():
        pytest.skip(f"{path} is missing")
    m = load_kinematics(path)
    home = home_qpos(m)
    # the published keyframe is rounded to about 6 digits
    assert 1e-6 < np.max(np.abs(equality_residual(m, home))) < 1e-2
    motors = {name: home[m.joint(name).qposadr[0]] for name in _actuated_joints(m)}
    springs = [f"{side}-{j}" for side in ("left", "right") for j in ("shin", "heel-spring")]
    q = continuation(m, home, motors, fixed=springs, steps=1)
    assert np.max(np.abs(equality_residual(m, q))) < TOL
    np.testing.assert_array_equal(q[:7], home[:7])  # the floating base is not solved for
