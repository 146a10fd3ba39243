"""Generate the standalone C of a leg's transmission: motor <-> output-joint maps.

:func:`write_transmission` writes, for a C prefix ``P`` (default ``scdk``), the C form of
:func:`scdk_sym.transmission` (:mod:`scdk_sym.solvers.transmission`) for a controller, without
CasADi or any other library at run time:

- ``P_fwd_kernels.c/.h``, ``P_fwd_tracker.c/.h``: the generated tracker of the model (motors
  -> configuration, :func:`~scdk_sym.codegen.generate.generate` with prefix ``P_fwd``);
- ``P_inv_kernels.c/.h``, ``P_inv_tracker.c/.h``: the tracker of the same mechanism with the
  outputs as inputs (``model.with_inputs(outputs)``, prefix ``P_inv``);
- ``P_transmission.c`` and ``P_transmission.h``, the one header a controller includes: the
  templates ``transmission.c.in`` and ``transmission.h.in`` (beside this module) filled with
  the map's tables (which unknown is which output, the blocks of the map and the stages of the
  closures each depends on, as :meth:`~scdk_sym.solvers.transmission.Transmission.margin`
  defines them), its names, units and home values, and the generated kernel of its
  derivatives, ``P_loop_jac``: ``J_p`` and ``J_s`` of the closures in each loop's root frame
  (:mod:`scdk_sym.solvers.transmission_frames`);
- ``scdk_lu.h``, the pivoted LU both use.

Every source compiles with ``gcc -std=c99 -Wall -Wextra -Werror`` and links with ``-lm``
alone. The inverse kinematics of the trackers is left out (``<P>_fwd_ik_solve`` refuses).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from ..codegen import status, templates
from ..codegen.generate import (
    COMPILE_FLAGS,
    LINK_FLAGS,
    GeneratedSources,
    c_ints,
    check_prefix,
    generate,
    output_directory,
)
from ..errors import BuildError, InputError, OutputError
from ..kernels.compile import compile_parallel
from ..robot import Model
from ..robot.blocks import Block
from .transmission import SINGULAR_MARGIN, Transmission, transmission
from .transmission_frames import derivative_kernel, loop_jacobians, pattern

#: The folder of the transmission's C templates (beside this module), in the package.
FOLDER = "solvers"
HEADER = "transmission.h.in"
SOURCE = "transmission.c.in"


@dataclass(frozen=True)
class TransmissionSources:
    """Paths of the generated C files of a transmission.

    Attributes:
        directory: where they were written.
        prefix: C prefix of the transmission's names (``<prefix>_forward``, ...).
        header: ``<prefix>_transmission.h`` (include this one).
        source: ``<prefix>_transmission.c``.
        forward: the forward tracker's files (prefix ``<prefix>_fwd``).
        inverse: the inverse tracker's files (prefix ``<prefix>_inv``).
    """

    directory: Path
    prefix: str
    header: Path
    source: Path
    forward: GeneratedSources
    inverse: GeneratedSources

    @property
    def sources(self) -> tuple[Path, ...]:
        """The C sources to compile."""
        return (*self.forward.sources, *self.inverse.sources, self.source)

    @property
    def files(self) -> tuple[Path, ...]:
        """Every file written."""
        parts = (self.forward, self.inverse)
        headers = tuple(h for p in parts for h in (p.kernels_h, p.tracker_h))
        return (*self.sources, *headers, self.header, self.forward.lu_h)


def write_transmission(
    source: Transmission | Model,
    outputs: Sequence[str] | None,
    directory: str | Path,
    prefix: str = "scdk",
) -> TransmissionSources:
    """Write the C sources and the header of a transmission into ``directory``.

    Args:
        source: a transmission (:func:`scdk_sym.transmission`), or a model whose inputs are
            the motors.
        outputs: the output joints (as many as the motors, a motor may be its own output);
            None with a transmission (its own).
        directory: output directory (created if needed; its parent must exist).
        prefix: C prefix of the transmission (the trackers get ``<prefix>_fwd`` and
            ``<prefix>_inv``).

    Returns:
        The paths of the generated files.

    Raises:
        InputError: ``prefix`` is not a C identifier, or ``outputs`` do not match
            ``source``.
        UnknownNameError: an output is not a one-coordinate joint.
        OutputError: ``directory`` cannot be created or written.
    """
    trans = _transmission(source, outputs)
    prefix = check_prefix(prefix)
    out = output_directory(directory)
    fwd, inv = f"{prefix}_fwd", f"{prefix}_inv"
    J_p, J_s = loop_jacobians(trans.model, trans._stages)
    kernel = derivative_kernel(trans.model, J_p, J_s, f"{prefix}_loop_jac")
    values = {
        "P": prefix,
        "PU": prefix.upper(),
        "FWD": fwd,
        "FWDU": fwd.upper(),
        "INV": inv,
        "INVU": inv.upper(),
        "STATUS_DEFINES": status.transmission_defines(prefix),
        **_description(trans),
        **_tables(trans, pattern(J_p), pattern(J_s)),
        **_kernel_code(kernel, prefix),
    }
    try:
        forward = generate(trans.model, out, fwd, inverse_kinematics=False)
        inverse = generate(trans.inverse_model, out, inv, inverse_kinematics=False)
        header = out / f"{prefix}_transmission.h"
        code = out / f"{prefix}_transmission.c"
        header.write_text(templates.fill(templates.template(HEADER, FOLDER), values))
        code.write_text(templates.fill(templates.template(SOURCE, FOLDER), values))
    except OSError as exc:
        raise OutputError(f"cannot write: {exc.strerror or exc}", exc.filename or out) from exc
    return TransmissionSources(out, prefix, header, code, forward, inverse)


def compile_transmission(sources: TransmissionSources, target: str | Path) -> Path:
    """Compile generated transmission sources into a shared library (the flags of
    :func:`~scdk_sym.codegen.generate.compile_library`; the trackers and the transmission at
    :data:`~scdk_sym.kernels.compile.LOOP_OPT`).

    Raises:
        BuildError: no compiler, or the compilation failed (first error line quoted).
    """
    hot = (sources.forward.tracker_c, sources.inverse.tracker_c, sources.source)
    return compile_parallel(
        sources.sources,
        Path(target).resolve(),
        COMPILE_FLAGS,
        LINK_FLAGS,
        cwd=sources.directory,
        optimised=hot,
    )


def _transmission(source: Transmission | Model, outputs: Sequence[str] | None) -> Transmission:
    """The transmission to write: ``source`` itself, or made from the model and outputs."""
    if isinstance(source, Transmission):
        if outputs is not None and tuple(outputs) != source.outputs:
            raise InputError(
                f"outputs {list(outputs)} differ from the transmission's {list(source.outputs)}"
                ": pass None or the same outputs"
            )
        return source
    if outputs is None:
        raise InputError("outputs are required with a model: the output joints, one per motor")
    trans = transmission(source, outputs)
    if tuple(trans.inverse_model.actuated) != trans.outputs:
        raise BuildError(  # the Python inverse map reads q_out in that order too
            f"the inverse model's inputs {list(trans.inverse_model.actuated)} are not the "
            f"outputs {list(trans.outputs)} in order"
        )
    return trans


def _description(trans: Transmission) -> dict[str, str]:
    """Names, units, comment lines and home values of the map (placeholders)."""
    model, inv = trans.model, trans.inverse_model
    home = model.home.coordinates
    blocks = trans.blocks()
    motor_lines = [f" *   {j} {_comment(m)} [{model.units[m]}]" for j, m in enumerate(trans.motors)]
    output_lines = [
        f" *   {i} {_comment(o)} [{inv.units[o]}]"
        + (" (a motor: its own output)" if o in model.actuated else "")
        for i, o in enumerate(trans.outputs)
    ]
    names = [f"({', '.join(ms)}) -> ({', '.join(os)})" for ms, os in blocks]
    block_lines = [f" *   {b} {_comment(name)}" for b, name in enumerate(names)]
    return {
        "VERSION": _version(),
        "MODEL": _comment(model.name),
        "HASH": model.content_hash[:16],
        "LENGTH_UNIT": _comment(model.length_unit),
        "MOTOR_LINES": "\n".join(motor_lines),
        "OUTPUT_LINES": "\n".join(output_lines),
        "BLOCK_LINES": "\n".join(block_lines),
        "NMOTORS": str(model.k),
        "NOUTPUTS": str(len(trans.outputs)),
        "NBLOCKS": str(len(blocks)),
        "SINGULAR_MARGIN": repr(float(SINGULAR_MARGIN)),
        "MOTOR_NAMES": ", ".join(_string(m) for m in trans.motors),
        "OUTPUT_NAMES": ", ".join(_string(o) for o in trans.outputs),
        "BLOCK_NAMES": ", ".join(_string(name) for name in names),
        "HOME_MOTORS": _doubles(model.home.theta),
        "HOME_OUTPUTS": _doubles([home[o] for o in trans.outputs]),
    }


def _kernel_code(kernel: ca.Function, prefix: str) -> dict[str, str]:
    """The C of the derivative kernel (written into the transmission's source) and its work
    sizes (placeholders)."""
    gen = ca.CodeGenerator(f"{prefix}_loops", {"with_header": False, "with_export": False})
    gen.add(kernel)
    return {
        "LOOP_KERNEL": gen.dump().strip(),
        "LJ_SZ_ARG": str(max(1, kernel.sz_arg())),
        "LJ_SZ_RES": str(max(1, kernel.sz_res())),
        "LJ_SZ_IW": str(max(1, kernel.sz_iw())),
        "LJ_SZ_W": str(max(1, kernel.sz_w())),
    }


def _tables(trans: Transmission, jp: np.ndarray, js: np.ndarray) -> dict[str, str]:
    """The index tables of the C source: outputs and motors in the two models' unknowns, the
    blocks and the stages of the closures they depend on; each stage's inputs and motors from
    the structural nonzeros ``jp``, ``js`` of the derivative kernel's ``J_p``, ``J_s``
    (placeholders)."""
    model, inv = trans.model, trans.inverse_model
    order = trans._stages  # triangular_blocks(model): the stages, dependencies first
    index = {(tuple(st.rows), tuple(st.unknowns)): i for i, st in enumerate(order)}
    needed = [[index[tuple(r), tuple(u)] for r, u in trans._stages_of(outs)]
              for _, outs in trans.blocks()]  # fmt: skip
    used = sorted({i for ids in needed for i in ids})
    stages = [order[i] for i in used]
    if any(len(st.rows) != len(st.unknowns) for st in stages):
        raise BuildError(f"a stage of the closures of {model.name!r} is not square")
    covered = {u for st in stages for u in st.unknowns}
    if any(o in model.unknowns and model.unknowns.index(o) not in covered for o in trans.outputs):
        raise BuildError(f"an output of {model.name!r} is in no stage of its closures")
    block_stages = [[used.index(i) for i in ids] for ids in needed]
    block_motors = [[trans.motors.index(m) for m in ms] for ms, _ in trans.blocks()]
    block_outputs = [[trans.outputs.index(o) for o in os] for _, os in trans.blocks()]
    sizes = [len(st.rows) for st in stages]
    inputs = [sorted(set(np.flatnonzero(jp[list(st.rows)].any(axis=0)).tolist()) - set(st.unknowns))
              for st in stages]  # fmt: skip
    stage_motors = _stage_motors(js, stages, inputs)
    wanted = {u for ids in inputs for u in ids}
    wanted |= {model.unknowns.index(o) for o in trans.outputs if o in model.unknowns}
    elimination = [_elimination(jp, st, wanted) for st in stages]
    sizes += [max(len(a), len(b)) for a, b in zip(block_motors, block_outputs, strict=True)]
    return {
        "OUT_Y": c_ints(_position(model, o) for o in trans.outputs),
        "MOTOR_Y": c_ints(_position(inv, m) for m in trans.motors),
        "NSTAGES": str(len(stages)),
        "STAGE_START": _starts([st.rows for st in stages]),
        "STAGE_ROWS": c_ints(r for st in stages for r in st.rows),
        "STAGE_COLS": c_ints(u for e in elimination for u in e[0]),
        "STAGE_HI": c_ints(i for e in elimination for i in e[1]),
        "STAGE_LO": c_ints(i for e in elimination for i in e[2]),
        "STAGE_LOW": c_ints(i for e in elimination for i in e[3]),
        "STAGE_FIRST": c_ints(
            min((e[0].index(u) for u in e[0] if u in wanted), default=len(e[0]))
            for e in elimination
        ),
        "STAGE_CASES": "\n".join(
            f"    case {i}: return solve_sized(t, {i}, {len(st.rows)});"
            for i, st in enumerate(stages)
        ),  # fmt: skip
        "STAGE_INPUT_START": _starts(inputs),
        "STAGE_INPUTS": c_ints(u for ids in inputs for u in ids),
        "STAGE_MOTOR_START": _starts(stage_motors),
        "STAGE_MOTORS": c_ints(j for ids in stage_motors for j in ids),
        "BLOCK_STAGE_START": _starts(block_stages),
        "BLOCK_STAGES": c_ints(s for ids in block_stages for s in ids),
        "BLOCK_MOTOR_START": _starts(block_motors),
        "BLOCK_MOTORS": c_ints(j for ids in block_motors for j in ids),
        "BLOCK_OUTPUT_START": _starts(block_outputs),
        "BLOCK_OUTPUTS": c_ints(i for ids in block_outputs for i in ids),
        "MAX_DIM": str(max([1, *sizes])),
        "JP_ALLOC": str(max(1, model.m * model.m)),
        "JS_ALLOC": str(max(1, model.m * model.k)),
        "NSTAGES_ALLOC": str(max(1, len(stages))),
    }


def _stage_motors(
    js: np.ndarray, stages: Sequence[Block], inputs: Sequence[Sequence[int]]
) -> list[list[int]]:
    """For each stage (dependencies first), the motors its unknowns depend on: those whose
    column of ``J_s`` (structural nonzeros ``js``) is nonzero on its rows, and those of the
    stages its inputs belong to (the other columns of ``J_p^-1 J_s`` are zero on its
    unknowns)."""
    owner: dict[int, int] = {}
    found: list[list[int]] = []
    for i, st in enumerate(stages):
        motors = set(np.flatnonzero(js[list(st.rows)].any(axis=0)).tolist())
        for u in inputs[i]:
            motors.update(found[owner[u]])
        found.append(sorted(motors))
        owner.update((u, i) for u in st.unknowns)
    return found


def _elimination(
    jp: np.ndarray, stage: Block, wanted: set[int]
) -> tuple[list[int], list[int], list[int], list[int]]:
    """The order of a stage's unknowns (columns of its block ``B`` of ``J_p``, structural
    nonzeros ``jp``) for its LU factorisation, and per column ``k`` of that order the last
    row ``hi[k]`` that may be nonzero when it is eliminated, the first row ``lo[k]`` of ``U``
    and the last row of ``L`` (``hi[k]``, or further where a later step exchanges a row in
    that range with one below it) that may be nonzero.

    The columns come by their last nonzero row, then fewest nonzeros first: a loop's own
    unknowns, eliminated within its rows, before those it shares with the next loops; then
    the ``wanted`` unknowns (outputs, inputs of later stages) last, where back substitution
    starts. The
    fill is bounded as partial pivoting may have it: at column ``k`` any row from ``k`` to the
    last one nonzero there may be the pivot, and each of those rows gets the union of their
    patterns; every other row is zero in column ``k`` (its multiplier 0: skipping it is the
    same elimination)."""
    block = jp[np.ix_(list(stage.rows), list(stage.unknowns))]
    nz = [np.flatnonzero(block[:, j]) for j in range(block.shape[1])]
    late = [stage.unknowns[j] in wanted for j in range(len(nz))]
    order = sorted(
        range(len(nz)), key=lambda j: (int(nz[j].max(initial=-1)), len(nz[j]), late[j], j)
    )
    P = block[:, order].copy()
    n, hi = len(order), []
    for k in range(n):
        rows = np.flatnonzero(P[k:, k]) + k
        last = int(rows.max(initial=k))
        P[k : last + 1, k:] |= P[k : last + 1, k:].any(axis=0)
        hi.append(last)
    lo = [int(np.flatnonzero(np.triu(P)[:, k]).min(initial=k)) for k in range(n)]
    low = list(hi)  # the rows of L's column k once the later row exchanges are applied
    for k in range(n):
        for later in range(k + 1, n):
            if later <= low[k]:
                low[k] = max(low[k], hi[later])
    return [stage.unknowns[j] for j in order], hi, lo, low


def _position(model: Model, joint: str) -> int:
    """Where a joint's value is in a model's state: its index among the unknowns, else
    ``-1 - `` its index among the inputs."""
    if joint in model.unknowns:
        return model.unknowns.index(joint)
    if joint in model.actuated:
        return -1 - model.actuated.index(joint)
    raise InputError(f"joint {joint!r} is neither an unknown nor an input of {model.name!r}")


def _starts(groups: Sequence[Sequence[int]]) -> str:
    """C initialiser of the offsets of consecutive groups in a flat array (len + 1 values)."""
    offsets = [0]
    for group in groups:
        offsets.append(offsets[-1] + len(group))
    return c_ints(offsets)


def _doubles(values) -> str:
    """C initialiser of a double array (shortest round-trip literals)."""
    return ", ".join(repr(float(v)) for v in values) or "0.0"


def _string(text: str) -> str:
    """A C string literal of ``text`` (UTF-8, non-ASCII bytes as octal escapes)."""
    out = []
    for byte in text.encode():
        char = chr(byte)
        if char in '"\\':
            out.append("\\" + char)
        elif 32 <= byte < 127:
            out.append(char)
        else:
            out.append(f"\\{byte:03o}")
    return '"' + "".join(out) + '"'


def _comment(text: str) -> str:
    """``text`` safe inside a C block comment."""
    return text.replace("*/", "* /").replace("\n", " ")


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("scdk_sym")
    except Exception:  # pragma: no cover - not installed
        return "dev"
