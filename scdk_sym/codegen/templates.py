"""The C templates of the standalone tracker, shipped as package data.

The templates are C files with placeholders ``@NAME@`` (no braces, so the templates read as
C); :mod:`scdk_sym.codegen.generate` fills them with :func:`fill`. ``codegen/c/tracker.h.in``
is the header; the source ``<prefix>_tracker.c`` is one file made of the parts
:data:`SOURCE_PARTS`, one idea each, joined in that order by :func:`source`: the constants
and the small public functions (``codegen/c/tracker.c.in``), then parts that each sit beside
the Python module they mirror and take its name: the numerics and kernel calls
(``solvers/tracker_numerics.c.in``), the context of a step (``follower/context.c.in``), the
curve follower (``follower/curve.c.in``), the divergent walk (``follower/singular.c.in``),
the judging rule (``solvers/tracker.c.in``), the tracker's state and tracks
(``solvers/track.c.in``), the solves (``solvers/solve.c.in``) and the atlas sweep
(``atlases/chunk.c.in``). ``@P@`` is the lower-case C prefix of every exported name, ``@PU@``
its upper-case form for macros; the others are the model's sizes, names, home configuration,
the constants of the judging rule (:mod:`scdk_sym.solvers.track`) and the status codes
(:mod:`scdk_sym.codegen.status`).
"""

from __future__ import annotations

import re
from importlib import resources
from typing import NamedTuple

from ..errors import BuildError

#: The folder of the templates that mirror no module of their own (the tracker's header and
#: the head of its source), relative to the package ``scdk_sym``.
FOLDER = "codegen/c"
HEADER = "tracker.h.in"
SOURCE = "tracker.c.in"


class Part(NamedTuple):
    """A template file: ``name`` in the folder ``folder`` of the package ``scdk_sym``."""

    folder: str
    name: str

    @property
    def path(self) -> str:
        """The file's path relative to the package ``scdk_sym``."""
        return f"{self.folder}/{self.name}"


#: The header's file.
HEADER_PART = Part(FOLDER, HEADER)
#: The parts of the tracker's source, in the order :func:`source` joins them, each in the
#: package of the Python module it mirrors.
SOURCE_PARTS: tuple[Part, ...] = (
    Part(FOLDER, SOURCE),  # the model's constants, the options and the status strings
    Part("solvers", "tracker_numerics.c.in"),  # small numerics, LU, the kernel calls, Newton
    Part("follower", "context.c.in"),  # what one step knows (step_ctx)
    Part("follower", "curve.c.in"),  # the curve follower (follow)
    Part("follower", "singular.c.in"),  # the divergent solve's walk, judged step by step
    Part("solvers", "tracker.c.in"),  # the judging rule: cheap continuations, candidates, choice
    Part("solvers", "track.c.in"),  # the state, a step, whole tracks
    Part("solvers", "solve.c.in"),  # the convergent and divergent solves, the inverse kinematics
    Part("atlases", "chunk.c.in"),  # the atlas sweep
)

_PLACEHOLDER = re.compile(r"@([A-Z_]+)@")


def template(name: str, folder: str = FOLDER) -> str:
    """The text of a template file.

    The file is read as package data of ``scdk_sym`` (the folder of its subpackage joined
    on), so that no subpackage is imported: several of them sit above this one.

    Args:
        name: file name (:data:`HEADER`, the name of one of :data:`SOURCE_PARTS`, ...).
        folder: its folder relative to the package ``scdk_sym`` (default :data:`FOLDER`).

    Raises:
        BuildError: the file is missing (an installation without the package data).
    """
    place = resources.files("scdk_sym")
    for step in (*folder.split("/"), name):
        place = place.joinpath(step)
    try:
        return place.read_text(encoding="utf-8")
    except (FileNotFoundError, OSError) as exc:
        raise BuildError(
            f"C template {name!r} not found in the scdk_sym package: reinstall scdk_sym "
            f"(the package data {folder}/*.in must be installed)"
        ) from exc


def source() -> str:
    """The template of the tracker's source: the parts :data:`SOURCE_PARTS` joined in order,
    a blank line between two.

    Raises:
        BuildError: a part is missing.
    """
    return "\n".join(template(part.name, part.folder) for part in SOURCE_PARTS)


def placeholders(text: str) -> set[str]:
    """The placeholder names used in a template."""
    return set(_PLACEHOLDER.findall(text))


def fill(text: str, values: dict[str, str]) -> str:
    """Replace every ``@NAME@`` of ``text`` by ``values[NAME]``.

    Raises:
        BuildError: a placeholder has no value.
    """
    missing = placeholders(text) - values.keys()
    if missing:
        raise BuildError(
            f"C template placeholders without a value: {', '.join(sorted(missing))}; "
            "the template and scdk_sym.codegen.generate disagree: reinstall scdk_sym"
        )
    return _PLACEHOLDER.sub(lambda match: values[match.group(1)], text)
