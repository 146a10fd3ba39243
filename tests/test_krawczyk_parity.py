"""The binary64 interval Krawczyk test in C (scdk_sym.algebraic.certify.krawczyk_c) against its
Python twin, the Arb test (scdk_sym.algebraic.certify.krawczyk_arb).

References are independent of the code under test: the exact results of the operations on
binary64 endpoints in Arb at 300 bits, roots known exactly in binary64 (every term of the
system carries a factor ``x - r``), and the Arb test of :mod:`scdk_sym.algebraic.certify`
(run with the C test switched off).
"""

from __future__ import annotations

import contextlib

import casadi as ca
import numpy as np
import pytest
from flint import arb, arb_mat, ctx
from stewart import DIETMAIER_BASE, DIETMAIER_LENGTHS, DIETMAIER_PLATFORM

import scdk_sym as sc
from scdk_sym.algebraic import certify_all, certify_configurations, closure_function, krawczyk
from scdk_sym.algebraic.certify import points as certify_module
from scdk_sym.algebraic.certify.krawczyk_c import replay, tape
from scdk_sym.errors import InputError

EPS = float(np.finfo(float).eps)

#: CasADi expression and exact Arb range (from the endpoints: every operation here is
#: monotone on each sign-definite piece, the pieces meeting at 0) of each supported operation.
_OPS = {
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
    "mul": lambda a, b: a * b,
    "div": lambda a, b: a / b,
    "sq": lambda a, b: a**2,
    "neg": lambda a, b: -a,
    "twice": lambda a, b: 2 * a,
    "inv": lambda a, b: 1 / b,
    "fabs": lambda a, b: ca.fabs(a) if isinstance(a, ca.SX) else abs(a),
    "sign": lambda a, b: ca.sign(a) if isinstance(a, ca.SX) else arb(a.sgn()),
}


@contextlib.contextmanager
def _bits_300():
    """Arb at 300 bits inside the block."""
    old = ctx.prec
    ctx.prec = 300
    try:
        yield
    finally:
        ctx.prec = old


def _hull(values: list[arb]) -> tuple[arb, arb]:
    """The least and the greatest of some exact values."""
    lo = hi = values[0]
    for v in values[1:]:
        lo, hi = (v if v < lo else lo), (v if v > hi else hi)
    return lo, hi


def _exact_range(op, a: tuple[float, float], b: tuple[float, float]) -> tuple[arb, arb]:
    """The exact range of ``op`` over the boxes, at 300 bits (endpoints, and 0 for sq/fabs)."""
    with _bits_300():
        pa = [arb(v) for v in a] + ([arb(0)] if a[0] < 0 < a[1] else [])
        pb = [arb(v) for v in b]
        return _hull([_OPS[op](x, y) for x in pa for y in pb])


@pytest.mark.parametrize("lanes", [False, True])
@pytest.mark.parametrize("op", sorted(_OPS))
def test_each_operation_encloses_its_exact_range_within_a_few_ulps(op, lanes):
    """Every lane on the operands, and each lane on operands of its own (each lane checked,
    bit for bit, against an evaluation with its operands in every lane)."""
    a, b = ca.SX.sym("a"), ca.SX.sym("b")
    t = tape(ca.Function("f", [a, b], [_OPS[op](a, b)]))
    assert t is not None
    rng = np.random.default_rng(21)
    for i in range(400):
        # endpoints with many significant bits, of mixed signs and magnitudes
        ca_, cb = rng.uniform(-3, 3, 2) * 10.0 ** rng.integers(-5, 6, 2)
        ra, rb = np.abs(rng.normal(size=2)) * 10.0 ** rng.integers(-12, 0, 2) * np.abs([ca_, cb])
        A, B = (ca_ - ra, ca_ + ra), (cb - rb, cb + rb)
        if i % 4 == 1:  # intervals holding 0 (the branches of sq, fabs and sign)
            A = (-abs(ca_) * rng.uniform(0.1, 2), abs(cb) * rng.uniform(0.1, 2))
        elif i % 4 == 2:  # sums and differences with an end exactly 0
            B = (-A[0], -A[0] + rb) if rng.uniform() < 0.5 else (A[1] - rb, A[1])
        elif i % 4 == 3:  # an end exactly 0 (products and quotients of 0)
            A = (0.0, abs(ca_)) if rng.uniform() < 0.5 else (-abs(ca_), 0.0)
        if op in ("div", "inv") and B[0] <= 0 <= B[1]:
            assert replay(t, np.array([A]), np.array([B]), lanes) is None  # divisor holds 0
            continue
        out = replay(t, np.array([A]), np.array([B]), lanes)[0]
        lo, hi = _exact_range(op, A, B)
        assert arb(out[0]) <= lo and hi <= arb(out[1]), (op, A, B, out)
        # two outward steps at most per bound (a few more for a sum's cancellation)
        assert out[1] - out[0] <= float(hi - lo) + 8 * EPS * max(abs(out[0]), abs(out[1]))


