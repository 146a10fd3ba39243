"""The C templates of the tracker (scdk_sym/codegen/c, package data) and their filling."""

import fnmatch
import re
import subprocess

import pytest
from factories import ROOT, shipped

from scdk_sym.codegen import templates
from scdk_sym.codegen.generate import generate
from scdk_sym.errors import BuildError, ScdkError
from scdk_sym.kernels.compile import compiler

TEMPLATE_DIR = ROOT / "scdk_sym" / "codegen" / "c"
STRICT = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror"]


def _compiler() -> str:
    try:
        return compiler()
    except BuildError as exc:
        pytest.skip(f"no C compiler to build the generated tracker: {exc}")


@pytest.fixture(scope="module")
def planar(tmp_path_factory):
    """Generated sources of models/planar_hexa (no floating joint)."""
    return generate(shipped("planar_hexa"), tmp_path_factory.mktemp("planar_hexa"))


def test_generated_tracker_compiles_with_wall_wextra_werror(planar):
    cc = _compiler()
    for source in planar.sources:
        proc = subprocess.run(
            [cc, *STRICT, "-c", str(source), "-o", str(source.with_suffix(".o"))],
            capture_output=True,
            text=True,
            cwd=planar.directory,
        )
        assert proc.returncode == 0, (source.name, proc.stderr)
        assert proc.stderr == "", (source.name, proc.stderr)


def test_every_placeholder_is_filled(planar):
    for path in (planar.tracker_c, planar.tracker_h):
        left = re.findall(r"@[A-Z_]+@", path.read_text())
        assert left == [], (path.name, left)
    model = shipped("planar_hexa")
    header = planar.tracker_h.read_text()
    assert f"#define SCDK_NY {model.m}\n" in header and "#define SCDK_NC 0\n" in header
    assert "int scdk_tracker_step(scdk_state *st" in header


def test_templates_are_the_package_data_files():
    names = sorted(p.name for p in TEMPLATE_DIR.iterdir() if p.is_file())
    from scdk_sym.solvers import transmission_c

    assert names == sorted(
        [templates.HEADER, templates.SOURCE, transmission_c.HEADER, transmission_c.SOURCE]
    )
    for name in names:
        assert templates.template(name) == (TEMPLATE_DIR / name).read_text()
    # shipped by a non-editable install: matched by the package-data patterns
    tomllib = pytest.importorskip("tomllib", reason="reading pyproject.toml needs Python 3.11")
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["scdk_sym"]
    for name in names:
        assert any(fnmatch.fnmatch(f"codegen/c/{name}", pat) for pat in patterns), name


def test_a_placeholder_without_a_value_is_a_build_error():
    text = "#define @PU@_NY @NY@\n"
    assert templates.fill(text, {"PU": "AB", "NY": "3"}) == "#define AB_NY 3\n"
    with pytest.raises(BuildError, match="NY") as info:
        templates.fill(text, {"PU": "AB"})
    assert isinstance(info.value, ScdkError)


def test_a_missing_template_is_a_build_error():
    with pytest.raises(BuildError, match="reinstall scdk_sym"):
        templates.template("absent.c.in")
