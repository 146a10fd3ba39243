"""Generate the standalone C tracker of a model: CasADi kernels + the tracker template.

:func:`generate` writes, for a C prefix ``P`` (default ``scdk``):

- ``P_kernels.c`` / ``P_kernels.h``: CasADi's ``CodeGenerator`` output for ``g``, ``J_p`` and
  ``J_s``, the pose, the curve follower's kernels (the oriented SC tangent, one RK4
  predictor-corrector step, the RK4 step in ``s``, the Newton corrector and polish), the chart
  re-centring and an inverse-kinematics step (self-contained C, see
  :mod:`scdk_sym.kernels.tracker_functions`);
- ``P_tracker.c`` / ``P_tracker.h``: the tracker, the templates of
  :data:`~scdk_sym.codegen.templates.SOURCE_PARTS` (parts joined into one source, each beside
  the Python module it mirrors) and ``codegen/c/tracker.h.in`` (package data,
  :mod:`scdk_sym.codegen.templates`) filled with the model's sizes, tolerances and home
  configuration, and the status codes of :mod:`scdk_sym.codegen.status`.

The four files compile with ``gcc -std=c99 -O2 -Wall -Wextra`` (no warnings) and ``-lm``
alone.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from ..errors import InputError, OutputError
from ..kernels.compile import (
    LOOP_OPT,
    LU_HEADER,
    OPT,
    compile_parallel,
    compiler_tag,
    write_c,
    write_c_parts,
)
from ..kernels.tracker_functions import UNOPTIMISED, build_tracker_kernels
from ..robot.blocks import triangular_blocks
from . import status, templates

#: Flags compiling each source of the shared library built for Python (the optimisation
#: level of :mod:`scdk_sym.kernels.compile`; ``-fno-semantic-interposition``: the kernels'
#: helpers such as ``casadi_sq``, global functions, are inlined as in a static build instead
#: of called, since ``-Bsymbolic`` binds them inside the library anyway;
#: ``-fstrict-aliasing``, on from -O2: a store of a double may not change a pointer, so the
#: kernels do not load their output pointer ``res[i]`` again before each store, a tenth of
#: the closure kernel's instructions; the generated C and the tracker access every object
#: through its own type).
COMPILE_FLAGS = (
    "-std=c99", OPT, "-Wall", "-fPIC", "-fno-semantic-interposition", "-fstrict-aliasing",
)  # fmt: skip
#: Flags linking it (``-Bsymbolic``: the tracker calls its own kernels even if another library
#: of the process exports the same names).
LINK_FLAGS = ("-shared", "-Wl,-Bsymbolic")
SHARED_FLAGS = (*COMPILE_FLAGS, *LINK_FLAGS)


@dataclass(frozen=True)
class GeneratedSources:
    """Paths of the generated C files.

    Attributes:
        directory: where they were written.
        prefix: C prefix of every exported name.
        kernels_c: CasADi-generated kernels (``<prefix>_kernels.c``; written split, the first
            of ``parts``).
        kernels_h: their header.
        tracker_c: the tracker (``<prefix>_tracker.c``).
        tracker_h: its header (include this one).
        lu_h: the LU factorisation the tracker includes (``scdk_lu.h``, a copy of
            :data:`~scdk_sym.kernels.compile.LU_HEADER`).
        parts: written split, the kernels' sources, one per group of kernels
            (``<prefix>_kernels_00.c``, ..., see
            :data:`~scdk_sym.kernels.tracker_functions.GROUPS`), else empty.
        unoptimised: those of ``parts`` that the shared library compiles at ``-O0``
            (:data:`~scdk_sym.kernels.tracker_functions.UNOPTIMISED`).
    """

    directory: Path
    prefix: str
    kernels_c: Path
    kernels_h: Path
    tracker_c: Path
    tracker_h: Path
    lu_h: Path
    parts: tuple[Path, ...] = ()
    unoptimised: tuple[Path, ...] = ()

    @property
    def sources(self) -> tuple[Path, ...]:
        """The C sources to compile."""
        return (*(self.parts or (self.kernels_c,)), self.tracker_c)


def check_prefix(prefix: str) -> str:
    """Validate a C prefix (a lower-case C identifier without double underscores)."""
    if not re.fullmatch(r"[a-z][a-z0-9]*(_[a-z0-9]+)*", prefix or ""):
        raise InputError(
            f"C prefix must be a lower-case identifier (letters, digits, single underscores, "
            f"starting with a letter), got {prefix!r}"
        )
    return prefix


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("scdk_sym")
    except Exception:  # pragma: no cover - not installed
        return "dev"


def _floats(values) -> str:
    arr = np.asarray(values, dtype=float).ravel()
    if arr.size == 0:
        return "0.0"
    return ", ".join(repr(float(v)) for v in arr)


def source_key(sources: GeneratedSources) -> str:
    """Content hash of generated sources (templates filled), the library flags and the
    compiler (the cache key)."""
    h = hashlib.sha256()
    for path in (*sources.sources, sources.kernels_h, sources.tracker_h, sources.lu_h):
        h.update(path.read_bytes())
        h.update(b"\0")
    h.update(" ".join(SHARED_FLAGS).encode())
    for path in sources.unoptimised:
        h.update(f"\0{path.name} -O0".encode())
    h.update(f"\0{sources.tracker_c.name} {LOOP_OPT}".encode())
    h.update(compiler_tag().encode())
    return h.hexdigest()[:24]


def output_directory(directory: str | Path) -> Path:
    """The folder to write into, created if needed (its parent must exist).

    Raises:
        OutputError: ``directory`` is a file, its parent folder does not exist, or it cannot be
            created or written.
    """
    out = Path(directory)
    if out.exists() and not out.is_dir():
        raise OutputError("is a file, not a folder; choose a folder to write into", out)
    parent = out.absolute().parent
    if not out.exists() and not parent.is_dir():
        raise OutputError(
            f"its parent folder {str(parent)!r} does not exist; create it first or choose "
            "another folder",
            out,
        )
    try:
        out.mkdir(exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the folder: {exc.strerror or exc}", out) from exc
    if not os.access(out, os.W_OK | os.X_OK):
        raise OutputError("the folder is not writable; choose another folder", out)
    return out


def generate(
    model,
    directory: str | Path,
    prefix: str = "scdk",
    split: bool = False,
    inverse_kinematics: bool = True,
) -> GeneratedSources:
    """Write the C sources and headers of the model's tracker into ``directory``.

    Args:
        model: the model (:class:`~scdk_sym.robot.Model`).
        directory: output directory (created if needed).
        prefix: C prefix of every exported name and file name.
        split: one kernel source per group of kernels (compiled in parallel, see
            :data:`~scdk_sym.kernels.tracker_functions.GROUPS`) instead of one
            ``<prefix>_kernels.c``; the same header and functions.
        inverse_kinematics: False to leave out the inverse kinematics (no ``ik_step``
            kernel, ``<PREFIX>_HAS_IK`` 0: ``<prefix>_ik_solve`` refuses): the library that
            Python loads, which never calls it, compiles faster without.

    Returns:
        The paths of the generated files.

    Raises:
        InputError: ``prefix`` is not a C identifier.
        OutputError: ``directory`` cannot be created or written (see :func:`output_directory`).
    """
    prefix = check_prefix(prefix)
    out = output_directory(directory)
    try:
        return _generate(model, out, prefix, split, inverse_kinematics)
    except OSError as exc:
        name = exc.filename or out
        raise OutputError(f"cannot write: {exc.strerror or exc}", name) from exc


def _generate(
    model, out: Path, prefix: str, split: bool = False, inverse_kinematics: bool = True
) -> GeneratedSources:
    kern = build_tracker_kernels(model.symbolic, model.chart.rotations, prefix)
    left_out = set() if inverse_kinematics else {kern.ik_step.name()}
    groups = [[f for f in group if f.name() not in left_out] for group in kern.groups()]
    groups = [group for group in groups if group]
    funcs = [f for f in kern.all() if f.name() not in left_out]
    unoptimised: list[Path] = []
    if split:
        parts, _ = write_c_parts(groups, f"{prefix}_kernels", out)
        cold = {getattr(kern, name).name() for name in UNOPTIMISED}
        unoptimised = [
            part
            for part, group in zip(parts, groups, strict=True)
            if all(f.name() in cold for f in group)
        ]
    else:
        parts = [write_c(funcs, f"{prefix}_kernels", out, with_header=True)]
    for part in parts:
        _quiet_unused_parameters(part)
    home = model.home
    y_loc, c = model.chart.to_local(home.y)
    has_ik = inverse_kinematics and len(model.workspace) == model.k
    values = {
        "P": prefix,
        "PU": prefix.upper(),
        "VERSION": _version(),
        "MODEL": model.name,
        "HASH": model.content_hash[:16],
        "UNKNOWNS": ", ".join(model.unknowns),
        "ACTUATED": ", ".join(model.actuated),
        "WORKSPACE": ", ".join(model.workspace),
        "NY": str(model.m),
        "NTHETA": str(model.k),
        "NC": str(model.chart.size),
        "NX": str(len(model.workspace)),
        "NC_ALLOC": str(max(1, model.chart.size)),
        "SZ_ARG": str(max(f.sz_arg() for f in funcs)),
        "SZ_RES": str(max(f.sz_res() for f in funcs)),
        "SZ_IW": str(max(1, max(f.sz_iw() for f in funcs))),
        "SZ_W": str(max(1, max(f.sz_w() for f in funcs))),
        "HAS_IK": "1" if has_ik else "0",
        "HOME_Y": _floats(y_loc),
        "HOME_C": _floats(c),
        "HOME_THETA": _floats(home.theta),
        "HOME_X": _floats(home.x),
        "TOL": repr(float(model.tolerance)),
        "LENGTH_SCALE": repr(float(max(model.length_scale, 1e-300))),
        **_rule_constants(),
        **_follower_constants(),
        "PERIODIC": _periodic(model),
        "ROTATION": ", ".join(str(i) for idx in model.chart.rotations for i in idx) or "0",
        "NROT_ALLOC": str(max(1, 3 * len(model.chart.rotations))),
        **_lu_blocks(model),
        **status.template_values(prefix),
    }
    header = templates.fill(templates.template(templates.HEADER), values)
    source = templates.fill(templates.source(), values)
    (out / f"{prefix}_tracker.h").write_text(header)
    (out / f"{prefix}_tracker.c").write_text(source)
    (out / LU_HEADER.name).write_bytes(LU_HEADER.read_bytes())
    return GeneratedSources(
        directory=out,
        prefix=prefix,
        kernels_c=parts[0],
        kernels_h=out / f"{prefix}_kernels.h",
        tracker_c=out / f"{prefix}_tracker.c",
        tracker_h=out / f"{prefix}_tracker.h",
        lu_h=out / LU_HEADER.name,
        parts=tuple(parts) if split else (),
        unoptimised=tuple(unoptimised),
    )


#: Put first in CasADi's generated kernels: their functions keep the common signature
#: ``(arg, res, iw, w, mem)`` whether or not they use every argument.
_UNUSED_PARAMETERS = """/* CasADi's kernels share one signature; some leave arguments unused */
#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif
"""


def _quiet_unused_parameters(source: Path) -> None:
    """Silence ``-Wunused-parameter`` in a CasADi-generated C file (``-Wall -Wextra`` clean)."""
    source.write_text(_UNUSED_PARAMETERS + source.read_text())


def _periodic(model) -> str:
    from ..follower.geometry import periodic

    mask = np.zeros(model.m, dtype=int)
    mask[periodic(model)] = 1
    return ", ".join(str(v) for v in mask)


def _lu_blocks(model) -> dict[str, str]:
    """The tables and generated calls of the tracker's block LU of J_p (tracker_numerics.c.in:
    LU_BLOCKS): the blocks of :func:`~scdk_sym.robot.blocks.triangular_blocks` (J_p's fine
    block-triangular decomposition), rows and columns in block order, the
    columns left of each block its rows involve, and the sign of the two permutations."""
    parts = triangular_blocks(model)
    if model.m == 0 or len(parts) < 2:
        return {"LU_BLOCKS": "1", "LU_SIGN": "1.0", **dict.fromkeys(_LU_TABLES, "0"),
                **dict.fromkeys(_LU_CALLS, "")}  # fmt: skip
    rows = [r for block in parts for r in block.rows]
    cols = [c for block in parts for c in block.unknowns]
    start = np.cumsum([0] + [len(block.rows) for block in parts]).tolist()
    pattern = np.array(ca.DM(model.symbolic.J_p.sparsity(), 1), dtype=bool)
    permuted = pattern[np.ix_(rows, cols)]
    left: list[int] = []
    left_start = [0]
    for b in range(len(parts)):
        used = permuted[start[b] : start[b + 1], : start[b]].any(axis=0)
        left.extend(np.flatnonzero(used).tolist())
        left_start.append(len(left))
    blocks = list(zip(start[:-1], np.diff(start).tolist(), strict=True))
    return {
        "LU_BLOCKS": str(len(parts)),
        "LU_ROWS": c_ints(rows),
        "LU_COLS": c_ints(cols),
        "LU_START": c_ints(start),
        "LU_LEFT_START": c_ints(left_start),
        "LU_LEFT": c_ints(left),
        "LU_SIGN": repr(float(_permutation_sign(rows) * _permutation_sign(cols))),
        "LU_FACTOR_BLOCKS": "\n".join(
            f"    if (!lu_factor_block(B, piv, {s}, {n})) return 0;" for s, n in blocks),
        "LU_DET_BLOCKS": "\n".join(
            f"    det *= scdk_lu_det(LU + {s} + {s} * NY, {n}, 1, NY, piv + {s});"
            for s, n in blocks),
        "LU_SOLVE_BLOCKS": "\n".join(
            f"        lu_solve_block(LU, piv, x, {b}, {s}, {n}, 0);"
            for b, (s, n) in enumerate(blocks)),
        "LU_SOLVE_T_BLOCKS": "\n".join(
            f"        lu_solve_block(LU, piv, x, {b}, {s}, {n}, 1);"
            for b, (s, n) in reversed(list(enumerate(blocks)))),
    }  # fmt: skip


_LU_TABLES = ("LU_ROWS", "LU_COLS", "LU_START", "LU_LEFT_START", "LU_LEFT")
_LU_CALLS = ("LU_FACTOR_BLOCKS", "LU_DET_BLOCKS", "LU_SOLVE_BLOCKS", "LU_SOLVE_T_BLOCKS")


def c_ints(values) -> str:
    """C initialiser of an int array (one 0 for an empty one: C has no empty arrays)."""
    return ", ".join(str(int(v)) for v in values) or "0"


def _permutation_sign(order: list[int]) -> int:
    """+1 or -1: the sign of the permutation ``order`` of ``0 .. n - 1``."""
    seen, sign = [False] * len(order), 1
    for i in range(len(order)):
        length, j = 0, i
        while not seen[j]:
            seen[j] = True
            j = order[j]
            length += 1
        if length and length % 2 == 0:
            sign = -sign
    return sign


def _c_literals(module, floats: tuple[str, ...], ints: tuple[str, ...]) -> dict[str, str]:
    """Constants of a Python module as C literals, by name (the C mirrors of its rules)."""
    out = {name: repr(float(getattr(module, name))) for name in floats}
    out.update({name: str(int(getattr(module, name))) for name in ints})
    return out


def _follower_constants() -> dict[str, str]:
    """The step-control constants of the curve follower (:mod:`scdk_sym.follower.curve`),
    which the C tracker's ``follow`` mirrors, and its bound telling folds from bifurcations."""
    from ..follower import follow_rule

    floats = ("MAX_PREDICTOR_ERROR", "NEWTON_TOL", "MIN_COS", "SMOOTH_CORRECTION", "SMOOTH_COS")
    limits = ("GROW", "STRUCTURAL", "RECENTRE", "CHART_LIMIT")
    return _c_literals(follow_rule, (*floats, *limits), ("FINE",))


