"""Every command's --json output against the shipped JSON Schema (scdk_sym/schema)."""

from __future__ import annotations

import copy
import json
import math

import jsonschema
import numpy as np
import pytest
from factories import MODELS, SEED_THETA0, compiler_missing, shipped

from scdk_sym import backends
from scdk_sym.cli import main
from scdk_sym.errors import InputError
from scdk_sym.schema import OUTPUTS, command_schema, load_schema

SEED = ["--theta", ",".join(repr(float(v)) for v in SEED_THETA0), "--from-x", "0,0,0.4"]
HEXA = str(MODELS / "planar_hexa")
#: Keys of every configuration record, and of every crossing record (DESIGN.md section 5).
CONFIGURATION = {"x", "y", "theta", "platform_pose", "joints", "residual"}
CROSSING = {"s", "x", "y", "theta", "index", "kind"}


def validate(record: dict, output: str) -> None:
    jsonschema.Draft202012Validator(command_schema(output)).validate(record)


def run_json(capsys, *argv) -> dict:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def assert_pose_matches_x(pose, x) -> None:
    """Planar seed robot: the pose's translation is (x, y), its rotation about z is phi."""
    T = np.array(pose)
    np.testing.assert_allclose(T[3], [0, 0, 0, 1], atol=0)
    np.testing.assert_allclose(T[:2, 3], x[:2], atol=1e-12)
    assert abs(math.atan2(T[1, 0], T[0, 0]) - x[2]) < 1e-12


@pytest.fixture(scope="module")
def seed_csv(tmp_path_factory):
    """The seed robot turning through its singular orientation phi = 0.5754 (12 readings)."""
    model = shipped("planar_hexa")
    phis = np.linspace(0.45, 0.70, 12)
    rows = [model.inverse_kinematics([0.0, 0.0, p]).theta for p in phis]
    path = tmp_path_factory.mktemp("track") / "thetas.csv"
    path.write_text("\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    return path, phis


def test_schema_is_draft_2020_12_and_names_the_registry_backends():
    schema = load_schema()
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    jsonschema.Draft202012Validator.check_schema(schema)
    assert set(OUTPUTS) <= set(schema["$defs"])
    emitted = set(backends.BACKENDS) - {"auto"}  # auto is resolved before it is reported
    assert set(schema["$defs"]["backend"]["enum"]) == emitted
    assert set(schema["$defs"]["configuration"]["required"]) == CONFIGURATION
    assert set(schema["$defs"]["crossing"]["required"]) == CROSSING
    with pytest.raises(InputError, match="outputs: solve, solve-both, modes"):
        command_schema("verify-me")


@pytest.mark.parametrize("branch", ["convergent", "divergent"])
def test_solve_json_validates(capsys, branch):
    out = run_json(capsys, "solve", HEXA, *SEED, "--branch", branch)
    validate(out, "solve")
    jsonschema.validate(out, load_schema())
    # the paper's section 5: phi = 0.2074 (convergent), 0.9999 after one fold (divergent)
    assert abs(out["x"][2] - {"convergent": 0.2074, "divergent": 0.9999}[branch]) < 1.5e-3
    assert out["backend"] == "cvodes" and out["branch"] == branch
    assert_pose_matches_x(out["platform_pose"], out["x"])
    model = shipped("planar_hexa")
    assert set(out["joints"]) >= set(model.actuated) | set(model.unknowns)
    np.testing.assert_allclose([out["joints"][a] for a in model.actuated], SEED_THETA0)
    for c in out["crossings"]:
        assert set(c) == CROSSING and type(c["index"]) is int and c["index"] == -1


def test_solve_both_json_validates_with_a_failed_branch(capsys, monkeypatch):
    out = run_json(capsys, "solve", HEXA, *SEED, "--branch", "both")
    validate(out, "solve-both")
    assert [round(s["x"][2], 3) for s in out["solutions"]] == [0.207, 1.0]
    import scdk_sym.solvers.solve as sc_module
    from scdk_sym.errors import PathError

    real = sc_module.solve

    def solve(model, theta0, *args, branch="convergent", **kwargs):
        if branch == "divergent":
            raise PathError("stand-in failure of the divergent branch")
        return real(model, theta0, *args, branch=branch, **kwargs)

    monkeypatch.setattr(sc_module, "solve", solve)
    out = run_json(capsys, "solve", HEXA, *SEED, "--branch", "both")
    validate(out, "solve-both")
    assert out["solutions"][1]["status"] == "failed"
    assert out["solutions"][1]["error_type"] == "PathError"


@pytest.mark.parametrize("method", ["homotopy", "curves"])
def test_modes_json_validates(capsys, method):
    theta = ",".join(repr(float(v)) for v in SEED_THETA0)
    out = run_json(capsys, "modes", HEXA, "--theta", theta, "--method", method)
    validate(out, "modes")
    assert out["count"] == len(out["solutions"]) and out["method"] == method
    if method == "curves":
        assert out["backend"] == "cvodes"  # the curve search's default is unchanged
    else:
        assert out["backend"] == ("cvodes" if compiler_missing() else "compiled")  # auto
    # the paper's two solutions phi = 0.2074 and 0.9999 are among the modes
    phis = sorted(s["x"][2] for s in out["solutions"])
    for phi in (0.2074, 0.9999):
        assert min(abs(p - phi) for p in phis) < 1.5e-3
    for s in out["solutions"]:
        assert set(s) >= CONFIGURATION and s["crossings"] == []
        assert_pose_matches_x(s["platform_pose"], s["x"])


@pytest.mark.parametrize("backend", ["cvodes", "c"])
def test_track_json_validates_with_a_pose_per_sample(capsys, seed_csv, backend):
    if backend == "c" and compiler_missing():
        pytest.skip(compiler_missing())
    path, phis = seed_csv
    out = run_json(capsys, "track", HEXA, "--thetas", str(path), "--from-x", "0,0,0.4",
                   "--backend", backend)  # fmt: skip
    validate(out, "track")
    assert out["backend"] == backend
    model = shipped("planar_hexa")
    assert len(out["platform_pose"]) == len(out["joints"]) == len(out["x"]) == len(phis)
    for x, pose, joints, theta, phi in zip(
        out["x"], out["platform_pose"], out["joints"], out["theta"], phis, strict=True
    ):
        assert abs(x[2] - phi) < 1e-9  # the readings' inverse kinematics
        assert_pose_matches_x(pose, x)
        assert [joints[a] for a in model.actuated] == theta
    (c,) = out["crossings"]
    assert set(c) == CROSSING and type(c["index"]) is int
    assert c["index"] == int(np.nonzero(phis < 0.5754)[0][-1]) and c["kind"] == "fold"


def test_atlas_json_validates(capsys, tmp_path):
    grid = "theta_1=1.25:1.35:3,theta_2=-0.85:-0.75:2"
    argv = ["atlas", HEXA, "--grid", grid, "--out", str(tmp_path / "a.zarr"),
            "--from-x", "0,0,0.4", "--chunk", "4", "--no-progress"]  # fmt: skip
    out = run_json(capsys, *argv)
    validate(out, "atlas")
    assert out["points"] == 6 and out["chunks"] == 2 and out["computed"] == 2
    assert sum(s["count"] for s in out["statuses"]) == 6
    again = run_json(capsys, *argv)  # resumed: nothing left to solve
    validate(again, "atlas")
    assert again["computed"] == 0 and again["statuses"] == out["statuses"]


def test_codegen_json_validates(capsys, tmp_path):
    out = run_json(capsys, "codegen", str(MODELS / "planar_3rpr"), "--out", str(tmp_path),
                   "--no-shared")  # fmt: skip
    validate(out, "codegen")
    assert out["library"] is None
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.rsplit("/", 1)[-1] for p in out["files"]
    )


