"""The in-memory cache of a model's solver products, with its keys declared in one place.

Every product a solver builds once per model (kernels, compiled libraries, algebraic forms,
start systems...) is kept by :class:`Products`, owned by the model as ``model.products``::

    form = model.products.get(ALGEBRAIC_FORM, lambda: _build(model, backend), backend)

A product is built on the first :meth:`Products.get` of its key (and variant) and returned
as is afterwards; it lives as long as its model, and two models never share one. Only the
keys of :data:`KEYS` are accepted, so the list below is the whole cache. This module
imports nothing above :mod:`scdk_sym.errors`, so every layer may use it.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any, TypeVar

from .errors import InputError

T = TypeVar("T")


@dataclass(frozen=True)
class Key:
    """A declared product of a model.

    Attributes:
        name: short identifier (unique).
        holds: what the product is.
        depends: what it is computed from (besides the model), i.e. its variants.
    """

    name: str
    holds: str
    depends: str


#: Zero-copy callers of ``model.kernels`` (:class:`~scdk_sym.kernels.fastcall.ModelCalls`).
MODEL_CALLS = Key("model_calls", "zero-copy callers of model.kernels", "the model only")
#: Follower kernels per backend (:class:`~scdk_sym.follower.calls.FollowerKernels`).
FOLLOWER_KERNELS = Key(
    "follower_kernels", "SC follower kernels (SX or compiled externals)", "backend"
)
#: Zero-copy callers of the follower kernels per backend.
FOLLOWER_CALLS = Key("follower_calls", "zero-copy callers of the follower kernels", "backend")
#: The compiled backend's library of a model and the Functions it was generated from
#: (:func:`scdk_sym.kernels.compile.compiled_library`).
COMPILED_LIBRARY = Key(
    "compiled_library", "the compiled backend's kernel library and its Functions", "the model only"
)
#: CVODES integrator engines of the SC field per backend (:mod:`scdk_sym.follower.cvodes`).
CVODES_ENGINES = Key("cvodes_engines", "CVODES integrators of the SC field", "backend")
#: Indices of the unknowns by kind (revolute angles, floating rotations, others).
UNKNOWN_KINDS = Key("unknown_kinds", "indices of the unknowns by kind", "the model only")
#: Buffered SX kernels of the Python tracker
#: (:func:`scdk_sym.solvers.tracker_numerics.track_kernels`).
TRACK_KERNELS = Key("track_kernels", "buffered SX kernels of the tracker", "the model only")
#: The model's compiled C tracker (:func:`scdk_sym.codegen.library.tracker_library`).
C_TRACKER = Key("c_tracker", "the compiled C curve tracker library", "the model only")
#: Algebraic forms per backend (:func:`scdk_sym.algebraic.form.algebraic_form`).
ALGEBRAIC_FORM = Key("algebraic_form", "polynomial form of the closure system", "backend")
#: The compiled homotopy continuation of the algebraic form
#: (:mod:`scdk_sym.algebraic.paths.continuation_c`).
HOMOTOPY_TRACKER = Key(
    "homotopy_tracker", "compiled homotopy path tracker of the algebraic form", "the model only"
)
#: Start systems of the homotopy (:func:`scdk_sym.solvers.start_system.model_start_system`).
START_SYSTEM = Key("start_system", "monodromy start system", "(backend, seed, max_loops)")

#: The Pinocchio model of an edited joint tree (:func:`scdk_sym.verify.pinocchio.pinocchio_model`).
PINOCCHIO_MODEL = Key(
    "pinocchio_model", "Pinocchio model of the edited joint tree", "the model only"
)
#: The closure rows as one square SX system, for Krawczyk
#: (:func:`scdk_sym.algebraic.certify.closure_function`).
CLOSURE_FUNCTION = Key(
    "closure_function", "closure rows as an SX Function of (y, [theta; c])", "the model only"
)
#: The block whose joints alone place the reported frame (:mod:`scdk_sym.solvers.blockwise`).
PLACING_BLOCK = Key(
    "placing_block", "index of the block that alone places the reported frame", "the model only"
)

#: Rods between ball joints and the model with each one a distance row
#: (:func:`scdk_sym.robot.rods.rod_reduction`).
ROD_REDUCTION = Key(
    "rod_reduction", "rods between balls and the model with them as distances", "the model only"
)
#: The compiled backends ``auto`` builds in the background (:mod:`scdk_sym.solvers.background`).
BACKGROUND_BUILDS = Key(
    "background_builds", "the background builds of the compiled backends and their state",
    "the model only",
)  # fmt: skip
#: The Jacobians of a model's full closure rows (:func:`scdk_sym.verify.mujoco.jacobian_error`).
CLOSURE_JACOBIANS = Key(
    "closure_jacobians", "the Jacobians of the full closure rows", "the model only"
)
#: The C solves bound to the last start each was called from, per branch
#: (:func:`scdk_sym.solvers.solve_c.solve_c`).
BOUND_C_SOLVES = Key(
    "bound_c_solves", "the C solves bound to their last start, per branch", "the model only"
)
#: The last start configuration checked assembled, and the last one's ``det J_p``
#: (:func:`scdk_sym.solvers.query.validate_start`, :func:`scdk_sym.solvers.query.start_det`).
CHECKED_START = Key(
    "checked_start", "the last start checked assembled and the last start's det J_p",
    "the model only",
)  # fmt: skip
#: Every declared key, by name.
KEYS: dict[str, Key] = {
    k.name: k
    for k in (
        MODEL_CALLS,
        FOLLOWER_KERNELS,
        FOLLOWER_CALLS,
        COMPILED_LIBRARY,
        CVODES_ENGINES,
        UNKNOWN_KINDS,
        TRACK_KERNELS,
        C_TRACKER,
        ALGEBRAIC_FORM,
        HOMOTOPY_TRACKER,
        START_SYSTEM,
        PINOCCHIO_MODEL,
        PLACING_BLOCK,
        CLOSURE_FUNCTION,
        ROD_REDUCTION,
        BACKGROUND_BUILDS,
        CLOSURE_JACOBIANS,
        BOUND_C_SOLVES,
        CHECKED_START,
    )
}


class Products:
    """The products of one model, built once per (key, variant)."""

    def __init__(self) -> None:
        self._store: dict[tuple[str, Hashable], Any] = {}

    @staticmethod
    def _slot(key: Key, variant: Hashable) -> tuple[str, Hashable]:
        if KEYS.get(getattr(key, "name", None)) is not key:  # type: ignore[arg-type]
            raise InputError(
                f"undeclared product key {key!r}; declare it in scdk_sym.products.KEYS"
            )
        return (key.name, variant)

    def get(self, key: Key, build: Callable[[], T], variant: Hashable = None) -> T:
        """The product ``key`` (of ``variant``), built by ``build()`` on first use.

        Args:
            key: a declared key of :data:`KEYS`.
            build: makes the product; called at most once per (key, variant). When it
                raises, nothing is stored.
            variant: what the product depends on besides the model (e.g. the backend).

        Returns:
            The stored product.

        Raises:
            InputError: ``key`` is not declared.
        """
        slot = self._slot(key, variant)
        if slot not in self._store:
            self._store[slot] = build()
        return self._store[slot]

    def put(self, key: Key, value: T, variant: Hashable = None) -> T:
        """Store ``value`` as the product ``key`` (of ``variant``), replacing any stored one.

        Raises:
            InputError: ``key`` is not declared.
        """
        self._store[self._slot(key, variant)] = value
        return value

    def peek(self, key: Key, variant: Hashable = None) -> Any:
        """The stored product ``key`` (of ``variant``), or ``None`` when not built yet.

        Raises:
            InputError: ``key`` is not declared.
        """
        return self._store.get(self._slot(key, variant))

    def __len__(self) -> int:
        return len(self._store)
