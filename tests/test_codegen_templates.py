"""The C templates of the tracker (package data: codegen/c and the parts beside their Python
twins) and their filling."""

import fnmatch
import re
import subprocess

import pytest
from factories import ROOT, shipped

from scdk_sym.codegen import templates
from scdk_sym.codegen.generate import generate
from scdk_sym.codegen.status import STATUS, SweepCode, TrackerStatus
from scdk_sym.errors import BuildError, ScdkError
from scdk_sym.kernels.compile import compiler

PACKAGE = ROOT / "scdk_sym"
TEMPLATE_DIR = PACKAGE / "codegen" / "c"
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
    from scdk_sym.solvers import transmission_c

    names = sorted(p.name for p in TEMPLATE_DIR.iterdir() if p.is_file())
    parts = [templates.HEADER_PART, *templates.SOURCE_PARTS]
    own = [part.name for part in parts if part.folder == templates.FOLDER]
    assert names == sorted(own)
    assert templates.SOURCE_PARTS[0] == (templates.FOLDER, templates.SOURCE)
    assert templates.HEADER_PART == (templates.FOLDER, templates.HEADER)
    # every template part of the package is one of the parts, each beside its Python twin
    found = sorted(p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*.c.in"))
    assert found == sorted(
        [part.path for part in parts if part.name.endswith(".c.in")]
        + [f"{transmission_c.FOLDER}/{transmission_c.SOURCE}"]
    )
    for part in parts:
        assert templates.template(part.name, part.folder) == (PACKAGE / part.path).read_text()
        if part.folder != templates.FOLDER:
            assert (PACKAGE / part.folder / part.name.replace(".c.in", ".py")).is_file(), part
    for name in names:
        assert templates.template(name) == (TEMPLATE_DIR / name).read_text()
    # shipped by a non-editable install: matched by the package-data patterns
    tomllib = pytest.importorskip("tomllib", reason="reading pyproject.toml needs Python 3.11")
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["scdk_sym"]
    transmission = [
        f"{transmission_c.FOLDER}/{n}" for n in (transmission_c.HEADER, transmission_c.SOURCE)
    ]
    assert (PACKAGE / transmission_c.FOLDER / "transmission.py").is_file()  # its Python twin
    for name in (transmission_c.HEADER, transmission_c.SOURCE):
        text = templates.template(name, transmission_c.FOLDER)
        assert text == (PACKAGE / transmission_c.FOLDER / name).read_text()
    paths = [*(part.path for part in parts), *(f"codegen/c/{name}" for name in names)]
    for path in [*paths, *transmission]:
        assert any(fnmatch.fnmatch(path, pat) for pat in patterns), path


def test_a_placeholder_without_a_value_is_a_build_error():
    text = "#define @PU@_NY @NY@\n"
    assert templates.fill(text, {"PU": "AB", "NY": "3"}) == "#define AB_NY 3\n"
    with pytest.raises(BuildError, match="NY") as info:
        templates.fill(text, {"PU": "AB"})
    assert isinstance(info.value, ScdkError)


def test_a_missing_template_is_a_build_error():
    with pytest.raises(BuildError, match="reinstall scdk_sym"):
        templates.template("absent.c.in")


def test_the_source_is_its_parts_in_order(planar):
    text = planar.tracker_c.read_text()
    assert text.startswith("/* scdk_tracker.c: standalone")
    heads = [
        templates.template(part.name, part.folder).splitlines()[0].replace("@P@", "scdk")
        for part in templates.SOURCE_PARTS
    ]
    at = [text.index(head) for head in heads]
    assert at == sorted(at) and len(set(heads)) == len(heads)
    for part in templates.SOURCE_PARTS:  # one idea per file
        assert len(templates.template(part.name, part.folder).splitlines()) < 500, part


def test_status_codes_come_from_one_table(planar):
    """The header's codes and the status strings are those of TrackerStatus and SweepCode."""
    header = planar.tracker_h.read_text()
    defined = dict(re.findall(r"#define SCDK_(\w+) \(?(-?\d+)\)? +/\*", header))
    expected = {code.name: str(int(code)) for code in TrackerStatus}
    expected.update({f"SWEEP_{code.name}": str(int(code)) for code in SweepCode})
    assert defined == expected
    source = planar.tracker_c.read_text()
    for code in TrackerStatus:
        assert re.search(rf'case SCDK_{code.name}:\s+return "{re.escape(code.message)}";', source)
    from scdk_sym.codegen import library
    from scdk_sym.solvers import track

    assert library.STATUS is STATUS and STATUS[-9] == TrackerStatus.ERR_UNDECIDABLE.message
    assert library.ERR_UNDECIDABLE is track.ERR_UNDECIDABLE is TrackerStatus(-9)
    assert library.SWEEP_DIRECT is SweepCode.DIRECT and library.OK_PATH == 1
