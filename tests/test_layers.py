"""Imports run one way: description (scdk_sym.model) -> symbolic -> kernels -> robot -> ...

Over the whole package, every import (module level or inside a function) goes from a
subpackage or top-level module to one on a lower tier of :data:`TIERS`: no cycle, no
upward import.

Checked twice, independently: by importing a layer in a fresh interpreter and listing
``sys.modules``, and by reading every import statement of the layer's source (including the
imports inside functions, which the first check cannot see until they run).
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import scdk_sym as sc

PACKAGE = Path(sc.__path__[0])
MODELS = Path(__file__).resolve().parents[1] / "models"

#: Layer -> the package's modules it may import (besides itself).
ALLOWED = {
    "model": {"scdk_sym.errors", "scdk_sym.results", "scdk_sym.optional"},
    "symbolic": {"scdk_sym.errors", "scdk_sym.results", "scdk_sym.model"},
}


#: The package's subpackages and top-level modules, bottom tier first; an import goes only to
#: a lower tier (``<init>``: the package's ``__init__``, which loads the API on first use).
TIERS = (
    ("errors", "graphs"),
    ("interrupts", "products", "optional", "schema"),
    ("model",),
    ("results",),
    ("symbolic",),
    ("kernels",),
    ("backends",),
    ("robot",),
    ("follower", "drawing", "algebraic", "builders"),
    ("codegen",),
    ("solvers",),
    ("plot", "verify"),
    ("atlases", "view"),
    ("<init>",),
    ("cli",),
    ("__main__",),
)


def _unit(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "<init>"


def test_every_import_goes_to_a_lower_tier():
    rank = {u: i for i, tier in enumerate(TIERS) for u in tier}
    units, upward = set(), {}
    for f in sorted(PACKAGE.rglob("*.py")):
        rel = f.relative_to(PACKAGE.parent).with_suffix("")
        module = ".".join(p for p in rel.parts if p != "__init__")
        here = _unit(module)
        units.add(here)
        for target in _package_imports(f):
            there = _unit(target)
            if there != here and not rank.get(there, -1) < rank.get(here, -1):
                upward.setdefault(str(f.relative_to(PACKAGE)), []).append(target)
    assert units - set(rank) == set(), "place the new subpackage or module in TIERS"
    assert len(units) >= 20  # the walk saw the package
    assert not upward, upward


def _loaded_after(code: str) -> list[str]:
    """Module names in ``sys.modules`` after running ``code`` in a fresh interpreter."""
    script = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def _package_imports(path: Path) -> set[str]:
    """Every ``scdk_sym`` module imported anywhere in a source file (relative ones resolved)."""
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    package = parts if parts[-1] == "__init__" else parts[:-1]
    if package[-1] == "__init__":
        package = package[:-1]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            module = ".".join([*base, *(node.module.split(".") if node.module else [])])
            # "from . import x" imports the submodule x
            names = [module] if node.module else [f"{module}.{a.name}" for a in node.names]
        else:
            continue
        found.update(n for n in names if n == "scdk_sym" or n.startswith("scdk_sym."))
    return found


def test_description_imports_neither_casadi_nor_the_symbolic_layer():
    loaded = _loaded_after(
        "import scdk_sym.model, scdk_sym.model.files, scdk_sym.model.spec, "
        "scdk_sym.model.urdf, scdk_sym.model.chart\n"
        "from scdk_sym.model.files import read_description\n"
        f"tree, spec, _, _ = read_description({str(MODELS / 'planar_hexa')!r})\n"
        "assert spec.actuated == ('theta_1', 'theta_2', 'theta_3'), spec.actuated\n"
        "assert 'platform' in tree.links"
    )
    assert "scdk_sym.model.files" in loaded  # the check ran
    assert "casadi" not in loaded
    upper = [m for m in loaded if m.startswith("scdk_sym.") and m.split(".")[1] not in ALLOWED]
    assert not [m for m in upper if m not in ALLOWED["model"]], upper
    assert not [m for m in loaded if m.startswith("scdk_sym.symbolic")]


def test_symbolic_layer_imports_nothing_above_it():
    loaded = _loaded_after("import scdk_sym.symbolic.system, scdk_sym.symbolic.kinematics")
    assert "casadi" in loaded and "scdk_sym.symbolic.system" in loaded
    mine = {m for m in loaded if m.startswith("scdk_sym.")}
    above = {m for m in mine if m.split(".")[1] not in ("model", "symbolic", "errors", "results")}
    assert not above, sorted(above)


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_layer_sources_import_only_lower_layers(layer):
    files = sorted((PACKAGE / layer).glob("*.py"))
    assert files
    allowed = {*ALLOWED[layer], f"scdk_sym.{layer}"}
    bad = {}
    for f in files:
        wrong = {
            m
            for m in _package_imports(f)
            if not any(m == a or m.startswith(a + ".") for a in allowed)
        }
        if wrong:
            bad[f.name] = sorted(wrong)
    assert not bad, bad


def test_import_reader_sees_relative_and_function_level_imports(tmp_path):
    # the reader behind the source check, on a file written for it
    src = PACKAGE / "model" / "_probe_for_test.py"
    src.write_text(
        "from ..symbolic import system\nfrom . import spec\n"
        "def f():\n    from ..kernels.functions import build_kernels\n    import scdk_sym.cli\n"
    )
    try:
        found = _package_imports(src)
    finally:
        src.unlink()
    assert found == {
        "scdk_sym.symbolic",
        "scdk_sym.model.spec",
        "scdk_sym.kernels.functions",
        "scdk_sym.cli",
    }


def test_public_names_still_resolve():
    loaded = _loaded_after("import scdk_sym")
    assert "casadi" not in loaded  # the package itself loads its layers on first use
    for name in sc.__all__:
        assert getattr(sc, name) is not None
    assert {"load_model", "solve", "track", "assembly_modes", "builders", "atlas"} <= set(dir(sc))
    model = sc.load_model(MODELS / "planar_hexa")
    assert isinstance(model, sc.Model) and model.actuated == ("theta_1", "theta_2", "theta_3")
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        _ = sc.not_a_name


def test_atlas_is_the_function_and_its_subpackage_has_another_name():
    """``sc.atlas`` is the function whatever was imported before (its subpackage is
    ``scdk_sym.atlases``: no name is both), and the package is a plain module."""
    code = (
        "import types, scdk_sym as sc, scdk_sym.atlases.store\n"
        "from scdk_sym import atlas, open_atlas\n"
        "print(callable(sc.atlas), sc.atlas is atlas, sc.atlas.__module__, "
        "open_atlas.__module__, type(sc) is types.ModuleType)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == [
        "True", "True", "scdk_sym.atlases.run", "scdk_sym.atlases.store", "True"
    ]  # fmt: skip


def test_no_private_name_is_imported_from_another_module():
    crossing = {}
    for f in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module != "__future__":
                private = [a.name for a in node.names
                           if a.name.startswith("_") and not a.name.startswith("__")]  # fmt: skip
                if private:
                    crossing.setdefault(str(f.relative_to(PACKAGE)), []).extend(private)
    assert not crossing, crossing


def test_no_private_name_is_imported_across_modules():
    """A module's ``_private`` names stay its own: no ``from x import _name`` in the
    package (an alias such as ``import points as _points`` of a public name is fine)."""
    crossing = []
    for f in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module != "__future__":
                crossing += [
                    f"{f.relative_to(PACKAGE)}:{node.lineno} {node.module}.{a.name}"
                    for a in node.names
                    if a.name.startswith("_") and not a.name.startswith("__")
                ]
    assert not crossing, crossing