def test_verify_json_validates(capsys):
    from scdk_sym.cli import COMMANDS

    if "verify" not in COMMANDS:
        pytest.skip("this build has no scdk verify")
    rc = main(["verify", str(MODELS / "planar_hexa"), "--samples", "1", "--json"])
    out = json.loads(capsys.readouterr().out)
    validate(out, "verify")
    assert rc == (0 if out["passed"] else 1)
    assert out["passed"] == all(c["passed"] for c in out["checks"])
    assert {c["kind"] for c in out["checks"]} == {"placements", "closures", "jacobians"}


@pytest.fixture(scope="module")
def solve_record():
    """A valid ``solve --json`` record with one crossing (the divergent seed solve)."""
    import scdk_sym as sc

    model = shipped("planar_hexa")
    start = model.inverse_kinematics([0.0, 0.0, 0.4])
    res = sc.solve(model, SEED_THETA0, start=start, branch="divergent")
    record = json.loads(json.dumps(dict(res.to_dict(), backend="cvodes"), default=float))
    validate(record, "solve")
    return record


def _broken(record: dict, edit) -> dict:
    broken = copy.deepcopy(record)
    edit(broken)
    return broken


@pytest.mark.parametrize(
    "edit",
    [
        lambda r: r.pop("platform_pose"),
        lambda r: r.pop("joints"),
        lambda r: r.update(residual=-1.0),
        lambda r: r.update(status="ok"),
        lambda r: r.update(backend="casadi"),  # a deprecated name is never reported
        lambda r: r.update(residul=0.0),  # a misspelt key
        lambda r: r["platform_pose"].pop(),
        lambda r: r["joints"].update(mot1="1.0"),
        lambda r: r["crossings"][0].update(index="0"),
        lambda r: r["crossings"][0].update(index=0.5),
        lambda r: r["crossings"][0].update(kind="cusp"),
        lambda r: r["crossings"][0].pop("kind"),
    ],
)
def test_a_broken_record_is_rejected(solve_record, edit):
    with pytest.raises(jsonschema.ValidationError):
        validate(_broken(solve_record, edit), "solve")


def test_a_solve_record_is_not_a_track_and_a_track_needs_its_poses(solve_record):
    with pytest.raises(jsonschema.ValidationError):
        validate(solve_record, "track")
    track = {
        "x": [solve_record["x"]],
        "y": [solve_record["y"]],
        "theta": [solve_record["theta"]],
        "residual": [solve_record["residual"]],
        "crossings": [],
        "status": "converged",
        "backend": "c",
        "platform_pose": [solve_record["platform_pose"]],
        "joints": [solve_record["joints"]],
    }
    validate(track, "track")
    for key in ("platform_pose", "joints"):
        with pytest.raises(jsonschema.ValidationError):
            validate(_broken(track, lambda r, key=key: r.pop(key)), "track")
    with pytest.raises(jsonschema.ValidationError):
        validate(_broken(track, lambda r: r.update(platform_pose=solve_record["platform_pose"])),
                 "track")  # fmt: skip
