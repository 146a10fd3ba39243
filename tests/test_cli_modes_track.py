"""scdk modes | track | plot: JSON schema and numbers against independent references."""

from __future__ import annotations

import json

import numpy as np
import pytest
from factories import MODELS, SEED_THETA0, shipped
from test_modes import pose_distance, rpr_reference

import scdk_sym as sc
from scdk_sym.cli import main

KEYS = {"x", "y", "theta", "platform_pose", "residual", "crossings", "status"}


def run_json(capsys, *argv) -> dict:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_modes_json_has_every_3rpr_solution(tmp_path, capsys):
    rng = np.random.default_rng(11)
    while True:  # a seeded 3-RPR whose leg lengths have four or more real assembly modes
        A, C, rho = (
            rng.uniform(-1, 1, (3, 2)),
            rng.uniform(-0.6, 0.6, (3, 2)),
            rng.uniform(0.3, 1.5, 3),
        )
        ref = rpr_reference(A, C, rho)
        if len(ref) >= 4:
            break
    directory = sc.builders.planar_3rpr(A, C).save(tmp_path / "rpr")
    out = run_json(
        capsys, "modes", str(directory), "--theta", ",".join(repr(float(v)) for v in rho)
    )
    sols = out["solutions"]
    assert len(sols) == len(ref) == out["count"]
    assert out["certified"] is True and out["root_count"] == 6
    assert out["report"].startswith("certified complete")
    assert "complete" not in out
    assert all(s["certified"] is True for s in sols)
    for s in sols:
        assert set(s) >= KEYS
        assert s["status"] == "converged" and s["residual"] < 1e-9
        assert np.allclose(s["theta"], rho, atol=1e-12)
    for r in ref:
        assert min(pose_distance(np.array(s["x"]), r) for s in sols) < 1e-8


def test_modes_human_output(capsys):
    assert main(["modes", str(MODELS / "planar_hexa"), "--theta", "1.292,-0.802,-2.896"]) == 0
    out = capsys.readouterr().out
    assert "2 real solution(s)" in out and "certified complete" in out
    assert "0.999914" in out and "0.207456" in out


def test_modes_curve_search_is_never_called_complete(capsys):
    theta = "1.292,-0.802,-2.896"
    out = run_json(capsys, "modes", str(MODELS / "planar_hexa"), "--theta", theta, "--method",
                   "curves")  # fmt: skip
    assert out["certified"] is False and out["method"] == "curves" and "complete" not in out
    assert out["report"].startswith("not certified")
    assert all(s["certified"] is False for s in out["solutions"])
    assert main(["modes", str(MODELS / "planar_hexa"), "--theta", theta, "--method", "curves"]) == 0
    text = capsys.readouterr().out
    assert "not certified" in text and "certified complete" not in text


def seed_csv(tmp_path, phis, header: str | None = None, order=(0, 1, 2)):
    model = shipped("planar_hexa")
    thetas = np.array([model.inverse_kinematics([0.0, 0.0, p]).theta for p in phis])
    lines = [header] if header else []
    lines += [",".join(repr(float(v)) for v in row[list(order)]) for row in thetas]
    path = tmp_path / "thetas.csv"
    path.write_text("# seed robot turning through its singularity\n" + "\n".join(lines) + "\n")
    return path


def test_track_json_follows_the_motion_through_the_singularity(tmp_path, capsys):
    phis = np.linspace(0.40, 1.00, 15)
    csv = seed_csv(tmp_path, phis)
    model = str(MODELS / "planar_hexa")
    out = run_json(capsys, "track", model, "--thetas", str(csv), "--from-x", "0,0,0.4")
    x = np.array(out["x"])
    assert x.shape == (15, 3)
    assert np.max(np.abs(x[:, 2] - phis)) < 1e-9
    assert np.max(np.abs(x[:, :2])) < 1e-9
    assert len(out["crossings"]) == 1
    assert out["crossings"][0]["index"] == int(np.nonzero(phis < 0.5754)[0][-1])
    assert abs(out["crossings"][0]["x"][2] - 0.57536) < 1e-3
    # a header naming the columns in another order gives the same track
    csv2 = seed_csv(tmp_path, phis, header="theta_3,theta_1,theta_2", order=(2, 0, 1))
    out2 = run_json(capsys, "track", model, "--thetas", str(csv2), "--from-x", "0,0,0.4")
    assert np.max(np.abs(np.array(out2["x"]) - x)) < 1e-12


