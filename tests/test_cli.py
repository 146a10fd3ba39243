"""Command-line interface (scdk_sym.cli)."""

import json
import math

import pytest
from factories import MODELS, shipped

import scdk_sym.solvers.solve as sc_module
from scdk_sym.cli import main
from scdk_sym.errors import PathError

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
    # the paper's phi = 0.2074 and 0.9999 (section 5), printed to 6 digits
    assert lines[1].strip().startswith("convergent: x = [") and "0.207456]" in lines[1]
    assert lines[2].strip().startswith("divergent: x = [") and "0.999914]" in lines[2]
    assert "crossings 0" in lines[1] and "crossings 1" in lines[2]
    # the paper's singular configuration phi = 0.5754, a turning point of the curve
    assert lines[3].strip().startswith("singular crossing (fold) at s = -0.278")
    assert lines[3].endswith("0.575367]")


def test_solve_both_branches_json(capsys):
    assert main(["solve", str(MODELS / "planar_hexa"), *SEED, "--branch", "both", "--json"]) == 0
    sols = json.loads(capsys.readouterr().out)["solutions"]
    assert [round(s["x"][2], 3) for s in sols] == [0.207, 1.0]


def delta_arm_step() -> tuple[list[str], float]:
    """``--theta`` for the Delta's arms 0.02 rad below home, and the closed-form z there [m].

    With equal arm angles the platform stays on the axis; each rod (length l) then joins the
    elbow (R + L cos t, -L sin t) to its anchor (r, z) in the arm's vertical plane, so
    z = -L sin t - sqrt(l^2 - (R - r + L cos t)^2) (platform below the elbows). Dimensions of
    models/README.md: inradii of the 457.3 mm and 115.0 mm triangles, arm 112 mm, rod 232 mm.
    """
    t = float(shipped("delta").home.theta[0]) + 0.02
    big_r, r = 0.4573 / (2 * math.sqrt(3)), 0.1150 / (2 * math.sqrt(3))
    arm, rod = 0.112, 0.232
    z = -arm * math.sin(t) - math.sqrt(rod**2 - (big_r - r + arm * math.cos(t)) ** 2)
    return [f"--theta={t!r},{t!r},{t!r}"], z


#: The one-line message of the stand-in solver failure.
LOST = "the solution curve from the start did not reach s = 1 (stand-in failure)"


def fail_branches(monkeypatch, *failing: str, sep: str = "\n  ") -> None:
    """Make ``sc.solve`` raise PathError for the ``failing`` branches, solve the others.

    The message is ``LOST``, ``sep`` and the branch in parentheses (by default on two lines,
    which ``--branch both`` must print on one).
    """
    real = sc_module.solve

    def solve(model, theta0, *args, branch="convergent", **kwargs):
        if branch in failing:
            raise PathError(f"{LOST}{sep}({branch})")
        return real(model, theta0, *args, branch=branch, **kwargs)

    monkeypatch.setattr(sc_module, "solve", solve)


