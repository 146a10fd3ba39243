"""Code generation: kernels -> C sources -> shared library (gcc), cached by content hash.

The generated C of a model's kernels (``casadi.CodeGenerator``, one source file per group of
kernels, :func:`model_library`) is compiled once, the files in parallel
(:func:`compile_parallel`), into the cache directory and loaded with ``casadi.external``.
The compiled backend's library (:func:`compiled_library`) holds the model's kernels that its
solvers call and the curve follower's; :func:`compiled_kernels` returns a
:class:`~scdk_sym.kernels.functions.Kernels` with the same signatures. The kernels of one
source that evaluate the closures call one Function of them
(:func:`~scdk_sym.kernels.curve.closure_function`), written once in it; on a large model they
solve in loops and are MX Functions of calls (:func:`~scdk_sym.kernels.curve.compact`), so
that the generated C grows with the closures, not with the symbolic solves. The first
compilation for a model prints ``compiling kernels for MODEL...`` to stderr
(:func:`announce`).
"""

from __future__ import annotations

import hashlib
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Collection, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, fields
from pathlib import Path

import casadi as ca

from ..errors import BuildError
from ..products import COMPILED_LIBRARY
from .cache import cache_dir, cached_file
from .curve import closure_function
from .follower import FollowerKernels, build_follower_kernels
from .functions import Kernels, build_kernels

#: Optimisation level of every compiled library (``-O1``: the generated kernels are
#: straight-line code that ``-O2``/``-O3`` do not make measurably faster, at several times the
#: compile time; ``benchmarks/track_hexapod.py --opt`` measures both).
OPT = "-O1"
#: Optimisation level of hand-written numeric loops compiled beside the kernels (the C
#: tracker's fixed-size LU factorisations and solves): they vectorise at ``-O3``, where the
#: straight-line kernels gain nothing (``benchmarks/gepetto_legs.py``).
LOOP_OPT = "-O3"
#: Flags compiling one source into an object of a shared library.
COMPILE_FLAGS = (OPT, "-fPIC")
#: Flags linking the objects into a shared library.
LINK_FLAGS = ("-shared",)
CFLAGS = (*COMPILE_FLAGS, *LINK_FLAGS)
#: Package sources a model's kernels are built from (a folder: every module in it): the
#: description layer (URDF and spec parsing, chart, rotations), the symbolic layer, the kernel
#: definitions, the follower's kernels they call and this module (which of them it builds,
#: and how).
KERNEL_SOURCES = (
    "model",
    "symbolic",
    "kernels/functions.py",
    "kernels/compile.py",
    "kernels/curve.py",
    "kernels/follower.py",
    "follower/calls.py",
)
#: Root of the package, the folder the source lists are relative to.
PACKAGE_ROOT = Path(__file__).resolve().parents[1]
#: The package's one pivoted elimination in C (real and complex LU with partial pivoting),
#: included by every C source that eliminates (package data).
LU_HEADER = Path(__file__).resolve().parent / "c" / "scdk_lu.h"

_announced: set[str] = set()


def announce(name: str) -> None:
    """Print ``compiling kernels for NAME...`` to stderr, once per name and process (a first
    use that compiles takes seconds)."""
    if name not in _announced:
        _announced.add(name)
        print(f"compiling kernels for {name}...", file=sys.stderr, flush=True)


