"""Model loading, validation, square reduction, inverse kinematics (scdk_sym.robot.model)."""

import dataclasses
import math
import shutil
from collections.abc import Mapping

import numpy as np
import pytest
import yaml
from factories import MODELS, seed_models, shipped

import scdk_sym as sc
from scdk_sym.builders.planar import rrr_leg_angles, seed_geometry
from scdk_sym.errors import (
    InputError,
    ModelError,
    NonSquareSystemError,
    NotAssembledError,
    UnknownNameError,
    UnreachableError,
)


def _copy(tmp_path, name="planar_hexa"):
    d = tmp_path / name
    shutil.copytree(MODELS / name, d)
    return d


def _edit_yaml(d, **changes):
    data = yaml.safe_load((d / "robot.yaml").read_text())
    for k, v in changes.items():
        if v is None:
            data.pop(k, None)
        else:
            data[k] = v
    (d / "robot.yaml").write_text(yaml.safe_dump(data))


def test_names_of_the_seed_models():
    full, reduced = seed_models()
    assert full.actuated == reduced.actuated == ("theta_1", "theta_2", "theta_3")
    assert set(full.unknowns) == {"elbow_1", "wrist_1", "elbow_2", "elbow_3"}
    assert reduced.unknowns == ("px", "py", "phi")
    assert full.workspace == reduced.workspace == ("x", "y", "phi")
    assert full.reduction is None and reduced.reduction is None


def test_inverse_kinematics_matches_the_closed_form_and_the_paper():
    g = seed_geometry()
    rng = np.random.default_rng(7)
    for model in seed_models():
        for _ in range(20):
            x = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-0.3, 0.5)])
            cfg = model.inverse_kinematics(x)
            R = np.array([[math.cos(x[2]), -math.sin(x[2])], [math.sin(x[2]), math.cos(x[2])]])
            ref = [
                rrr_leg_angles(g["base_points"][i], x[:2] + R @ g["platform_points"][i], 7, 7, -1)[
                    0
                ]
                for i in range(3)
            ]
            np.testing.assert_allclose(cfg.theta, ref, atol=1e-10)
            np.testing.assert_allclose(cfg.x, x, atol=1e-10)
            assert cfg.residual < 1e-12
        # the paper: the singular configuration x = y = 0, phi = 0.575 has
        # theta = [1.166, -0.928, -3.023]
        sing = model.inverse_kinematics([0, 0, 0.575])
        np.testing.assert_allclose(sing.theta, [1.166, -0.928, -3.023], atol=5e-4)


def test_configuration_is_immutable_and_complete():
    model = shipped("planar_hexa")
    cfg = model.home
    with pytest.raises(ValueError):
        cfg.theta[0] = 1.0
    with pytest.raises(TypeError):
        cfg.joints["theta_1"] = 1.0
    assert set(cfg.joints) == set(model.tree.movable_joints)
    assert cfg.platform_pose.shape == (4, 4)


def test_batch_configurations_joints_are_the_named_values_read_only():
    """The joints of a batch of configurations (one table, values read when asked) against
    the rule itself: locked joints at their values, then y and theta by name, URDF order;
    on a model with locked joints (a closed chain with idle joints)."""
    from gepetto_reference import FIXTURE

    model = sc.load_model(FIXTURE, frame="effector")
    assert model.locked  # the case of interest
    rng = np.random.default_rng(5)
    y0, c0 = model.chart.to_local(model.home.y)
    ys = y0 + 0.01 * rng.normal(size=(4, model.m))
    thetas = model.home.theta + 0.01 * rng.normal(size=(4, model.k))
    cfgs = model.configurations(ys, thetas, np.tile(c0, (4, 1)))
    for cfg in cfgs:
        plain = dict(model.locked)
        plain.update(zip(model.unknowns, cfg.y.tolist(), strict=True))
        plain.update(zip(model.actuated, cfg.theta.tolist(), strict=True))
        expected = {j: plain[j] for j in model.tree.coordinates}
        assert list(cfg.joints.items()) == list(expected.items())  # values and order, exact
        assert model.joint_values(cfg.y, cfg.theta) == expected
        assert cfg.to_dict()["joints"] == expected
        with pytest.raises(TypeError):
            cfg.joints["mot1_rod1"] = 0.0  # type: ignore[index]
        with pytest.raises(KeyError):
            cfg.joints["no_such_joint"]
        # built without __init__: the same fields as the checked constructor makes them
        checked = sc.Configuration(cfg.theta, cfg.y, cfg.x, cfg.platform_pose, expected,
                                   cfg.residual)  # fmt: skip
        for f in dataclasses.fields(sc.Configuration):
            a, b = getattr(cfg, f.name), getattr(checked, f.name)
            assert type(a) is type(b) or isinstance(a, Mapping) and isinstance(b, Mapping)
            if isinstance(a, np.ndarray):
                assert a.dtype == b.dtype and not a.flags.writeable and not b.flags.writeable
                np.testing.assert_array_equal(a, b)
            else:
                assert dict(a) == dict(b) if isinstance(a, Mapping) else a == b
        with pytest.raises(dataclasses.FrozenInstanceError):
            cfg.residual = 0.0  # type: ignore[misc]


