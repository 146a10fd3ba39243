"""The package's shape, measured from its sources and held by a ratchet.

Five measures over every ``.py`` file of ``scdk_sym``, read with :mod:`ast` (nothing is
imported):

* **Import cycles between modules.** A node is a module: a ``.py`` file, a package being its
  ``__init__.py`` under the package's name. Every ``import`` and ``from ... import`` statement
  of a file is an edge, wherever it stands (module level, inside a function or a class, under
  ``try``), except the ones under ``if TYPE_CHECKING:``: those never run, so they cannot take
  part in an import cycle. ``import a.b.c`` goes to ``a.b.c``; ``from a.b import c`` goes to
  the module ``a.b.c`` when ``c`` is a module of the package, otherwise to ``a.b``; relative
  imports are resolved against the file's package. The parent packages Python imports on the
  way (``a``, ``a.b``) are not edges: a package's ``__init__`` that imports its own modules
  would otherwise be in a cycle with each of them. Modules loaded by name at run time
  (``importlib.import_module``) are not seen. A cycle is a strongly connected component of two
  modules or more, named by its sorted modules (an import of a module by itself is ignored).
* **Files over 500 lines** (every line counts).
* **Classes over 300 lines**, from the ``class`` line to the class's last line (decorators not
  counted).
* **Functions and methods over 80 lines**, from the ``def`` line to the function's last line,
  decorators and the docstring's lines not counted. A nested function is measured on its own,
  and its lines also count in the function around it.
* **Functions and methods with more than 10 parameters.** Every parameter counts once:
  positional-only, ordinary, keyword-only, ``*args`` and ``**kwargs`` (one each); a first
  parameter named ``self`` or ``cls`` does not count.

Functions and classes are named ``path::qualified.name``, the path relative to the package
folder. Two definitions of one name (a property and its setter, ``typing.overload``) are one
entry, measured by the larger.

Each measure is held by a ratchet: its allow-list below holds today's offenders with their
size. A test fails when a new offender appears, when an allowed one grows, and when an
allowed one no longer offends (then its entry has to go: "remove X from the allow-list"). An
offender that shrinks but still offends passes; regenerating the lists locks the smaller size.

``python -m tests.test_layout`` (from the project's root) prints the counts and the allow-lists
of the current tree in this file's syntax; ``python -m tests.test_layout --write`` also writes
them into this file, between the two marker comments.
"""

from __future__ import annotations

import ast
import sys
from collections import deque
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "scdk_sym"

#: The limits: a file, a class, a function [lines], a function's parameters.
MAX_FILE_LINES = 500
MAX_CLASS_LINES = 300
MAX_FUNCTION_LINES = 80
MAX_PARAMETERS = 10

# ---- allow-lists: written by `python -m tests.test_layout --write` ----

#: Today's import cycles, each the sorted modules of one strongly connected component.
ALLOWED_CYCLES: list[tuple[str, ...]] = []

#: Today's files over MAX_FILE_LINES -> lines.
ALLOWED_LONG_FILES: dict[str, int] = {}

#: Today's classes over MAX_CLASS_LINES -> lines.
ALLOWED_LONG_CLASSES: dict[str, int] = {}

#: Today's functions over MAX_FUNCTION_LINES -> lines (docstring not counted).
ALLOWED_LONG_FUNCTIONS: dict[str, int] = {}

#: Today's functions over MAX_PARAMETERS -> parameters.
ALLOWED_MANY_PARAMETERS: dict[str, int] = {}

# ---- end of allow-lists ----


# ------------------------------------------------------------------------------ measuring


@dataclass
class Shape:
    """The measures of one package's sources (see the module's docstring for the rules)."""

    #: Module -> the package's modules it imports.
    imports: dict[str, set[str]] = field(default_factory=dict)
    #: File -> lines.
    files: dict[str, int] = field(default_factory=dict)
    #: ``path::Class`` -> lines.
    classes: dict[str, int] = field(default_factory=dict)
    #: ``path::function`` -> lines, docstring not counted.
    functions: dict[str, int] = field(default_factory=dict)
    #: ``path::function`` -> parameters.
    parameters: dict[str, int] = field(default_factory=dict)

    @property
    def cycles(self) -> list[tuple[str, ...]]:
        return import_cycles(self.imports)


