"""Motor <-> joint maps of legs: ``sc.transmission`` against independent references.

``forward`` against a continuation on Pinocchio alone (Gepetto's loader, ``gepetto_loader``)
or in MuJoCo's own kinematics (``mjcf_reference``); ``inverse(forward(theta))`` against
``theta``; ``jacobian`` against central differences of ``forward``; ``torques`` by virtual
work on finite displacements; ``margin`` at a fold of the biped's ankle that a curve on the
closures (not the package's tracker) passes.
"""

from __future__ import annotations

import warnings
from functools import cache
from pathlib import Path

import gepetto_loader as gl
import numpy as np
import pytest

import scdk_sym as sc
from scdk_sym.errors import InputError, ModelWarning, SingularTransmissionError, UnknownNameError
from scdk_sym.kernels.fastcall import model_calls
from scdk_sym.robot.blocks import triangular_blocks
from scdk_sym.verify.pinocchio import pinocchio_q

GEPETTO = Path(__file__).resolve().parent / "fixtures" / "gepetto"
CASSIE = Path(__file__).resolve().parent / "fixtures" / "mjcf" / "menagerie" / "agility_cassie"
HIPS = ("motor_hip_x", "motor_hip_y", "motor_hip_z")
OUTPUTS = {
    "digit_like": (*HIPS, "free_knee", "free_foot1", "free_foot2"),
    "cassie_like": ("motor_hip1", "motor_hip2", "motor_tigh", "free_knee", "free_ankle"),
}


@cache
def model(name: str) -> sc.Model:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        return sc.load_model(GEPETTO / name)


def readings(m: sc.Model, seed: int, count: int = 3, size: float = 0.05) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return m.home.theta + size * rng.uniform(-1, 1, (count, m.k))


