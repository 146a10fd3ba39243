"""The C sources of the algebraic engine compiled into cached libraries.

Each C twin keeps its source beside its Python module (``paths/continuation.c``,
``certify/krawczyk.c``, package data); :func:`source_library` compiles one, with its header
and the package's LU factorisation, into a library cached on disk under the hash of all it is
built from. :func:`simd_flags` are the instruction-set flags of this processor that leave
every lane's arithmetic as the scalar one.
"""

from __future__ import annotations

import functools
import hashlib
import tempfile
from pathlib import Path


def source_library(
    source: Path, flags: tuple[str, ...], generated: dict[str, str] | None = None
) -> Path:
    """A library compiled from the C file ``source`` (and its header beside it, and the
    package's LU factorisation :data:`~scdk_sym.kernels.compile.LU_HEADER` it may include),
    cached under the hash of its sources, flags and compiler.

    Args:
        source: the path of ``<stem>.c``; ``<stem>.h`` lies beside it, and the library is
            cached as ``<stem>_<hash>.so``.
        flags: compiler flags.
        generated: file name -> text of generated sources, written beside each other and
            on the include path (their texts hashed too); a ``main.c`` among them is
            compiled instead of ``source`` (it includes it).

    Raises:
        BuildError: no C compiler, or the compilation failed.
    """
    from ..kernels.cache import cache_dir, cached_file
    from ..kernels.compile import LU_HEADER, compiler_tag, run_compiler

    src, stem = source.parent, source.stem
    generated = generated or {}
    h = hashlib.sha256()
    for path in (src / f"{stem}.h", source, LU_HEADER):
        h.update(path.read_bytes())
    h.update(" ".join(flags).encode())
    h.update(compiler_tag().encode())
    for name, text in sorted(generated.items()):
        h.update(name.encode() + b"\0" + text.encode() + b"\0")
    target = cache_dir() / f"{stem}_{h.hexdigest()[:20]}.so"

    def build(path: Path) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            for name, text in generated.items():
                (Path(tmp) / name).write_text(text)
            main = Path(tmp) / "main.c" if "main.c" in generated else source
            run_compiler([*flags, f"-I{src}", f"-I{LU_HEADER.parent}", f"-I{tmp}", str(main),
                          "-o", str(path), "-lm"])  # fmt: skip

    return cached_file(target, build, "compiled library")


@functools.cache
def _cpu_flags() -> tuple[str, ...]:
    """The processor's feature flags (Linux ``/proc/cpuinfo``; none elsewhere), read once per
    process (every interval test asks for its library's flags)."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return ()
    return tuple(next((ln.split(":", 1)[1].split() for ln in info.splitlines()
                       if ln.startswith("flags")), []))  # fmt: skip


def simd_flags() -> tuple[str, ...]:
    """``-mavx2`` where the processor has AVX2, and ``-mavx512f`` where it has AVX-512F too,
    else nothing: the lanes then run on the baseline instruction set. No ``-mfma`` (and
    ``-std=c99`` keeps GCC from contracting): each lane rounds as the scalar evaluation
    does, whatever the vector width."""
    flags = _cpu_flags()
    if "avx2" not in flags:
        return ()
    return ("-mavx2", "-mavx512f") if "avx512f" in flags else ("-mavx2",)
