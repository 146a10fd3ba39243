"""Optional dependencies: imported on first use, with the install command when missing."""

from __future__ import annotations

import importlib
from types import ModuleType

from .errors import ScdkError


def require(
    modules: str | tuple[str, ...],
    *,
    needed_for: str,
    install: str,
    error: type[ScdkError],
) -> ModuleType:
    """Import optional modules, or raise ``error`` saying how to install them.

    Args:
        modules: a module name, or several (all must import); the first one is returned.
        needed_for: what needs them, for the message (e.g. "figures").
        install: the install command (e.g. ``pip install "scdk_sym[plot]"``).
        error: the :class:`~scdk_sym.errors.ScdkError` subclass raised.

    Returns:
        The first module.

    Raises:
        error: a module cannot be imported (the message names it and the install command).
    """
    names = (modules,) if isinstance(modules, str) else modules
    loaded = []
    for name in names:
        try:
            loaded.append(importlib.import_module(name))
        except ImportError as exc:
            raise error(
                f"{name.split('.')[0]} is not installed (needed for {needed_for}): {install}"
            ) from exc
    return loaded[0]