@pytest.mark.parametrize("lanes", [False, True])
def test_results_that_round_to_zero_are_still_enclosed(lanes):
    """Products, squares and quotients whose exact value is below the smallest binary64
    number round to 0: the bounds step past it (to the smallest subnormal on each side), so
    the interval still holds the exact value (Arb, 300 bits)."""
    a, b = ca.SX.sym("a"), ca.SX.sym("b")
    cases = [
        ("mul", (1e-200, 2e-200), (3e-200, 4e-200)),
        ("mul", (-2e-200, -1e-200), (1e-200, 1e-200)),
        ("sq", (1e-170, 1e-170), (0.0, 0.0)),
        ("sq", (-1e-170, -1e-170), (0.0, 0.0)),
        ("div", (1e-300, 1e-300), (1e100, 1e100)),
        ("div", (-1e-300, -1e-300), (1e100, 2e100)),
    ]
    for op, A, B in cases:
        t = tape(ca.Function("f", [a, b], [_OPS[op](a, b)]))
        out = replay(t, np.array([A]), np.array([B]), lanes)[0]
        lo, hi = _exact_range(op, A, B)
        assert arb(out[0]) <= lo and hi <= arb(out[1]), (op, A, B, out)
        assert out[0] < 0.0 or out[1] > 0.0  # a bound stepped off 0
        assert max(abs(out[0]), abs(out[1])) <= 1e-300  # and only a few subnormals far


def _exact_trig_range(fn: str, lo: float, hi: float) -> tuple[arb, arb]:
    """The exact range of sin or cos over [lo, hi] at 300 bits: the ends and every critical
    point (1 + 2 j) pi/2 (sin) or j pi (cos) inside."""
    with _bits_300():
        f = arb.sin if fn == "sin" else arb.cos
        values = [f(arb(lo)), f(arb(hi))]
        half_pi = arb.pi() / 2
        for j in range(int(np.floor(lo / np.pi)) - 2, int(np.floor(hi / np.pi)) + 3):
            c = (1 + 2 * j) * half_pi if fn == "sin" else 2 * j * half_pi
            if arb(lo) <= c <= arb(hi):
                values.append(arb(1 if j % 2 == 0 else -1))
        return _hull(values)


@pytest.mark.parametrize("lanes", [False, True])
@pytest.mark.parametrize("fn", ["sin", "cos"])
def test_sin_and_cos_enclose_their_exact_range_within_a_few_ulps(fn, lanes):
    """Points and intervals of widths up to 1, near and far from the multiples of pi/2
    (where the reduction and the extrema matter), up to |x| = 1e5; the hull past 2^20; point
    by point and in the lanes."""
    x, p = ca.SX.sym("x"), ca.SX.sym("p")
    t = tape(ca.Function("f", [x, p], [getattr(ca, fn)(x)]))
    assert t is not None
    rng = np.random.default_rng(4)
    for i in range(600):
        if i % 3 == 0:  # next to a multiple of pi/2
            c = rng.integers(-200, 200) * np.pi / 2 + rng.choice([-1, 1]) * 10.0 ** -rng.integers(
                1, 17
            )
        else:
            c = rng.uniform(-1, 1) * 10.0 ** rng.integers(-8, 6)
        w = 0.0 if i % 2 else rng.uniform(0, 1) * 10.0 ** rng.integers(-15, 1)
        lo, hi = c, c + w
        out = replay(t, np.array([[lo, hi]]), np.zeros((1, 2)), lanes)[0]
        low, high = _exact_trig_range(fn, lo, hi)
        assert arb(out[0]) <= low and high <= arb(out[1]), (fn, lo, hi, out)
        # a few ulps, and the reduction's rounding: one ulp of x per step of pi/2
        assert out[1] - out[0] <= float(high - low) + 16 * EPS * (1 + abs(c)), (fn, lo, hi, out)
    far = replay(t, np.array([[2.0**21, 2.0**21]]), np.zeros((1, 2)), lanes)[0]
    np.testing.assert_array_equal(far, [-1.0, 1.0])


