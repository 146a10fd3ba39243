"""The path tracker of :mod:`scdk_sym.algebraic.paths.continuation` in C, for parameter homotopies
of a model's algebraic form.

``continuation.c`` (beside this module) tracks every path of a
:class:`~scdk_sym.algebraic.parameter_homotopy.ParameterHomotopy` in one call, with the
predictor, corrector and step rules of the numpy tracker (which stays the reference).
:func:`lanes` paths (4 with AVX2, 8 with AVX-512) advance in lock step, one per lane of a
vector of doubles: the real-pair evaluation of ``G`` (:func:`~scdk_sym.algebraic.pairs.complexify`)
is written for lane vectors (:func:`~scdk_sym.kernels.lanes.lane_source`) and compiled into
the tracker with the system's sizes, so one library per system, compiled once and cached on
disk under the hash of everything it is built from
(:func:`~scdk_sym.algebraic.clibrary.source_library`). Only straight segments in ``t`` are
tracked here; the endgame's circles stay in numpy.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from ...errors import BuildError, HomotopyError, InputError
from ...products import HOMOTOPY_TRACKER
from ..clibrary import simd_flags, source_library
from .continuation import DONE, TrackerOptions, TrackOutcome

#: Tracker choices of :func:`~scdk_sym.algebraic.solve_homotopy`.
TRACKERS = ("auto", "c", "python")
#: Flags of the tracker library (warnings are errors: the source must stay clean; complex
#: products without the C99 NaN recovery: the tracker checks finiteness itself).
TRACKER_CFLAGS = (
    "-std=c99", "-O3", "-fcx-limited-range", "-shared", "-fPIC", "-Wall", "-Wextra", "-Werror",
)  # fmt: skip
#: Paths tracked in lock step, one per lane of a GCC vector of doubles, without AVX-512
#: (:func:`lanes`).
LANES = 4
_ERRORS = {1: "out of memory", 3: "bad sizes"}


class _Options(ctypes.Structure):
    """``scdk_options`` of ``continuation.h``: the fields of :class:`TrackerOptions`."""

    _fields_ = [
        ("h0", ctypes.c_double),
        ("h_min", ctypes.c_double),
        ("h_max", ctypes.c_double),
        ("eta", ctypes.c_double),
        ("trust", ctypes.c_double),
        ("theta", ctypes.c_double),
        ("tol", ctypes.c_double),
        ("floor", ctypes.c_double),
        ("noise", ctypes.c_double),
        ("max_steps", ctypes.c_int64),
        ("max_norm", ctypes.c_double),
        ("third", ctypes.c_int64),
    ]


def source_dir() -> Path:
    """The directory of ``continuation.c`` and ``continuation.h`` (package data, beside this
    module)."""
    return Path(str(resources.files("scdk_sym.algebraic.paths")))


def lanes() -> int:
    """Paths the tracker advances in lock step: 8 (one 512-bit vector of doubles) with
    AVX-512F, else :data:`LANES`. Lane by lane the arithmetic is that of one path alone, so
    the count changes the speed only, never a value."""
    return 8 if "-mavx512f" in simd_flags() else LANES


def tracker_library(form, flags: tuple[str, ...] | None = None, width: int = 0) -> Path:
    """The compiled tracker of an :class:`~scdk_sym.algebraic.form.AlgebraicForm` (cached
    under the hash of the tracker's sources, the generated lane evaluation, the sizes, flags
    and compiler).

    Args:
        form: the form.
        flags: instruction-set flags (default :func:`~scdk_sym.algebraic.clibrary.simd_flags`).
        width: paths in lock step (default :func:`lanes`).

    Raises:
        BuildError: no C compiler, the compilation failed, or ``G`` uses an operation with no
            lane evaluation.
    """
    from ...kernels.lanes import lane_source

    main = (
        f"#define SCDK_N {form.n}\n#define SCDK_K {form.n_params}\n"
        f"#define SCDK_LANES {width or lanes()}\n"
        '#define SCDK_EVAL_FILE "scdk_eval.c"\n#include "continuation.c"\n'
    )
    evaluation = lane_source(form.G_pairs, "scdk_eval")
    return source_library(
        source_dir() / "continuation.c",
        (*TRACKER_CFLAGS, *(simd_flags() if flags is None else flags)),
        {"scdk_eval.c": evaluation, "main.c": main},
    )


def _form_and_weights(system) -> tuple[object, np.ndarray] | None:
    """``(AlgebraicForm, row weights)`` of a form or a scaled form; ``None`` otherwise."""
    from ..form import AlgebraicForm
    from ..scaled import ScaledForm

    if isinstance(system, ScaledForm):
        return system.form, np.asarray(system.weights, dtype=float)
    if isinstance(system, AlgebraicForm):
        return system, np.ones(system.n)
    return None


def _options(o: TrackerOptions) -> _Options:
    """The C structure of step control options."""
    return _Options(o.h0, o.h_min, o.h_max, o.eta, o.trust, o.theta, o.tol, o.floor, o.noise,
                    int(o.max_steps), o.max_norm, int(o.third))  # fmt: skip


@dataclass(frozen=True)
class SplitOutcome:
    """What :meth:`CTracker.track_split` returns.

    Attributes:
        end: the :class:`~scdk_sym.algebraic.paths.continuation.TrackOutcome` of every path
            (M paths) at its last stop (``steps`` and ``accepted`` count both parts).
        reached: (K,) int, the paths that reached the split time.
        z_split: (K, n) complex, their points there.
        arrived: (A,) int, those of them that arrived at t = 1 (status ``DONE``).
        z_newton: (A, n) complex, their ends after the Newton steps at t = 1.
        nu: (A, iterations) the relative norm of each Newton update.
        bound: (A,) an upper bound of the scaled condition number of ``H_z`` at
            ``z_newton`` (as :meth:`CTracker.newton` returns it).
    """

    end: TrackOutcome
    reached: np.ndarray
    z_split: np.ndarray
    arrived: np.ndarray
    z_newton: np.ndarray
    nu: np.ndarray
    bound: np.ndarray


class CTracker:
    """The C tracker bound to one algebraic form's generated ``G`` (see the module docs).

    Args:
        form: an :class:`~scdk_sym.algebraic.form.AlgebraicForm`.
        library: its compiled tracker (default :func:`tracker_library` of the form).

    Raises:
        BuildError: no C compiler, or a compilation failed.
    """

    def __init__(self, form, library: Path | None = None) -> None:
        self.n, self.k = form.n, form.n_params
        lib = ctypes.CDLL(str(library or tracker_library(form)))
        f = lib.scdk_ptrack
        dbl = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
        cdbl = np.ctypeslib.ndpointer(dtype=np.complex128, flags="C_CONTIGUOUS")
        i64 = np.ctypeslib.ndpointer(dtype=np.int64, flags="C_CONTIGUOUS")
        I = ctypes.c_int64  # noqa: E741
        f.argtypes = [I, I, dbl, cdbl, cdbl, cdbl, cdbl, cdbl, I, i64,
                      cdbl, dbl, dbl, dbl, ctypes.POINTER(_Options), i64, i64, i64]  # fmt: skip
        f.restype = ctypes.c_int
        g = lib.scdk_pnewton
        g.argtypes = [I, I, dbl, cdbl, cdbl, cdbl, cdbl, cdbl, I, i64,
                      cdbl, dbl, I, dbl, ctypes.c_void_p, ctypes.c_void_p]  # fmt: skip
        g.restype = ctypes.c_int
        s = lib.scdk_psolve
        s.argtypes = [I, I, dbl, cdbl, cdbl, cdbl, cdbl, cdbl, I, i64, cdbl, dbl, dbl,
                      ctypes.POINTER(_Options), i64, i64, i64, ctypes.c_double, cdbl, i64, I,
                      cdbl, dbl, dbl]  # fmt: skip
        s.restype = ctypes.c_int
        self._lib, self._track, self._newton, self._solve = lib, f, g, s

    def _data(self, homotopy, weights: np.ndarray) -> tuple:
        """The homotopy's per-datum arrays as the C functions take them."""
        cd = np.ascontiguousarray
        return (
            cd(weights, dtype=np.float64), cd(homotopy.p_from, dtype=np.complex128),
            cd(homotopy.dp, dtype=np.complex128), cd(homotopy.b_from, dtype=np.complex128),
            cd(homotopy.db, dtype=np.complex128), cd(homotopy.gamma, dtype=np.complex128),
        )  # fmt: skip

    def newton(
        self,
        homotopy,
        z: np.ndarray,
        t: np.ndarray,
        idx: np.ndarray,
        iterations: int,
        weights: np.ndarray,
        condition: bool = True,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Newton's method on ``H(., t) = 0`` in C, as
        :func:`~scdk_sym.algebraic.paths.continuation.newton`.

        Args:
            homotopy: as :meth:`track`'s.
            z: (M, n) complex points.
            t: (M,) real times.
            idx: (M,) int, each point's datum in the homotopy.
            iterations: Newton steps.
            weights: (n,) row weights of the system.
            condition: also ``H_z`` and the condition bound at the final points (False: no
                last evaluation; ``None`` returned for both).

        Returns:
            ``z`` (M, n) after the steps, ``nu`` (M, iterations) the relative norm of each
            update, ``H_z`` (M, n, n) at the final points and (M,) an upper bound of each
            one's :func:`~scdk_sym.algebraic.homotopy.scaled_cond` (``|A|_F |A^-1|_F`` of the
            scaled matrix; ``inf`` or NaN when singular).

        Raises:
            HomotopyError: the C function reported a failure.
        """
        M = len(z)
        z = np.array(z, dtype=np.complex128, order="C").reshape(M, self.n)
        nu = np.zeros((M, iterations))
        hz = np.zeros((M, self.n, self.n), dtype=np.complex128) if condition else None
        cond = np.zeros(M) if condition else None
        rc = self._newton(
            self.n, self.k, *self._data(homotopy, weights), M,
            np.ascontiguousarray(idx, dtype=np.int64), z,
            np.ascontiguousarray(np.broadcast_to(t, (M,)), dtype=np.float64), iterations, nu,
            None if hz is None else hz.ctypes.data, None if cond is None else cond.ctypes.data,
        )  # fmt: skip
        if rc:
            raise HomotopyError(
                f"C Newton failed ({_ERRORS.get(rc, rc)}) on {M} points of an "
                f"{self.n}-unknown system; rerun with tracker='python'"
            )
        return z, nu, hz, cond

    def track(
        self,
        homotopy,
        z0: np.ndarray,
        idx: np.ndarray,
        tau0: np.ndarray,
        tau1: np.ndarray,
        weights: np.ndarray,
        options: TrackerOptions | None = None,
        h0: np.ndarray | None = None,
    ) -> TrackOutcome:
        """Track every path along ``t = tau`` from ``tau0`` to ``tau1`` (one C call).

        Args:
            homotopy: a :class:`~scdk_sym.algebraic.parameter_homotopy.ParameterHomotopy` of
                the form whose rows are scaled by ``weights``.
            z0: (M, n) complex start points.
            idx: (M,) int, each path's datum in the homotopy.
            tau0: (M,) start times.
            tau1: (M,) end times.
            weights: (n,) row weights of the system (ones for the plain form).
            options: step control (defaults to :class:`TrackerOptions`).
            h0: (M,) initial steps (default ``options.h0``).

        Returns:
            A :class:`~scdk_sym.algebraic.paths.continuation.TrackOutcome`, as
            :func:`~scdk_sym.algebraic.paths.continuation.track` with the identity time map
            returns it.

        Raises:
            HomotopyError: the C tracker reported a failure.
        """
        o = options or TrackerOptions()
        M = len(z0)
        z = np.array(z0, dtype=np.complex128, order="C").reshape(M, self.n)
        tau = np.array(np.broadcast_to(tau0, (M,)), dtype=np.float64)
        t1 = np.ascontiguousarray(np.broadcast_to(tau1, (M,)), dtype=np.float64)
        h = np.full(M, o.h0) if h0 is None else np.array(h0, dtype=np.float64)
        ix = np.ascontiguousarray(idx, dtype=np.int64)
        status, steps, accepted = (np.zeros(M, dtype=np.int64) for _ in range(3))
        rc = self._track(
            self.n, self.k, *self._data(homotopy, weights), M, ix, z, tau, t1, h,
            ctypes.byref(_options(o)), status, steps, accepted,
        )  # fmt: skip
        if rc:
            raise HomotopyError(
                f"C path tracker failed ({_ERRORS.get(rc, rc)}) on {M} paths of an "
                f"{self.n}-unknown system; rerun with tracker='python'"
            )
        return TrackOutcome(z=z, tau=tau, status=status, steps=steps, accepted=accepted, h=h)

    def track_split(
        self,
        homotopy,
        z0: np.ndarray,
        idx: np.ndarray,
        split: float,
        weights: np.ndarray,
        options: TrackerOptions | None = None,
        iterations: int = 2,
    ) -> SplitOutcome:
        """Track every path from ``t = 0`` to ``split``, each that gets there on to ``t = 1``
        in the same lane, and refine the ends of those that arrive by Newton steps at
        ``t = 1``, in one C call: the values of :meth:`track` to ``split``, of :meth:`track`
        of the paths that reached it from there (``tau0`` and ``h0`` their reached times
        and last steps), and of :meth:`newton` at ``t = 1`` of the arrived ends.

        Args:
            homotopy: as :meth:`track`'s.
            z0: (M, n) complex start points.
            idx: (M,) int, each path's datum in the homotopy.
            split: the time of the first stop, in (0, 1).
            weights: (n,) row weights of the system.
            options: step control (defaults to :class:`TrackerOptions`).
            iterations: Newton steps at ``t = 1``.

        Returns:
            A :class:`SplitOutcome`.

        Raises:
            HomotopyError: the C call reported a failure.
        """
        o = options or TrackerOptions()
        M = len(z0)
        z = np.array(z0, dtype=np.complex128, order="C").reshape(M, self.n)
        tau, h = np.zeros(M), np.full(M, o.h0)
        status, steps, accepted = (np.zeros(M, dtype=np.int64) for _ in range(3))
        z_mid, mid = np.zeros((M, self.n), dtype=np.complex128), np.full(M, -1, dtype=np.int64)
        z_end = np.zeros((M, self.n), dtype=np.complex128)
        nu, bound = np.zeros((M, iterations)), np.zeros(M)
        rc = self._solve(
            self.n, self.k, *self._data(homotopy, weights), M,
            np.ascontiguousarray(idx, dtype=np.int64), z, tau, h, ctypes.byref(_options(o)),
            status, steps, accepted, float(split), z_mid, mid, iterations, z_end, nu, bound,
        )  # fmt: skip
        if rc:
            raise HomotopyError(
                f"C path tracker failed ({_ERRORS.get(rc, rc)}) on {M} paths of an "
                f"{self.n}-unknown system; rerun with tracker='python'"
            )
        reached = np.flatnonzero(mid >= 0)
        arrived = reached[status[reached] == DONE]
        return SplitOutcome(
            end=TrackOutcome(z=z, tau=tau, status=status, steps=steps, accepted=accepted, h=h),
            reached=reached, z_split=z_mid[reached], arrived=arrived, z_newton=z_end[arrived],
            nu=nu[arrived], bound=bound[arrived],
        )  # fmt: skip


class BoundTracker:
    """The C tracker of one system (its row weights bound): call it to track, as
    :func:`~scdk_sym.algebraic.paths.continuation.track` with the identity time map; :meth:`newton`
    refines points."""

    def __init__(self, tracker: CTracker, weights: np.ndarray) -> None:
        self._tracker, self._weights = tracker, weights

    def __call__(self, homotopy, z0, idx, tau0, tau1, options=None, h0=None) -> TrackOutcome:
        """``CTracker.track`` with the system's weights."""
        return self._tracker.track(homotopy, z0, idx, tau0, tau1, self._weights, options, h0)

    def split(self, homotopy, z0, idx, split: float, options=None) -> SplitOutcome:
        """``CTracker.track_split`` with the system's weights."""
        return self._tracker.track_split(homotopy, z0, idx, split, self._weights, options)

    def newton(self, homotopy, z, t, idx, iterations: int, condition: bool = True):
        """``CTracker.newton`` with the system's weights: ``(z, nu, H_z, cond bound)``."""
        return self._tracker.newton(homotopy, z, t, idx, iterations, self._weights, condition)


