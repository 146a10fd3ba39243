"""The C templates of the standalone tracker, shipped as package data in ``codegen/c/``.

``tracker.h.in`` and ``tracker.c.in`` are C files with placeholders ``@NAME@`` (no braces, so
the templates read as C); :mod:`scdk_sym.codegen.generate` fills them with :func:`fill`.
``@P@`` is the lower-case C prefix of every exported name, ``@PU@`` its upper-case form for
macros; the others are the model's sizes, names, home configuration and the constants of the
judging rule (:mod:`scdk_sym.solvers.track`).
"""

from __future__ import annotations

import re
from importlib import resources

from ..errors import BuildError

#: The template files, in the package directory ``scdk_sym/codegen/c``.
HEADER = "tracker.h.in"
SOURCE = "tracker.c.in"

_PLACEHOLDER = re.compile(r"@([A-Z_]+)@")


def template(name: str) -> str:
    """The text of a template file.

    Args:
        name: file name in ``scdk_sym/codegen/c`` (:data:`HEADER` or :data:`SOURCE`).

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