def test_operations_without_correct_rounding_have_no_tape():
    x, p = ca.SX.sym("x"), ca.SX.sym("p")
    for expr in (ca.tan(x), ca.sqrt(x), x**3.5, ca.exp(x) + p):
        assert tape(ca.Function("f", [x, p], [expr])) is None
    t = tape(ca.Function("f", [x, p], [x * p]))
    with pytest.raises(InputError, match="takes 1 and 1"):
        replay(t, np.zeros((2, 2)), np.zeros((1, 2)))


def _rational_system(rng: np.random.Generator, n: int) -> tuple[ca.Function, np.ndarray]:
    """A rational square system (x, p) with the exact binary64 root r at p = 1."""
    r = rng.uniform(-2, 2, n)
    A = rng.normal(size=(n, n)) + n * np.eye(n)
    x, p = ca.SX.sym("x", n), ca.SX.sym("p")
    u = x - r  # exactly 0 at x = r
    rows = []
    for i in range(n):
        j, k = rng.integers(0, n, 2)
        b = rng.normal(size=3)
        rows.append(
            p * ca.dot(A[i], u)
            + b[0] * u[j] * u[k]
            + b[1] * u[j] / (2 + x[k] ** 2)
            + b[2] * (u[k] ** 2) * ca.fabs(x[j])
        )
    return ca.Function("f", [x, p], [ca.vertcat(*rows)]), r


def _c_only(f: ca.Function, xs: np.ndarray, p: list) -> list:
    """The certificates of the C test alone (None where it proves nothing)."""
    sq = certify_module.square_system(f)
    assert sq.fast is not None  # rational: the C test applies
    _, bounds, _ = certify_module.parameters(p, sq.n_params)
    return certify_module.first_boxes(sq, np.atleast_2d(xs), bounds, certify_module.TIGHTEN)


@pytest.mark.parametrize("n", [1, 3, 6])
def test_rational_systems_are_proven_around_the_known_root_as_by_arb(n):
    rng = np.random.default_rng(n)
    for _ in range(5):
        f, r = _rational_system(rng, n)
        x = r + rng.normal(size=n) * 1e-9
        fast = _c_only(f, x, [1.0])[0]
        assert fast is not None and fast.proven and fast.contains(r), fast
        assert fast.radius <= 1e-13
        assert np.all(fast.domain[:, 0] < r) and np.all(r < fast.domain[:, 1])
        slow = krawczyk(f, x, [1.0], arithmetic="arb")
        assert slow.proven and slow.contains(r)
        # the same uniqueness box (from the same Newton point, up to the rounding floor)
        assert np.allclose(fast.domain, slow.domain, rtol=0, atol=1e-13)
        assert np.all(fast.box[:, 0] <= slow.box[:, 1]) and np.all(slow.box[:, 0] <= fast.box[:, 1])
        again = krawczyk(f, x, [1.0])  # krawczyk takes the C certificate
        assert np.array_equal(again.box, fast.box) and again.reason == fast.reason


def test_a_parameter_box_is_proven_for_every_parameter_in_it():
    rng = np.random.default_rng(4)
    f, r = _rational_system(rng, 3)
    x = r + 1e-9
    thin, wide = _c_only(f, x, [1.0])[0], _c_only(f, x, [[1.0 - 1e-6, 1.0 + 1e-6]])[0]
    assert thin is not None and wide is not None and thin.contains(r) and wide.contains(r)
    assert wide.radius > thin.radius  # the zero is the same for every p, its enclosure wider
    far = krawczyk(f, r + 0.5, [1.0])  # the C test proves nothing; Arb says why
    assert _c_only(f, r + 0.5, [1.0]) == [None]
    assert not far.proven and far.reason