def test_save_and_load_round_trip(tmp_path):
    g = seed_geometry()
    model = sc.builders.planar_3rrr(**g)
    again = sc.load_model(model.save(tmp_path / "m"))
    assert (again.actuated, again.unknowns, again.workspace, again.frame) == (
        model.actuated,
        model.unknowns,
        model.workspace,
        model.frame,
    )
    np.testing.assert_allclose(again.home.y, model.home.y, atol=1e-14)
    assert again.length_unit == model.length_unit == "cm"  # the paper's unit, kept
    cfg_a, cfg_b = model.inverse_kinematics([1, -1, 0.3]), again.inverse_kinematics([1, -1, 0.3])
    np.testing.assert_allclose(cfg_a.theta, cfg_b.theta, atol=1e-12)
    # loading through the YAML path gives the same model
    assert sc.load_model(tmp_path / "m" / "robot.yaml").unknowns == model.unknowns


def test_unknown_frame_lists_the_valid_ones(tmp_path):
    d = _copy(tmp_path)
    _edit_yaml(d, closed_loop=[["vertex_2", "nowhere"], ["vertex_3", "rod_end_3"]])
    with pytest.raises(UnknownNameError, match="unknown frame 'nowhere'; frames: base, ") as info:
        sc.load_model(d)
    assert info.value.name == "nowhere" and "rod_end_2" in info.value.valid


def test_unknown_actuated_joint_lists_the_valid_ones(tmp_path):
    d = _copy(tmp_path)
    _edit_yaml(d, name_mot=["theta_1", "theta_2", "motor_9"])
    with pytest.raises(
        UnknownNameError,
        match="unknown joint .motor_9.; joints: theta_1, theta_2, theta_3, elbow_1",
    ):
        sc.load_model(d)


def test_unknown_reported_frame(tmp_path):
    with pytest.raises(UnknownNameError, match="unknown frame 'tool'"):
        sc.load_model(MODELS / "planar_hexa", frame="tool")