def test_track_human_output_marks_the_crossing(tmp_path, capsys):
    csv = seed_csv(tmp_path, np.linspace(0.35, 0.65, 4))
    assert (
        main(["track", str(MODELS / "planar_hexa"), "--thetas", str(csv), "--from-x", "0,0,0.35"])
        == 0
    )
    out = capsys.readouterr().out
    assert "singular crossing: x = [0, 0, 0.5753" in out
    assert "4 samples, 1 singular crossing(s)" in out


def test_plot_commands_write_pngs(tmp_path, capsys):
    model = str(MODELS / "planar_hexa")
    theta = ",".join(map(str, SEED_THETA0))
    assert (
        main(["plot", model, "--theta", theta, "--from-x", "0,0,0.4", "--out", str(tmp_path)]) == 0
    )
    csv = seed_csv(tmp_path, np.linspace(0.5, 0.65, 8))
    assert (
        main(["plot", model, "--thetas", str(csv), "--from-x", "0,0,0.5", "--out", str(tmp_path)])
        == 0
    )
    names = ["configurations", "det_jp", "phase", "track"]
    out = capsys.readouterr().out
    for name in names:
        path = tmp_path / f"planar_hexa_{name}.png"
        assert f"wrote {path}" in out
        assert path.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("1,2\n", "row 1 has 2 values, expected 3 (theta_1, theta_2, theta_3)"),
        (
            "theta_1,theta_9,theta_3\n1,2,3\n",
            "unknown actuated joint 'theta_9'; actuated joints: theta_1",
        ),
        ("1,2,x\n", "row 1: expected comma-separated numbers"),
        ("# only a comment\n", "has no rows"),
    ],
)
def test_track_csv_errors_name_the_cause(tmp_path, capsys, content, message):
    csv = tmp_path / "bad.csv"
    csv.write_text(content)
    assert main(["track", str(MODELS / "planar_hexa"), "--thetas", str(csv)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("scdk track: error: ")
    assert message in err
    assert err.count("\n") == 1


def test_missing_csv_and_bad_theta(tmp_path, capsys):
    missing = tmp_path / "nope.csv"
    assert main(["track", str(MODELS / "planar_hexa"), "--thetas", str(missing)]) == 1
    assert f"cannot read '{missing}'" in capsys.readouterr().err
    assert main(["modes", str(MODELS / "planar_hexa"), "--theta", "1,2"]) == 1
    assert "theta0 (theta_1, theta_2, theta_3) must have 3 values" in capsys.readouterr().err


def test_atlas_modes_only_counts_the_polynomial_roots(tmp_path, capsys):
    """``scdk atlas --modes-only``: the certified counts of a 3 x 3 leg grid equal the real
    roots of the 3-RPR polynomial at every point, with no convergent solve."""
    pytest.importorskip("zarr")
    from scdk_sym.atlases import open_atlas

    rng = np.random.default_rng(11)
    A, C = rng.uniform(-1, 1, (3, 2)), rng.uniform(-0.6, 0.6, (3, 2))
    directory = sc.builders.planar_3rpr(A, C).save(tmp_path / "rpr")
    model = sc.load_model(directory)
    leg = model.home.theta
    grid = ",".join(f"{name}={float(v) * 0.9!r}:{float(v) * 1.1!r}:3" for name, v in
                    zip(model.actuated[:2], leg[:2], strict=True))  # fmt: skip
    out = run_json(capsys, "atlas", str(directory), "--grid", grid, "--modes-only", "--out",
                   str(tmp_path / "map.zarr"), "--no-progress")  # fmt: skip
    assert out["statuses"] == [{"code": 5, "name": "not solved", "count": 9}]
    store = open_atlas(tmp_path / "map.zarr")
    ref = [len(rpr_reference(A, C, th)) for th in store["theta"][:]]
    np.testing.assert_array_equal(store["n_modes"][:], ref)
    assert sum(ref) > 0  # the grid has assembly modes to count