def test_a_double_root_is_not_proven():
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p")
    f = ca.Function("f", [x, p], [ca.vertcat((x[0] - 1) ** 2, x[1] - p)])
    assert _c_only(f, [1.0 + 1e-9, 2.0], [2.0]) == [None]
    assert not krawczyk(f, [1.0 + 1e-9, 2.0], [2.0]).proven


def test_dietmaier_assembly_modes_c_and_arb_certificates_agree():
    model = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    sols = sc.assembly_modes(model, DIETMAIER_LENGTHS)
    ys = np.vstack([s.y for s in sols])
    fast = certify_configurations(model, ys, DIETMAIER_LENGTHS)
    q = np.concatenate([DIETMAIER_LENGTHS, model.chart.to_local(ys[0])[1]])
    local = np.vstack([c.x for c in fast.certificates])
    c_only = _c_only(closure_function(model), local, q)
    assert sum(c is not None for c in c_only) >= 38  # nearly all proven in C
    slow = certify_configurations(model, ys, DIETMAIER_LENGTHS, arithmetic="arb")
    assert fast.proven and slow.proven and fast.count == slow.count == 40
    for a, b in zip(fast.certificates, slow.certificates, strict=True):
        assert np.all(a.box[:, 0] <= b.box[:, 1]) and np.all(b.box[:, 0] <= a.box[:, 1])
        assert a.radius <= max(1e-12, 8 * b.radius)


@pytest.mark.parametrize("name", ["planar_3rpr", "five_bar", "delta", "planar_hexa"])
def test_revolute_models_are_certified_in_c_as_by_arb(name):
    """Closure rows with sin and cos (revolute joints): every assembly mode proven by the C
    test alone, its box meeting the Arb test's, about as tight."""
    from factories import shipped

    model = shipped(name)
    sols = sc.assembly_modes(model, model.home.theta)
    assert sols.certified and len(sols) >= 2
    ys = np.vstack([s.y for s in sols])
    fast = certify_configurations(model, ys, model.home.theta)
    q = np.concatenate([model.home.theta, model.chart.to_local(ys[0])[1]])
    local = np.vstack([c.x for c in fast.certificates])
    c_only = _c_only(closure_function(model), local, q)
    assert all(c is not None and c.proven for c in c_only)
    slow = certify_configurations(model, ys, model.home.theta, arithmetic="arb")
    assert fast.proven and slow.proven and fast.count == slow.count == len(sols)
    for a, b in zip(c_only, slow.certificates, strict=True):
        assert np.all(a.box[:, 0] <= b.box[:, 1]) and np.all(b.box[:, 0] <= a.box[:, 1])
        assert a.radius <= max(1e-12, 8 * b.radius)


def test_certify_all_checks_every_row_and_counts_distinct_zeros():
    rng = np.random.default_rng(12)
    f, r = _rational_system(rng, 2)
    s = certify_all(f, np.vstack([r, r + 1e-12]), [1.0])
    assert not s.proven and s.count == 1 and s.duplicates == ((0, 1),), s.reason
    with pytest.raises(InputError, match="x must be 2"):
        certify_all(f, np.array([[0.0, np.nan]]), [1.0])
    with pytest.raises(InputError, match="unknown arithmetic"):
        certify_all(f, np.vstack([r]), [1.0], arithmetic="float")


def _near_singular_system(rng: np.random.Generator, n: int, cond: float):
    """The system ``A x + x * x / 20 - p b``, ``A`` of condition number about ``cond``, and
    its zero near a random point at p = 1 by Newton steps in Arb at 300 bits: (f, zero,
    cond(A))."""
    U, _ = np.linalg.qr(rng.normal(size=(n, n)))
    V, _ = np.linalg.qr(rng.normal(size=(n, n)))
    A = U @ np.diag(np.geomspace(1.0, 1.0 / cond, n)) @ V.T
    r = rng.uniform(-2, 2, n)
    b = A @ r + r * r / 20
    x, p = ca.SX.sym("x", n), ca.SX.sym("p")
    f = ca.Function("f", [x, p], [ca.mtimes(ca.DM(A), x) + x * x / 20 - p * ca.DM(b)])
    with _bits_300():
        Aa, ba = arb_mat(A.tolist()), arb_mat([[v] for v in b])
        z = arb_mat([[v] for v in r])
        for _ in range(12):
            z = arb_mat([[z[i, 0].mid()] for i in range(n)])
            F = Aa * z + arb_mat([[z[i, 0] ** 2 / 20] for i in range(n)]) - ba
            J = Aa + arb_mat(
                n, n, [z[i, 0] / 10 if i == j else 0 for i in range(n) for j in range(n)]
            )
            z = z - J.solve(F)
        zero = np.array([float(z[i, 0].mid()) for i in range(n)])
        assert float(max(abs(F[i, 0]) for i in range(n)).mid()) < 1e-60
    return f, zero, float(np.linalg.cond(A))


