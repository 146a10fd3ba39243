"""Zero-copy calls of CasADi Functions from numpy (``casadi.Function.buffer``).

A plain ``f(numpy...)`` converts every argument to a ``DM`` and back (tens of microseconds
per call); a :class:`Buffered` function writes into preallocated numpy arrays instead
(about a microsecond). Outputs are the buffers themselves: copy what must outlive the next
call. A :class:`Dense` function is called the same way but returns fresh dense arrays shaped
like ``numpy.array(f(...))``, so it replaces a plain call without changing any value.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..products import MODEL_CALLS


class Buffered:
    """A CasADi Function called through preallocated numpy buffers (dense, column-major)."""

    def __init__(self, f: ca.Function) -> None:
        self.function = f
        self.names = f.name_in()
        self._buf, self._run = f.buffer()
        self.args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self.res = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
        for i, a in enumerate(self.args):
            self._buf.set_arg(i, memoryview(a))  # type: ignore[call-arg, arg-type]
        for i, r in enumerate(self.res):
            self._buf.set_res(i, memoryview(r))  # type: ignore[call-arg, arg-type]

    def __call__(self, *args) -> list[np.ndarray]:
        for a, v in zip(self.args, args, strict=True):
            a[:] = v
        self._run()
        return self.res

    def run(self) -> list[np.ndarray]:
        """Evaluate with the arguments as they stand in ``self.args`` (filled in place)."""
        self._run()
        return self.res


class Dense:
    """A CasADi Function called through zero-copy buffers, returning what a plain call returns.

    ``Dense(f)(*args)`` evaluates the same Function as ``f(*args)`` (the same values, bit for
    bit) and returns each output as a new dense, C-ordered array of the output's shape
    (structural zeros filled in), like ``numpy.array`` of the ``DM`` a plain call returns (the
    memory order matters too: numpy's products sum in an order that depends on it); a single
    output is returned alone, several as a tuple. Outputs listed in ``scalars`` (1 x 1) are
    returned as floats. Arguments are dense, column-major (vectors as they are); one column
    is repeated across an input of several columns. Not thread-safe: one instance shares its
    buffers between calls.

    Args:
        f: the Function (inputs dense).
        scalars: indices of 1 x 1 outputs to return as floats.
    """

    def __init__(self, f: ca.Function, scalars: Sequence[int] = ()) -> None:
        for i in range(f.n_in()):
            if not f.sparsity_in(i).is_dense():
                raise ValueError(f"{f.name()}: input {f.name_in(i)} is not dense")
        self.function = f
        self._call = Buffered(f)
        self._outputs = []
        for i in range(f.n_out()):
            sp = f.sparsity_out(i)
            shape = (sp.size1(), sp.size2())
            if i in scalars:
                if shape != (1, 1):
                    raise ValueError(f"{f.name()}: output {f.name_out(i)} is not a scalar")
                kind = "scalar"
                where = None
            elif sp.is_dense():
                kind, where = "dense", None
            else:
                rows, cols = sp.get_triplet()
                kind = "sparse"
                where = np.asarray(rows, dtype=np.intp) * shape[1] + np.asarray(cols, np.intp)
            self._outputs.append((kind, shape, where))
        self._single = f.n_out() == 1
        self._inputs = [f.sparsity_in(i).shape for i in range(f.n_in())]

    @staticmethod
    def _argument(v, shape: tuple[int, int]):
        """An argument as the buffer takes it: column-major, and a column repeated across an
        input of several columns (as a plain call does, e.g. the parameters of a map)."""
        if np.ndim(v) > 1:
            v = np.ravel(v, order="F")
        rows, cols = shape
        if cols > 1 and rows > 1 and np.size(v) == rows:
            v = np.tile(v, cols)
        return v

    def __call__(self, *args):
        buf = self._call
        if len(args) != len(buf.args):
            raise TypeError(f"{self.function.name()}: {len(buf.args)} arguments expected")
        for a, v, shape in zip(buf.args, args, self._inputs, strict=True):
            try:
                a[:] = v  # a vector, or a scalar repeated (as a plain call does)
            except ValueError:
                a[:] = self._argument(v, shape)
        res = buf.run()
        out: list[float | np.ndarray] = []
        for r, (kind, shape, where) in zip(res, self._outputs, strict=True):
            if kind == "scalar":
                out.append(float(r[0]) if r.size else 0.0)
            elif kind == "dense":
                out.append(r.reshape(shape, order="F").copy(order="C"))
            else:
                a = np.zeros(shape[0] * shape[1])
                a[where] = r
                out.append(a.reshape(shape))
        return out[0] if self._single else tuple(out)


class Verify:
    """The pose, the closure rows and ``J_p`` at one point in one zero-copy call: an MX
    Function of calls of the three kernels, each output exactly that of its own kernel.

    ``verify(y, theta, c)`` returns ``(T, x, residual, J_p)``: the (4, 4) platform placement,
    the (n,) workspace coordinates, max |closure row| (a float) and the (m, m) ``J_p``, the
    arrays fresh and C-ordered as :class:`Dense` returns them. Not thread-safe.

    Args:
        pose: the model's pose kernel ``(y, theta, c) -> (T, x)``.
        check: its closure rows ``(y, theta, c) -> rows``.
        jac: its Jacobians ``(y, theta, c) -> (J_p, J_s)``.
    """

    def __init__(self, pose: ca.Function, check: ca.Function, jac: ca.Function) -> None:
        ins = [ca.MX.sym(pose.name_in(i), pose.sparsity_in(i)) for i in range(pose.n_in())]
        T, x = pose(*ins)
        f = ca.Function("verify", ins, [T, x, check(*ins), jac(*ins)[0]])
        for i in range(f.n_out()):
            if not f.sparsity_out(i).is_dense():
                f = ca.Function("verify", ins, [ca.densify(e) for e in f.call(ins)])
                break
        self._call = Buffered(f)
        self._shapes = (f.size_out(0), f.size_out(3))

    def __call__(self, y, theta, c) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        T, x, rows, Jp = self._call(y, theta, c)
        (tr, tc), (jr, jc) = self._shapes
        return (
            T.reshape((tr, tc), order="F").copy(order="C"),
            x.copy(),
            float(np.abs(rows).max()),
            Jp.reshape((jr, jc), order="F").copy(order="C"),
        )


#: Mapped callers kept per model (:meth:`ModelCalls.mapped`; the oldest dropped first): a
#: mode map's fronts ask for each kernel over up to a few hundred different point counts, each
#: made once (about 80 us) and a few kB.
MAPS_KEPT = 512


@dataclass(frozen=True)
class ModelCalls:
    """Zero-copy callers of a model's kernels (:class:`Dense` of ``model.kernels``)."""

    g: Dense
    check: Dense
    jac: Dense
    pose: Dense
    verify: Verify
    _maps: dict[tuple[str, int], Dense] = field(default_factory=dict, repr=False, compare=False)

    def mapped(self, name: str, count: int) -> Dense:
        """The caller of kernel ``name`` (``"g"``, ``"check"``, ``"jac"`` or ``"pose"``) over
        ``count`` points in one call: each input one column per point (an input given as one
        column is repeated), each output the points' outputs side by side (``Function.map``:
        each point's values exactly those of a single call).
        """
        key = (name, count)
        f = self._maps.get(key)
        if f is None:
            if len(self._maps) >= MAPS_KEPT:
                self._maps.pop(next(iter(self._maps)))
            f = self._maps[key] = Dense(getattr(self, name).function.map(count))
        return f


def model_calls(model) -> ModelCalls:
    """The (cached) zero-copy callers of ``model.kernels``: same signatures and values as the
    plain calls, outputs as numpy arrays."""

    def build() -> ModelCalls:
        kern = model.kernels
        calls = (Dense(kern.g), Dense(kern.check), Dense(kern.jac), Dense(kern.pose))
        return ModelCalls(*calls, Verify(kern.pose, kern.check, kern.jac))

    return model.products.get(MODEL_CALLS, build)
