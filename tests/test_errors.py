"""Failures as a new user meets them: each is an ScdkError with a one-line message naming the
input and what to try; in the CLI a one-line ``error:`` on stderr and exit code 1 (2 for
usage), never a traceback."""

from __future__ import annotations

import importlib
import importlib.metadata
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from factories import MODELS, ROOT, SEED_THETA0, needs_compiler, shipped

import scdk_sym as sc
from scdk_sym import cli
from scdk_sym.cli import main, read_thetas
from scdk_sym.errors import (
    BuildError,
    InputError,
    ModelError,
    NonSquareSystemError,
    OutputError,
    PlotError,
    ScdkError,
    UnknownNameError,
)
from scdk_sym.kernels import compile as comp

gen = importlib.import_module("scdk_sym.codegen.generate")
FIXTURES = Path(__file__).resolve().parent / "fixtures" / "gepetto"
HEXA = str(MODELS / "planar_hexa")


def copy_model(tmp_path: Path, name: str = "planar_hexa") -> Path:
    d = tmp_path / name
    shutil.copytree(MODELS / name, d)
    return d


def edit_yaml(d: Path, **changes) -> None:
    data = yaml.safe_load((d / "robot.yaml").read_text())
    data.update(changes)
    (d / "robot.yaml").write_text(yaml.safe_dump(data))


def cli_error(capsys, argv: list[str], code: int = 1) -> str:
    """Run the CLI expecting a failure: the one stderr line, checked to be an ``error:``."""
    assert main(argv) == code
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"scdk {argv[0]}: error: ")
    assert "Traceback" not in err
    return lines[0]


# ---------------------------------------------------------------------------- codegen output


def test_codegen_under_a_missing_folder(capsys, tmp_path):
    out = tmp_path / "missing" / "generated"
    line = cli_error(capsys, ["codegen", HEXA, "--out", str(out), "--no-shared"])
    assert str(out) in line and "does not exist" in line and "create it first" in line
    assert not (tmp_path / "missing").exists()  # nothing created on the way


def test_codegen_onto_an_existing_file(capsys, tmp_path):
    blocker = tmp_path / "file.txt"
    blocker.write_text("keep me")
    line = cli_error(capsys, ["codegen", HEXA, "--out", str(blocker), "--no-shared"])
    assert str(blocker) in line and "is a file, not a folder" in line
    assert blocker.read_text() == "keep me"
    # a folder under a file cannot be created either
    with pytest.raises(OutputError, match="does not exist"):
        gen.output_directory(blocker / "sub")


def test_codegen_into_an_unwritable_folder(monkeypatch, tmp_path):
    # permissions do not bind every user (root): simulate the refusal of the file system
    monkeypatch.setattr(gen.os, "access", lambda path, mode: False)
    with pytest.raises(OutputError, match="not writable; choose another folder") as info:
        gen.output_directory(tmp_path / "out")
    assert info.value.path == str(tmp_path / "out")

    def refuse(self, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "mkdir", refuse)
    with pytest.raises(OutputError, match="cannot create the folder: Permission denied"):
        gen.output_directory(tmp_path / "other")


# ---------------------------------------------------------------------------- compiler


def test_compiler_from_cc_that_does_not_exist(monkeypatch, capsys, tmp_path):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    with pytest.raises(BuildError, match="'/nonexistent/cc' .from \\$CC=.*not found; set CC"):
        comp.compiler_command()
    # the command ends before the model is loaded or anything is written
    line = cli_error(capsys, ["codegen", HEXA, "--out", str(tmp_path / "gen")])
    assert "/nonexistent/cc" in line and "not found" in line
    assert not (tmp_path / "gen").exists()


def test_compiler_that_cannot_start_is_a_build_error(monkeypatch, tmp_path):
    monkeypatch.setattr(comp, "compiler_command", lambda: [str(tmp_path)])  # a folder
    with pytest.raises(BuildError, match="cannot run the C compiler"):
        comp.run_compiler(["x.c"])