def test_solve_both_keeps_the_convergent_answer_when_divergent_fails(capsys, monkeypatch):
    theta, z = delta_arm_step()
    fail_branches(monkeypatch, "divergent")
    assert main(["solve", str(MODELS / "delta"), *theta, "--branch", "both"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    lines = captured.out.splitlines()
    assert len(lines) == 4
    head, _, tail = lines[2].partition("]")
    assert head.startswith("convergent: x = [") and tail.endswith("crossings 0")
    x = [float(v) for v in head.removeprefix("convergent: x = [").split(",")]
    assert abs(x[0]) < 1e-12 and abs(x[1]) < 1e-12 and abs(x[2] - z) < 1e-6  # 6 digits
    assert lines[3] == f" divergent: error: {LOST} (divergent)"


def test_solve_both_json_reports_the_failed_branch(capsys, monkeypatch):
    theta, z = delta_arm_step()
    fail_branches(monkeypatch, "divergent")
    assert main(["solve", str(MODELS / "delta"), *theta, "--branch", "both", "--json"]) == 0
    sols = json.loads(capsys.readouterr().out)["solutions"]
    assert len(sols) == 2
    good, bad = sols
    assert good["branch"] == "convergent" and good["status"] == "converged"
    assert abs(good["x"][0]) < 1e-12 and abs(good["x"][1]) < 1e-12
    assert abs(good["x"][2] - z) < 1e-12 and good["residual"] <= 1e-10
    assert good["crossings"] == [] and len(good["platform_pose"]) == 4
    assert bad == {
        "branch": "divergent",
        "status": "failed",
        "error": f"{LOST} (divergent)",
        "error_type": "PathError",
        "backend": "cvodes",
    }


@pytest.mark.parametrize("json_output", [False, True])
def test_solve_both_branches_failing_exit_1(capsys, monkeypatch, json_output):
    theta, _ = delta_arm_step()
    fail_branches(monkeypatch, "convergent", "divergent")
    argv = ["solve", str(MODELS / "delta"), *theta, "--branch", "both"]
    assert main(argv + ["--json"] * json_output) == 1
    captured = capsys.readouterr()
    assert captured.err.splitlines() == [
        f"scdk solve: error: {br}: {LOST} ({br})" for br in ("convergent", "divergent")
    ]
    if json_output:
        sols = json.loads(captured.out)["solutions"]
        assert [(s["branch"], s["status"], s["error_type"]) for s in sols] == [
            ("convergent", "failed", "PathError"),
            ("divergent", "failed", "PathError"),
        ]
        assert sols[0]["error"] == f"{LOST} (convergent)"
    else:
        lines = captured.out.splitlines()
        expected = [f"{br:>10}: error: {LOST} ({br})" for br in ("convergent", "divergent")]
        assert lines[2:] == expected


def test_solve_single_branch_failure_is_unchanged(capsys, monkeypatch):
    theta, _ = delta_arm_step()
    fail_branches(monkeypatch, "divergent", sep=" ")
    assert main(["solve", str(MODELS / "delta"), *theta, "--branch", "divergent"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.splitlines() == [f"scdk solve: error: {LOST} (divergent)"]


def test_solve_both_input_error_is_reported_once(capsys):
    argv = ["solve", str(MODELS / "planar_hexa"), "--theta", "1,2", "--branch", "both"]
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    message = "theta0 (theta_1, theta_2, theta_3) must have 3 values, got 2: [1.0, 2.0]"
    assert captured.err.splitlines() == [f"scdk solve: error: {message}"]


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


def test_readme_quick_start_prints_what_the_readme_says(capsys):
    """The first command of the README and the output it shows, line for line."""
    from factories import ROOT

    text = (ROOT / "README.md").read_text()
    command = text.split("pip install . && scdk ", 1)[1].split("\n", 1)[0]
    shown = text.split("on both branches and prints:\n\n```text\n", 1)[1].split("```", 1)[0]
    argv = command.split()
    argv[1] = str(ROOT / argv[1])
    assert main(argv) == 0
    assert capsys.readouterr().out == shown


def test_importing_the_cli_loads_no_heavy_dependency():
    import subprocess
    import sys

    script = (
        "import json, sys, scdk_sym.cli\n"
        "assert len(scdk_sym.cli.COMMANDS) >= 10, list(scdk_sym.cli.COMMANDS)\n"
        "print(json.dumps(sorted(sys.modules)))"
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True
    ).stdout
    loaded = {m.split(".")[0] for m in json.loads(out.strip().splitlines()[-1])}
    heavy = {"casadi", "matplotlib", "dask", "viser", "pinocchio", "zarr", "scipy"}
    assert not heavy & loaded, sorted(heavy & loaded)


def _subparsers():
    import argparse

    from scdk_sym.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, sub.choices


def test_every_option_has_help_and_states_its_default():
    import argparse

    parser, commands = _subparsers()
    assert len(commands) >= 10
    missing, no_default = [], []
    for name, p in commands.items():
        formatter = p._get_formatter()
        for action in p._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            text = formatter._expand_help(action) if action.help else ""
            if not text.strip():
                missing.append((name, action.dest))
            stated = action.default is None or action.default is False or "default" in text
            if action.option_strings and not stated:  # 0 is a default to state
                no_default.append((name, action.dest))
    assert not missing, missing
    assert not no_default, no_default


def test_every_command_shows_an_example_that_parses():
    import shlex

    from scdk_sym.cli import COMMANDS

    parser, commands = _subparsers()
    assert set(commands) == set(COMMANDS)
    for name, p in commands.items():
        help_text = p.format_help()
        assert "\nexample:\n  scdk " + name + " " in help_text, name
        words = shlex.split(COMMANDS[name].example)
        args = parser.parse_args(words[1:])  # argparse exits (SystemExit) on a bad example
        assert args.command == name and args.run is COMMANDS[name].run
        for word in words:  # the models it names are shipped
            if word.startswith("models/"):
                assert (MODELS / word.split("/", 1)[1]).is_dir(), word
