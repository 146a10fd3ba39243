"""Assembly without ``home`` (scdk_sym.robot.assembly) and the files a model is read from."""

from __future__ import annotations

import shutil
import types
import warnings
from pathlib import Path

import numpy as np
import pytest

import scdk_sym as sc
from scdk_sym.errors import ModelError, ModelWarning
from scdk_sym.model.urdf import TreeBuilder
from scdk_sym.robot.assembly import Assembly, closure_rows
from scdk_sym.robot.mechanism import distal_link
from scdk_sym.robot.model import Model

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "gepetto"


def load(path: Path) -> sc.Model:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        return sc.load_model(path)


@pytest.mark.parametrize("name", ["5bar_linkage_iso3d", "5bar_linkage_iso6d"])
def test_relaxed_closure_rows_match_finite_differences(name: str) -> None:
    """Point closures only (iso3d: no weld, the case of a model whose loops are all 3d) and
    welds (iso6d): the relaxed rows vanish at an assembly at level 1, equal their start value
    at level 0, and their Jacobian matches central differences."""
    m = load(FIXTURES / name)
    y, c = m.chart.to_local(m.home.y)
    z = np.concatenate([y, m.home.theta])
    rng = np.random.default_rng(7)
    start = z + rng.normal(scale=0.1, size=z.size)
    rows = closure_rows(m.symbolic, m.closures, c, start)
    r1, _ = rows(z, 1.0)
    assert np.abs(r1).max() <= 1e-12
    r0, _ = rows(start, 0.0)
    assert np.abs(r0).max() <= 1e-12  # the start solves the fully relaxed closure
    probe = z + rng.normal(scale=0.05, size=z.size)
    r, J = rows(probe, 0.5)
    assert J.shape == (r.size, z.size)
    h = 1e-6
    fd = np.column_stack(
        [
            (rows(probe + h * e, 0.5)[0] - rows(probe - h * e, 0.5)[0]) / (2 * h)
            for e in np.eye(z.size)
        ]
    )
    np.testing.assert_allclose(J, fd, rtol=0, atol=1e-6)


def test_a_folder_with_one_urdf_of_another_name_loads(tmp_path: Path) -> None:
    """robot.yaml beside a single URDF not named robot.urdf (as Gepetto's true_talos_2_legs):
    read, and the same model as with robot.urdf; two URDFs and no robot.urdf: refused."""
    d = tmp_path / "robot"
    d.mkdir()
    shutil.copy(FIXTURES / "5bar_linkage_iso3d" / "robot.yaml", d / "robot.yaml")
    shutil.copy(FIXTURES / "5bar_linkage_iso3d" / "robot.urdf", d / "five_bar_v2.urdf")
    m, ref = load(d), load(FIXTURES / "5bar_linkage_iso3d")
    assert m.unknowns == ref.unknowns
    np.testing.assert_array_equal(m.home.y, ref.home.y)
    shutil.copy(d / "five_bar_v2.urdf", d / "other.urdf")
    with pytest.raises(ModelError, match="robot.urdf: file not found"):
        load(d)


def test_default_frame_is_the_deepest_leaf_a_determined_joint_moves() -> None:
    """A humanoid's arm (every joint actuated) is deeper than its leg, whose loop leaves a
    joint to the closures: the leg's foot is reported; with nothing actuated, the arm's hand."""
    b = TreeBuilder("humanoid", "torso")
    for i, (parent, child) in enumerate(
        [("torso", "a1"), ("a1", "a2"), ("a2", "a3"), ("a3", "hand")]
    ):
        b.add(f"arm{i}", "revolute", parent, child, xyz=(0.1, 0, 0))
    b.add("hip", "revolute", "torso", "thigh", xyz=(0, 0, -0.1))
    b.add("knee", "revolute", "thigh", "foot", xyz=(0, 0, -0.4))
    tree = b.build()
    assert distal_link(tree, (), ("arm0", "arm1", "arm2", "arm3", "hip")) == "foot"
    assert distal_link(tree, ()) == "hand"


def test_assembled_angles_are_the_turn_nearest_neutral_within_limits() -> None:
    """A continuation that wound a limited revolute a turn past: brought back into its limits
    (the same configuration), an unlimited one to the turn nearest neutral."""
    b = TreeBuilder("pair", "base")
    b.add("limited", "revolute", "base", "l1", limits=(-1.27, 0.68))
    b.add("free", "continuous", "base", "l2")
    model = types.SimpleNamespace(tree=b.build())
    found = Assembly(np.array([-6.08, 7.0, 3.0]), 1e-12, 0, 3, 7.0)
    out = Model._nearest_turns(model, found, ("limited", "free", "other"))  # type: ignore[arg-type]
    np.testing.assert_allclose(out.z, [-6.08 + 2 * np.pi, 7.0 - 2 * np.pi, 3.0], rtol=0, atol=1e-15)
    assert out.change == pytest.approx(3.0)
