"""CasADi Functions of the curve follower (SX, or generated C compiled once and cached).

The curve is ``H(q) = 0`` with ``q = (y, s)``, ``H = g(y, theta1 + s dtheta)`` and
``p = (theta1, dtheta)``; its Jacobian is ``[J_p, -j_s]`` with ``j_s = J_s dtheta``. Lengths along
it are measured in the metric ``|dy|^2 + (|dtheta| ds)^2`` (arc length in joint space).

The oriented tangent has one definition in the package,
:func:`~scdk_sym.kernels.curve.bordered_tangent`, the bordered solve
``[H'; v^T] t = e_{m+1}``: by Cramer's rule ``t`` is parallel to the SC field
``nu = [adj(J_p) j_s; det J_p]`` (the generalised cross product of the rows of ``H'``) with
``v . t > 0``. It is regular on the singular manifold ``det J_p = 0`` (folds) and only fails
where ``H'`` drops rank (bifurcations, handled by the follower). Along a branch
``sign(t_s) = sign(det J_p) * sign(det [H'; v^T])``: at a fold ``t_s`` and ``det J_p`` change
sign together; at a bifurcation ``det J_p`` changes sign while ``t_s`` does not.

The Functions are built by :func:`~scdk_sym.kernels.follower.build_follower_kernels` (from the
symbolic steps of :mod:`scdk_sym.kernels.curve`: the tangent, the Newton correction, the RK4
step in ``s``, which the CVODES field, :mod:`scdk_sym.kernels.functions`, is also built from);
the generated C tracker's curve kernels are the same Functions
(:mod:`scdk_sym.kernels.tracker_functions`). This module keeps them per model and backend, and their
zero-copy callers.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import casadi as ca

from ..backends import resolve
from ..kernels.fastcall import Dense
from ..kernels.follower import (
    CORRECTIONS,
    FOLD_STEPS,
    NEWTON_ITERATIONS,
    PLANE_STEPS,
    POLISH_STEPS,
    STEPS,
    FollowerKernels,
    build_follower_kernels,
)
from ..products import FOLLOWER_CALLS, FOLLOWER_KERNELS

__all__ = [
    "COMPILED_GROUPS",
    "CORRECTIONS",
    "FOLD_STEPS",
    "INLINE_MAX_UNKNOWNS",
    "NEWTON_ITERATIONS",
    "PLANE_STEPS",
    "POLISH_STEPS",
    "STEPS",
    "FollowerCalls",
    "FollowerKernels",
    "build_follower_kernels",
    "follower_calls",
    "follower_kernels",
]

#: The kernels of the compiled backend (:func:`follower_kernels`), in its library
#: (:func:`~scdk_sym.kernels.compile.compiled_library`, whose
#: :data:`~scdk_sym.kernels.compile.LIBRARY_GROUPS` lay them out): those called at every
#: predictor-corrector chunk, then the locators called a few times per singular point or
#: projection (the plane, the fold, the singular-manifold Newton data). ``newton`` and
#: ``predict``, which only the C tracker calls, are not compiled.
COMPILED_GROUPS = (("steps", "step", "tangent", "polish"), ("plane", "fold", "singular"))


#: Largest number of unknowns whose SX follower kernels are written out (inlined); larger
#: systems call their inner Functions (the same operations, built in a tenth of the time).
INLINE_MAX_UNKNOWNS = 9


def follower_kernels(model, backend: str = "cvodes") -> FollowerKernels:
    """The (cached) follower kernels of a model.

    Args:
        model: the model.
        backend: "cvodes" (SX virtual machine) or "compiled" (generated C compiled with the
            system compiler once, cached on disk by content hash: the kernels of
            :data:`COMPILED_GROUPS`, the others SX Functions); see :mod:`scdk_sym.backends`.

    Raises:
        InputError: a backend the kernel builders do not offer.
        BuildError: no C compiler (compiled backend).
    """
    backend = resolve(backend, "kernels")

    def build() -> FollowerKernels:
        if backend != "compiled":
            # above INLINE_MAX_UNKNOWNS the written-out kernels take seconds to build (an
            # 18-unknown leg: 3.8 s inlined, 0.3 s as calls of the inner Functions)
            return build_follower_kernels(model.symbolic, inline=model.m <= INLINE_MAX_UNKNOWNS)
        from ..kernels.compile import compiled_library

        # calls of one closure Function and of each Newton step: the same operations as the
        # inlined kernels, several times less C to compile; the small bordered solves written
        # out (calls of one solver cost the steps, the hot kernel, 4-9% of their time)
        lib = compiled_library(model)
        compiled = {name for group in COMPILED_GROUPS for name in group}
        kern = lib.follower
        return FollowerKernels(
            *(
                ca.external(getattr(kern, f.name).name(), str(lib.path))
                if f.name in compiled
                else getattr(kern, f.name)
                for f in fields(kern)
            )
        )

    return model.products.get(FOLLOWER_KERNELS, build, backend)


@dataclass(frozen=True)
class FollowerCalls:
    """Zero-copy callers of :class:`FollowerKernels` (:class:`~scdk_sym.kernels.fastcall.Dense`):
    the same signatures and values as the plain calls, outputs as numpy arrays (the residuals
    of ``plane`` and ``polish`` as floats)."""

    steps: Dense
    tangent: Dense
    plane: Dense
    fold: Dense
    polish: Dense
    singular: Dense


def follower_calls(model, backend: str = "cvodes") -> FollowerCalls:
    """The (cached) zero-copy callers of :func:`follower_kernels` (same arguments)."""
    backend = resolve(backend, "kernels")

    def build() -> FollowerCalls:
        kern = follower_kernels(model, backend)
        return FollowerCalls(
            Dense(kern.steps),
            Dense(kern.tangent),
            Dense(kern.plane, scalars=(1,)),
            Dense(kern.fold),
            Dense(kern.polish, scalars=(1,)),
            Dense(kern.singular),
        )

    return model.products.get(FOLLOWER_CALLS, build, backend)