def _rule_constants() -> dict[str, str]:
    """The constants of the judging rule (:mod:`scdk_sym.follower.track_rule`), shared with
    :mod:`scdk_sym.solvers.track`."""
    from ..follower import track_rule as rule

    floats = ("ACCEPT", "MARGIN", "BUDGET", "SMOOTH", "PARTNER_STEP", "PARTNER_REACH")
    ints = ("FAST_ITERATIONS", "NEWTON_CALLS", "PREDICTED_CALLS", "PARTNER_ITERATIONS",
            "HITS_PER_DIRECTION", "MAX_STEPS")  # fmt: skip
    return _c_literals(rule, floats, ints)


def compile_library(sources: GeneratedSources, target: str | Path) -> Path:
    """Compile generated sources into a shared library (gcc, flags :data:`SHARED_FLAGS`), the
    sources in parallel, the tracker's own loops at
    :data:`~scdk_sym.kernels.compile.LOOP_OPT`.

    Raises:
        BuildError: no compiler, or the compilation failed (first error line quoted).
    """
    target = Path(target).resolve()
    return compile_parallel(
        sources.sources,
        target,
        COMPILE_FLAGS,
        LINK_FLAGS,
        cwd=sources.directory,
        unoptimised=sources.unoptimised,
        optimised=(sources.tracker_c,),
    )
