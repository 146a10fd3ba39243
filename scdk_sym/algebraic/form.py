"""The algebraic form of a loaded model: a square polynomial system ``G(z, p) = 0``.

:func:`algebraic_form` turns a model's reduced loop-closure system ``g(y, theta) = 0`` into the
square system of :mod:`scdk_sym.algebraic.polynomial` (holomorphic in the unknowns ``z`` and
the parameters ``p``), whose real solutions at ``p = params(theta0)`` correspond one-to-one to
the real solutions ``y`` of ``g(y, theta0) = 0`` (angles modulo 2 pi; a rotation whose
quaternion lies on the chart's hyperplane at infinity ``a . q = 0``, a set of measure zero,
has no image). The returned :class:`AlgebraicForm` implements the polynomial-system protocol
agreed with the homotopy engine (``scdk_sym.algebraic.system.PolynomialSystem``, quoted
verbatim but for the docstring quotes)::

    class PolynomialSystem(Protocol):
        '''A square family G(z, p) = 0, holomorphic in z (C^n) and in the parameters p
        (C^n_params).'''

        n: int                    # number of complex unknowns z (= number of rows)
        n_params: int             # number of complex parameters p
        offset_rows: np.ndarray   # (n,) bool: rows that take a generic constant offset b_i in
                                  # the homotopy family G(z, p) + b = 0 (closure rows).
                                  # Structural rows (c^2 + s^2 - 1, a quaternion chart
                                  # a.q - 1, w (q.q) - 1) are False: b_i = 0 there always.

        def evaluate(self, z: np.ndarray, p: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            '''z: (N, n) complex, p: (N, n_params) complex ->
            G (N, n), dG/dz (N, n, n), dG/dp (N, n, n_params), all complex.'''

        def random_point(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
            '''A random complex z (n,) on which every structural row (offset_rows False)
            vanishes, and a random complex parameter point p (n_params,).'''

        def content_hash(self) -> str:
            '''A hex digest of everything G depends on (start systems are cached under it).'''

The homotopy family is ``F(z; p, b) = G(z, p) + b`` (``b_i = 0`` on structural rows); the
target of a query is ``(params(theta0), b = 0)``. :class:`AlgebraicForm` also accepts one
point (``z`` (n,)) and a shared ``p`` (n_params,) in :meth:`~AlgebraicForm.evaluate`, and
adds the mapping to and from the model (:meth:`AlgebraicForm.params`,
:meth:`~AlgebraicForm.to_model`, :meth:`~AlgebraicForm.from_model`,
:meth:`~AlgebraicForm.is_real`) and the real restriction :attr:`AlgebraicForm.G_real` that an
interval certifier can replay.

Complex evaluation: CasADi has no complex type, so the real SX Function ``G_real`` is replayed
on (real, imaginary) pairs once (:mod:`scdk_sym.algebraic.pairs`), giving one SX Function
``(zr, zi, pr, pi) -> (Re G, Im G, Re dG/dz, Im dG/dz, Re dG/dp, Im dG/dp)``, mapped over the
columns of a batch (``Function.map``) so that one :meth:`~AlgebraicForm.evaluate` is one call.
Backend ``"cvodes"`` runs it in CasADi's SX virtual machine, ``"compiled"`` as generated C
(compiled once, cached on disk by the hash of its source).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from ..backends import resolve
from ..errors import AlgebraicFormError, InputError
from ..kernels.fastcall import Buffered
from ..model.rotations import cayley, quaternion_matrix, quaternion_of, rot_exp
from ..products import ALGEBRAIC_FORM
from .pairs import complexify
from .polynomial import PolynomialRows, polynomial_rows

if TYPE_CHECKING:
    from ..robot import Model

#: Version of the algebraic form (part of :meth:`AlgebraicForm.content_hash`).
FORM_VERSION = "1"
#: Scale of the imaginary parts of random complex angles (start points and angle parameters).
ANGLE_IMAG = 0.1
#: Step of the monodromy loops in an angle parameter [rad] (:attr:`AlgebraicForm.param_widths`).
LOOP_ANGLE = 0.5
#: Batch sizes whose mapped Functions are kept per form.
_MAPS_KEPT = 16


def _complex(re: np.ndarray, im: np.ndarray) -> np.ndarray:
    out = np.empty(re.shape, dtype=complex)
    out.real = re
    out.imag = im
    return out


def _source_digest() -> bytes:
    here = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for part in ("form.py", "polynomial.py", "pairs.py"):
        h.update((here / part).read_bytes())
    return h.digest()


@dataclass(frozen=True, eq=False)
class AlgebraicForm:
    """A model's closure system as a square polynomial system ``G(z, p) = 0``.

    Make one with :func:`algebraic_form`. Structurally a
    ``scdk_sym.algebraic.system.PolynomialSystem`` (see the module docstring).

    Attributes:
        model: the model (:class:`~scdk_sym.robot.Model`).
        backend: ``"cvodes"`` (SX) or ``"compiled"`` (see :mod:`scdk_sym.backends`).
        n: number of complex unknowns ``z`` (= number of rows).
        n_params: number of complex parameters ``p`` (= ``model.k``).
        offset_rows: (n,) bool, True on closure rows, False on structural rows.
        rows: the symbolic system (:class:`~scdk_sym.algebraic.polynomial.PolynomialRows`):
            slots, names of the unknowns, row labels.
        G_real: SX Function ``(z[n], p[n_params]) -> G[n]``, real coefficients.
        G_complex: Function ``(zr[n], zi[n], pr[k], pi[k]) -> (Gr[n], Gi[n], Jz_r[n,n],
            Jz_i[n,n], Jp_r[n,k], Jp_i[n,k])`` of one point (SX, or the compiled external).
        G_pairs: the SX Function ``G_complex`` is (or is compiled from): its algorithm, which
            the C path tracker compiles for lane vectors.
    """

    model: Model = field(repr=False)
    backend: str
    n: int
    n_params: int
    offset_rows: np.ndarray = field(repr=False)
    rows: PolynomialRows = field(repr=False)
    G_real: ca.Function = field(repr=False)
    G_complex: ca.Function = field(repr=False)
    G_pairs: ca.Function = field(repr=False)
    _maps: dict[int, Buffered] = field(default_factory=dict, repr=False, compare=False)

    # ------------------------------------------------------------------ protocol

    def evaluate(self, z: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``G``, ``dG/dz`` and ``dG/dp`` at a batch of complex points, in one call.

        Args:
            z: (N, n) complex unknowns (or (n,) for one point).
            p: (N, n_params) complex parameters, or (n_params,) shared by every point.

        Returns:
            ``G`` (N, n), ``dG/dz`` (N, n, n) and ``dG/dp`` (N, n, n_params), complex (without
            the leading N when ``z`` is (n,)).

        The mapped Functions run through preallocated buffers (one per batch size, the last 16
        sizes kept): call one form from one thread at a time.

        Raises:
            InputError: wrong shapes or non-finite values.
        """
        z = np.asarray(z, dtype=complex)
        single = z.ndim == 1
        z = np.atleast_2d(z)
        if z.ndim != 2 or z.shape[1] != self.n:
            raise InputError(f"z must be (N, {self.n}) complex, got shape {np.shape(z)}")
        N = z.shape[0]
        p = np.asarray(p, dtype=complex)
        if p.ndim == 1 and N > 1:
            p = np.broadcast_to(p, (N, p.size))
        if p.shape != (N, self.n_params) and (N, p.shape) != (1, (self.n_params,)):
            raise InputError(
                f"p must be ({N}, {self.n_params}) or ({self.n_params},) complex, "
                f"got shape {p.shape}"
            )
        if not (np.isfinite(z).all() and np.isfinite(p).all()):
            raise InputError("z and p must be finite")
        n, k = self.n, self.n_params
        if N == 0:
            empty = np.zeros((0, n), complex)
            return empty, np.zeros((0, n, n), complex), np.zeros((0, n, k), complex)
        # column-major (n, N) inputs are the row-major (N, n) arrays, flattened
        out = self._mapped(N)(z.real.ravel(), z.imag.ravel(), p.real.ravel(), p.imag.ravel())
        G = _complex(out[0], out[1]).reshape(N, n)
        Jz = _complex(out[2], out[3]).reshape(N, n, n).transpose(0, 2, 1)
        Jp = _complex(out[4], out[5]).reshape(N, k, n).transpose(0, 2, 1)
        if single:
            return G[0], Jz[0], Jp[0]
        return G, Jz, Jp

    def random_point(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """A random complex ``z`` (n,) on which every structural row vanishes, and a random
        complex parameter point ``p`` (n_params,).

        Angles: ``(cos t, sin t)`` of a complex ``t`` with an imaginary part of the order of
        :data:`ANGLE_IMAG`; quaternions: a complex normal ``q`` scaled onto the chart
        (``a . q = 1``), ``w = 1 / (q . q)``; lengths and translations: complex normals times
        the model's size; ``p``: the home actuator values plus a complex normal (times the
        model's size for lengths, times :data:`ANGLE_IMAG` for angles).

        The imaginary parts of angles add up along a chain of joints and a rotation grows
        like ``exp`` of their sum: with imaginary parts of order one, a model with long
        chains (several loops in series) gets a base fibre whose points are hundreds of
        times the model's scale, where Newton stagnates above the tracker's tolerances.
        """
        scale = float(self.model.length_scale) or 1.0
        z = np.zeros(self.n, dtype=complex)

        def cnormal(size=None):
            return rng.normal(size=size) + 1j * rng.normal(size=size)

        for s in self.rows.slots:
            if s.kind == "angle":
                t = rng.uniform(-np.pi, np.pi) + 1j * ANGLE_IMAG * rng.normal()
                z[list(s.z)] = np.cos(t), np.sin(t)
            elif s.kind == "length":
                z[s.z[0]] = scale * cnormal()
            else:
                q = cnormal(4)
                q = q / (np.asarray(s.chart) @ q)
                z[list(s.z[:3])] = scale * cnormal(3)
                z[list(s.z[3:7])] = q
                z[s.z[7]] = 1.0 / (q @ q)
        widths = np.array([scale if k == "length" else ANGLE_IMAG for k in self.rows.param_kinds])
        p = self.model.home.theta + widths * cnormal(self.n_params)
        return z, p

    @property
    def param_widths(self) -> np.ndarray:
        """(n_params,) size of the monodromy loops' steps in each parameter: the model's
        size for lengths, :data:`LOOP_ANGLE` for angles (a complex angle step of order one
        swings a chain's rotations by ``e`` per joint, and half of the loops' paths fail)."""
        scale = float(self.model.length_scale) or 1.0
        return np.array([scale if k == "length" else LOOP_ANGLE for k in self.rows.param_kinds])

    def content_hash(self) -> str:
        """Hex digest of everything ``G`` depends on: the model's kernel cache key (its files,
        frame, the symbolic code, CasADi's version), the form's version and source."""
        from ..kernels.compile import cache_key

        h = hashlib.sha256(cache_key(self.model).encode())
        h.update(FORM_VERSION.encode())
        h.update(_source_digest())
        return h.hexdigest()

    # ------------------------------------------------------------------ model mapping

    def params(self, theta) -> np.ndarray:
        """Parameters ``p`` (n_params,) complex of real actuator values ``theta`` (k,)
        [rad or model length unit]: the values themselves (angles enter ``G`` through
        cos and sin)."""
        from ..robot import as_vector

        return as_vector(theta, self.n_params, "theta").astype(complex)

    def from_model(self, y, c: np.ndarray | None = None) -> np.ndarray:
        """Unknowns ``z`` (n,) real of the model's unknowns.

        Args:
            y: (m,) unknowns, canonical (``c is None``: rotation vectors for floating joints)
                or in the local chart ``c`` (see :mod:`scdk_sym.model.chart`).
            c: the chart of ``y`` (9 per floating joint), or ``None``.

        Raises:
            InputError: wrong size or non-finite values.
            AlgebraicFormError: a rotation on the quaternion chart's plane at infinity.
        """
        from ..robot import as_vector

        m = self.model
        y = as_vector(y, m.m, "y")
        if c is not None:
            c = as_vector(c, m.chart.size, "c")
        z = np.zeros(self.n)
        for s in self.rows.slots:
            if s.kind == "angle":
                z[list(s.z)] = np.cos(y[s.y[0]]), np.sin(y[s.y[0]])
            elif s.kind == "length":
                z[s.z[0]] = y[s.y[0]]
            else:
                rot = y[list(s.y[3:])]
                if c is None:
                    R = rot_exp(rot)
                else:
                    i = m.chart.rotations.index(tuple(s.y[3:]))
                    R = c[9 * i : 9 * i + 9].reshape(3, 3, order="F") @ cayley(rot)
                q = quaternion_of(R)
                aq = float(np.asarray(s.chart) @ q)
                if abs(aq) < 1e-12:
                    raise AlgebraicFormError(
                        f"the rotation of floating joint {s.joint!r} lies on the quaternion "
                        "chart's plane at infinity (a . q = 0); perturb y slightly"
                    )
                q = q / aq
                z[list(s.z[:3])] = y[list(s.y[:3])]
                z[list(s.z[3:7])] = q
                z[s.z[7]] = 1.0 / (q @ q)
        return z

    def to_model(
        self, z, reference: np.ndarray | None = None, tol: float = 1e-8
    ) -> tuple[np.ndarray, np.ndarray]:
        """The model's unknowns ``(y, c)`` of a real ``z``: ``y`` in the local chart ``c``
        (floating rotations: ``rho = 0`` and ``c`` their rotation), ready for
        ``model.configuration(y, theta, c)`` and ``model.residual(y, theta, c)``.

        Args:
            z: (n,) real unknowns, or a batch (N, n) (complex accepted when its imaginary part
                is below ``tol``, relative to ``max(1, |z|)``).
            reference: (m,) canonical unknowns; each angle is taken the nearest to its
                reference value modulo 2 pi (default: in (-pi, pi]).
            tol: tolerance on the imaginary part.

        Returns:
            ``y`` (m,) and ``c`` (chart size,), or (N, m) and (N, chart size) for a batch.

        Raises:
            InputError: wrong size, non-finite, or not real (any row of a batch).
        """
        m = self.model
        z = np.asarray(z)
        single = z.ndim == 1
        if z.shape[-1:] != (self.n,) or z.ndim > 2 or not np.all(np.isfinite(z)):
            raise InputError(f"z must be {self.n} finite numbers, got shape {z.shape}")
        z = np.atleast_2d(z)
        if np.iscomplexobj(z):
            if not np.all(self.is_real(z, tol)):
                raise InputError(
                    f"z is not real (max |Im z| = {np.abs(z.imag).max():.2e} > {tol:.1e}); "
                    "select real solutions with is_real first"
                )
            z = z.real
        z = np.asarray(z, dtype=float)
        ref = None if reference is None else np.asarray(reference, dtype=float)
        y = np.zeros((len(z), m.m))
        c = np.zeros((len(z), m.chart.size))
        for s in self.rows.slots:
            if s.kind == "angle":
                a = np.arctan2(z[:, s.z[1]], z[:, s.z[0]])
                if ref is not None:
                    a += 2 * np.pi * np.round((ref[s.y[0]] - a) / (2 * np.pi))
                y[:, s.y[0]] = a
            elif s.kind == "length":
                y[:, s.y[0]] = z[:, s.z[0]]
            else:
                R = quaternion_matrix(z[:, list(s.z[3:7])])  # orthonormal to rounding
                i = m.chart.rotations.index(tuple(s.y[3:]))
                c[:, 9 * i : 9 * i + 9] = R.transpose(0, 2, 1).reshape(len(z), 9)
                y[:, list(s.y[:3])] = z[:, list(s.z[:3])]
        return (y[0], c[0]) if single else (y, c)

    def is_real(self, z, tol: float = 1e-8) -> bool | np.ndarray:
        """Whether ``z`` (n,) is real: ``max |Im z| <= tol max(1, max |z|)``; for a batch
        (N, n), one bool per row (N,)."""
        z = np.asarray(z)
        if not np.iscomplexobj(z):
            return True if z.ndim == 1 else np.ones(z.shape[0], dtype=bool)
        ok = np.abs(z.imag).max(axis=-1) <= tol * np.maximum(1.0, np.abs(z).max(axis=-1))
        return bool(ok) if z.ndim == 1 else ok

    # ------------------------------------------------------------------ internals

    def _mapped(self, N: int) -> Buffered:
        f = self._maps.get(N)
        if f is None:
            if len(self._maps) >= _MAPS_KEPT:
                self._maps.pop(next(iter(self._maps)))
            f = self._maps[N] = Buffered(self.G_complex if N == 1 else self.G_complex.map(N))
        return f


def _build(model: Model, backend: str) -> AlgebraicForm:
    rows = polynomial_rows(model)
    G_real = ca.Function("G_real", [rows.z, rows.p], [rows.G], ["z", "p"], ["G"])
    G_pairs = G_complex = complexify(G_real, "algebraic_G")
    if backend == "compiled":
        from ..kernels.compile import cached_library

        path = cached_library([G_pairs], "algebraic_G")
        G_complex = ca.external(G_pairs.name(), str(path))
    return AlgebraicForm(
        model=model,
        backend=backend,
        n=rows.n,
        n_params=rows.k,
        offset_rows=rows.offset_rows,
        rows=rows,
        G_real=G_real,
        G_complex=G_complex,
        G_pairs=G_pairs,
    )


def algebraic_form(model: Model, backend: str = "cvodes") -> AlgebraicForm:
    """The algebraic form of a loaded model (built once per model and backend, cached on it).

    Args:
        model: a loaded :class:`~scdk_sym.robot.Model`.
        backend: ``"cvodes"`` (CasADi SX virtual machine) or ``"compiled"`` (generated C,
            compiled once and cached on disk by content hash); see :mod:`scdk_sym.backends`.

    Returns:
        The :class:`AlgebraicForm`.

    Raises:
        InputError: a backend the kernel builders do not offer.
        AlgebraicFormError: a joint type with no algebraic form.
        BuildError: the compiled backend cannot compile (no C compiler).
    """
    backend = resolve(backend, "kernels")
    return model.products.get(ALGEBRAIC_FORM, lambda: _build(model, backend), backend)