def test_home_that_is_not_assembled_is_refused(tmp_path):
    d = _copy(tmp_path)
    data = yaml.safe_load((d / "robot.yaml").read_text())
    data["home"]["elbow_2"] += 0.1
    (d / "robot.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(NotAssembledError, match="'home' is not assembled: closure 2d\\(vertex_2"):
        sc.load_model(d)


def test_missing_files(tmp_path):
    with pytest.raises(ModelError, match="file not found"):
        sc.load_model(tmp_path)
    with pytest.raises(ModelError, match="expected a model directory, a .yaml"):
        sc.load_model(tmp_path / "x.txt")


def test_under_constrained_system_is_refused_with_counts(tmp_path):
    # only one of the two closures: the platform keeps two freedoms the actuators do not fix
    d = _copy(tmp_path)
    _edit_yaml(d, closed_loop=[["vertex_2", "rod_end_2"]], type=["2d"])
    with pytest.raises(
        NonSquareSystemError, match="4 unknown joints, 2 closure rows, rank 2"
    ) as info:
        sc.load_model(d)
    assert (info.value.rows, info.value.unknowns, info.value.rank) == (2, 4, 2)


def test_redundant_rows_are_reduced_with_a_note(tmp_path):
    # the reduced model with a 3d closure replacing a distance one is not square as written
    model = shipped("planar_hexa")
    d = _copy(tmp_path)
    _edit_yaml(
        d, closed_loop=[["vertex_2", "rod_end_2"], ["vertex_3", "rod_end_3"]], type=["3d", "2d"]
    )
    reduced = sc.load_model(d)
    assert reduced.reduction is not None and "dropped 1 redundant row" in reduced.reduction
    assert reduced.m == 4 and len(reduced.rows) == 4
    cfg = reduced.inverse_kinematics([0.5, 0.2, 0.1])
    np.testing.assert_allclose(
        cfg.theta, model.inverse_kinematics([0.5, 0.2, 0.1]).theta, atol=1e-10
    )


def test_inverse_kinematics_bad_input():
    model = shipped("planar_hexa_reduced")
    with pytest.raises(InputError, match="must have 3 values, got 2"):
        model.inverse_kinematics([0, 0])
    with pytest.raises(InputError, match="finite"):
        model.inverse_kinematics([0, float("nan"), 0])
    with pytest.raises(UnreachableError, match="not reachable in the home working mode"):
        model.inverse_kinematics([30.0, 0, 0])


SLIDERS = """<robot name="sliders">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="p" type="prismatic"><parent link="base"/><child link="a"/>
    <axis xyz="{axis}"/><limit lower="-1" upper="1" effort="0" velocity="0"/></joint>
  <joint name="q" type="prismatic"><parent link="base"/><child link="b"/>
    <axis xyz="{axis}"/><limit lower="-1" upper="1" effort="0" velocity="0"/></joint>
</robot>
"""


@pytest.mark.parametrize(("axis", "same", "moving"), [("0 1 0", "x", "y"), ("1 0 0", "y", "x")])
def test_reduction_names_the_2d_row_it_drops(tmp_path, axis, same, moving):
    """Two sliders along one axis joined by a 2d closure: the row of the other axis is
    identically zero and is the one dropped; the note names it by its component."""
    d = tmp_path / f"sliders_{same}"
    d.mkdir()
    (d / "robot.urdf").write_text(SLIDERS.format(axis=axis))
    (d / "robot.yaml").write_text("closed_loop: [[a, b]]\ntype: [2d]\nname_mot: [p]\n")
    model = sc.load_model(d)
    assert model.unknowns == ("q",) and model.rows == ({"x": 0, "y": 1}[moving],)
    assert f"dropped 1 redundant row(s) ['2d(a,b).{same}']" in model.reduction


def test_a_product_is_built_once_per_model_and_not_shared(monkeypatch):
    from scdk_sym.errors import InputError
    from scdk_sym.follower.geometry import kinds
    from scdk_sym.kernels import fastcall
    from scdk_sym.products import MODEL_CALLS, UNKNOWN_KINDS, Key

    made = []
    real = fastcall.Dense
    monkeypatch.setattr(fastcall, "Dense", lambda f, **kw: made.append(f) or real(f, **kw))
    a = sc.load_model(MODELS / "planar_hexa")
    b = sc.load_model(MODELS / "planar_hexa")
    first = fastcall.model_calls(a)
    assert fastcall.model_calls(a) is first and len(made) == 4  # g, check, jac, pose once
    assert fastcall.model_calls(b) is not first and len(made) == 8  # b builds its own
    assert a.products.peek(MODEL_CALLS) is first and b.products.peek(MODEL_CALLS) is not first
    # the stored product has the value of its reference: revolute unknowns from the tree
    types = {j.name: j.type for j in a.tree.joints}
    revolute = [i for i, u in enumerate(a.unknowns) if types[u] in ("revolute", "continuous")]
    per, rot, plain = kinds(a)
    assert per.tolist() == revolute and len(per) + len(rot) + len(plain) == a.m
    assert kinds(a)[0] is per and a.products.peek(UNKNOWN_KINDS)[0] is per
    # a failed build stores nothing; an undeclared key is refused
    calls = []

    def failing():
        calls.append(1)
        raise RuntimeError("no")

    for _ in range(2):
        with pytest.raises(RuntimeError):
            a.products.get(MODEL_CALLS, failing, "other")
    assert len(calls) == 2 and a.products.peek(MODEL_CALLS, "other") is None
    with pytest.raises(InputError, match="undeclared product key"):
        a.products.get(Key("model_calls", "a copy", "nothing"), lambda: 1)


def test_frozen_arrays_copy_unless_nothing_can_write_them():
    """A configuration's arrays are read-only; rows of a read-only owner are taken as they
    are, a read-only view of a writable array is copied (writing the array leaves it)."""
    from scdk_sym.results import Configuration, frozen_array

    owner = np.arange(6.0).reshape(2, 3).copy()
    owner.setflags(write=False)
    assert frozen_array(owner[1]) is not None and np.shares_memory(frozen_array(owner[1]), owner)
    base = np.arange(3.0)
    view = base[:]
    view.setflags(write=False)
    kept = frozen_array(view)
    base[0] = 42.0
    assert kept[0] == 0.0 and not kept.flags.writeable
    cfg = Configuration(base, base, base, np.eye(4), {"a": 1.0})
    base[1] = -1.0
    assert cfg.y[1] == 1.0 and not cfg.y.flags.writeable
    with pytest.raises(ValueError):
        cfg.x[0] = 3.0
