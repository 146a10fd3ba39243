"""Code generation: kernels -> C source -> shared library (gcc), cached by content hash.

The generated C of every kernel (``casadi.CodeGenerator``) is compiled once with
``gcc -O3 -shared -fPIC`` into the cache directory and loaded with ``casadi.external``; the
result is a :class:`~scdk_sym.kernels.functions.Kernels` with the same signatures.
"""

from __future__ import annotations

import hashlib
import os
import shlex
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from dataclasses import fields
from pathlib import Path

import casadi as ca

from ..errors import BuildError
from .cache import cache_dir
from .functions import Kernels

CFLAGS = ("-O3", "-shared", "-fPIC")


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


def generate_c(kernels: Kernels, name: str, directory: Path, with_header: bool = True) -> Path:
    """Write the C source (and header) of all kernels of a model; returns the source path."""
    # "jac_<field>": CVODES asks for the Jacobian of the field it integrates
    return write_c([*kernels.all(), kernels.field.jacobian()], name, directory, with_header)


def cached_library(functions: Sequence[ca.Function], name: str) -> Path:
    """A shared library of some Functions, compiled once into the cache directory.

    Keyed by a hash of the generated source and the compiler flags; for the kernels of a
    model prefer :func:`compiled_kernels`, which needs no code generation when cached.
    """
    with tempfile.TemporaryDirectory() as tmp:
        src = write_c(functions, name, Path(tmp), with_header=False)
        key = hashlib.sha256(src.read_bytes() + " ".join(CFLAGS).encode()).hexdigest()[:20]
        target = cache_dir() / f"{name}_{key}.so"
        if not target.exists():
            _compile_into(src, target)
    return target


def _compile_into(source: Path, target: Path) -> None:
    partial = target.with_suffix(f".{os.getpid()}.tmp")
    compile_shared(source, partial)
    os.replace(partial, target)  # atomic: concurrent processes never load a partial file


def compile_shared(source: Path, target: Path) -> Path:
    """Compile a C source into a shared library.

    Raises:
        BuildError: see :func:`run_compiler`.
    """
    run_compiler([*CFLAGS, str(source), "-o", str(target), "-lm"])
    return target


def cache_key(model) -> str:
    """Content hash of a model's compiled kernels: the model files, the code that turns them
    into kernels, the CasADi version and the compiler flags."""
    h = hashlib.sha256(model.content_hash.encode())
    here = Path(__file__).resolve().parents[1]
    for part in ("kernels/functions.py", "symbolic/kinematics.py", "symbolic/system.py"):
        h.update((here / part).read_bytes())
    h.update(str(getattr(ca, "__version__", "")).encode())
    h.update(" ".join(CFLAGS).encode())
    return h.hexdigest()[:24]


def compiled_kernels(model) -> Kernels:
    """The model's kernels compiled to C and loaded with ``casadi.external``.

    The shared library is cached on disk (:func:`~scdk_sym.kernels.cache.cache_dir`) under
    :func:`cache_key`; only the first call for a model generates and compiles (seconds).
    """
    kern = model.kernels
    target = cache_dir() / f"kernels_{cache_key(model)}.so"
    if not target.exists():
        with tempfile.TemporaryDirectory() as tmp:
            _compile_into(generate_c(kern, "scdk_kernels", Path(tmp), with_header=False), target)
    loaded = {f.name: ca.external(getattr(kern, f.name).name(), str(target)) for f in fields(kern)}
    return Kernels(**loaded)
