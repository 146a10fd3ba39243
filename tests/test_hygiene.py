"""The test session itself: a private kernel cache, compile tests skipped without a compiler,
and the package clean for mypy and ruff (skipped only when the tool is not installed)."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from factories import compiler_missing, needs_compiler

from scdk_sym.kernels import compile as comp
from scdk_sym.kernels.cache import cache_dir


def test_cache_is_private_to_the_session(private_cache):
    user = Path(os.path.expanduser("~")) / ".cache" / "scdk_sym"
    assert cache_dir() == private_cache
    assert private_cache.resolve() != user.resolve()
    assert user.resolve() not in private_cache.resolve().parents
    # processes started by tests (the scdk command) see it too
    out = subprocess.run(
        [sys.executable, "-c", "from scdk_sym.kernels.cache import cache_dir; print(cache_dir())"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout.strip()
    assert out == str(private_cache)


def test_skip_helper_names_a_missing_compiler(monkeypatch):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    reason = compiler_missing()
    assert reason is not None and "/nonexistent/cc" in reason and "not found" in reason
    mark = needs_compiler()
    assert mark.name == "skipif" and mark.args == (True,) and mark.kwargs["reason"] == reason
    # without $CC and nothing on the PATH
    monkeypatch.delenv("CC")
    monkeypatch.setattr(comp.shutil, "which", lambda name: None)
    assert "no C compiler found" in compiler_missing()


def test_skip_helper_lets_compile_tests_run_with_a_compiler(monkeypatch):
    monkeypatch.setenv("CC", sys.executable)  # any executable passes the check
    assert compiler_missing() is None
    assert needs_compiler().args == (False,)


@pytest.mark.parametrize("module", ["test_compile", "test_codegen", "test_track_c"])
def test_compile_modules_use_the_helper(module):
    text = (Path(__file__).parent / f"{module}.py").read_text()
    assert "needs_compiler()" in text


def test_compile_tests_skip_when_cc_is_missing(tmp_path):
    env = dict(os.environ, CC="/nonexistent/cc")
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider",
         str(Path(__file__).parent / "test_compile.py")],
        capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-2000:]
    assert "failed" not in proc.stdout and "passed" not in proc.stdout
    assert "SKIPPED" in proc.stdout and "/nonexistent/cc" in proc.stdout


ROOT = Path(__file__).resolve().parents[1]


def _tool(name: str) -> list[str]:
    """The command running ``name`` from this environment, or a skip when it is missing."""
    if importlib.util.find_spec(name) is not None:
        return [sys.executable, "-m", name]
    found = shutil.which(name)
    if found is None:
        pytest.skip(f"{name} is not installed: pip install '.[test]'")
    return [found]


def test_mypy_is_clean():
    # the configuration in pyproject.toml; its cache (.mypy_cache) keeps reruns to seconds
    proc = subprocess.run([*_tool("mypy")], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "Success: no issues found" in proc.stdout


@pytest.mark.parametrize("args", [["check", "."], ["format", "--check", "."]])
def test_ruff_is_clean(args):
    proc = subprocess.run(
        [*_tool("ruff"), *args], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]


# ---------------------------------------------------------------- the one cache of products

PACKAGE = ROOT / "scdk_sym"


def _dict_writers(root: Path) -> list[str]:
    """``file:line`` of every ``__dict__`` use in the sources under ``root``."""
    return [
        f"{f.relative_to(root)}:{n}"
        for f in sorted(root.rglob("*.py"))
        for n, line in enumerate(f.read_text().splitlines(), 1)
        if "__dict__" in line
    ]


def test_products_are_stored_only_through_the_declared_cache(tmp_path):
    # the scan finds a writer in a file written for it ...
    probe = tmp_path / "pkg" / "probe.py"
    probe.parent.mkdir()
    probe.write_text("def f(form):\n    form.model.__dict__['_x'] = 1\n")
    assert _dict_writers(tmp_path) == [str(Path("pkg") / "probe.py") + ":2"]
    # ... and none in the package: every product goes through model.products
    assert _dict_writers(PACKAGE) == [], "use model.products.get(KEY, build) (scdk_sym.products)"


def test_every_declared_product_key_is_used():
    import ast

    from scdk_sym import products

    declared = {n for n, v in vars(products).items() if isinstance(v, products.Key)}
    assert {getattr(products, n).name for n in declared} == set(products.KEYS)
    used: set[str] = set()
    for f in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").endswith("products"):
                used.update(a.name for a in node.names)
    assert declared - used == set(), "declared product keys that no module uses"
    for key in products.KEYS.values():
        assert key.holds and key.depends, key


#: The module-level tables the package may fill (memos, a registry), none of them a product
#: of one model (those go through ``model.products``) -> why it is kept per process.
PROCESS_MEMOS = {
    "kernels/curve.py:_SOLVERS": "the linear-solve Function of a sparsity pattern, any model",
    "kernels/curve.py:_LOOP_SOLVERS": "the loop-QR solve Function of a sparsity pattern, any model",
    "atlases/store.py:_OPEN": "the atlas stores this process has open",
    "atlases/chunk.py:_MODELS": "a worker's models, rebuilt from their sources once per process",
    "algebraic/certify/square.py:_SQUARES": "square systems of CasADi Functions, by identity",
    "algebraic/interval.py:_CACHE": "interval translations of CasADi Functions, by identity",
    "algebraic/certify/krawczyk_c.py:_LIBRARIES": "the loaded interval library, per SIMD flags",
    "cli/common.py:COMMANDS": "the subcommands' registry, filled as their modules import",
}


def _module_memos(root: Path) -> set[str]:
    """``file:name`` of every module-level empty dict or function cache under ``root``."""
    import ast

    found = set()
    for f in sorted(root.rglob("*.py")):
        for node in ast.parse(f.read_text()).body:
            value = node.value if isinstance(node, (ast.Assign, ast.AnnAssign)) else None
            targets = (
                node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
            )
            empty = isinstance(value, ast.Dict) and not value.keys
            call = isinstance(value, ast.Call) and getattr(value.func, "id", "") in (
                "dict", "OrderedDict", "FunctionCache", "WeakKeyDictionary", "WeakValueDictionary"
            )  # fmt: skip
            if empty or call:
                found.update(
                    f"{f.relative_to(root).as_posix()}:{t.id}"
                    for t in targets
                    if isinstance(t, ast.Name)
                )
    return found


def test_no_module_level_cache_holds_a_model_s_product(tmp_path):
    """One cache of model products (``model.products``); the only other memos are listed, each
    with the reason it is per process."""
    probe = tmp_path / "pkg" / "probe.py"
    probe.parent.mkdir()
    probe.write_text("_BY_MODEL: dict[str, object] = {}\nTABLE = {'a': 1}\n")
    assert _module_memos(tmp_path) == {"pkg/probe.py:_BY_MODEL"}
    assert _module_memos(PACKAGE) == set(PROCESS_MEMOS), "use model.products.get(KEY, build)"


#: The longest function the package may hold [lines, docstring included].
MAX_FUNCTION_LINES = 100


def test_no_function_is_longer_than_100_lines():
    """Small steps: every function and method of the package fits in 100 lines (the curve
    follower's walk was one function of 438)."""
    import ast

    import scdk_sym

    long = []
    for f in sorted(Path(scdk_sym.__path__[0]).rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{f.name}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, long