def c_tracker(system, tracker: str = "auto") -> BoundTracker | None:
    """The C tracker of a system, or ``None`` for the numpy tracker.

    Args:
        system: a polynomial system; the C tracker needs an algebraic form (scaled or not).
        tracker: ``"auto"`` (C when the system is a form and a C compiler is present),
            ``"c"`` (C, or an error) or ``"python"`` (``None``).

    Returns:
        A :class:`BoundTracker` (``track(homotopy, z0, idx, tau0, tau1, options, h0) ->
        TrackOutcome`` when called) or ``None``.

    Raises:
        InputError: an unknown ``tracker``, or ``"c"`` for a system that is no form.
        BuildError: ``"c"`` without a working C compiler.
    """
    if tracker not in TRACKERS:
        raise InputError(f"unknown tracker {tracker!r}; trackers: {', '.join(TRACKERS)}")
    if tracker == "python":
        return None
    fw = _form_and_weights(system)
    if fw is None:
        if tracker == "c":
            raise InputError(
                f"tracker='c' needs a model's algebraic form, got {type(system).__name__}; "
                "use tracker='python' for other systems"
            )
        return None
    form, weights = fw
    try:
        products = form.model.products  # type: ignore[attr-defined]
        ct = products.get(HOMOTOPY_TRACKER, lambda: CTracker(form))
    except BuildError:
        if tracker == "c":
            raise
        return None
    return BoundTracker(ct, weights)
