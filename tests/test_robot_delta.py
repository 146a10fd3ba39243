"""Gepetto's ``robot_delta`` across its flat parallelograms, against a Pinocchio continuation.

The reference (tests/gepetto_reference.py, Pinocchio alone) moves the motors straight from
home to each point of a 9 x 9 grid over [-0.4, 0.4]^2 rad (absolute motor values; home has
both motors at 0) with a secant predictor and a Levenberg-Marquardt corrector: the assembly
the robot reaches. Lines to the 18 points with ``mot1_rod2 > pi/12`` pass loop 1 flat (at
``mot1_rod2 = pi/12``); lines to the 6 points of ``FLAT_3_POINTS`` pass loop 3 flat, on a
curve from (-0.399, 0.146) to (-0.114, 0.4) through the motor values where the five-bar's rod
ends coincide (``ROD_ENDS_MEET``). At a flat point the parallelogram and the crossed
parallelogram branches cross. A convergent solve from home must return the continued
assembly at every point, a divergent one another verified assembly, each within
``SOLVE_BUDGET`` and the grid of a branch within ``GRID_BUDGET`` (the solves run in a child
process, ended when over budget; the failure lists every point with what was expected).
"""

from __future__ import annotations

import json
import queue
import subprocess
import sys
import tempfile
import threading
import time
from functools import cache
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from gepetto_reference import FIXTURE, Assembly, ContinuationResult, reference, wrap

import scdk_sym as sc

GRID = np.round(np.linspace(-0.4, 0.4, 9), 12)
#: Absolute motor values (mot1_rod1, mot1_rod2) [rad], C order (mot1_rod1 slowest).
POINTS = [(float(a), float(b)) for a in GRID for b in GRID]
#: Tolerances: effector placement [m, -], free joints modulo 2 pi [rad], closures [m, rad].
PLACEMENT_TOL = 1e-7
JOINT_TOL = 1e-6
CLOSURE_TOL = 1e-9
FLAT_1 = np.pi / 12  # mot1_rod2 where loop 1 is flat on the parallelogram branch
#: Motor values where the rod ends of the five-bar coincide (rod1 is tilted by 0.0211706 rad).
ROD_ENDS_MEET = np.array([-np.arcsin(0.25) - 0.021170584225393279665, np.arcsin(0.25)])
#: Grid points whose straight line from home passes loop 3 flat.
FLAT_3_POINTS = {(-0.4, 0.2), (-0.4, 0.3), (-0.4, 0.4), (-0.3, 0.3), (-0.3, 0.4), (-0.2, 0.4)}


@cache
def model() -> sc.Model:
    return sc.load_model(FIXTURE, frame="effector")


@cache
def home_q() -> np.ndarray:
    """Pinocchio q of the package's home (its idle joints fix the gauge of the reference)."""
    return reference().q_of(model().home.joints)


@cache
def expected(theta: tuple[float, float]) -> ContinuationResult:
    return reference().continuation(home_q(), theta)


def joint_mismatch(joints, q_ref: np.ndarray) -> tuple[float, str]:
    """(largest |joint - reference| modulo 2 pi [rad], the joint) over the free joints."""
    ref = reference()
    worst, name = 0.0, ""
    for n in model().unknowns + tuple(model().locked):
        d = abs(float(wrap(joints[n] - q_ref[ref.index[n]])))
        if d > worst:
            worst, name = d, n
    return worst, name


def describe(q: np.ndarray) -> str:
    a = reference().classify(q)
    loops = [
        f"loop {n} {'crossed' if c else 'parallelogram'}"
        for n, c in zip((1, 3), a.crossed, strict=True)
    ]
    return f"five-bar mode {a.mode:+d}, " + ", ".join(loops)


def test_home_is_the_neutral_assembly() -> None:
    # the package's home: both motors at 0, assembled; Pinocchio's neutral q assembled by LM
    # (all 12 free joints) is the same assembly up to the idle spins of the cut joint pairs
    ref, m = reference(), model()
    np.testing.assert_array_equal(m.home.theta, [0.0, 0.0])
    q, q0 = home_q(), ref.home
    assert ref.closure(q) <= 1e-13
    spun = {n for pair in ref.cut_pairs for n in pair}
    d = wrap(q - q0)
    assert max(abs(d[ref.index[n]]) for n in ref.names if n not in spun) <= 1e-9
    for a, b in ref.cut_pairs:  # a spin adds the same angle to both joints of the pair
        assert abs(wrap(d[ref.index[a]] - d[ref.index[b]])) <= 1e-9, (a, b)
    np.testing.assert_allclose(ref.placement(q), ref.placement(q0), rtol=0, atol=1e-12)
    np.testing.assert_allclose(m.home.platform_pose, ref.placement(q), rtol=0, atol=1e-12)


