"""``sc.verify_model`` and ``scdk verify``: a model's kinematics against Pinocchio and
finite differences, on every shipped model (all pass) and on a model whose two descriptions
disagree (a joint origin moved in the URDF that Pinocchio reads)."""

from __future__ import annotations

import dataclasses
import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from factories import MODELS, ROOT, shipped

import scdk_sym as sc
import scdk_sym.robot
from scdk_sym.cli import main
from scdk_sym.errors import InputError
from scdk_sym.robot import Model

SHIPPED = sorted(p.name for p in MODELS.iterdir() if (p / "robot.yaml").exists())
#: Joint whose origin is moved, and by how much along x [cm] (planar_hexa).
MOVED_JOINT, SHIFT = "elbow_2", 0.5


def _moved_origin(urdf: str, joint: str, dx: float) -> str:
    root = ET.fromstring(urdf)
    origin = root.find(f"joint[@name='{joint}']/origin")
    xyz = [float(v) for v in origin.get("xyz").split()]
    xyz[0] += dx
    origin.set("xyz", " ".join(repr(v) for v in xyz))
    return ET.tostring(root, encoding="unicode")


def _corrupted() -> Model:
    """planar_hexa whose symbolic build reads the shipped URDF but Pinocchio a moved joint."""
    good = shipped("planar_hexa")
    text = _moved_origin(good.urdf_text, MOVED_JOINT, SHIFT)
    return Model(good.tree, good.spec, good.path, None, urdf_text=text)


def _descendants(model: Model, joint: str) -> set[str]:
    links = {model.tree.joint(joint).child}
    grew = True
    while grew:
        more = {j.child for j in model.tree.joints if j.parent in links} - links
        links |= more
        grew = bool(more)
    return links


def test_verify_report_shape_and_numbers_on_the_seed_robot():
    model = shipped("planar_hexa")
    report = sc.verify_model(model, samples=2, seed=3)
    assert isinstance(report, sc.VerifyReport) and report.passed and not report.failures
    kinds = [c.kind for c in report.checks]
    assert kinds == ["placements"] * 3 + ["closures"] * 3 + ["jacobians"] * 3
    assert [c.where for c in report.checks[:3]] == [
        "home",
        "random configuration 1",
        "random configuration 2",
    ]
    for c in report.checks:
        assert 0 <= c.error <= c.tolerance
    # placements and closures agree with Pinocchio to rounding; Jacobians with central
    # differences to O(h^2) with h = 1e-6 (relative)
    assert max(c.error for c in report.checks if c.kind != "jacobians") < 1e-12
    assert max(c.error for c in report.checks if c.kind == "jacobians") < 1e-8
    with pytest.raises(dataclasses.FrozenInstanceError):
        report.checks[0].error = 1.0  # type: ignore[misc]


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_model_passes(name):
    report = sc.verify_model(shipped(name), samples=2, seed=11)
    assert report.passed, report.text()
    assert len(report.checks) == 9


def test_gepetto_delta_passes():
    model = sc.load_model(ROOT / "tests/fixtures/gepetto/robot_delta", frame="effector")
    report = sc.verify_model(model, samples=2, seed=5)
    assert report.passed, report.text()


def test_corrupted_model_fails_and_names_the_check_and_frames():
    model = _corrupted()
    report = sc.verify_model(model, samples=2, seed=3)
    assert not report.passed
    moved = _descendants(model, MOVED_JOINT)
    assert moved == {"rod_2", "rod_end_2"}
    placements = [c for c in report.checks if c.kind == "placements"]
    assert all(not c.passed for c in placements)
    for c in placements:
        # every link below the moved joint is off by R_parent [SHIFT, 0, 0]: its largest
        # component lies between SHIFT / sqrt(3) and SHIFT
        assert c.item.removeprefix("frame ").strip("'") in moved, c.item
        assert SHIFT / math.sqrt(3) - 1e-9 <= c.error <= SHIFT + 1e-9
    closures = [c for c in report.checks if c.kind == "closures"]
    assert all(not c.passed and c.item == "closure 2d(vertex_2,rod_end_2)" for c in closures)
    # our own kinematics are self-consistent: the Jacobians still match finite differences
    assert all(c.passed for c in report.checks if c.kind == "jacobians")
    last = report.text().splitlines()[-1]
    assert last.startswith("FAILED: 6 of 9 checks; first: placements at home, frame ")