def jobs() -> int:
    """Compiler processes run at once: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def compiler_command() -> list[str]:
    """The C compiler command: ``$CC`` split like a shell (it may carry flags), else gcc or cc
    on the PATH.

    Raises:
        BuildError: ``$CC`` names no executable, or no compiler is on the PATH.
    """
    cc = os.environ.get("CC", "").strip()
    if cc:
        try:
            cmd = shlex.split(cc)
        except ValueError as exc:
            raise BuildError(f"$CC={cc!r} cannot be split into a command: {exc}") from exc
        if shutil.which(cmd[0]) is None:
            raise BuildError(
                f"C compiler {cmd[0]!r} (from $CC={cc!r}) not found; set CC to an installed "
                "compiler (e.g. CC=gcc) or unset it"
            )
        return cmd
    found = shutil.which("gcc") or shutil.which("cc")
    if not found:
        raise BuildError("no C compiler found: install gcc (e.g. apt-get install gcc) or set $CC")
    return [found]


def compiler() -> str:
    """The C compiler command as one string (``$CC`` or gcc/cc on the PATH)."""
    return shlex.join(compiler_command())


def run_compiler(args: Sequence[str], cwd: Path | None = None) -> None:
    """Run the C compiler with ``args`` (sources, flags, ``-o target``).

    Raises:
        BuildError: no compiler, it cannot be started, or it failed (its first error line
            quoted, with the command).
    """
    cmd = [*compiler_command(), *map(str, args)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd)
    except OSError as exc:
        raise BuildError(
            f"cannot run the C compiler ({shlex.join(cmd)}): {exc.strerror or exc}; "
            "set CC to an installed compiler"
        ) from exc
    if proc.returncode != 0:
        lines = [ln for ln in proc.stderr.strip().splitlines() if "error" in ln.lower()]
        first = (lines or proc.stderr.strip().splitlines() or ["?"])[0].strip()
        raise BuildError(
            f"C compilation failed ({shlex.join(cmd)}): {first}; check $CC and its flags"
        )


def write_c(
    functions: Sequence[ca.Function], name: str, directory: Path, with_header: bool = True
) -> Path:
    """Write the C source ``name.c`` (and ``name.h``) of some CasADi Functions; returns the
    source path."""
    gen = ca.CodeGenerator(f"{name}.c", {"with_header": with_header, "with_export": True})
    for f in functions:
        gen.add(f)
    directory.mkdir(parents=True, exist_ok=True)
    gen.generate(f"{directory}{os.sep}")
    return directory / f"{name}.c"


def write_c_parts(
    functions: Sequence[ca.Function | Sequence[ca.Function]], name: str, directory: Path
) -> tuple[list[Path], Path]:
    """Write one self-contained C source per Function or group of Functions (``name_00.c``,
    ...) and one header ``name.h`` declaring them all, so that the sources compile in parallel.

    The inner Functions that the Functions of one group call are written once into its
    source; a Function alone is a group of one.

    Returns:
        The source paths, in the order of ``functions``, and the header path.
    """
    sources, headers = [], []
    for i, group in enumerate(functions):
        members = [group] if isinstance(group, ca.Function) else list(group)
        src = write_c(members, f"{name}_{i:02d}", directory, with_header=True)
        part_h = src.with_suffix(".h")
        headers.append(part_h.read_text())
        part_h.unlink()
        sources.append(src)
    guard = f"{name.upper()}_H"
    header = directory / f"{name}.h"
    header.write_text(f"#ifndef {guard}\n#define {guard}\n" + "".join(headers) + "#endif\n")
    return sources, header


def compile_parallel(
    sources: Sequence[Path],
    target: Path,
    compile_flags: Sequence[str] = COMPILE_FLAGS,
    link_flags: Sequence[str] = LINK_FLAGS,
    cwd: Path | None = None,
    unoptimised: Sequence[Path] = (),
    optimised: Sequence[Path] = (),
) -> Path:
    """Compile C sources into objects in parallel (:func:`jobs` at once, largest first) and
    link them into the shared library ``target``.

    Args:
        sources: the C sources.
        target: the shared library to write.
        compile_flags: flags compiling each source.
        link_flags: flags linking the objects.
        cwd: working directory of the compiler.
        unoptimised: those of ``sources`` compiled with ``-O0`` appended to ``compile_flags``
            (rarely called code whose optimisation costs more than it saves).
        optimised: those of ``sources`` compiled with :data:`LOOP_OPT` appended (small
            hand-written loops, which vectorise there, among straight-line kernels).

    Raises:
        BuildError: see :func:`run_compiler`.
    """
    cold = {Path(s).resolve() for s in unoptimised}
    hot = {Path(s).resolve() for s in optimised}
    # longest first: unoptimised sources compile about 2.5 times faster per byte
    sources = sorted(
        (Path(s).resolve() for s in sources),
        key=lambda p: -p.stat().st_size * (0.4 if p in cold else 1.0),
    )
    with tempfile.TemporaryDirectory() as tmp:
        objects = [Path(tmp) / f"{i:03d}_{src.stem}.o" for i, src in enumerate(sources)]

        def one(pair: tuple[Path, Path]) -> None:
            extra = ["-O0"] if pair[0] in cold else [LOOP_OPT] if pair[0] in hot else []
            flags = [*compile_flags, *extra]
            run_compiler([*flags, "-c", str(pair[0]), "-o", str(pair[1])], cwd=cwd)

        with ThreadPoolExecutor(max_workers=jobs()) as pool:
            list(pool.map(one, zip(sources, objects, strict=True)))
        link = [
            *compile_flags,
            *link_flags,
            *map(str, objects),
            "-o",
            str(Path(target).resolve()),
            "-lm",
        ]
        run_compiler(link, cwd=cwd)
    return Path(target)


#: The layout of the compiled backend's library (:func:`compiled_library`): the kernels of
#: each source, by their names in :class:`~scdk_sym.kernels.functions.Kernels` and
#: :class:`~scdk_sym.kernels.follower.FollowerKernels`. First those its solvers call at every
#: step (the warm kernel, the SC field CVODES integrates and its probe, the curve follower's
#: steps, tangent and polish: one copy of the closure Function they call); then those called
#: a few times per singular point or projection (the follower's plane, fold and the data of
#: the descent onto the singular manifold), compiled at ``-O0`` (a third of the compile time;
#: a few tenths of a millisecond more per call). The two sources compile in parallel.
LIBRARY_GROUPS = (
    ("warm", "field", "probe", "steps", "step", "tangent", "polish"),
    ("plane", "fold", "singular"),
)
#: The groups of :data:`LIBRARY_GROUPS` compiled at ``-O0`` (by index).
UNOPTIMISED_GROUPS = (1,)
#: The model kernels of the library (:func:`compiled_kernels`; the others stay the SX
#: Functions of ``model.kernels``).
KERNEL_GROUPS = (("warm", "field", "probe"),)


def cached_library(
    functions: Sequence[ca.Function],
    name: str,
    announce_as: str | None = None,
    opt: str = "-O3",
) -> Path:
    """A shared library of some Functions, compiled once into the cache directory.

    Keyed by a hash of the generated sources, the compiler flags, the compiler
    (:func:`compiler_tag`) and the CasADi version; for the kernels of a
    model prefer :func:`compiled_kernels`, which needs no code generation when cached.
    ``announce_as``: the model name to :func:`announce` when it compiles; ``opt``: the
    optimisation level (-O3 by default: batched loops such as the algebraic form's gain from
    it; :data:`OPT` for straight-line kernels).
    """
    flags = (opt, *COMPILE_FLAGS[1:])
    with tempfile.TemporaryDirectory() as tmp:
        sources, _ = write_c_parts(functions, name, Path(tmp))
        h = hashlib.sha256()
        for src in sources:
            h.update(src.read_bytes())
        h.update(" ".join((*flags, *LINK_FLAGS)).encode())
        h.update(f"{compiler_tag()} casadi {getattr(ca, '__version__', '')}".encode())
        target = cache_dir() / f"{name}_{h.hexdigest()[:20]}.so"

        def build(path: Path) -> None:
            if announce_as:
                announce(announce_as)
            compile_parallel(sources, path, flags)

        return cached_file(target, build, "compiled library")


def compile_shared(source: Path, target: Path) -> Path:
    """Compile a C source into a shared library.

    Raises:
        BuildError: see :func:`run_compiler`.
    """
    run_compiler([*CFLAGS, str(source), "-o", str(target), "-lm"])
    return target


def source_digest(parts: Sequence[str]) -> bytes:
    """SHA-256 of package sources: ``parts`` are paths relative to :data:`PACKAGE_ROOT`, a
    folder standing for every ``*.py`` in it (each file hashed with its relative path)."""
    h = hashlib.sha256()
    for part in parts:
        path = PACKAGE_ROOT / part
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for f in files:
            h.update(f.relative_to(PACKAGE_ROOT).as_posix().encode() + b"\0")
            h.update(f.read_bytes() + b"\0")
    return h.digest()


def compiler_tag() -> str:
    """Short hash of the compiler command ``$CC`` (empty: gcc or cc on the PATH); part of the
    key of every compiled library, so that a change of compiler compiles again."""
    return hashlib.sha256(os.environ.get("CC", "").strip().encode()).hexdigest()[:8]


def cache_key(model) -> str:
    """Content hash of a model's kernels: the model files, its square reduction, the package
    sources that turn them into kernels (:data:`KERNEL_SOURCES`), the CasADi version and the
    compiler flags (the compiler itself: :func:`compiler_tag`, in the library names)."""
    h = hashlib.sha256(model.content_hash.encode())
    locked = sorted((name, float(v)) for name, v in model.locked.items())
    structure = (model.actuated, model.unknowns, [int(r) for r in model.rows], locked)
    h.update(repr(structure).encode())
    h.update(source_digest(KERNEL_SOURCES))
    h.update(str(getattr(ca, "__version__", "")).encode())
    h.update(" ".join(CFLAGS).encode())
    return h.hexdigest()[:24]


def library_path(
    model,
    name: str,
    groups: Sequence[Sequence[ca.Function]],
    unoptimised: Collection[str] = (),
) -> Path:
    """Where :func:`model_library` keeps a library of a model's kernels (same arguments).

    The file name carries :func:`cache_key`, the layout of the sources (the Functions of each
    and whether it is compiled at ``-O0``) and :func:`compiler_tag`.
    """
    h = hashlib.sha256(cache_key(model).encode())
    for group in groups:
        names = [f.name() for f in group]
        cold = all(n in unoptimised for n in names)
        h.update((" ".join(names) + (" -O0" if cold else "") + "\n").encode())
    return cache_dir() / f"{name}_{h.hexdigest()[:24]}_{compiler_tag()}.so"


def model_library(
    model,
    name: str,
    groups: Sequence[Sequence[ca.Function]],
    unoptimised: Collection[str] = (),
) -> Path:
    """A shared library of some of a model's kernels, compiled once into the cache directory.

    Each group of Functions is written into one source (the inner Functions they call written
    once in it, :func:`write_c_parts`), and the sources compile in parallel
    (:func:`compile_parallel`); the first compilation for a model is announced
    (:func:`announce`). Keyed by :func:`library_path`: a cached library is found without
    generating any C.

    Args:
        model: the model whose kernels ``groups`` are (they must be built by the package
            sources that :func:`cache_key` hashes).
        name: prefix of the library's file name and of its sources.
        groups: the Functions of each source.
        unoptimised: names of Functions whose source, if it holds nothing else, compiles at
            ``-O0``.

    Raises:
        BuildError: see :func:`run_compiler`.
    """

    def build(path: Path) -> None:
        announce(model.name)
        with tempfile.TemporaryDirectory() as tmp:
            sources, _ = write_c_parts(groups, name, Path(tmp))
            cold = [
                src
                for src, group in zip(sources, groups, strict=True)
                if all(f.name() in unoptimised for f in group)
            ]
            compile_parallel(sources, path, unoptimised=cold)

    return cached_file(library_path(model, name, groups, unoptimised), build, "kernel library")


@dataclass(frozen=True)
class CompiledLibrary:
    """The compiled backend's library of a model (:func:`compiled_library`).

    Attributes:
        path: the shared library (in the cache directory).
        kernels: the model's kernels it was generated from (MX or SX Functions; those of
            :data:`KERNEL_GROUPS` are in the library).
        follower: the curve follower's kernels it was generated from (those of
            :data:`LIBRARY_GROUPS` are in the library).
    """

    path: Path
    kernels: Kernels
    follower: FollowerKernels


def compiled_library(model) -> CompiledLibrary:
    """The model's kernels and curve follower kernels for C, and their library compiled once
    into the cache directory (:func:`model_library`, :data:`LIBRARY_GROUPS`; kept per model
    object).

    The kernels are built for C (``loops``): one closure Function called by all of them
    (:func:`~scdk_sym.kernels.curve.closure_function`), a large system solved in loops
    (:func:`~scdk_sym.kernels.curve.loop_solver`), a large model's kernels MX Functions of
    calls (:func:`~scdk_sym.kernels.curve.compact`): generated C proportional to the closures'.

    Raises:
        BuildError: see :func:`run_compiler`.
    """
    return model.products.get(COMPILED_LIBRARY, lambda: _build_library(model))


def _build_library(model) -> CompiledLibrary:
    sym = model.symbolic
    closure = closure_function(sym)
    kern = build_kernels(sym, closure=closure, loops=True)
    follower = build_follower_kernels(
        sym, inline=False, closure=closure, solver_calls=False, loops=True
    )
    by_name = {f.name: getattr(kern, f.name) for f in fields(kern)}
    by_name.update({f.name: getattr(follower, f.name) for f in fields(follower)})
    groups = [[by_name[name] for name in group] for group in LIBRARY_GROUPS]
    cold = [f.name() for i in UNOPTIMISED_GROUPS for f in groups[i]]
    path = model_library(model, "compiled", groups, unoptimised=cold)
    return CompiledLibrary(path, kern, follower)


def compiled_kernels(model) -> Kernels:
    """The model's kernels, those of :data:`KERNEL_GROUPS` compiled to C and loaded with
    ``casadi.external`` (the others: ``model.kernels``'s SX Functions).

    They are in the compiled backend's library (:func:`compiled_library`: cached on disk,
    only the first call for a model generates and compiles, seconds). The field is loaded
    with finite differences for its derivatives: CVODES's functional iteration
    (:data:`~scdk_sym.follower.cvodes.CVODES_OPTIONS`) never evaluates the Jacobian that
    CasADi builds at the integrator's creation, so none is compiled.
    """
    lib = compiled_library(model)
    loaded = {f.name: getattr(model.kernels, f.name) for f in fields(lib.kernels)}
    for name in (name for group in KERNEL_GROUPS for name in group):
        opts = {"enable_fd": True} if name == "field" else {}
        loaded[name] = ca.external(getattr(lib.kernels, name).name(), str(lib.path), opts)
    return Kernels(**loaded)