def _module_name(path: Path, root: Path) -> str:
    """The dotted name of the module in ``path`` (a package's ``__init__`` is the package)."""
    parts = [root.name, *path.relative_to(root).with_suffix("").parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_type_checking(test: ast.expr) -> bool:
    """``TYPE_CHECKING`` or ``typing.TYPE_CHECKING``."""
    if isinstance(test, ast.Name):
        return test.id == "TYPE_CHECKING"
    return isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"


def _running_imports(node: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    """Every import statement under ``node``, except those under ``if TYPE_CHECKING:``."""
    found: list[ast.Import | ast.ImportFrom] = []
    todo: list[ast.AST] = [node]
    while todo:
        here = todo.pop()
        if isinstance(here, ast.Import | ast.ImportFrom):
            found.append(here)
        elif isinstance(here, ast.If) and _is_type_checking(here.test):
            todo.extend(here.orelse)
        else:
            todo.extend(ast.iter_child_nodes(here))
    return found


def _imported_modules(tree: ast.Module, module: str, is_package: bool, known: set[str]) -> set[str]:
    """The modules of ``known`` that the running imports of ``module``'s source ``tree`` load."""
    package = module.split(".") if is_package else module.split(".")[:-1]
    top = module.split(".")[0]

    def resolve(name: str) -> str | None:
        # the module itself, or the closest package above it that the package holds
        parts = name.split(".")
        while parts and ".".join(parts) not in known:
            parts.pop()
        return ".".join(parts) if parts else None

    targets: set[str | None] = set()
    for node in _running_imports(tree):
        if isinstance(node, ast.Import):
            targets.update(resolve(a.name) for a in node.names if a.name.split(".")[0] == top)
            continue
        base = package[: len(package) - node.level + 1] if node.level else []
        source = ".".join([*base, *(node.module.split(".") if node.module else [])])
        if source.split(".")[0] != top:
            continue
        for alias in node.names:
            child = f"{source}.{alias.name}"
            targets.add(child if child in known else resolve(source))
    return {t for t in targets if t is not None and t != module}


def _docstring_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    first = node.body[0]
    if (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
    ):
        return (first.end_lineno or first.lineno) - first.lineno + 1
    return 0


def _parameter_count(args: ast.arguments) -> int:
    named = [*args.posonlyargs, *args.args]
    count = len(named) + len(args.kwonlyargs) + (args.vararg is not None)
    count += args.kwarg is not None
    if named and named[0].arg in ("self", "cls"):
        count -= 1
    return count


def _measure_definitions(tree: ast.Module, path: str, shape: Shape) -> None:
    """Add the classes, functions and methods of one file's ``tree`` to ``shape``."""
    todo: list[tuple[ast.AST, str]] = [(tree, "")]
    while todo:
        node, prefix = todo.pop()
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                name = f"{prefix}{child.name}"
                key = f"{path}::{name}"
                span = (child.end_lineno or child.lineno) - child.lineno + 1
                if isinstance(child, ast.ClassDef):
                    shape.classes[key] = max(span, shape.classes.get(key, 0))
                else:
                    lines = span - _docstring_lines(child)
                    shape.functions[key] = max(lines, shape.functions.get(key, 0))
                    count = _parameter_count(child.args)
                    shape.parameters[key] = max(count, shape.parameters.get(key, 0))
                todo.append((child, f"{name}."))
            else:
                todo.append((child, prefix))


def measure(root: Path) -> Shape:
    """The measures of the package whose folder is ``root`` (its name is the package's)."""
    files = sorted(root.rglob("*.py"))
    modules = {_module_name(f, root): f for f in files}
    known = set(modules)
    shape = Shape()
    for module, f in modules.items():
        text = f.read_text()
        tree = ast.parse(text, filename=str(f))
        path = f.relative_to(root).as_posix()
        shape.files[path] = len(text.splitlines())
        is_package = f.name == "__init__.py"
        shape.imports[module] = _imported_modules(tree, module, is_package, known)
        _measure_definitions(tree, path, shape)
    return shape


def import_cycles(graph: dict[str, set[str]]) -> list[tuple[str, ...]]:
    """The strongly connected components of more than one node, each sorted, in order."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[tuple[str, ...]] = []

    def visit(node: str) -> None:  # Tarjan's algorithm
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(graph.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                found.append(tuple(sorted(component)))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(found)


def cycle_path(graph: dict[str, set[str]], component: tuple[str, ...]) -> list[str]:
    """A shortest import cycle through the first module of ``component``, as a path."""
    start, inside = component[0], set(component)
    came_from: dict[str, str] = {}
    queue = deque([start])
    while queue:
        node = queue.popleft()
        for nxt in sorted(graph.get(node, set()) & inside):
            if nxt == start:
                path = [node]
                while path[-1] != start:
                    path.append(came_from[path[-1]])
                return [*reversed(path), start]
            if nxt not in came_from:
                came_from[nxt] = node
                queue.append(nxt)
    return [start]


@cache
def package_shape() -> Shape:
    return measure(PACKAGE)


# -------------------------------------------------------------------------------- ratchet


def over(sizes: dict[str, int], limit: int) -> dict[str, int]:
    """The entries of ``sizes`` above ``limit``, sorted by name."""
    return {k: v for k, v in sorted(sizes.items()) if v > limit}


def ratchet(
    list_name: str, sizes: dict[str, int], limit: int, allowed: dict[str, int]
) -> list[str]:
    """What breaks the ratchet: new offenders, grown ones, allowed entries that no longer
    offend."""
    problems = []
    for key, size in over(sizes, limit).items():
        if key not in allowed:
            problems.append(f"{key}: {size} > {limit} (new; make it smaller)")
        elif size > allowed[key]:
            problems.append(f"{key}: grew from {allowed[key]} to {size} (limit {limit})")
    for key in sorted(allowed):
        if sizes.get(key, 0) <= limit:
            now = "is gone" if key not in sizes else f"is {sizes[key]} <= {limit}"
            problems.append(f"{key} {now}: remove {key!r} from the allow-list {list_name}")
    return problems


def cycle_ratchet(graph: dict[str, set[str]], allowed: list[tuple[str, ...]]) -> list[str]:
    """What breaks the ratchet of import cycles (an allowed cycle matches exactly)."""
    current = set(import_cycles(graph))
    known = {tuple(sorted(c)) for c in allowed}
    new, gone = sorted(current - known), sorted(known - current)
    problems = []
    for component in new:
        path = " -> ".join(cycle_path(graph, component))
        wider = [g for g in gone if set(component) < set(g)]
        if wider:
            problems.append(
                f"the allowed cycle {wider[0]} is now {component} ({path}): replace it in "
                "the allow-list ALLOWED_CYCLES"
            )
        else:
            problems.append(f"new import cycle {component}, for instance {path}")
    for component in gone:
        if not any(set(c) < set(component) for c in new):
            problems.append(f"remove {component} from the allow-list ALLOWED_CYCLES")
    return problems


# ---------------------------------------------------------------------------------- tests


def test_no_new_import_cycle() -> None:
    shape = package_shape()
    assert len(shape.imports) >= 50  # the walk saw the package
    problems = cycle_ratchet(shape.imports, ALLOWED_CYCLES)
    assert not problems, "\n".join(problems)


def test_no_new_file_over_500_lines() -> None:
    problems = ratchet(
        "ALLOWED_LONG_FILES", package_shape().files, MAX_FILE_LINES, ALLOWED_LONG_FILES
    )
    assert not problems, "\n".join(problems)


def test_no_new_class_over_300_lines() -> None:
    problems = ratchet(
        "ALLOWED_LONG_CLASSES", package_shape().classes, MAX_CLASS_LINES, ALLOWED_LONG_CLASSES
    )
    assert not problems, "\n".join(problems)


def test_no_new_function_over_80_lines() -> None:
    problems = ratchet(
        "ALLOWED_LONG_FUNCTIONS",
        package_shape().functions,
        MAX_FUNCTION_LINES,
        ALLOWED_LONG_FUNCTIONS,
    )
    assert not problems, "\n".join(problems)


def test_no_new_function_with_over_10_parameters() -> None:
    problems = ratchet(
        "ALLOWED_MANY_PARAMETERS",
        package_shape().parameters,
        MAX_PARAMETERS,
        ALLOWED_MANY_PARAMETERS,
    )
    assert not problems, "\n".join(problems)


def test_allow_lists_are_sorted_and_hold_offenders_only() -> None:
    assert sorted(ALLOWED_CYCLES) == ALLOWED_CYCLES
    assert all(list(c) == sorted(set(c)) and len(c) > 1 for c in ALLOWED_CYCLES)
    for allowed, limit in (
        (ALLOWED_LONG_FILES, MAX_FILE_LINES),
        (ALLOWED_LONG_CLASSES, MAX_CLASS_LINES),
        (ALLOWED_LONG_FUNCTIONS, MAX_FUNCTION_LINES),
        (ALLOWED_MANY_PARAMETERS, MAX_PARAMETERS),
    ):
        assert list(allowed) == sorted(allowed)
        assert all(size > limit for size in allowed.values())


def _body(lines: int) -> str:
    return "".join(f"    x{i} = {i}\n" for i in range(lines))


def test_measures_of_a_package_written_for_the_test(tmp_path: Path) -> None:
    root = tmp_path / "pkg"
    (root / "sub").mkdir(parents=True)
    (root / "__init__.py").write_text("from . import a\n")
    # a <-> b through an import inside a function; c -> b only under TYPE_CHECKING
    (root / "a.py").write_text("import os\n\n\ndef f():\n    from .sub import b\n    return b\n")
    (root / "sub" / "__init__.py").write_text("")
    (root / "sub" / "b.py").write_text(
        "from typing import TYPE_CHECKING\n\nfrom .. import a\nfrom . import c\n"
    )
    (root / "sub" / "c.py").write_text(
        "import typing\n\nif typing.TYPE_CHECKING:\n    from pkg.sub import b\nelse:\n"
        "    import pkg.long\n"
    )
    long = '    """A docstring\n\n    of three lines."""\n' + _body(80)  # 1 + 3 + 80 lines
    (root / "long.py").write_text(
        f"def long():\n{long}\n\n"
        f"def short():\n{_body(79)}\n\n"
        "def many(a, b, /, c, d, *args, e, f, g, h, i, **kw):\n    pass\n\n\n"
        "class Ten:\n"
        "    def method(self, a, b, c, d, e, f, g, h, i, j):\n        pass\n\n"
        "    @property\n    def x(self):\n        return 1\n\n"
        "    @x.setter\n    def x(self, value):\n        def inner():\n            pass\n"
    )
    shape = measure(root)
    assert shape.imports == {
        "pkg": {"pkg.a"},
        "pkg.a": {"pkg.sub.b"},
        "pkg.sub": set(),
        "pkg.sub.b": {"pkg.a", "pkg.sub.c"},
        "pkg.sub.c": {"pkg.long"},
        "pkg.long": set(),
    }
    assert shape.cycles == [("pkg.a", "pkg.sub.b")]
    assert cycle_path(shape.imports, ("pkg.a", "pkg.sub.b")) == ["pkg.a", "pkg.sub.b", "pkg.a"]
    assert shape.files["long.py"] == 184 and shape.files["a.py"] == 6
    assert shape.files["sub/__init__.py"] == 0
    assert shape.classes == {"long.py::Ten": 12}
    assert shape.functions == {
        "a.py::f": 3,
        "long.py::long": 81,
        "long.py::short": 80,
        "long.py::many": 2,
        "long.py::Ten.method": 2,
        "long.py::Ten.x": 3,
        "long.py::Ten.x.inner": 2,
    }
    assert over(shape.functions, MAX_FUNCTION_LINES) == {"long.py::long": 81}
    assert over(shape.parameters, MAX_PARAMETERS) == {"long.py::many": 11}
    assert shape.parameters["long.py::Ten.method"] == 10
    assert shape.parameters["long.py::Ten.x"] == 1
    # the ratchet: an allowed offender grown, one no longer offending, a new one, one gone
    assert ratchet("L", shape.functions, 80, {"long.py::long": 80, "a.py::f": 90}) == [
        "long.py::long: grew from 80 to 81 (limit 80)",
        "a.py::f is 3 <= 80: remove 'a.py::f' from the allow-list L",
    ]
    assert ratchet("L", shape.parameters, 10, {}) == [
        "long.py::many: 11 > 10 (new; make it smaller)"
    ]
    assert ratchet("L", shape.parameters, 10, {"gone.py::g": 12, "long.py::many": 11}) == [
        "gone.py::g is gone: remove 'gone.py::g' from the allow-list L"
    ]
    assert ratchet("L", shape.functions, 80, {"long.py::long": 82}) == []  # shrank, offends
    assert cycle_ratchet(shape.imports, []) == [
        "new import cycle ('pkg.a', 'pkg.sub.b'), for instance pkg.a -> pkg.sub.b -> pkg.a"
    ]
    assert cycle_ratchet(shape.imports, [("pkg.a", "pkg.sub.b")]) == []
    assert cycle_ratchet(shape.imports, [("pkg.a", "pkg.sub.b", "pkg.sub.c")]) == [
        "the allowed cycle ('pkg.a', 'pkg.sub.b', 'pkg.sub.c') is now ('pkg.a', 'pkg.sub.b') "
        "(pkg.a -> pkg.sub.b -> pkg.a): replace it in the allow-list ALLOWED_CYCLES"
    ]
    assert cycle_ratchet({"x": set()}, [("x", "y")]) == [
        "remove ('x', 'y') from the allow-list ALLOWED_CYCLES"
    ]


# ------------------------------------------------------------------------- regenerating

_BEGIN = "# ---- allow-lists: written by"
_END = "# ---- end of allow-lists ----"


def _dict_source(name: str, comment: str, entries: dict[str, int]) -> str:
    lines = [f"#: {comment}", f"{name}: dict[str, int] = {{"]
    lines += [f'    "{key}": {size},' for key, size in entries.items()]
    return "\n".join([*lines, "}"]) if entries else f"#: {comment}\n{name}: dict[str, int] = {{}}"


def _cycles_source(cycles: list[tuple[str, ...]]) -> str:
    lines = [
        "#: Today's import cycles, each the sorted modules of one strongly connected component.",
        "ALLOWED_CYCLES: list[tuple[str, ...]] = [",
    ]
    for cycle in cycles:
        flat = "    (" + ", ".join(f'"{m}"' for m in cycle) + "),"
        lines += (
            [flat] if len(flat) <= 100 else ["    (", *[f'        "{m}",' for m in cycle], "    ),"]
        )
    return (
        "\n".join([*lines, "]"])
        if cycles
        else lines[0] + "\nALLOWED_CYCLES: list[tuple[str, ...]] = []"
    )


def allow_lists_source(shape: Shape) -> str:
    """The allow-lists of ``shape`` in this file's syntax, markers included."""
    blocks = [
        "# ---- allow-lists: written by `python -m tests.test_layout --write` ----",
        _cycles_source(shape.cycles),
        _dict_source(
            "ALLOWED_LONG_FILES",
            "Today's files over MAX_FILE_LINES -> lines.",
            over(shape.files, MAX_FILE_LINES),
        ),
        _dict_source(
            "ALLOWED_LONG_CLASSES",
            "Today's classes over MAX_CLASS_LINES -> lines.",
            over(shape.classes, MAX_CLASS_LINES),
        ),
        _dict_source(
            "ALLOWED_LONG_FUNCTIONS",
            "Today's functions over MAX_FUNCTION_LINES -> lines (docstring not counted).",
            over(shape.functions, MAX_FUNCTION_LINES),
        ),
        _dict_source(
            "ALLOWED_MANY_PARAMETERS",
            "Today's functions over MAX_PARAMETERS -> parameters.",
            over(shape.parameters, MAX_PARAMETERS),
        ),
        _END,
    ]
    return "\n\n".join(blocks) + "\n"


def summary(shape: Shape) -> str:
    counts = (
        ("import cycles", len(shape.cycles)),
        (f"files over {MAX_FILE_LINES} lines", len(over(shape.files, MAX_FILE_LINES))),
        (f"classes over {MAX_CLASS_LINES} lines", len(over(shape.classes, MAX_CLASS_LINES))),
        (
            f"functions over {MAX_FUNCTION_LINES} lines",
            len(over(shape.functions, MAX_FUNCTION_LINES)),
        ),
        (
            f"functions over {MAX_PARAMETERS} parameters",
            len(over(shape.parameters, MAX_PARAMETERS)),
        ),
    )
    return "\n".join(f"# {name}: {count}" for name, count in counts)


def main(argv: list[str]) -> None:
    shape = measure(PACKAGE)
    source = allow_lists_source(shape)
    if "--write" in argv:
        path = Path(__file__)
        text = path.read_text()
        start, end = text.index(_BEGIN), text.index(_END) + len(_END) + 1
        path.write_text(text[:start] + source + text[end:])
    else:
        print(source)
    print(summary(shape))


if __name__ == "__main__":
    main(sys.argv[1:])
