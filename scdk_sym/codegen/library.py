"""The generated C tracker as a shared library, compiled once per model and loaded with ctypes.

The library is built from the sources that :func:`~scdk_sym.codegen.generate.generate`
writes (split, without the inverse kinematics that Python does not call), into the on-disk
cache (:mod:`scdk_sym.kernels.cache`) under a hash of those sources and the compiler flags;
later processes regenerate the sources (a fraction of a second) and load the cached library
without compiling.
"""

from __future__ import annotations

import ctypes
import hashlib
import shutil
import tempfile
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import BuildError, SolveError
from ..kernels.cache import cache_dir, cached_file, damage, read_entry, write_entry
from ..kernels.compile import announce, cache_key, compiler_tag, source_digest
from ..products import C_TRACKER
from . import status, templates
from .generate import compile_library, generate, source_key
from .outputs import Options, Refusal, SolveOutput, SweepOutput, TrackOutput, refusal_type
from .status import SweepCode, TrackerStatus

PREFIX = "scdk"

#: The messages of the generated tracker's status codes (``<PREFIX>_OK`` ... in its header),
#: by value (:class:`~scdk_sym.codegen.status.TrackerStatus`).
STATUS = status.STATUS
OK = TrackerStatus.OK
OK_PATH = TrackerStatus.OK_PATH
OK_PREDICTED = TrackerStatus.OK_PREDICTED
ERR_NULL = TrackerStatus.ERR_NULL
ERR_SIZE = TrackerStatus.ERR_SIZE
ERR_NONFINITE = TrackerStatus.ERR_NONFINITE
ERR_NOT_ASSEMBLED = TrackerStatus.ERR_NOT_ASSEMBLED
ERR_NO_SOLUTION = TrackerStatus.ERR_NO_SOLUTION
ERR_VERIFY = TrackerStatus.ERR_VERIFY
ERR_STATE = TrackerStatus.ERR_STATE
ERR_OPTIONS = TrackerStatus.ERR_OPTIONS
ERR_UNDECIDABLE = TrackerStatus.ERR_UNDECIDABLE
ERR_SINGULAR_PATH = TrackerStatus.ERR_SINGULAR_PATH
#: Codes of a point of ``<PREFIX>_sweep`` (the error codes otherwise).
SWEEP_CONTINUED = SweepCode.CONTINUED
SWEEP_DIRECT = SweepCode.DIRECT


_dp = ctypes.POINTER(ctypes.c_double)
_vp = ctypes.c_void_p
_ip = ctypes.POINTER(ctypes.c_int)
_lp = ctypes.POINTER(ctypes.c_long)


