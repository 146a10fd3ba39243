"""URDF parsing and writing (scdk_sym.model.urdf)."""

import math

import numpy as np
import pytest

from scdk_sym.errors import ModelError
from scdk_sym.model.rotations import rpy_from_matrix, rpy_matrix
from scdk_sym.model.urdf import parse_urdf, tree_to_urdf

TWO_LINK = """<robot name="r">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="1 2 3" rpy="0.1 0.2 0.3"/><axis xyz="0 0 2"/>
    <limit lower="-1" upper="1" effort="0" velocity="0"/></joint>
  <joint name="j2" type="prismatic"><parent link="a"/><child link="b"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.5" effort="0" velocity="0"/></joint>
</robot>"""


def _rx(a):
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def _ry(a):
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def _rz(a):
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def test_parse_two_link_tree():
    tree = parse_urdf(TWO_LINK)
    assert tree.root == "base"
    assert tree.links == ("base", "a", "b")
    j1, j2 = tree.joints
    np.testing.assert_allclose(j1.origin[:3, 3], [1, 2, 3], atol=1e-15)
    np.testing.assert_allclose(j1.origin[:3, :3], _rz(0.3) @ _ry(0.2) @ _rx(0.1), atol=1e-12)
    np.testing.assert_allclose(j1.axis, [0, 0, 1], atol=1e-15)  # normalised
    assert (j1.lower, j1.upper) == (-1.0, 1.0)
    assert j2.type == "prismatic" and tree.movable_joints == ("j1", "j2")


def test_rpy_matches_urdf_convention_and_round_trips():
    rng = np.random.default_rng(1)
    for _ in range(50):
        r, p, y = rng.uniform(-3, 3), rng.uniform(-1.5, 1.5), rng.uniform(-3, 3)
        R = rpy_matrix(r, p, y)
        np.testing.assert_allclose(R, _rz(y) @ _ry(p) @ _rx(r), atol=1e-12)
        np.testing.assert_allclose(rpy_matrix(*rpy_from_matrix(R)), R, atol=1e-12)


def test_write_then_parse_is_identical():
    tree = parse_urdf(TWO_LINK)
    again = parse_urdf(tree_to_urdf(tree))
    assert again.links == tree.links
    for a, b in zip(tree.joints, again.joints, strict=True):
        assert (a.name, a.type, a.parent, a.child) == (b.name, b.type, b.parent, b.child)
        np.testing.assert_allclose(a.origin, b.origin, atol=1e-14)
        np.testing.assert_allclose(a.axis, b.axis, atol=1e-15)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("<robot name='r'><link name='a'>", "malformed URDF"),
        ("<robot name='r'></robot>", "no links"),
        (
            "<robot name='r'><link name='a'/><link name='b'/></robot>",
            "exactly one root link",
        ),
        (
            "<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='planar'>"
            "<parent link='a'/><child link='b'/></joint></robot>",
            "unsupported type 'planar'",
        ),
        (
            "<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'>"
            "<parent link='a'/><child link='b'/><axis xyz='0 0 0'/></joint></robot>",
            "zero axis",
        ),
    ],
)
def test_malformed_urdf_is_refused(text, message):
    with pytest.raises(ModelError, match=message):
        parse_urdf(text, "robot.urdf")


def test_a_urdf_is_read_without_trimesh_which_still_loads_when_a_scene_is_built():
    """yourdfpy reads the URDF while ``trimesh`` is a stand-in (no mesh machinery imported);
    a scene built afterwards gets the real trimesh: the box's extents, the same numbers."""
    import subprocess
    import sys
    from pathlib import Path

    script = """
import io, sys
import scdk_sym as sc
m = sc.load_model("models/planar_hexa")
print(sorted(n for n in sys.modules if n.split(".")[0] == "trimesh"))
import yourdfpy
box = '''<robot name="r"><link name="a"><visual><geometry><box size="0.1 0.2 0.3"/></geometry>
</visual></link></robot>'''
u = yourdfpy.URDF.load(io.StringIO(box), build_scene_graph=True, load_meshes=True)
print(type(u.scene).__module__, sorted(float(e) for e in u.scene.extents))
"""
    root = Path(__file__).resolve().parents[1]
    out = subprocess.run(
        [sys.executable, "-c", script], cwd=root, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr[-2000:]
    loaded, scene = out.stdout.splitlines()
    assert "'trimesh'" not in loaded and "trimesh.scene" not in loaded, loaded
    module, extents = scene.split(" ", 1)
    assert module == "trimesh.scene.scene"
    np.testing.assert_allclose(eval(extents), [0.1, 0.2, 0.3], atol=1e-12)
