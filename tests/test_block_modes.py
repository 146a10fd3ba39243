"""Assembly modes of a model whose blocks fall in independent groups (two five-bars on one
base, like a biped's two legs): a product of the groups' sets, built when read, equal to
each five-bar's own modes solved as a whole model."""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from factories import MODELS

import scdk_sym as sc
from scdk_sym.robot.blocks import triangular_blocks, triangular_models
from scdk_sym.solvers.block_modes import ModeProduct, block_modes, groups

#: The second five-bar's base offset along x [m].
OFFSET = 1.0


def two_five_bars(tmp: Path) -> Path:
    """models/five_bar twice on one base: names prefixed ``a_`` and ``b_``, the second
    moved by :data:`OFFSET` along x."""
    urdf = (MODELS / "five_bar" / "robot.urdf").read_text()
    body = urdf.split(">", 1)[1].rsplit("</robot>", 1)[0].replace('<link name="base"/>', "")

    def copy(prefix: str, dx: float) -> str:
        text = re.sub(r'(name|link)="([^"]+)"',
                      lambda mt: f'{mt[1]}="{mt[2] if mt[2] == "base" else prefix + mt[2]}"',
                      body)  # fmt: skip
        return re.sub(  # the joints on the base: moved along x
            r'(<parent link="base"/>\s*<child link="[^"]+"/>\s*<origin xyz=")([-\d.]+)',
            lambda mt: f"{mt[1]}{float(mt[2]) + dx!r}",
            text,
        )

    out = tmp / "two_five_bars"
    out.mkdir()
    (out / "robot.urdf").write_text(
        '<robot name="two_five_bars">\n  <link name="base"/>'
        + copy("a_", 0.0)
        + copy("b_", OFFSET)
        + "</robot>\n"
    )
    spec = yaml.safe_load((MODELS / "five_bar" / "robot.yaml").read_text())
    home = spec["home"]
    both = {
        "closed_loop": [[p + a, p + b] for p in ("a_", "b_") for a, b in spec["closed_loop"]],
        "type": spec["type"] * 2,
        "name_mot": [p + n for p in ("a_", "b_") for n in spec["name_mot"]],
        "format_version": 1,
        "length": spec["length"] * 2,
        "platform": "a_effector",
        "workspace": spec["workspace"],
        "home": {p + k: v for p in ("a_", "b_") for k, v in home.items()},
    }
    (out / "robot.yaml").write_text(yaml.safe_dump(both))
    return out


def test_independent_groups_give_a_product_equal_to_each_group_solved_alone(tmp_path):
    m = sc.load_model(two_five_bars(tmp_path))
    one = sc.load_model(MODELS / "five_bar")
    blocks = triangular_blocks(m)
    assert len(groups(blocks)) == 2
    rng = np.random.default_rng(3)
    theta = np.array(m.home.theta) + rng.uniform(-0.05, 0.05, m.k)
    sols = block_modes(m, theta, blocks, triangular_models(m))
    assert isinstance(sols.solutions, ModeProduct) and sols.certified, sols.report
    # each five-bar alone, as a whole model (no blocks): its modes at its two actuators
    legs = []
    for p in ("a_", "b_"):
        th = [theta[m.actuated.index(p + n)] for n in one.actuated]
        alone = sc.assembly_modes(one, th)
        assert alone.certified, alone.report
        legs.append(sorted(tuple(np.round(c.y, 9)) for c in alone))
    assert sols.groups == tuple(len(leg) for leg in legs)
    assert len(sols) == len(legs[0]) * len(legs[1]) >= 4
    assert f"{len(legs[0])} x {len(legs[1])}" in sols.report
    got = []
    for cfg in sols:
        assert m.residual(cfg.y, cfg.theta) <= 1e-10
        j = cfg.joints
        got.append(tuple(round(j[p + u], 9) for p in ("a_", "b_") for u in one.unknowns))
    want = [a + b for a, b in itertools.product(*legs)]
    assert len(set(got)) == len(got)
    np.testing.assert_allclose(sorted(got), sorted(want), rtol=0, atol=1e-8)
    np.testing.assert_array_equal(sols[-1].y, sols[len(sols) - 1].y)
    assert [c.y.tolist() for c in sols[1:3]] == [sols[1].y.tolist(), sols[2].y.tolist()]
    with pytest.raises(IndexError):
        sols[len(sols)]
    d = sols.to_dict()
    assert d["groups"] == list(sols.groups) and d["count"] == len(sols)


def test_a_group_without_an_assembly_leaves_none_and_nothing_failed(tmp_path):
    m = sc.load_model(two_five_bars(tmp_path))
    theta = np.array(m.home.theta, dtype=float)
    # the second five-bar's elbows 0.6 apart, beyond the two 0.25 rods: it cannot close
    theta[m.actuated.index("b_theta_1")], theta[m.actuated.index("b_theta_2")] = np.pi, 0.0
    alone = sc.assembly_modes(sc.load_model(MODELS / "five_bar"), [np.pi, 0.0])
    assert len(alone) == 0
    sols = block_modes(m, theta, triangular_blocks(m), triangular_models(m))
    assert len(sols) == 0 and sols.groups == (0, 0)  # no part verified without the other
    assert sols.certified == alone.certified and "fail the model's residual" not in sols.report