class CTracker:
    """A loaded tracker library of one model.

    Attributes:
        path: the shared library.
        m, k, nc, n: sizes of y, theta, the chart and x.
    """

    def __init__(self, path: Path, m: int, k: int, nc: int, n: int, prefix: str = PREFIX):
        self.path = Path(path)
        self.m, self.k, self.nc, self.n = m, k, nc, n
        lib = ctypes.CDLL(str(path))
        self._lib = lib
        p = prefix
        self._refusal_type = refusal_type(m, k, n, nc)
        self._track = getattr(lib, f"{p}_tracker_track_res")
        self._track.restype = ctypes.c_int
        self._track.argtypes = [
            _dp, ctypes.c_int, _dp, ctypes.c_int, _dp, ctypes.c_int, ctypes.POINTER(Options),
            ctypes.c_long, _dp, _dp, _dp, _dp, _dp, _dp, _ip, _lp,
            ctypes.POINTER(self._refusal_type),
        ]  # fmt: skip
        defaults = getattr(lib, f"{p}_default_options")
        defaults.restype = None
        defaults.argtypes = [ctypes.POINTER(Options)]
        for name, struct in (("options", Options), ("refusal", self._refusal_type)):
            size = getattr(lib, f"{p}_{name}_size")
            size.restype = ctypes.c_int
            if size() != ctypes.sizeof(struct):
                raise BuildError(
                    f"{path}: {name} struct has {size()} bytes, the binding expects "
                    f"{ctypes.sizeof(struct)}"
                )
        self._defaults = defaults
        self._solve = getattr(lib, f"{p}_solve_convergent")
        self._solve.restype = ctypes.c_int
        # arrays by address (an int: a third of the cost of a typed pointer per call)
        self._solve.argtypes = [
            _vp, ctypes.c_int, _vp, ctypes.c_int, _vp, ctypes.c_int, _vp,
            ctypes.POINTER(Options), _vp, _vp, _vp, _dp, _dp, _vp,
        ]  # fmt: skip
        self._solve_divergent = getattr(lib, f"{p}_solve_divergent")
        self._solve_divergent.restype = ctypes.c_int
        self._solve_divergent.argtypes = [*self._solve.argtypes, _vp]  # fold, then checks
        self._sweep = getattr(lib, f"{p}_sweep")
        self._sweep.restype = ctypes.c_int
        self._sweep.argtypes = [
            _dp, ctypes.c_int, _dp, ctypes.c_int, _dp, ctypes.c_int, ctypes.POINTER(Options),
            ctypes.c_long, _dp, ctypes.c_long, ctypes.c_int, _lp, ctypes.c_double,
            _dp, _dp, _dp, _ip,
        ]  # fmt: skip

    def default_options(self) -> Options:
        """The library's default options (tolerance, budgets)."""
        opt = Options()
        self._defaults(ctypes.byref(opt))
        return opt

    def track(
        self,
        y0: np.ndarray,
        c0: np.ndarray,
        theta0: np.ndarray,
        thetas: np.ndarray,
        options: Options | None = None,
    ) -> TrackOutput:
        """Run the whole sequence in one call into C.

        Args:
            y0: (m,) start unknowns in the chart ``c0``.
            c0: (nc,) start chart.
            theta0: (k,) start actuated values.
            thetas: (N, k) readings to track.
            options: tracker options (default: the library's).

        Returns:
            The raw output arrays (no verification: see :func:`scdk_sym.solvers.track_c`).
        """
        y0 = np.ascontiguousarray(y0, dtype=float)
        c0 = np.ascontiguousarray(c0, dtype=float)
        theta0 = np.ascontiguousarray(theta0, dtype=float)
        th = np.ascontiguousarray(thetas, dtype=float)
        N = th.shape[0] if th.ndim == 2 else 0
        Y = np.empty((N, self.m))
        C = np.empty((N, self.nc))
        X = np.empty((N, self.n))
        D = np.empty(N)
        res = np.empty(N)
        codes = np.empty(N, dtype=np.intc)
        failed = ctypes.c_long(-1)
        ref = self._refusal_type()
        c_arg = _ptr(c0) if c0.size else _ptr(np.zeros(1))
        status = self._track(
            _ptr(y0), y0.size, c_arg, c0.size, _ptr(theta0), theta0.size,
            ctypes.byref(options) if options is not None else None,
            N, _ptr(th), _ptr(Y), _ptr(C) if self.nc else None, _ptr(X), _ptr(D), _ptr(res),
            codes.ctypes.data_as(_ip), ctypes.byref(failed), ctypes.byref(ref),
        )  # fmt: skip
        refusal = None
        if status == ERR_UNDECIDABLE and ref.count > 0:
            count = int(ref.count)
            refusal = Refusal(
                y=np.array(ref.y)[:count].copy(),
                c=np.array(ref.c)[: self.nc].copy(),
                x=np.array(ref.x)[:count].copy(),
                theta=np.array(ref.theta).copy(),
                miss=np.array(ref.miss)[:count].copy(),
                accuracy=float(ref.accuracy),
                step=float(ref.step),
            )
        return TrackOutput(int(status), int(failed.value), Y, C, X, D, codes, res, refusal)

    def solve_convergent(
        self,
        y1: np.ndarray,
        c1: np.ndarray,
        theta1: np.ndarray,
        theta0: np.ndarray,
        options: Options | None = None,
    ) -> SolveOutput:
        """The convergent solution at ``theta0`` from an assembled start, in one call into C
        (``<prefix>_solve_convergent``: the first ``s = 1`` crossing of the straight line's
        curve, refused with status -10 where the path meets a singular point first).

        Args:
            y1: (m,) start unknowns in the chart ``c1``.
            c1: (nc,) start chart.
            theta1: (k,) start actuated values.
            theta0: (k,) target actuated values.
            options: tracker options (default: the library's).
        """
        return self._call_solve(self._solve, y1, c1, theta1, theta0, options)

    def solve_divergent(
        self,
        y1: np.ndarray,
        c1: np.ndarray,
        theta1: np.ndarray,
        theta0: np.ndarray,
        options: Options | None = None,
    ) -> SolveOutput:
        """The divergent solution at ``theta0`` along the paper's divergent path, in one call
        into C (``<prefix>_solve_divergent``: the straight line's curve followed where ``s``
        decreases, through exactly one fold and back through ``s = 0`` on the other sheet, to
        its first ``s = 1`` crossing; refused with status -10 where the walk meets what it
        does not decide). The same arguments as :meth:`solve_convergent`; the output's ``y``
        is in the chart ``c``, its ``fold_y`` in the chart ``fold_c`` (the walk re-centres
        its chart).
        """
        return self._call_solve(self._solve_divergent, y1, c1, theta1, theta0, options,
                                fold=True)  # fmt: skip

    def sweep(
        self,
        y1: np.ndarray,
        c1: np.ndarray,
        theta1: np.ndarray,
        thetas: np.ndarray,
        offset: int,
        shape: tuple[int, ...],
        rcond_min: float,
        options: Options | None = None,
    ) -> SweepOutput:
        """The convergent solutions of a chunk of a grid, each continued from its neighbour,
        in one call into C (``<prefix>_sweep``, whose header states the rule).

        Args:
            y1: (m,) start unknowns in the chart ``c1``.
            c1: (nc,) start chart.
            theta1: (k,) start actuated values.
            thetas: (N, k) readings of grid points ``offset`` to ``offset + N - 1``.
            offset: flat (C-order) index of the first point in the grid.
            shape: the grid's shape (a list of readings: ``(total,)``, each point the
                neighbour of the one before).
            rcond_min: points whose ``1 / (m |J_p|_1 |J_p^-1|_1)`` is not above this are left
                to the caller.
            options: tracker options (default: the library's).

        Raises:
            SolveError: the call refused its input (status and meaning in the message).
        """
        y1, c1, theta1 = (np.ascontiguousarray(a, dtype=float) for a in (y1, c1, theta1))
        th = np.ascontiguousarray(thetas, dtype=float).reshape(-1, self.k)
        N = th.shape[0]
        shp = np.ascontiguousarray(shape, dtype=np.int_)
        X = np.empty((N, self.n))
        D = np.empty(N)
        R = np.empty(N)
        codes = np.empty(N, dtype=np.intc)
        status = self._sweep(
            _ptr(y1), y1.size, _ptr(c1) if c1.size else _ptr(np.zeros(1)), c1.size,
            _ptr(theta1), theta1.size, ctypes.byref(options) if options is not None else None,
            N, _ptr(th), int(offset), shp.size, shp.ctypes.data_as(_lp), float(rcond_min),
            _ptr(X), _ptr(D), _ptr(R), codes.ctypes.data_as(_ip),
        )  # fmt: skip
        if status < 0:
            why = STATUS.get(status, f"status {status}")
            raise SolveError(
                f"C sweep refused a chunk of {N} points at offset {offset} of a grid of shape "
                f"{tuple(shape)}: {why} (status {status})"
            )
        return SweepOutput(X, D, R, codes)

    def _call_solve(self, fn, y1, c1, theta1, theta0, options, fold=False) -> SolveOutput:
        return BoundSolve(self, fn, y1, c1, theta1, options, fold)(theta0)

    def bound_solve(self, y1: np.ndarray, c1: np.ndarray, theta1: np.ndarray,
                    divergent: bool = False) -> BoundSolve:  # fmt: skip
        """:meth:`solve_convergent` (or, ``divergent``, :meth:`solve_divergent`) from one
        start, its arguments bound once: the call then costs the C work and one ctypes call
        (the arguments as for :meth:`solve_convergent`, the library's default options)."""
        fn = self._solve_divergent if divergent else self._solve
        return BoundSolve(self, fn, y1, c1, theta1, None, divergent)


