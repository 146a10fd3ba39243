"""Zero-copy calls of CasADi Functions from numpy (``casadi.Function.buffer``).

A plain ``f(numpy...)`` converts every argument to a ``DM`` and back (tens of microseconds
per call); a :class:`Buffered` function writes into preallocated numpy arrays instead
(about a microsecond). Outputs are the buffers themselves: copy what must outlive the next
call.
"""

from __future__ import annotations

import casadi as ca
import numpy as np


class Buffered:
    """A CasADi Function called through preallocated numpy buffers (dense, column-major)."""

    def __init__(self, f: ca.Function) -> None:
        self.function = f
        self.names = f.name_in()
        self._buf, self._run = f.buffer()
        self.args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self.res = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
        for i, a in enumerate(self.args):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self.res):
            self._buf.set_res(i, memoryview(r))

    def __call__(self, *args) -> list[np.ndarray]:
        for a, v in zip(self.args, args, strict=True):
            a[:] = v
        self._run()
        return self.res
