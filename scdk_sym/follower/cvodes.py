"""CVODES, CasADi's integrator, on the stabilised singularity-consistent field.

The field (:mod:`scdk_sym.kernels.functions`) is integrated over one chunk of arc length at a
time with ``GRID`` output samples; the curve follower judges each chunk (its ``cvodes``
predictor, :mod:`scdk_sym.follower.predictors`) exactly as it judges the explicit
predictor-corrector steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from ..backends import resolve
from ..kernels.fastcall import Buffered
from ..products import CVODES_ENGINES

#: Output samples per integrated chunk.
GRID = 8
#: Stabilisation gain K (g decays as exp(-K tau) over one chunk).
GAIN = 5.0
CVODES_OPTIONS: dict[str, Any] = {
    "linear_multistep_method": "adams",
    "nonlinear_solver_iteration": "functional",
    "abstol": 1e-11,
    "reltol": 1e-10,
    "max_num_steps": 500,
    "disable_internal_warnings": True,
}


@dataclass
class Engine:
    """Per-model numeric machinery of the SC solver (kernels, integrator, mapped probe).

    ``integrator``, ``probe`` and ``warm`` are called through zero-copy buffers (see
    :mod:`scdk_sym.kernels.fastcall`): use :meth:`integrate` and :meth:`probe_samples`. The
    integrator and the probe are built on first use (CasADi builds the field's Jacobian for
    CVODES, about 0.4 s for an 18-unknown leg, though functional iteration never calls it):
    a solve the warm kernel answers builds neither.
    """

    model: object
    kernels: object
    m: int
    k: int
    warm: Buffered

    @cached_property
    def integrator(self) -> Buffered:
        """CVODES over one chunk of the field, ``GRID`` output samples."""
        kern: Any = self.kernels
        q = ca.MX.sym("q", self.m + 1)
        p = ca.MX.sym("p", 2 * self.k + self.m + 3)
        c = ca.MX.sym("c", self.model.chart.size)  # type: ignore[attr-defined]
        dae = {"x": q, "p": ca.vertcat(p, c), "ode": without_jacobian(kern.field)(q, p, c)}
        grid = np.linspace(0.0, 1.0, GRID + 1)[1:]
        return Buffered(ca.integrator("sc_chunk", "cvodes", dae, 0.0, grid, CVODES_OPTIONS))

    @cached_property
    def probe(self) -> Buffered:
        """The probe kernel mapped over the ``GRID + 1`` points of a chunk."""
        kern: Any = self.kernels
        return Buffered(kern.probe.map(GRID + 1))

    def integrate(self, q: np.ndarray, p: np.ndarray) -> np.ndarray:
        """(m+1, GRID) samples of one chunk of the SC field from ``q``; p = (params, chart)."""
        f = self.integrator
        f.args[f.names.index("x0")][:] = q
        f.args[f.names.index("p")][:] = p
        out = f.run()
        return out[0].reshape(self.m + 1, GRID, order="F").copy()

    def probe_samples(self, Q: np.ndarray, p: np.ndarray, c: np.ndarray):
        """(tangents (m+1, N), vec J_p (m*m, N), x (n, N)) at the N = GRID + 1 samples Q."""
        n = GRID + 1
        f = self.probe
        f.args[0][:] = Q.ravel(order="F")
        f.args[1].reshape(n, -1)[:] = p  # the same p in every column
        if f.args[2].size:
            f.args[2].reshape(n, -1)[:] = c
        T, J, X = f.run()
        return (
            T.reshape(-1, n, order="F").copy(),
            J.reshape(-1, n, order="F").copy(),
            X.reshape(-1, n, order="F").copy(),
        )


def without_jacobian(f: ca.Function) -> ca.Function:
    """``f`` with a Jacobian that is not built: every entry NaN (a wrapper Function).

    CasADi builds the Jacobian of an integrator's right-hand side when it creates the
    integrator (about 0.4 s for the field of an 18-unknown leg, symbolically), though CVODES's
    functional iteration (:data:`CVODES_OPTIONS`) never evaluates it; a NaN Jacobian costs
    nothing to build, and an iteration that did use it would fail loudly, never silently.
    ``jac_penalty`` 0 makes CasADi derive the directional derivatives it prepares from that
    Jacobian too (NaN as well) instead of building them by AD.
    """
    ins = [ca.MX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    outs = [ca.MX.sym(f"out_{f.name_out(i)}", f.sparsity_out(i)) for i in range(f.n_out())]
    jac = [
        ca.MX(ca.DM.nan(f.nnz_out(j), f.nnz_in(i)))
        for j in range(f.n_out())
        for i in range(f.n_in())
    ]
    name = f"{f.name()}_no_jacobian"
    nan = ca.Function(f"jac_{name}", ins + outs, jac)
    return ca.Function(name, ins, f.call(ins), {"custom_jacobian": nan, "jac_penalty": 0})


def engine(model, backend: str = "cvodes") -> Engine:
    """The (cached) SC engine of a model.

    Args:
        model: the model.
        backend: "cvodes" (SX Functions) or "compiled" (generated C, cached on disk); see
            :mod:`scdk_sym.backends`.

    Raises:
        InputError: a backend the kernel builders do not offer.
    """
    backend = resolve(backend, "kernels")
    return model.products.get(CVODES_ENGINES, lambda: _build_engine(model, backend), backend)


def _build_engine(model, backend: str) -> Engine:
    """Build the SC engine of ``model`` with the kernels of ``backend`` (resolved)."""
    if backend == "cvodes":
        kern = model.kernels
    else:
        from ..kernels.compile import compiled_kernels

        kern = compiled_kernels(model)
    return Engine(model, kern, model.m, model.k, Buffered(kern.warm))