class BoundSolve:
    """One C solve function of a :class:`CTracker` with its start and output arrays bound:
    ``call(theta0)`` fills them and returns a fresh :class:`SolveOutput`.

    Args:
        lib: the tracker library.
        fn: its ``<prefix>_solve_convergent`` or ``<prefix>_solve_divergent``.
        y1: (m,) start unknowns in the chart ``c1``.
        c1: (nc,) start chart.
        theta1: (k,) start actuated values.
        options: tracker options (None: the library's defaults).
        fold: the divergent solve's extra output (its fold) is bound too.
    """

    def __init__(self, lib: CTracker, fn, y1, c1, theta1, options: Options | None,
                 fold: bool) -> None:  # fmt: skip
        self.m, self.n, self.nc, self.fold = lib.m, lib.n, lib.nc, fold
        y1, c1, theta1 = (np.array(a, dtype=float) for a in (y1, c1, theta1))
        self._start = (y1, c1 if c1.size else np.zeros(1), theta1)  # C has no empty arrays
        self.theta0 = np.full(lib.k, np.nan)
        self.y, self.x = np.empty(lib.m), np.empty(lib.n)
        self.c = np.empty(max(1, lib.nc))
        self.res, self.det = ctypes.c_double(), ctypes.c_double()
        self.extra = np.empty(1 + lib.m + lib.n + lib.nc) if fold else None
        self._fn = fn
        self.checks = np.empty(18)  # T (column-major), det J_p, |J_p|_F at the answer
        self._args = (
            y1.ctypes.data, y1.size, self._start[1].ctypes.data, c1.size,
            theta1.ctypes.data, theta1.size, self.theta0.ctypes.data,
            ctypes.byref(options) if options is not None else None,
            self.y.ctypes.data, self.c.ctypes.data, self.x.ctypes.data, ctypes.byref(self.res),
            ctypes.byref(self.det), *(() if self.extra is None else (self.extra.ctypes.data,)),
            self.checks.ctypes.data,
        )  # fmt: skip
        self._options = options  # kept alive with the pointer to it
        self._lock = threading.Lock()  # the C call releases the GIL: one call at a time

    def __call__(self, theta0: np.ndarray) -> SolveOutput:
        """The solve at ``theta0`` ((k,) actuated values; another size is refused by the C
        call's status)."""
        with self._lock:
            return self._call(np.asarray(theta0, dtype=float))

    def _call(self, theta0: np.ndarray) -> SolveOutput:
        args = self._args
        if theta0.size == len(self.theta0):
            self.theta0[:] = theta0
        else:
            args = (*args[:6], None, *args[7:])
        for a in (self.y, self.c, self.x, self.checks):
            a.fill(np.nan)
        self.res.value = self.det.value = np.nan
        if self.extra is not None:
            self.extra.fill(np.nan)
        status = self._fn(*args)
        out = SolveOutput(int(status), self.y.copy(), self.c[: self.nc].copy(), self.x.copy(),
                          float(self.res.value), float(self.det.value),
                          checks=self.checks.copy())  # fmt: skip
        if self.extra is None:
            return out
        m, n, e = self.m, self.n, self.extra.copy()
        return replace(out, fold_s=float(e[0]), fold_y=e[1 : 1 + m],
                       fold_x=e[1 + m : 1 + m + n], fold_c=e[1 + m + n :])  # fmt: skip


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_dp)


