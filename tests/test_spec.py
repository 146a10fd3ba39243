"""The loop-closure YAML (scdk_sym.model.spec)."""

import math

import pytest

from scdk_sym.errors import ModelError
from scdk_sym.model.spec import parse_spec

GEPETTO = "closed_loop: [['a', 'b']]\ntype: ['6d']\nname_mot: ['mot1', 'mot2']\n"


def test_gepetto_keys_only():
    spec = parse_spec(GEPETTO)
    assert spec.actuated == ("mot1", "mot2")
    assert [(c.frame_a, c.frame_b, c.type, c.rows) for c in spec.closures] == [("a", "b", "6d", 6)]
    assert spec.platform is None and spec.workspace is None and spec.home == {}


def test_extensions_round_trip():
    text = (
        "closed_loop: [[e1, v1], [e2, v2]]\ntype: [distance, distance]\nname_mot: [t1, t2]\n"
        "length: [7.0, leg_2]\nplatform: p\nworkspace: [x, y, phi]\nhome: {t1: 0.5}\n"
    )
    spec = parse_spec(text)
    assert spec.closures[0].length == 7.0 and spec.closures[0].length_joint is None
    assert spec.closures[1].length_joint == "leg_2" and math.isnan(spec.closures[1].length)
    again = parse_spec(spec.to_yaml())
    assert again.closures == spec.closures
    assert (again.actuated, again.platform, again.workspace) == (
        ("t1", "t2"),
        "p",
        ("x", "y", "phi"),
    )
    assert again.home == {"t1": 0.5}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("closed_loop: [[a, b]\n", "malformed YAML"),
        ("- 1\n- 2\n", "must be a mapping"),
        ("closed_loop: [[a, b]]\ntype: [6d]\n", "missing key 'name_mot'"),
        (GEPETTO + "bogus: 1\n", "unknown keys \\['bogus'\\]"),
        ("closed_loop: [[a, b]]\ntype: [6d, 3d]\nname_mot: [m]\n", "'type' has 2 entries"),
        (
            "closed_loop: [[a, b]]\ntype: [7d]\nname_mot: [m]\n",
            "unknown closure type '7d'; types: 3d",
        ),
        ("closed_loop: [[a]]\ntype: [3d]\nname_mot: [m]\n", "pairs"),
        ("closed_loop: [[a, b]]\ntype: [distance]\nname_mot: [m]\n", "need 'length'"),
        ("closed_loop: [[a, b]]\ntype: [distance]\nname_mot: [m]\nlength: [-1]\n", "> 0"),
        ("closed_loop: [[a, b]]\ntype: [3d]\nname_mot: []\n", "empty"),
        ("closed_loop: [[a, b]]\ntype: [3d]\nname_mot: [m, m]\n", "duplicates"),
        (GEPETTO + "workspace: [x, w]\n", "unknown workspace coordinate 'w'"),
        (GEPETTO + "home: {mot1: .nan}\n", "finite"),
        (GEPETTO + "format_version: 2\n", "format_version"),
        (GEPETTO + "length_unit: 1\n", "'length_unit' must name the unit"),
    ],
)
def test_bad_yaml_is_refused_with_its_cause(text, message):
    with pytest.raises(ModelError, match=message) as info:
        parse_spec(text, "robot.yaml")
    assert str(info.value).startswith("robot.yaml: ")
    assert "\n" not in str(info.value)


def test_length_unit_is_kept_and_defaults_to_metres():
    assert parse_spec(GEPETTO).length_unit == "m"
    assert "length_unit" not in parse_spec(GEPETTO).to_yaml()
    spec = parse_spec(GEPETTO + "length_unit: cm\n")
    assert spec.length_unit == "cm" and parse_spec(spec.to_yaml()).length_unit == "cm"
