"""The C templates of the standalone tracker, shipped as package data in ``codegen/c/``.

The templates are C files with placeholders ``@NAME@`` (no braces, so the templates read as
C); :mod:`scdk_sym.codegen.generate` fills them with :func:`fill`. ``tracker.h.in`` is the
header; the source ``<prefix>_tracker.c`` is one file made of the parts
:data:`SOURCE_PARTS`, one idea each, joined in that order by :func:`source`: the constants
and the small public functions (``tracker.c.in``), the numerics and kernel calls, the context
of a step, the curve follower, the divergent walk, the judging rule, the tracker's state and
tracks, the solves and the atlas sweep. ``@P@`` is the lower-case C prefix of every exported
name, ``@PU@`` its upper-case form for macros; the others are the model's sizes, names, home
configuration, the constants of the judging rule (:mod:`scdk_sym.solvers.track`) and the
status codes (:mod:`scdk_sym.codegen.status`).
"""

from __future__ import annotations

import re
from importlib import resources

from ..errors import BuildError

#: The template files, in the package directory ``scdk_sym/codegen/c``.
HEADER = "tracker.h.in"
SOURCE = "tracker.c.in"
#: The parts of the tracker's source, in the order :func:`source` joins them.
SOURCE_PARTS = (
    SOURCE,  # the model's constants, the options and the status strings
    "tracker_numerics.c.in",  # small numerics, the LU wrappers, the kernel calls, Newton
    "tracker_context.c.in",  # what one step knows (step_ctx)
    "tracker_follow.c.in",  # the curve follower (follow)
    "tracker_walk.c.in",  # the divergent solve's walk, judged step by step
    "tracker_rule.c.in",  # the judging rule: cheap continuations, candidates, the choice
    "tracker_track.c.in",  # the state, a step, whole tracks
    "tracker_solve.c.in",  # the convergent and divergent solves, the inverse kinematics
    "tracker_sweep.c.in",  # the atlas sweep
)

_PLACEHOLDER = re.compile(r"@([A-Z_]+)@")


def template(name: str) -> str:
    """The text of a template file.

    Args:
        name: file name in ``scdk_sym/codegen/c`` (:data:`HEADER`, one of
            :data:`SOURCE_PARTS`, ...).

    Raises:
        BuildError: the file is missing (an installation without the package data).
    """
    try:
        return resources.files(__package__).joinpath("c").joinpath(name).read_text(encoding="utf-8")
    except (FileNotFoundError, OSError) as exc:
        raise BuildError(
            f"C template {name!r} not found in the scdk_sym package: reinstall scdk_sym "
            "(the package data codegen/c/*.in must be installed)"
        ) from exc


def source() -> str:
    """The template of the tracker's source: the parts :data:`SOURCE_PARTS` joined in order,
    a blank line between two.

    Raises:
        BuildError: a part is missing.
    """
    return "\n".join(template(name) for name in SOURCE_PARTS)


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