@needs_compiler()
def test_compiler_with_bad_flags(monkeypatch, tmp_path):
    cc = comp.compiler_command()[0]
    monkeypatch.setenv("CC", f"{cc} -m32x")
    assert comp.compiler_command() == [cc, "-m32x"]  # $CC may carry flags
    src = tmp_path / "one.c"
    src.write_text("int one(void) { return 1; }\n")
    with pytest.raises(BuildError) as info:
        comp.compile_shared(src, tmp_path / "one.so")
    msg = str(info.value)
    assert "C compilation failed" in msg and "-m32x" in msg and "check $CC" in msg
    assert "\n" not in msg
    monkeypatch.setenv("CC", cc)
    assert comp.compile_shared(src, tmp_path / "one.so").exists()


# ---------------------------------------------------------------------------- Python API


def test_load_model_of_a_number():
    with pytest.raises(InputError, match="path must be a model directory .* got 123 of type int"):
        sc.load_model(123)


@pytest.mark.parametrize(
    ("base", "platform", "arm", "rod", "message"),
    [
        (np.zeros((3, 2)), np.zeros((3, 2)), 7.0, 7.0, "base_points are collinear or coincident"),
        ([[0, 0], [10, 0], [0, 10]], [[0, 0], [1, 0], [0, 1]], 5.0, 5.0, "coincides with"),
        ([[0, 0], [10, 0], [0, 10]], [[0, 0], [1, 0], [0, 1]], 0.0, 5.0, "arm must be a pos"),
    ],
    ids=["coincident points", "vertex on its base joint", "zero arm"],
)
def test_degenerate_planar_3rrr(base, platform, arm, rod, message):
    with pytest.raises(InputError, match=message):
        sc.builders.planar_3rrr(base, platform, arm, rod)


def test_solve_arguments():
    model = shipped("planar_hexa")
    with pytest.raises(InputError, match=r"theta0 \(theta_1, theta_2, theta_3\) must be 3 numbers"):
        sc.solve(model, None)
    with pytest.raises(InputError, match="max_arc must be a positive arc length, got -1"):
        sc.solve(model, SEED_THETA0, max_arc=-1)


# ---------------------------------------------------------------------------- model files


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "the file is empty"),
        ("closed_loop: []\n", "not valid XML"),
        (
            "<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'>"
            "<child link='b'/></joint></robot>",
            "joint 'j' has no <parent link=",
        ),
        ("<model name='r'/>", "root element is <model>, expected <robot>"),
    ],
    ids=["empty", "not XML", "joint without parent", "not a robot"],
)
def test_urdf_that_is_not_a_urdf(tmp_path, text, message):
    d = copy_model(tmp_path)
    (d / "robot.urdf").write_text(text)
    with pytest.raises(ModelError, match=message) as info:
        sc.load_model(d)
    assert str(d / "robot.urdf") in str(info.value) and "\n" not in str(info.value)
    assert "bytes" not in str(info.value)


def test_urdf_that_is_not_text(tmp_path):
    d = copy_model(tmp_path)
    (d / "robot.urdf").write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(ModelError, match="not a UTF-8 text file"):
        sc.load_model(d)


def test_fixed_joint_named_as_actuated(tmp_path):
    d = copy_model(tmp_path)
    edit_yaml(d, name_mot=["theta_1", "theta_2", "platform_joint"])
    with pytest.raises(UnknownNameError) as info:
        sc.load_model(d)
    msg = str(info.value)
    assert "'platform_joint' in 'name_mot' is a fixed joint" in msg
    assert "movable joints: theta_1, theta_2, theta_3, elbow_1" in msg
    assert info.value.name == "platform_joint" and "wrist_1" in info.value.valid


def test_over_actuated_model_is_refused_at_load(tmp_path):
    d = copy_model(tmp_path)
    edit_yaml(d, name_mot=["theta_1", "theta_2", "theta_3", "elbow_1"])
    with pytest.raises(NonSquareSystemError) as info:
        sc.load_model(d)
    msg = str(info.value)
    assert "over-actuated: 4 actuated joints" in msg and "3 degree(s) of freedom" in msg
    assert "remove 1 joint(s) from 'name_mot'" in msg and "\n" not in msg
    assert (info.value.rows, info.value.unknowns, info.value.rank) == (4, 3, 3)