@pytest.mark.parametrize("arithmetic", ["auto", "arb"])
def test_tightening_near_a_singular_zero_holds_it_and_stops_on_its_own(arithmetic):
    """A nearly singular zero from a rough point: the tightened enclosure holds the zero (Arb,
    300 bits), is at least ten times narrower than the untightened one and within the
    binary64 bound cond(A) eps (1 + |x|); a larger step budget gives the same enclosure."""
    rng = np.random.default_rng(31)
    for n, cond in [(2, 1e6), (3, 1e8), (4, 1e7)]:
        f, zero, k = _near_singular_system(rng, n, cond)
        x = zero + rng.normal(size=n) * 1e-7
        c = krawczyk(f, x, [1.0], arithmetic=arithmetic)
        rough = krawczyk(f, x, [1.0], arithmetic=arithmetic, tighten=0)
        more = krawczyk(f, x, [1.0], arithmetic=arithmetic, tighten=40)
        assert c.proven and rough.proven, (c.reason, rough.reason)
        assert c.contains(zero) and rough.contains(zero)
        assert c.radius * 10 <= rough.radius
        assert c.radius <= k * EPS * (1 + float(np.max(np.abs(zero))))
        assert np.array_equal(c.box, more.box)


def test_the_lane_width_changes_no_outcome():
    """The library tests 2, 4 or 8 points at once (one register of doubles: the baseline
    instruction set, AVX2, AVX-512, each where the processor has it); on 37 points of the
    6-6 closure system (rotations through sin and cos) -- Dietmaier's 40 modes less three,
    three of them moved off their zero, one to a NaN and one with a parameter box per point
    -- every build gives the same statuses, radii and boxes to the bit, and the proven boxes
    hold the Arb test's."""
    from scdk_sym.algebraic.clibrary import _cpu_flags

    model = sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    sols = sc.assembly_modes(model, DIETMAIER_LENGTHS)
    ys = np.vstack([s.y for s in sols])[:37]
    q = np.concatenate([DIETMAIER_LENGTHS, model.chart.to_local(ys[0])[1]])
    f = closure_function(model)
    fast = certify_configurations(model, ys, DIETMAIER_LENGTHS)
    local = np.array(np.vstack([c.x for c in fast.certificates]))
    local[[3, 17, 30]] += np.array([1e-3, -1e-2, 0.5])[:, None]  # no zero close enough
    local[22, 1] = np.nan
    sq = certify_module.square_system(f)
    _, bounds, _ = certify_module.parameters(list(q), sq.n_params)
    boxes = np.repeat(bounds[None], 37, axis=0)
    boxes[5] = bounds + np.array([-1e-12, 1e-12])  # a box of parameters for one point
    cpu = _cpu_flags()
    builds = [()]
    if "avx2" in cpu:
        builds.append(("-mavx2",))
    if "avx512f" in cpu:
        builds.append(("-mavx2", "-mavx512f"))
    outs = [sq.fast.test(local, boxes, certify_module.TIGHTEN, certify_module.TINY,
                         certify_module.MAX_CONDITION, simd=b) for b in builds]  # fmt: skip
    proven = outs[0][0]
    assert proven.sum() == 33 and not proven[[3, 17, 22, 30]].any()
    for other in outs[1:]:
        for a, b in zip(outs[0], other, strict=True):
            np.testing.assert_array_equal(a, b)
    slow = certify_configurations(model, ys, DIETMAIER_LENGTHS, arithmetic="arb")
    for i in np.flatnonzero(proven)[::8]:
        a, b = outs[0][2][i], slow.certificates[i].box
        assert np.all(a[:, 0] <= b[:, 1]) and np.all(b[:, 0] <= a[:, 1])