@pytest.mark.parametrize("name", sorted(OUTPUTS))
def test_forward_equals_a_pinocchio_continuation_and_inverse_returns_the_motors(name: str):
    m = model(name)
    T = sc.transmission(m, OUTPUTS[name])
    gm = gl.load(GEPETTO / name)
    index = {n: gm.model.joints[gm.model.getJointId(n)].idx_q for n in OUTPUTS[name]}
    q0 = pinocchio_q(m, m.home, gm.model)
    for theta in readings(m, 1):
        T.reset()
        out = T.forward(theta)
        q, info = gl.continuation(gm, q0, theta)
        assert info.residual <= 1e-10
        expected = np.array([q[index[o]] for o in OUTPUTS[name]])
        np.testing.assert_allclose(out, expected, rtol=0, atol=1e-8)
        np.testing.assert_allclose(T.inverse(out), theta, rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", sorted(OUTPUTS))
def test_jacobian_equals_central_differences_and_torques_do_the_same_virtual_work(name: str):
    m = model(name)
    T = sc.transmission(m, OUTPUTS[name])
    theta = readings(m, 2, count=1)[0]
    T.forward(theta)
    J = T.jacobian()

    def out(th):
        U = sc.transmission(m, OUTPUTS[name])
        return U.forward(th)

    h = 1e-5
    fd = np.array([(out(theta + h * e) - out(theta - h * e)) / (2 * h) for e in np.eye(m.k)]).T
    assert np.abs(J - fd).max() <= 1e-6 * np.abs(J).max()
    np.testing.assert_allclose(T.inverse_jacobian() @ J, np.eye(m.k), rtol=0, atol=1e-10)
    # virtual work on a finite displacement of the motors: tau_m . dtheta = tau_out . dq_out
    rng = np.random.default_rng(5)
    tau_out, dtheta = rng.standard_normal(m.k), rng.standard_normal(m.k)
    tau_m = T.torques(None, tau_out)
    dq = (out(theta + h * dtheta) - out(theta - h * dtheta)) / (2 * h)
    assert tau_m @ dtheta == pytest.approx(tau_out @ dq, rel=1e-6, abs=1e-9)
    np.testing.assert_allclose(T.inverse_torques(None, tau_m), tau_out, rtol=0, atol=1e-9)
    np.testing.assert_allclose(T.velocities(None, dtheta), dq, rtol=0, atol=1e-6)
    np.testing.assert_allclose(
        T.inverse_velocities(None, T.velocities(None, dtheta)), dtheta, rtol=0, atol=1e-9
    )


def test_batch_forward_follows_the_readings_and_blocks_split_the_leg() -> None:
    m = model("digit_like")
    T = sc.transmission(m, OUTPUTS["digit_like"])
    t = np.linspace(0, 1, 20)[:, None]
    thetas = m.home.theta + 0.1 * np.sin(2 * np.pi * t) * np.array([1, -1, 1, 1, 1, -1])
    many = T.forward_many(thetas)
    U = sc.transmission(m, OUTPUTS["digit_like"])
    one = np.array([U.forward(th) for th in thetas])
    np.testing.assert_allclose(many, one, rtol=0, atol=1e-10)
    np.testing.assert_allclose(T.inverse_many(many), thetas, rtol=0, atol=1e-9)
    blocks = dict((o, mo) for mo, o in T.blocks())
    assert blocks[("free_knee",)] == ("motor_knee",)
    assert blocks[("free_foot1", "free_foot2")] == ("motor_shin1", "motor_shin2")
    assert blocks[("motor_hip_x",)] == ("motor_hip_x",)


def test_margin_vanishes_at_the_ankle_fold_that_a_closure_curve_passes() -> None:
    """The fold of ``examples/biped_ankle_singularity.py``: an arc-length continuation of the
    closures with only the right ankle motor free passes a turning point of that motor."""
    m = model("digit_like")
    T = sc.transmission(m, OUTPUTS["digit_like"])
    home = T.margin(m.home.theta)
    assert home.value > 1e-4
    margin = T._margin(fold_configuration(m))  # the motor's largest value: next to the fold
    assert margin.block_outputs[margin.worst] == ("free_foot1", "free_foot2")
    assert margin.value < 0.05 * home.value
    assert margin.blocks[OUTPUTS["digit_like"].index("free_knee")] > 0.5 * home.blocks[3]


def test_a_singular_map_raises_with_its_margin_and_bad_outputs_are_refused(monkeypatch):
    m = model("digit_like")
    T = sc.transmission(m, OUTPUTS["digit_like"])
    margin = T.margin()
    assert 1e-4 < margin.value < 1.0
    # a map whose margin is below the threshold is singular: its Jacobian is refused, the
    # error carrying the margin and the motors
    from scdk_sym.solvers import transmission as tr

    monkeypatch.setattr(tr, "SINGULAR_MARGIN", 2 * margin.value)
    with pytest.raises(SingularTransmissionError) as info:
        T.jacobian()
    assert info.value.margin == pytest.approx(margin.value, rel=1e-12)
    assert "free_foot1" in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(InputError, match="as many distinct outputs"):
        sc.transmission(m, HIPS)
    with pytest.raises(UnknownNameError, match="nope"):
        sc.transmission(m, (*HIPS, "free_knee", "free_foot1", "nope"))


def test_cassie_from_menagerie_knee_motor_to_tarsus_equals_mujocos_continuation() -> None:
    mujoco = pytest.importorskip("mujoco")
    import mjcf_reference as ref

    m = sc.load_model(CASSIE / "cassie.xml")
    legs = [(f"{s}-hip-roll", f"{s}-hip-yaw", f"{s}-hip-pitch", f"{s}-tarsus", f"{s}-foot")
            for s in ("left", "right")]  # fmt: skip
    outputs = legs[0] + legs[1]
    T = sc.transmission(m, outputs)
    mj = ref.load_kinematics(CASSIE / "cassie.xml")
    adr = {n: mj.jnt_qposadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n)]
           for n in outputs}  # fmt: skip
    springs = [j for j in m.held]
    for theta in readings(m, 3, count=2):
        T.reset()
        out = T.forward(theta)
        q = ref.continuation(mj, m.home.qpos, dict(zip(m.actuated, theta, strict=True)),
                             fixed=springs, steps=40)  # fmt: skip
        np.testing.assert_allclose(out, [q[adr[o]] for o in outputs], rtol=0, atol=1e-8)
        np.testing.assert_allclose(T.inverse(out), theta, rtol=0, atol=1e-9)