def test_idle_spins_are_the_cut_joint_pairs() -> None:
    # 18 rows x 12 free joints, rank 9: the null space is the joint pair of each cut spinning
    # together (+1, +1 on the two joints), so holding one joint per cut fixes the gauge
    ref = reference()
    _, J = ref.residual_jacobian(home_q())
    s = np.linalg.svd(J[:, ref.free], compute_uv=False)
    assert s[8] > 1e-4 and s[9] < 1e-12, s
    for a, b in ref.cut_pairs:
        v = np.zeros(ref.pm.nq)
        v[[ref.index[a], ref.index[b]]] = 1.0
        assert np.abs(J @ v).max() < 1e-12, (a, b)
    assert set(ref.idle_names) == set(model().locked)


def test_reference_jacobian_matches_finite_differences() -> None:
    ref = reference()
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, ref.pm.nq)
    _, J = ref.residual_jacobian(q)
    fd = np.empty_like(J)
    for i in range(ref.pm.nq):
        dq = np.zeros(ref.pm.nq)
        dq[i] = 1e-6
        fd[:, i] = (ref.residual(q + dq) - ref.residual(q - dq)) / 2e-6
    assert np.abs(J - fd).max() <= 1e-8


@pytest.mark.parametrize("theta", [(0.0, 0.0), (0.3, 0.4), (-0.4, 0.4)])
def test_eight_assemblies_one_per_branch(theta) -> None:
    # 2 five-bar modes x (parallelogram | crossed) in each loop, every one verified
    ref = reference()
    sols = ref.assemblies(theta, home_q(), starts=300, seed=11)
    kinds = {(a.mode, a.crossed) for a in map(ref.classify, sols)}
    assert len(sols) == 8 and len(kinds) == 8, [describe(q) for q in sols]
    assert max(ref.closure(q) for q in sols) <= 1e-13


def test_continuation_stays_on_the_home_branch_over_the_grid() -> None:
    # both parallelograms and home's five-bar mode at every point: the effector translates
    # with the tip of the five-bar (closed form) and free1_rod3 = mot1_rod2 (loop 1)
    ref = reference()
    home = ref.classify(home_q())
    for theta in POINTS:
        c = expected(theta)
        assert c.residual <= 1e-13, theta
        assert ref.classify(c.q) == home, (theta, describe(c.q))
        assert abs(wrap(c.q[ref.index["free1_rod3"]] - theta[1])) <= 1e-10, theta
        err = np.abs(c.placement - ref.closed_form_placement(theta)).max()
        assert err <= 1e-10, (theta, err)
    for loop, points in ((1, {t for t in POINTS if t[1] > FLAT_1}), (3, FLAT_3_POINTS)):
        crossing = {t for t in POINTS if any(n == loop for n, _ in expected(t).flat)}
        assert crossing == points, loop


def test_rod_ends_coincide_at_the_five_bar_singular_point() -> None:
    # the loop 3 flat curve passes through it; no grid line passes through it
    ref = reference()
    q = home_q().copy()
    q[ref.motors] = ROD_ENDS_MEET
    p = ref.joint_yz(q)
    assert np.abs(p["free1_rod1"] - p["free1_rod2"]).max() <= 1e-15
    for theta in POINTS:  # distance of the point to each straight line from home [rad]
        t = np.asarray(theta)
        if t.any():
            dist = abs(t[0] * ROD_ENDS_MEET[1] - t[1] * ROD_ENDS_MEET[0]) / np.linalg.norm(t)
            assert dist > 0.01 or t @ ROD_ENDS_MEET < 0, theta


