"""One backend vocabulary for every function and command with a ``backend`` argument.

Each name is defined once here, with one meaning and a one-line help (the backend
table of the user guide, docs/guide/c.md, is the same list):

- ``auto``: the fastest backend the function offers on this machine (the first of its
  :data:`OFFERS` whose requirements are met: a C compiler for ``compiled`` and ``c``);
- ``cvodes``: kernels as CasADi SX functions driven from Python (CVODES integrates the SC ODE
  where a path is integrated), nothing to compile;
- ``compiled``: the same kernels generated as C, compiled once and cached on disk;
- ``c``: the whole path in the generated C follower, compiled once and cached.

A public function validates its ``backend`` once with :func:`resolve`, which returns the
concrete name it runs as a :class:`Resolved` (``auto`` resolved) and raises
:class:`~scdk_sym.errors.InputError` listing the names the function offers. The
:class:`Resolved` is passed down: the layers below take it as it is (a ``str``, compared with
the names), without a second validation or a second choice for ``auto``. Deprecated aliases
(:data:`ALIASES`, e.g. ``casadi`` for ``cvodes``) keep working and warn once per process
with a :class:`DeprecationWarning`.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from types import MappingProxyType

from .errors import BuildError, InputError


@dataclass(frozen=True)
class Backend:
    """One backend name of the vocabulary.

    Attributes:
        name: the name passed as ``backend=`` or ``--backend``.
        help: one line: what runs, and what it needs.
        needs_compiler: it compiles generated C on first use (a C compiler must be found).
    """

    name: str
    help: str
    needs_compiler: bool = False


class Resolved(str):
    """A backend name resolved once, at a public boundary, and passed down as it is.

    A ``str`` (the concrete name: compare it with ``"c"``, ``"compiled"``, ...), so results
    and JSON carry the plain name.

    Attributes:
        asked: what the caller passed (``"auto"``, a deprecated alias, or the name itself);
            ``None`` when unknown (a copy made by pickling).
    """

    asked: str | None

    def __new__(cls, name: str, asked: str | None = None) -> Resolved:
        obj = super().__new__(cls, name)
        obj.asked = asked
        return obj


#: Every backend name -> its definition.
BACKENDS: Mapping[str, Backend] = MappingProxyType(
    {
        b.name: b
        for b in (
            Backend(
                "auto",
                "the fastest backend this function offers on this machine (a compiled one when "
                "a C compiler is found)",
            ),
            Backend(
                "cvodes",
                "CasADi SX kernels driven from Python (CVODES integrates the SC ODE); nothing "
                "to compile",
            ),
            Backend(
                "compiled",
                "the same kernels generated as C, compiled once with $CC (or gcc) and cached",
                needs_compiler=True,
            ),
            Backend(
                "c",
                "the whole path in the generated C follower, compiled once with $CC (or gcc) "
                "and cached",
                needs_compiler=True,
            ),
        )
    }
)

#: Deprecated name -> the name it stands for (same meaning); each warns once per process.
ALIASES: Mapping[str, str] = MappingProxyType({"casadi": "cvodes"})

#: Function -> the concrete backends it offers, fastest first (``auto`` takes the first one
#: available on this machine; every function also offers ``auto``). A function gains a backend
#: by adding its name here and dispatching on it (e.g. ``"c"`` for ``solve``).
OFFERS: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "solve": ("c", "compiled", "cvodes"),
        "track": ("c", "cvodes"),
        "modes": ("compiled", "cvodes"),  # the certified homotopy
        "curves": ("compiled", "cvodes"),  # the real-curve search of the modes
        "kernels": ("compiled", "cvodes"),  # the kernel builders under the solvers
    }
)

#: Function -> its default backend (unchanged from the first releases).
DEFAULTS: Mapping[str, str] = MappingProxyType(
    {"solve": "cvodes", "track": "cvodes", "modes": "auto", "curves": "cvodes", "kernels": "cvodes"}
)

_WARNED: set[str] = set()


def offered(function: str) -> tuple[str, ...]:
    """The backend names ``function`` accepts: ``auto`` and its concrete backends.

    Args:
        function: a key of :data:`OFFERS` (``"solve"``, ``"track"``, ``"modes"``, ...).
    """
    return ("auto", *OFFERS[function])


def canonical(backend: str, function: str) -> str:
    """The registry name of ``backend`` for ``function`` (an alias replaced, ``auto`` kept).

    Args:
        backend: a backend name or deprecated alias.
        function: a key of :data:`OFFERS`.

    Raises:
        InputError: ``function`` does not offer ``backend`` (the names it offers listed).
    """
    name = backend
    if isinstance(backend, str) and backend in ALIASES:
        name = ALIASES[backend]
        if backend not in _WARNED:
            _WARNED.add(backend)
            warnings.warn(
                f"backend {backend!r} is deprecated; use {name!r} (the same backend)",
                DeprecationWarning,
                stacklevel=4,  # the caller of the function that resolves its backend
            )
    names = offered(function)
    if name not in names:
        raise InputError(
            f"backend {backend!r} is not offered by {function}; backends: {', '.join(names)} "
            "(docs/guide/c.md: Backends)"
        )
    return name


def available(name: str) -> bool:
    """Whether backend ``name`` can run on this machine (a C compiler for compiled ones).

    The compiler search is remembered per value of ``$CC`` and ``$PATH``.
    """
    if not BACKENDS[name].needs_compiler:
        return True
    return _compiler_found(os.environ.get("CC", ""), os.environ.get("PATH", ""))


@lru_cache(maxsize=8)
def _compiler_found(cc: str, path: str) -> bool:
    """Whether :func:`~scdk_sym.kernels.compile.compiler_command` finds a compiler (the
    arguments are the environment it reads, as the cache key)."""
    from .kernels.compile import compiler_command

    try:
        compiler_command()
    except BuildError:
        return False
    return True


def resolve(backend: str, function: str) -> Resolved:
    """The concrete backend ``function`` runs for ``backend`` (validated, ``auto`` resolved).

    A :class:`Resolved` passed down from a public function is returned as it is when
    ``function`` offers it (no second validation, no second choice for ``auto``).

    Args:
        backend: a backend name or deprecated alias, or a :class:`Resolved`.
        function: a key of :data:`OFFERS`.

    Returns:
        One of ``OFFERS[function]``, as a :class:`Resolved`.

    Raises:
        InputError: ``function`` does not offer ``backend`` (the names it offers listed).
    """
    if isinstance(backend, Resolved) and backend in OFFERS[function]:
        return backend
    name = canonical(backend, function)
    if name == "auto":
        name = next((n for n in OFFERS[function] if available(n)), OFFERS[function][-1])
    return Resolved(name, backend)


def help_text(function: str, default: str | None = None) -> str:
    """The help of a ``--backend`` option: every name ``function`` offers with its one line.

    Args:
        function: a key of :data:`OFFERS`.
        default: how the default is stated (default: ``DEFAULTS[function]``).
    """
    lines = [f"{n}: {BACKENDS[n].help}" for n in offered(function)]
    lines += [f"{a}: deprecated name of {t}" for a, t in ALIASES.items() if t in OFFERS[function]]
    return (
        "; ".join(lines) + f" (default: {default or DEFAULTS[function]}; docs/guide/c.md: Backends)"
    )