def test_jacobian_check_detects_a_wrong_jacobian(monkeypatch):
    from scdk_sym.verify import report as rep

    model = shipped("planar_hexa_reduced")
    real = rep.model_calls(model)

    class Skewed:
        g = real.g

        @staticmethod
        def jac(y, theta, c):
            J_p, J_s = real.jac(y, theta, c)
            J_p = np.array(J_p)
            J_p[1, 2] *= 1.001  # 0.1 % off in one entry
            return J_p, J_s

    monkeypatch.setattr(rep, "model_calls", lambda m: Skewed)
    check = rep._jacobian_check(model, model.home, "home", 1e-6)
    assert not check.passed
    row = model.row_labels()[model.rows[1]]
    assert check.item == f"entry J_p[{row}, {model.unknowns[2]}]"
    y, c = model.chart.to_local(model.home.y)
    J_p, J_s = (np.array(a) for a in real.jac(y, model.home.theta, c))
    size = max(1.0, np.abs(J_p).max(), np.abs(J_s).max())
    assert check.error == pytest.approx(1e-3 * abs(J_p[1, 2]) / size, rel=1e-3)


def test_cli_verify_exit_codes_and_json(capsys, monkeypatch):
    assert main(["verify", str(MODELS / "five_bar"), "--samples", "1"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[-1] == "passed: 6 of 6 checks"
    assert out.startswith("model five_bar")

    monkeypatch.setattr(scdk_sym.robot, "load_model", lambda path, frame=None: _corrupted())
    assert main(["verify", str(MODELS / "planar_hexa"), "--json", "--samples", "1"]) == 1
    data = json.loads(capsys.readouterr().out)
    assert data["passed"] is False and data["model"] == "planar_hexa"
    failed = [c for c in data["checks"] if not c["passed"]]
    assert {c["kind"] for c in failed} == {"placements", "closures"}
    assert failed[0]["where"] == "home" and failed[0]["item"] in (
        "frame 'rod_2'",
        "frame 'rod_end_2'",
    )


@pytest.mark.parametrize(
    ("kwargs", "match"), [({"samples": -1}, "samples"), ({"spread": 0}, "spread")]
)
def test_bad_arguments_are_input_errors(kwargs, match):
    with pytest.raises(InputError, match=match):
        sc.verify_model(shipped("five_bar"), **kwargs)


def test_without_pinocchio_verify_names_the_install_and_solve_still_works(monkeypatch, capsys):
    import subprocess
    import sys

    from scdk_sym.errors import DependencyError

    monkeypatch.setitem(sys.modules, "pinocchio", None)  # import pinocchio -> ImportError
    with pytest.raises(DependencyError, match=r'pip install "scdk_sym\[verify\]"'):
        sc.verify_model(shipped("planar_hexa"))
    assert main(["verify", str(MODELS / "planar_hexa")]) != 0
    assert "scdk_sym[verify]" in capsys.readouterr().err
    # the solvers never import Pinocchio: the paper's example in a process without it
    code = (
        "import sys; sys.modules['pinocchio'] = None\n"
        "import numpy as np, scdk_sym as sc\n"
        f"m = sc.load_model({str(MODELS / 'planar_hexa')!r})\n"
        "start = m.inverse_kinematics([0.0, 0.0, 0.4])\n"
        "r = sc.solve(m, [1.292, -0.802, -2.896], start=start)\n"
        "print(r.x[2])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True
    )
    assert abs(float(out.stdout.split()[-1]) - 0.2074) < 1e-3  # the paper's phi (convergent)