def test_continuation_keeps_the_parallelogram_through_the_flat_point() -> None:
    # loop 1 flat at mot1_rod2 = pi/12: two branches cross; the secant predictor continues
    # the incoming tangent and the corrector stays on the parallelogram (free1_rod3 = mot1_rod2)
    ref = reference()
    c = expected((0.0, 0.4))
    assert [loop for loop, _ in c.flat] == [1]
    np.testing.assert_allclose(c.flat[0][1], [0.0, FLAT_1], rtol=0, atol=1e-9)
    assert abs(c.q[ref.index["free1_rod3"]] - 0.4) <= 1e-12
    assert ref.classify(c.q) == ref.classify(home_q())
    assert c.residual <= 1e-13
    # the crossed branch goes through the same flat configuration with another tangent
    qf = ref.flat_configuration(c.q, (0.0, FLAT_1))
    after = (0.0, FLAT_1 + 0.01)
    par = ref.continuation(home_q(), after).q
    sols = ref.assemblies(after, home_q(), starts=300, seed=5)
    crossed = [q for q in sols if ref.classify(q) == Assembly(mode=1, crossed=(True, False))]
    assert len(crossed) == 1
    t_par = (par - qf)[ref.solved] / 0.01
    t_crs = (crossed[0] - qf)[ref.solved] / 0.01
    assert np.abs(t_par - t_crs).max() > 0.5  # transversal: distinct tangents [rad / rad]
    assert np.abs(crossed[0] - qf).max() < 0.05  # both branches leave the flat point
    # H = [J_y, J_theta dtheta] (18 x 10) drops to rank 8 at the flat point
    dth = np.array([0.0, 1.0])

    def sigma9(q: np.ndarray) -> float:
        _, J = ref.residual_jacobian(q)
        H = np.c_[J[:, ref.solved], J[:, ref.motors] @ dth]
        return float(np.linalg.svd(H, compute_uv=False)[8])

    assert sigma9(qf) < 1e-12 < 1e-4 < sigma9(home_q())


# ---------------------------------------------------------------- the package on the grid

#: Wall-clock budgets [s]: one solve, and all the solves of one branch over the grid. A solve
#: that exceeds its budget is reported as such (its process is ended) and the next one starts.
SOLVE_BUDGET = 3.0
GRID_BUDGET = 60.0
#: Solves run in a child process so that a slow or hanging solve cannot stall the suite.
CHILD = r"""
import json, sys, time
sys.path[:0] = json.loads(sys.argv[4])  # import what the test process imports
import scdk_sym as sc
model = sc.load_model(sys.argv[1], frame="effector")
sc.solve(model, model.home.theta + 1e-3)  # builds what the first solve would build
if sys.argv[2] == "divergent":  # and what its certified last resort builds (start system)
    sc.assembly_modes(model, model.home.theta)
print(json.dumps({"ready": True}), flush=True)
for theta in json.loads(sys.argv[3]):
    t = time.perf_counter()
    try:
        r = sc.solve(model, theta, branch=sys.argv[2])
        out = {"joints": dict(r.joints), "pose": r.platform_pose.tolist(), "x": r.x.tolist(),
               "crossings": [[c.kind, c.theta.tolist()] for c in r.crossings]}
    except sc.ScdkError as err:
        out = {"error": type(err).__name__, "message": str(err)}
    out.update(theta=theta, time=time.perf_counter() - t)
    print(json.dumps(out), flush=True)
"""


def _solve_in_child(branch: str, points: list[tuple[float, float]], deadline: float) -> list[dict]:
    """Run ``CHILD`` on ``points`` until one exceeds its budget, crashes or the deadline."""
    out: list[dict] = []
    path = json.dumps([str(Path(p).resolve()) for p in sys.path if p])
    argv = [sys.executable, "-c", CHILD, str(FIXTURE), branch, json.dumps(points), path]
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(argv, cwd=FIXTURE, stdout=subprocess.PIPE, stderr=err, text=True)
        lines: queue.Queue = queue.Queue()

        def read() -> None:
            for line in proc.stdout:
                lines.put(line)
            lines.put(None)  # end of output: the child exited

        threading.Thread(target=read, daemon=True).start()
        ready = False
        try:
            while len(out) < len(points):
                wait = min(SOLVE_BUDGET if ready else 120.0, deadline - time.monotonic())
                try:
                    line = lines.get(timeout=max(wait, 0.0))
                except queue.Empty:
                    if ready and wait >= SOLVE_BUDGET:
                        msg = f"no answer within {SOLVE_BUDGET:g} s"
                        out.append({"error": "Timeout", "message": msg, "time": SOLVE_BUDGET})
                    break
                if line is None:
                    proc.wait()
                    err.seek(0)
                    tail = err.read().decode(errors="replace").strip().splitlines()[-1:]
                    msg = f"the solving process exited ({proc.returncode}): {' '.join(tail)}"
                    out.append({"error": "crash", "message": msg, "time": 0.0})
                    break
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue  # something else printed on stdout
                if not isinstance(rec, dict):
                    continue
                if rec.get("ready"):
                    ready = True
                else:
                    out.append(rec)
        finally:
            proc.kill()
            proc.wait()
    return out


@cache
def package(branch: str) -> dict[tuple[float, float], dict]:
    """theta -> the package's answer (joints, pose, crossings, or error and message).

    Points are solved nearest to home first, so that a spent budget leaves the far ones.
    """
    todo = sorted(POINTS, key=lambda t: (float(np.abs(t).max()), t))
    got: dict[tuple[float, float], dict] = {}
    deadline = time.monotonic() + GRID_BUDGET
    while todo and time.monotonic() < deadline:
        for rec in _solve_in_child(branch, todo, deadline):
            got[todo.pop(0)] = rec
    for theta in todo:
        msg = f"not attempted: the grid budget of {GRID_BUDGET:g} s was spent"
        got[theta] = {"error": "NotAttempted", "message": msg, "time": 0.0}
    return got


def where(theta: tuple[float, float]) -> str:
    flat = ", ".join(f"loop {n} flat at {np.round(t, 6).tolist()}" for n, t in expected(theta).flat)
    return f"theta={list(theta)}" + (f" (straight from home: {flat})" if flat else "")


def summary(failures: list[str], branch: str) -> str:
    n = len(failures)
    return f"{branch}: {n}/{len(POINTS)} grid points fail\n" + "\n".join(failures)


def test_convergent_solve_reaches_the_continued_assembly() -> None:
    # at every grid point: the effector placement and the free joints of the continuation
    # (the line to (-0.4, 0.4) passes the flat points of loops 1 and 3 0.00076 rad apart)
    failures = []
    for theta in POINTS:
        rec = package("convergent")[theta]
        exp = expected(theta)
        want = f"expected x={np.round(exp.placement[:3, 3], 9).tolist()} ({describe(exp.q)})"
        if "error" in rec:
            failures.append(
                f"{where(theta)}: {rec['error']} after {rec['time']:.2f} s: "
                f"{rec['message'][:160]}; {want}"
            )
            continue
        q = reference().q_of(rec["joints"])
        dT = float(np.abs(np.array(rec["pose"]) - exp.placement).max())
        dj, name = joint_mismatch(rec["joints"], exp.q)
        if dT > PLACEMENT_TOL or dj > JOINT_TOL:
            R = np.array(rec["pose"])[:3, :3]
            turn = float(np.linalg.norm(pin.log3(exp.placement[:3, :3].T @ R)))
            failures.append(
                f"{where(theta)}: {want}, got x={np.round(rec['x'], 9).tolist()} ({describe(q)})"
                f"; |dT|={dT:.2e}, effector turned by {turn:.2e} rad, |d {name}|={dj:.2e} rad"
            )
    assert not failures, summary(failures, "convergent")


def test_divergent_solve_returns_another_verified_assembly() -> None:
    # at every grid point: an assembly closed to CLOSURE_TOL (Pinocchio), not the continued one
    failures = []
    for theta in POINTS:
        rec = package("divergent")[theta]
        if "error" in rec:
            failures.append(
                f"{where(theta)}: {rec['error']} after {rec['time']:.2f} s: {rec['message'][:160]}"
            )
            continue
        q = reference().q_of(rec["joints"])
        closure = reference().closure(q)
        dj, _ = joint_mismatch(rec["joints"], expected(theta).q)
        if closure > CLOSURE_TOL or dj <= 1e-3:
            what = "the convergent assembly" if dj <= 1e-3 else f"closure residual {closure:.2e}"
            failures.append(f"{where(theta)}: returned {what}, x={rec['x']} ({describe(q)})")
    assert not failures, summary(failures, "divergent")


def test_convergent_crossings_report_the_flat_parallelogram_as_a_bifurcation() -> None:
    # the line from home to (0, 0.4) passes loop 1 flat at (0, pi/12)
    theta = (0.0, 0.4)
    rec = package("convergent")[theta]
    assert "error" not in rec, f"{where(theta)}: {rec['error']}: {rec['message'][:200]}"
    kinds = [(kind, np.round(t, 6).tolist()) for kind, t in rec["crossings"]]
    bif = [t for kind, t in rec["crossings"] if kind == "bifurcation"]
    assert bif, f"{where(theta)}: crossings {kinds}; expected a bifurcation at (0, pi/12)"
    assert min(abs(t[1] - FLAT_1) + abs(t[0]) for t in bif) <= 1e-6, kinds


def test_convergent_steps_over_two_flat_points_close_together() -> None:
    # the line to (-0.4, 0.4) passes loop 1 flat, then loop 3 flat 0.00076 rad further: both
    # are reported as bifurcations where the reference's continuation finds them
    theta = (-0.4, 0.4)
    rec = package("convergent")[theta]
    assert "error" not in rec, f"{where(theta)}: {rec['error']}: {rec['message'][:200]}"
    bif = [np.array(t) for kind, t in rec["crossings"] if kind == "bifurcation"]
    flat = [t for _, t in expected(theta).flat]
    assert len(bif) == len(flat) == 2, rec["crossings"]
    for got, want in zip(bif, flat, strict=True):
        assert np.abs(got - want).max() <= 1e-6, (got, want)