# ---------------------------------------------------------------------------- CLI input


def test_empty_theta_field_is_refused(capsys):
    line = cli_error(capsys, ["solve", HEXA, "--theta=1.292,,-0.802,-2.896"])
    assert "--theta: empty value in '1.292,,-0.802,-2.896' (field 2)" in line


def test_semicolon_csv_names_the_delimiter(tmp_path):
    path = tmp_path / "readings.csv"
    path.write_text("1.292;-0.802;-2.896\n1.3;-0.8;-2.9\n")
    with pytest.raises(InputError, match="line 1 is separated by semicolons; expected commas"):
        read_thetas(str(path), shipped("planar_hexa"))
    path.write_text("theta_1\ttheta_2\ttheta_3\n1.292\t-0.802\t-2.896\n")
    with pytest.raises(InputError, match="separated by tabs; expected commas"):
        read_thetas(str(path), shipped("planar_hexa"))


def test_broken_pipe_ends_quietly(monkeypatch, capsys):
    class Closed:
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(sys, "stdout", Closed())
    assert main(["cache"]) == cli.EXIT_BROKEN_PIPE
    assert capsys.readouterr().err == ""


def test_broken_pipe_in_a_real_pipe():
    proc = subprocess.Popen(
        [sys.executable, "-m", "scdk_sym", "cache"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=ROOT,
    )
    proc.stdout.close()  # the reader went away before anything was written (| head -c 0)
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == cli.EXIT_BROKEN_PIPE
    assert err == ""


# ---------------------------------------------------------------------------- CLI output


def test_version_from_the_package_metadata(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"scdk_sym {importlib.metadata.version('scdk_sym')}"


def test_every_backend_option_has_help():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    seen = 0
    for name, p in sub.choices.items():
        for action in p._actions:
            if action.dest == "backend":
                seen += 1
                assert action.help, name
                for choice in action.metavar.strip("{}").split(","):
                    assert f"{choice}:" in action.help, (name, choice)
    assert seen >= 3


def test_header_names_the_robot_its_folder_and_units():
    delta = sc.load_model(FIXTURES / "5bar_linkage")
    assert cli.label(delta) == "onshape (5bar_linkage)"
    assert cli.header(shipped("planar_hexa")) == (
        "model planar_hexa: x = (x, y, phi) [cm, cm, rad] of 'platform'"
    )
    assert cli.header(shipped("stewart_gough")).startswith(
        "model stewart_gough: x = (x, y, z, roll, pitch, yaw) [m, m, m, rad, rad, rad]"
    )
    legs = shipped("stewart_gough").units
    assert {legs[a] for a in shipped("stewart_gough").actuated} == {"m"}
    assert "length_unit" in cli.THETA_HELP and "rad" in cli.THETA_HELP


def test_plot_without_matplotlib_says_how_to_install(monkeypatch, capsys, tmp_path):
    for name in list(sys.modules):
        if name == "matplotlib" or name.startswith("matplotlib."):
            monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    line = cli_error(capsys, ["plot", HEXA, "--theta", "1,2,3", "--out", str(tmp_path)])
    assert 'pip install "scdk_sym[plot]"' in line
    assert list(tmp_path.iterdir()) == []
    assert issubclass(PlotError, ScdkError)


def test_save_onto_a_file(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("keep me")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        shipped("planar_hexa").save(blocker)
    with pytest.raises(OutputError, match="cannot save the model"):
        shipped("planar_hexa").save(blocker / "sub")
    assert blocker.read_text() == "keep me"
    with pytest.raises(ModelError, match="not found: expected a model directory"):
        sc.load_model(tmp_path / "no_such_model")


def test_help_for_a_model_states_its_units(monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "400")  # no wrapping
    with pytest.raises(SystemExit) as info:
        main(["solve", HEXA, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "this model: theta_1 [rad], theta_2 [rad], theta_3 [rad]" in out
    assert "this model: x [cm], y [cm], phi [rad]" in out
    with pytest.raises(SystemExit):
        main(["solve", str(MODELS / "no_such_model"), "--help"])  # generic help
    assert "this model" not in capsys.readouterr().out
