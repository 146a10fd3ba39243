"""Command-line interface (scdk_sym.cli)."""

import json

import pytest
from factories import MODELS

from scdk_sym.cli import main

SEED = ["--theta", "1.292,-0.802,-2.896", "--from-x", "0,0,0.4"]


@pytest.mark.parametrize("name", ["planar_hexa", "planar_hexa_reduced"])
@pytest.mark.parametrize(
    ("branch", "phi", "n_cross"), [("convergent", 0.2074, 0), ("divergent", 0.9999, 1)]
)
def test_solve_json_meets_the_paper(capsys, name, branch, phi, n_cross):
    assert main(["solve", str(MODELS / name), *SEED, "--branch", branch, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {"x", "y", "theta", "platform_pose", "residual", "crossings", "status"} <= set(out)
    assert abs(out["x"][2] - phi) < 1.5e-3 and abs(out["x"][0]) < 5e-3 and abs(out["x"][1]) < 5e-3
    assert out["residual"] <= 1e-8 and out["status"] == "converged"
    assert len(out["platform_pose"]) == 4 and all(len(r) == 4 for r in out["platform_pose"])
    assert len(out["crossings"]) == n_cross
    for c in out["crossings"]:
        assert set(c) >= {"s", "x"} and abs(c["x"][2] - 0.5754) < 2e-3


def test_solve_both_branches_human_output(capsys):
    assert main(["solve", str(MODELS / "planar_hexa"), *SEED, "--branch", "both"]) == 0
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if "x = [" in ln]
    assert lines[1].strip().startswith("convergent: x = [") and "0.2074" in lines[1]
    assert lines[2].strip().startswith("divergent: x = [") and "0.9999" in lines[2]
    assert "singular crossing at s = -0.27" in out and "0.5753" in out


def test_solve_both_branches_json(capsys):
    assert main(["solve", str(MODELS / "planar_hexa"), *SEED, "--branch", "both", "--json"]) == 0
    sols = json.loads(capsys.readouterr().out)["solutions"]
    assert [round(s["x"][2], 3) for s in sols] == [0.207, 1.0]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--theta", "1,2"], "must have 3 values, got 2"),
        (["--theta", "1,x,2"], "--theta: expected comma-separated numbers"),
        (["--theta", "1.292,-0.802,-2.896", "--from-x", "40,0,0"], "not reachable"),
        (["--theta=-0.5236,-2.618,1.5708", "--from-x", "0,0,0.4"], "did not reach s = 1"),
        (["--theta", "1,2,3", "--frame", "tool"], "unknown frame 'tool'; frames: base"),
    ],
)
def test_errors_exit_1_with_one_line(capsys, argv, message):
    assert main(["solve", str(MODELS / "planar_hexa"), *argv]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("scdk solve: error: ") and message in err
    assert "\n" not in err


def test_missing_model_and_usage_errors(capsys, tmp_path):
    assert main(["solve", str(tmp_path), "--theta", "1,2,3"]) == 1
    assert "file not found" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:
        main(["solve"])
    assert info.value.code == 2


def test_cache_command(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("SCDK_CACHE_DIR", str(tmp_path))
    (tmp_path / "kernels_x.so").write_bytes(b"123")
    assert main(["cache"]) == 0
    assert "1 item(s)" in capsys.readouterr().out
    assert main(["cache", "--clear"]) == 0
    assert "removed 1 cached item(s)" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []
