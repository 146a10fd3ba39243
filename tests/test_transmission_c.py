"""The generated C transmission (``scdk codegen MODEL --outputs ...``) against the Python one.

For two legs of Gepetto's collection, the C sources are generated, compiled with
``-std=c99 -Wall -Wextra -Werror -O2`` into a shared library (once per model) and called with
ctypes along a smooth seeded motion near home: forward, inverse, the Jacobian and its inverse,
velocities, torques and their inverse directions, and the margin equal
``sc.transmission``'s to 1e-10. At an exact fold of the ankle the derivative functions return
the SINGULAR status; bad inputs get their status and leave the state as it was. The example
control loop (``examples/c/transmission_loop.c``) builds with its Makefile target and runs.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from factories import ROOT, needs_compiler

import scdk_sym as sc
from scdk_sym.errors import ModelWarning, SingularTransmissionError
from scdk_sym.kernels.compile import compile_parallel
from scdk_sym.robot.blocks import triangular_blocks
from scdk_sym.solvers.transmission_c import TransmissionSources, write_transmission

pytestmark = needs_compiler()

GEPETTO = ROOT / "tests" / "fixtures" / "gepetto"
HIPS = ("motor_hip_x", "motor_hip_y", "motor_hip_z")
OUTPUTS = {
    "digit_like": (*HIPS, "free_knee", "free_foot1", "free_foot2"),
    "cassie_like": ("motor_hip1", "motor_hip2", "motor_tigh", "free_knee", "free_ankle"),
    # MuJoCo Menagerie's Cassie as published: both legs, hips, tarsus and foot joints
    "cassie.xml": tuple(
        f"{side}-{joint}"
        for side in ("left", "right")
        for joint in ("hip-roll", "hip-yaw", "hip-pitch", "tarsus", "foot")
    ),
}
#: C prefixes (distinct: the libraries are loaded in one process; the example expects scdk)
PREFIX = {"digit_like": "scdk", "cassie_like": "cassie", "cassie.xml": "mjcassie"}
MENAGERIE_CASSIE = ROOT / "tests" / "fixtures" / "mjcf" / "menagerie" / "agility_cassie"
STRICT = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-O2")
OK, ERR_NULL, ERR_SIZE, ERR_NONFINITE, ERR_STATE, ERR_SINGULAR = 0, -1, -2, -3, -7, -11

_dp = ctypes.POINTER(ctypes.c_double)


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_dp)


class CTransmission:
    """The generated functions of one library, on one ``<prefix>_transmission`` state."""

    def __init__(self, path: Path, prefix: str, k: int, nblocks: int) -> None:
        self.lib = ctypes.CDLL(str(path))
        self.p, self.k, self.nblocks = prefix, k, nblocks
        self.state = ctypes.create_string_buffer(self.fn("transmission_size")())
        assert self.fn("transmission_init")(self.state, None, None) == OK

    def fn(self, name: str):
        return getattr(self.lib, f"{self.p}_{name}")

    def map(self, name: str, values) -> tuple[int, np.ndarray]:
        """``<prefix>_<name>(t, in, k, out, k)``: forward, inverse, velocities, torques, ..."""
        v = np.ascontiguousarray(values, dtype=float)
        out = np.full(self.k, np.nan)
        status = self.fn(name)(self.state, _ptr(v), v.size, _ptr(out), self.k)
        return status, out

    def matrix(self, name: str) -> tuple[int, np.ndarray]:
        out = np.full(self.k * self.k, np.nan)
        status = self.fn(name)(self.state, _ptr(out), out.size)
        return status, out.reshape(self.k, self.k)

    def margin(self) -> tuple[int, float, int, np.ndarray]:
        value, worst = ctypes.c_double(np.nan), ctypes.c_int(-1)
        blocks = np.full(self.nblocks, np.nan)
        status = self.fn("margin")(
            self.state, ctypes.byref(value), ctypes.byref(worst), _ptr(blocks), self.nblocks
        )
        return status, value.value, worst.value, blocks


def load(name: str) -> sc.Model:
    if name.endswith(".xml"):
        pytest.importorskip("mujoco")  # MuJoCo's compiler reads MJCF
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        return sc.load_model(MENAGERIE_CASSIE / name if name.endswith(".xml") else GEPETTO / name)


_BUILT: dict[str, tuple[sc.Model, TransmissionSources, Path]] = {}


def built(name: str, tmp_path_factory) -> tuple[sc.Model, TransmissionSources, Path]:
    """Generated sources and the strictly compiled library of a model (once per module)."""
    if name not in _BUILT:
        model = load(name)
        src = write_transmission(model, OUTPUTS[name], tmp_path_factory.mktemp(name), PREFIX[name])
        lib = compile_parallel(src.sources, src.directory / f"lib{name}.so",
                               (*STRICT, "-fPIC"), ("-shared",), cwd=src.directory)  # fmt: skip
        _BUILT[name] = (model, src, lib)
    return _BUILT[name]


@pytest.fixture(scope="module", params=sorted(OUTPUTS))
def leg(request, tmp_path_factory):
    return request.param, *built(request.param, tmp_path_factory)


def motion(model: sc.Model, seed: int, count: int = 20) -> np.ndarray:
    """(count, k) a smooth seeded sine motion of every motor from home [rad]."""
    rng = np.random.default_rng(seed)
    amp, phase = rng.uniform(0.02, 0.06, model.k), rng.uniform(0, 2 * np.pi, model.k)
    t = np.linspace(0.0, 1.0, count + 1)[1:, None]
    return model.home.theta + amp * (np.sin(2 * np.pi * t + phase) - np.sin(phase))


def test_every_map_equals_the_python_transmission(leg):
    name, model, src, lib = leg
    T = sc.transmission(model, OUTPUTS[name])
    c = CTransmission(lib, src.prefix, model.k, len(T.blocks()))
    rng = np.random.default_rng(7)
    assert c.margin()[1] == pytest.approx(T.margin().value, rel=1e-10)  # home
    for theta in motion(model, 3):
        status, q = c.map("forward", theta)
        assert status >= 0
        np.testing.assert_allclose(q, T.forward(theta), rtol=0, atol=1e-10)
        status, J = c.matrix("jacobian")
        assert status == OK
        np.testing.assert_allclose(J, T.jacobian(), rtol=0, atol=1e-10)
        np.testing.assert_allclose(c.matrix("inverse_jacobian")[1], T.inverse_jacobian(),
                                   rtol=0, atol=1e-10)  # fmt: skip
        v = rng.standard_normal(model.k)
        for fn in ("velocities", "inverse_velocities", "torques", "inverse_torques"):
            status, out = c.map(fn, v)
            assert status == OK, fn
            np.testing.assert_allclose(out, getattr(T, fn)(None, v), rtol=0, atol=1e-10)
        status, value, worst, blocks = c.margin()
        m = T.margin()
        assert status == OK and worst == m.worst
        assert value == pytest.approx(m.value, rel=1e-10)
        np.testing.assert_allclose(blocks, m.blocks, rtol=1e-10, atol=0)
        status, motors = c.map("inverse", q)
        assert status >= 0
        np.testing.assert_allclose(motors, T.inverse(q), rtol=0, atol=1e-10)
        np.testing.assert_allclose(motors, theta, rtol=0, atol=1e-9)


def exact_fold(model: sc.Model, motor: str) -> tuple[np.ndarray, np.ndarray]:
    """``(y, theta)`` at the fold where ``motor`` turns back along the closures (the others
    held): from the closure curve's sample next to it, Newton on ``g = 0``, ``J_p v = 0``,
    ``|v| = 1`` over ``(y, theta_motor, v)``."""
    sys.path.insert(0, str(ROOT / "examples"))
    from biped_ankle_singularity import closure_curve

    ys, thetas = closure_curve(model, motor, 400, step=0.02)
    j = model.actuated.index(motor)
    i = int(np.argmax(thetas[:, j]))
    sym = model.symbolic
    v = ca.SX.sym("v", model.m)
    F = ca.vertcat(sym.g, sym.J_p @ v, ca.dot(v, v) - 1)
    dF = ca.horzcat(ca.jacobian(F, sym.y), ca.jacobian(F, sym.theta)[:, j], ca.jacobian(F, v))
    f = ca.Function("fold", [sym.y, sym.theta, sym.c, v], [F, dF])
    y, c = model.chart.to_local(ys[i])
    theta = thetas[i].copy()
    J_p = ca.Function("J_p", [sym.y, sym.theta, sym.c], [sym.J_p])
    vec = np.linalg.svd(np.array(J_p(y, theta, c)))[2][-1]  # the direction J_p loses
    for _ in range(30):
        r, d = (np.array(a) for a in f(y, theta, c, vec))
        step = np.linalg.solve(d, -r.ravel())
        y, theta[j], vec = y + step[: model.m], theta[j] + step[model.m], vec + step[model.m + 1 :]
        if np.abs(step).max() < 1e-15:
            break
    assert np.abs(np.array(f(y, theta, c, vec)[0])).max() < 1e-12
    return y, theta


def test_an_exact_fold_is_singular_and_bad_inputs_are_refused(tmp_path_factory):
    model, src, lib = built("digit_like", tmp_path_factory)
    T = sc.transmission(model, OUTPUTS["digit_like"])
    c = CTransmission(lib, src.prefix, model.k, len(T.blocks()))
    y, theta = exact_fold(model, "motor_shin1")
    cfg = model.configuration(y, theta)
    with pytest.raises(SingularTransmissionError):
        T._check(cfg)
    y_loc, chart = model.chart.to_local(cfg.y)
    chart = np.ascontiguousarray(chart if chart.size else np.zeros(1))
    start = c.fn("forward_start")
    assert start(c.state, _ptr(y_loc), model.m, _ptr(chart), model.chart.size,
                 _ptr(theta), model.k) == OK  # fmt: skip
    assert c.matrix("jacobian")[0] == ERR_SINGULAR
    for fn in ("velocities", "inverse_velocities", "torques", "inverse_torques"):
        status, out = c.map(fn, np.ones(model.k))
        assert status == ERR_SINGULAR and np.isnan(out).all(), fn  # nothing written
    status, value, worst, _ = c.margin()
    assert status == OK and value <= 1e-8 and worst == T._margin(cfg).worst == 4
    # refusals: the state is kept
    c = CTransmission(lib, src.prefix, model.k, len(T.blocks()))
    status, q = c.map("forward", model.home.theta + 0.01)
    assert status >= 0
    assert c.map("forward", np.full(model.k, np.nan))[0] == ERR_NONFINITE
    assert c.map("velocities", [np.inf] * model.k)[0] == ERR_NONFINITE
    out = np.zeros(model.k)
    assert c.fn("forward")(c.state, _ptr(out), model.k - 1, _ptr(out), model.k) == ERR_SIZE
    assert c.fn("jacobian")(c.state, None, model.k**2) == ERR_NULL
    assert c.fn("outputs")(c.state, _ptr(out), model.k) == OK
    np.testing.assert_array_equal(out, q)
    blank = ctypes.create_string_buffer(len(c.state))
    assert c.fn("jacobian")(blank, _ptr(np.zeros(model.k**2)), model.k**2) == ERR_STATE
    text = c.fn("transmission_status_string")
    text.restype = ctypes.c_char_p
    assert b"singular" in text(ERR_SINGULAR) and b"NaN" in text(ERR_NONFINITE)


def test_the_example_control_loop_builds_and_runs(tmp_path_factory, tmp_path):
    make = shutil.which("make")
    if make is None:
        pytest.skip("make is not installed")
    _, src, _ = built("digit_like", tmp_path_factory)
    # the generated sources were compiled with -O2 -Werror above: -O0 here keeps it quick
    flags = "-std=c99 -O0 -Wall -Wextra -Werror"
    proc = subprocess.run(
        [make, "-s", "-C", str(ROOT / "examples" / "c"), f"TGENERATED={src.directory}",
         f"TBUILD={tmp_path}", f"CFLAGS={flags}", "transmission"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "worst margin" in proc.stdout and "singular ticks: 0" in proc.stdout
    assert "(motor_shin1, motor_shin2) -> (free_foot1, free_foot2)" in proc.stdout


def test_the_derivative_kernel_and_its_stage_factors(tmp_path_factory):
    """The closures in each loop's root frame give ``J_p^-1 J_s`` of the world-frame ones at a
    tracked configuration with fewer structural nonzeros; the envelope of the stages' LU
    (``_elimination``, the loops of ``lu_factor`` and ``lu_solve_columns``, written out here)
    solves them for random values in their patterns, pivots anywhere partial pivoting takes
    them."""
    from scdk_sym.solvers.transmission_c import _elimination
    from scdk_sym.solvers.transmission_frames import loop_jacobians, pattern

    model, _, _ = built("digit_like", tmp_path_factory)
    T = sc.transmission(model, OUTPUTS["digit_like"])
    T.forward(motion(model, 5)[0])
    sym, cfg = model.symbolic, T.configuration()
    J_p, J_s = loop_jacobians(model, T._stages)
    assert pattern(J_p).sum() < pattern(sym.J_p).sum() and pattern(J_s).sum() < 0.3 * model.m**2
    f = ca.Function("f", [sym.y, sym.theta, sym.c], [J_p, J_s, sym.J_p, sym.J_s])
    y, c = model.chart.to_local(cfg.y)
    a, b, A, B = (np.array(v) for v in f(y, cfg.theta, c))
    np.testing.assert_allclose(np.linalg.solve(a, b), np.linalg.solve(A, B), atol=1e-12)
    rng = np.random.default_rng(1)
    for name in ("digit_like", "cassie_like", "cassie.xml"):
        m = load(name)
        P = pattern(loop_jacobians(m, triangular_blocks(m))[0])
        for st in triangular_blocks(m):
            cols, hi, lo, low = _elimination(P, st, set())
            mask = P[np.ix_(st.rows, cols)]
            for _ in range(20):
                Bm = np.where(mask, rng.standard_normal(mask.shape), 0.0)
                x = rng.standard_normal(len(cols))
                want = np.linalg.solve(Bm, x)
                np.testing.assert_allclose(_envelope_solve(Bm, x, hi, lo, low), want, atol=1e-8)


def _envelope_solve(B: np.ndarray, x: np.ndarray, hi, lo, low) -> np.ndarray:
    """``B^-1 x`` by the loops of the C template's ``lu_factor`` and ``lu_solve_columns``."""
    b, x, n = B.copy(), x.copy(), len(x)
    piv = []
    for k in range(n):
        p = k + int(np.argmax(np.abs(b[k : hi[k] + 1, k])))
        piv.append(p)
        b[[k, p]] = b[[p, k]]
        b[k + 1 : hi[k] + 1, k] /= b[k, k]
        b[k + 1 : hi[k] + 1, k + 1 :] -= np.outer(b[k + 1 : hi[k] + 1, k], b[k, k + 1 :])
    for k in range(n):
        x[[k, piv[k]]] = x[[piv[k], k]]
    for k in range(n):
        x[k + 1 : low[k] + 1] -= b[k + 1 : low[k] + 1, k] * x[k]
    for k in reversed(range(n)):
        x[k] /= b[k, k]
        x[lo[k] : k] -= b[lo[k] : k, k] * x[k]
    return x