def fold_configuration(m: sc.Model) -> sc.Configuration:
    """Next to the fold of the right ankle's rod motor (an arc-length continuation of the
    closures with only ``motor_shin1`` free, to where that motor turns back)."""
    calls = model_calls(m)
    j = m.actuated.index("motor_shin1")
    y, theta, prev, samples = m.home.y.copy(), m.home.theta.copy(), None, []
    for _ in range(400):
        y_loc, c = m.chart.to_local(y)
        J_p, J_s = (np.array(a) for a in calls.jac(y_loc, theta, c))
        tangent = np.linalg.svd(np.hstack([J_p, -J_s[:, [j]]]))[2][-1]
        if prev is None:
            tangent *= np.sign(tangent[-1])
        elif tangent @ prev < 0:
            tangent = -tangent
        prev = tangent
        y, theta = y + 0.02 * tangent[:-1], theta.copy()
        theta[j] += 0.02 * tangent[-1]
        for _ in range(20):
            y_loc, c = m.chart.to_local(y)
            g = np.array(calls.g(y_loc, theta, c)).ravel()
            J_p, J_s = (np.array(a) for a in calls.jac(y_loc, theta, c))
            d = np.linalg.lstsq(np.hstack([J_p, -J_s[:, [j]]]), -g, rcond=None)[0]
            y, theta[j] = y + d[:-1], theta[j] + d[-1]
            if np.abs(g).max() < 1e-13:
                break
        samples.append((theta[j], m.configuration(y, theta)))
        if len(samples) > 2 and samples[-1][0] < samples[-2][0]:
            return samples[-2][1]
    raise AssertionError("the curve did not turn back")


def test_certify_range_proves_a_box_around_home_and_not_one_holding_the_ankle_fold() -> None:
    m = model("digit_like")
    T = sc.transmission(m, OUTPUTS["digit_like"])
    home = T.inverse_model.home.theta
    lo, hi = home.copy(), home.copy()
    lo[4:] -= 3e-3
    hi[4:] += 3e-3
    cert = T.certify_range(lo, hi, depth=10, max_boxes=1000)
    assert cert.proven and not len(cert.open_boxes)
    # the proven parts cover the box exactly
    area = np.prod(np.diff(cert.boxes[:, 4:], axis=2)[..., 0], axis=1).sum()
    assert area == pytest.approx(np.prod(hi[4:] - lo[4:]), rel=1e-12)
    # the bound holds where the map is sampled: margins of J_p at seeded points of the box
    assert cert.margin_lower > 0
    rng = np.random.default_rng(11)
    for q in lo + (hi - lo) * rng.uniform(0, 1, (3, len(lo))):
        T.reset()
        theta = T.inverse_many(home + np.linspace(0, 1, 4)[1:, None] * (q - home))[-1]
        J_p, _ = T._parts(T._forward.many(theta[None], keep=False)[-1])
        for b in triangular_blocks(m):  # each block of J_p (a stage of the leg)
            sv = np.linalg.svd(J_p[np.ix_(b.rows, b.unknowns)], compute_uv=False)
            assert sv[-1] >= cert.sigma_lower
    # next to the fold of the ankle (its J_p nearly singular): the box around it is not
    # proven, and its open parts hold the fold's outputs
    fold = fold_configuration(m)
    q_fold = np.array([fold.coordinates[o] for o in OUTPUTS["digit_like"]])
    lo, hi = q_fold.copy(), q_fold.copy()
    lo[4:] -= 3e-3
    hi[4:] += 3e-3
    cert = T.certify_range(lo, hi, depth=6, max_boxes=200)
    assert not cert.proven and cert.contains_open(q_fold)
    assert any("forward map" in r for r in cert.reasons)


def test_cli_range_certifies_and_draws(tmp_path: Path, capsys) -> None:
    from scdk_sym.cli import main

    png = tmp_path / "range.png"
    code = main(["range", str(GEPETTO / "digit_like"), "--outputs", ",".join(OUTPUTS["digit_like"]),
                 "--box", "free_foot1=-0.012:-0.010,free_foot2=0.044:0.046", "--out", str(png),
                 "--n", "2", "--json"])  # fmt: skip
    assert code == 0
    import json

    out = json.loads(capsys.readouterr().out)
    assert out["proven"] and out["proven_boxes"] >= 1 and out["margin_lower"] > 0
    assert png.stat().st_size > 10_000
    with pytest.raises(SystemExit):
        main(["range", str(GEPETTO / "digit_like"), "--outputs", "nope"])
    assert main(["range", str(GEPETTO / "digit_like"), "--outputs",
                 ",".join(OUTPUTS["digit_like"]), "--box", "free_foot1=1"]) == 1  # fmt: skip
    assert "--box: expected NAME=LO:HI" in capsys.readouterr().err