def tracker_library(model) -> CTracker:
    """The model's C tracker, compiled on first use and cached on disk (and per model object).

    Raises:
        BuildError: no C compiler or the compilation failed.
    """
    return model.products.get(C_TRACKER, lambda: _build_tracker(model))


#: What the C tracker's sources are made from besides the model (its index key covers them).
TRACKER_SOURCES = (
    "codegen", "kernels/tracker_functions.py", "kernels/c/scdk_lu.h", "graphs.py",
    "robot/blocks.py",
    *(part.path for part in (*templates.SOURCE_PARTS, templates.HEADER_PART)),
)  # fmt: skip


def _index(model) -> Path:
    """The cache's index entry of the model's C tracker: the name of its library, keyed by
    the model's kernels (:func:`~scdk_sym.kernels.compile.cache_key`), the generator's own
    sources and the compiler, so that a cached tracker is found without generating C."""
    h = hashlib.sha256(cache_key(model).encode())
    h.update(source_digest(TRACKER_SOURCES))
    h.update(compiler_tag().encode())
    return cache_dir() / f"tracker_index_{h.hexdigest()[:24]}.txt"


def cached_tracker(model) -> Path | None:
    """The model's C tracker library in the cache, found through its index (no C generated),
    or ``None`` when it is not there (or the index or library is damaged)."""
    return _cached_at(_index(model))


def _cached_at(index: Path) -> Path | None:
    """:func:`cached_tracker` of the index entry ``index``."""
    name = read_entry(index, lambda p: p.read_text(encoding="utf-8").strip(), "index")
    if not name:
        return None
    target = cache_dir() / name
    return target if damage(target) is None else None


def _build_tracker(model) -> CTracker:
    """Generate, compile (or find on disk) and load the model's C tracker (without the
    inverse kinematics, which Python does not call)."""
    index = _index(model)
    found = _cached_at(index)
    if found is not None:
        return CTracker(found, model.m, model.k, model.chart.size, len(model.workspace))
    with tempfile.TemporaryDirectory() as tmp:
        src = generate(model, Path(tmp), PREFIX, split=True, inverse_kinematics=False)
        key = source_key(src)

        def build(path: Path) -> None:
            announce(model.name)
            compiled = Path(tmp) / "libtracker.so"
            compile_library(src, compiled)
            shutil.copyfile(compiled, path)

        target = cached_file(cache_dir() / f"tracker_{key}.so", build, "C tracker library")
    write_entry(index, lambda p: p.write_text(target.name, encoding="utf-8"))
    return CTracker(target, model.m, model.k, model.chart.size, len(model.workspace))
