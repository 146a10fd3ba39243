"""The algebraic form G(z, p) of every shipped model and of the Gepetto fixtures.

References are independent of the form: the model's own closure kernels (built with sin, cos
and the Rodrigues chart, cross-checked against Pinocchio in test_system), the model's
configurations (home, inverse kinematics, SC solves), central differences, and for the 6-6
platform and the 3-RPR the leg equations written here in numpy from the URDF anchors.
Tolerances are explicit; every RNG is seeded. CI time: 11.7 s and 18.0 s of CPU in two runs with
an empty compile cache (41 s and 57 s wall on a shared 2-core machine at load 11-12), measured
with ``SCDK_CACHE_DIR=$(mktemp -d) time pytest tests/test_algebraic_form.py``.
"""

from __future__ import annotations

import copy
from dataclasses import replace
from functools import cache
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from factories import MODELS, shipped
from roots import newton_roots
from stewart import DIETMAIER_BASE, DIETMAIER_LENGTHS, DIETMAIER_PLATFORM, anchors

import scdk_sym as sc
from scdk_sym.algebraic import algebraic_form
from scdk_sym.algebraic.pairs import complexify
from scdk_sym.algebraic.polynomial import polynomial_rows
from scdk_sym.errors import AlgebraicFormError, InputError
from scdk_sym.follower.geometry import features

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "gepetto"
SHIPPED = (
    "planar_hexa",
    "planar_hexa_reduced",
    "planar_3rpr",
    "stewart_gough",
    "delta",
    "hexa",
    "five_bar",
)
GEPETTO = ("robot_delta", "5bar_linkage", "5bar_linkage_iso3d", "5bar_linkage_iso6d")
NAMES = (*SHIPPED, *GEPETTO)


@cache
def load(name: str) -> sc.Model:
    if name in SHIPPED:
        return shipped(name)
    return sc.load_model(FIXTURES / name, frame="effector")


def scale(model) -> float:
    """Size of a closure row: distance rows are |a - b|^2 - L^2 [length unit^2]."""
    return max(1.0, model.length_scale) ** 2


def polish(model, y: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Newton on the model's own square system g (its kernels) down to rounding."""
    y, c = model.chart.to_local(y)
    for _ in range(8):
        g = np.array(model.kernels.g(y, theta, c)).ravel()
        if np.abs(g).max() < 1e-15 * max(1.0, model.length_scale):
            break
        Jp = np.array(model.kernels.jac(y, theta, c)[0])
        y, c = model.chart.recentre(y - np.linalg.solve(Jp, g), c)
    return model.chart.to_canonical(y, c)


@cache
def assembled(name: str) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """(y canonical, theta) of home and of 3 nearby assembled configurations, polished:
    inverse kinematics where the workspace matches the actuators, else SC solves."""
    model = load(name)
    rng = np.random.default_rng(sum(map(ord, name)))
    home = model.home
    configs = [home]
    for _ in range(3):
        if len(model.workspace) == model.k:
            step = 0.02 * max(1.0, model.length_scale)
            configs.append(model.inverse_kinematics(home.x + rng.uniform(-step, step, model.k)))
        else:
            theta = home.theta + rng.uniform(-0.05, 0.05, model.k)
            configs.append(sc.solve(model, theta, start=home))
    return tuple((polish(model, c.y, c.theta), c.theta) for c in configs)


def model_rows(model, y: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The model's kept closure rows at canonical y, scaled as G writes them (distance rows
    (|d|^2 - L^2) / (2 L) in the model, |d|^2 - L^2 in G)."""
    y_loc, c = model.chart.to_local(y)
    g = np.array(model.kernels.g(y_loc, theta, c)).ravel()
    values = dict(zip(model.unknowns, y, strict=True)) | dict(
        zip(model.actuated, theta, strict=True)
    )
    weights = []
    for cl in model.closures:
        w = 2 * (values[cl.length_joint] if cl.length_joint else cl.length)
        weights.extend([w if cl.type == "distance" else 1.0] * cl.rows)
    return g * np.array(weights)[list(model.rows)]


def random_real(model, rng) -> tuple[np.ndarray, np.ndarray]:
    y = model.home.y + rng.normal(scale=0.3, size=model.m)
    theta = model.home.theta + rng.normal(scale=0.3, size=model.k)
    return y, theta


# ---------------------------------------------------------------------- shape and protocol


@pytest.mark.parametrize("name", NAMES)
def test_square_with_structural_rows_vanishing_at_random_points(name):
    model = load(name)
    form = algebraic_form(model)
    assert form is algebraic_form(model)  # cached on the model
    assert form.G_real.size1_out(0) == form.G_real.size1_in(0) == form.n
    assert form.n_params == model.k == form.G_real.size1_in(1)
    assert form.offset_rows.shape == (form.n,)
    assert int(form.offset_rows.sum()) == len(model.rows)
    assert len(form.rows.names) == len(form.rows.labels) == form.n
    rng = np.random.default_rng(1)
    for _ in range(5):
        z, p = form.random_point(rng)
        assert z.shape == (form.n,) and p.shape == (form.n_params,)
        assert np.abs(z.imag).max() > 1e-3 and np.abs(p.imag).max() > 1e-3  # generic complex
        G, _, _ = form.evaluate(z, p)
        assert np.abs(G[~form.offset_rows]).max(initial=0.0) <= 1e-12 * max(1, np.abs(z).max())
        assert np.abs(G[form.offset_rows]).max() > 1e-6  # closure rows are not satisfied


# ---------------------------------------------------------------------- same rows as the model


@pytest.mark.parametrize("name", NAMES)
def test_closure_rows_equal_the_models_rows_at_random_real_points(name):
    """On the structural variety G's closure rows are the model's g (distance rows times 2L),
    at points that are not assembled: the zero sets agree everywhere, not only at home."""
    model = load(name)
    form = algebraic_form(model)
    rng = np.random.default_rng(2)
    for _ in range(10):
        y, theta = random_real(model, rng)
        z = form.from_model(y)
        G, _, _ = form.evaluate(z, form.params(theta))
        assert np.abs(G.imag).max() == 0.0
        np.testing.assert_allclose(
            G.real[form.offset_rows], model_rows(model, y, theta), rtol=0, atol=1e-12 * scale(model)
        )
        assert np.abs(G.real[~form.offset_rows]).max(initial=0.0) <= 1e-14
        np.testing.assert_allclose(
            np.array(form.G_real(z, theta)).ravel(), G.real, rtol=0, atol=1e-13 * scale(model)
        )


@pytest.mark.parametrize("name", NAMES)
def test_assembled_configurations_are_roots_and_map_back(name):
    model = load(name)
    form = algebraic_form(model)
    for y, theta in assembled(name):
        assert model.residual(y, theta) <= 1e-13 * max(1.0, model.length_scale)
        z = form.from_model(y)
        G, _, _ = form.evaluate(z, form.params(theta))
        assert np.abs(G).max() <= 1e-12 * scale(model)
        y_loc, c = form.to_model(z, reference=y)
        np.testing.assert_allclose(model.chart.to_canonical(y_loc, c), y, rtol=0, atol=1e-12)
        # the local chart of the model maps to the same z
        np.testing.assert_allclose(form.from_model(*model.chart.to_local(y)), z, atol=1e-13)


@pytest.mark.parametrize("name", NAMES)
def test_a_batch_of_points_maps_back_in_one_call(name):
    """to_model of the (N, n) points of several assembled configurations: each row's
    configuration (chart-free features: angles as cos and sin, rotations as matrices) is the
    one it came from; a batch with one complex row raises."""
    model = load(name)
    form = algebraic_form(model)
    ys = np.array([y for y, _ in assembled(name)])
    Z = np.array([form.from_model(y) for y in ys])
    Y_loc, C = form.to_model(Z, reference=ys[0])
    assert Y_loc.shape == (len(ys), model.m) and C.shape == (len(ys), model.chart.size)
    back = np.array([model.chart.to_canonical(y, c) for y, c in zip(Y_loc, C, strict=True)])
    np.testing.assert_allclose(features(model, back), features(model, ys), rtol=0, atol=1e-12)
    bad = Z.astype(complex)
    bad[-1, 0] += 1e-3j
    with pytest.raises(InputError):
        form.to_model(bad)


@pytest.mark.parametrize("name", NAMES)
def test_newton_on_G_converges_to_a_solution_of_g(name):
    """Newton on G from a perturbed root (off the structural variety too) converges, and its
    limit mapped back closes every loop of the model (dropped redundant rows included)."""
    model = load(name)
    form = algebraic_form(model)
    rng = np.random.default_rng(3)
    for y, theta in assembled(name):
        z_star = form.from_model(y)
        z = z_star + 1e-3 * max(1.0, model.length_scale) * rng.normal(size=form.n)
        p = form.params(theta)
        for _ in range(30):
            G, Jz, _ = form.evaluate(z, p)
            step = np.linalg.solve(Jz.real, G.real)
            z = z - step
            if np.abs(step).max() < 1e-15 * max(1.0, np.abs(z).max()):
                break
        assert np.abs(form.evaluate(z, p)[0]).max() <= 1e-12 * scale(model)
        np.testing.assert_allclose(z, z_star, rtol=0, atol=1e-9 * max(1.0, model.length_scale))
        y_new, c = form.to_model(z, reference=y)
        assert model.residual(y_new, theta, c) <= 1e-10 * max(1.0, model.length_scale)


# ---------------------------------------------------------------------- complex evaluation


@pytest.mark.parametrize("name", NAMES)
def test_complex_jacobians_match_differences(name):
    """At random complex points: dG/dz and dG/dp against central differences along the real
    and the imaginary directions (equal for a holomorphic G); at real points against the
    complex step, which needs no subtraction."""
    model = load(name)
    form = algebraic_form(model)
    rng = np.random.default_rng(4)
    h = 1e-6
    for _ in range(3):
        z, p = form.random_point(rng)
        _, Jz, Jp = form.evaluate(z, p)
        tol = 1e-7 * (1 + max(np.abs(Jz).max(), np.abs(Jp).max()))
        for u, J, n in ((z, Jz, form.n), (p, Jp, form.n_params)):
            for direction in (1.0, 1j):
                steps = direction * h * np.eye(n)
                batch_p = [p + s if u is p else p for s in steps] + [
                    p - s if u is p else p for s in steps
                ]
                batch_z = [z + s if u is z else z for s in steps] + [
                    z - s if u is z else z for s in steps
                ]
                G, _, _ = form.evaluate(np.array(batch_z), np.array(batch_p))
                fd = ((G[:n] - G[n:]) / (2 * direction * h)).T
                np.testing.assert_allclose(fd, J, rtol=0, atol=tol)
    y, theta = random_real(model, rng)
    z, p = form.from_model(y), form.params(theta)
    _, Jz, _ = form.evaluate(z, p)
    cs = np.array([form.evaluate(z + 1e-30j * e, p)[0].imag / 1e-30 for e in np.eye(form.n)]).T
    z_sym, p_sym = ca.SX.sym("z", form.n), ca.SX.sym("p", form.n_params)
    J_real = ca.Function("J", [z_sym, p_sym], [ca.jacobian(form.G_real(z_sym, p_sym), z_sym)])
    J_ad = np.array(J_real(z, theta))
    np.testing.assert_allclose(cs, J_ad, rtol=0, atol=1e-12 * (1 + np.abs(J_ad).max()))
    np.testing.assert_allclose(Jz.real, J_ad, rtol=0, atol=1e-12 * (1 + np.abs(J_ad).max()))
    assert np.abs(Jz.imag).max() == 0.0


def test_replay_on_pairs_is_numpys_complex_arithmetic():
    """Division, integer powers, cos, sin, negation, inversion: the replayed Function against
    numpy's complex evaluation of the same formula, values and Jacobians."""
    z, p = ca.SX.sym("z", 2), ca.SX.sym("p", 1)
    rows = ca.vertcat(
        z[0] ** 3 / (1 + z[1] * z[1]) + ca.cos(p[0]),
        ca.sin(z[0] * p[0]) - 2 * z[1] ** 2,
        1 / z[0] - z[1],
    )
    f = complexify(ca.Function("f", [z, p], [rows]), "f_pairs")

    def ref(z, p):
        return np.array(
            [
                z[0] ** 3 / (1 + z[1] ** 2) + np.cos(p[0]),
                np.sin(z[0] * p[0]) - 2 * z[1] ** 2,
                1 / z[0] - z[1],
            ]
        )

    rng = np.random.default_rng(14)
    for _ in range(5):
        zc = rng.normal(size=2) + 1j * rng.normal(size=2)
        pc = rng.normal(size=1) + 1j * rng.normal(size=1)
        Gr, Gi, Jzr, Jzi, Jpr, Jpi = (np.array(o) for o in f(zc.real, zc.imag, pc.real, pc.imag))
        np.testing.assert_allclose((Gr + 1j * Gi).ravel(), ref(zc, pc), rtol=1e-14, atol=1e-14)
        h = 1e-7
        fd_z = np.column_stack(
            [(ref(zc + h * e, pc) - ref(zc - h * e, pc)) / (2 * h) for e in np.eye(2)]
        )
        fd_p = (ref(zc, pc + h) - ref(zc, pc - h)) / (2 * h)
        np.testing.assert_allclose(Jzr + 1j * Jzi, fd_z, rtol=0, atol=1e-7 * np.abs(fd_z).max())
        np.testing.assert_allclose(
            (Jpr + 1j * Jpi).ravel(), fd_p, rtol=0, atol=1e-7 * np.abs(fd_p).max()
        )


def _quaternion_rotation(q: np.ndarray) -> np.ndarray:
    """R = ((q0^2 - v.v) I + 2 v v^T + 2 q0 [v]x) / (q.q), complex q (no conjugation)."""
    q0, v = q[0], q[1:]
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return ((q0 * q0 - v @ v) * np.eye(3) + 2 * np.outer(v, v) + 2 * q0 * vx) / (q @ q)


def test_stewart_gough_rows_match_the_leg_equations_at_complex_points():
    """|x + R(q) b_i - a_i|^2 - L_i^2 written here in numpy with the URDF anchors, at random
    complex points: the replayed complex evaluation is the holomorphic extension."""
    model = load("stewart_gough")
    form = algebraic_form(model)
    A, B = anchors(MODELS / "stewart_gough")
    names = form.rows.names
    ix = [names.index(f"platform_joint.{c}") for c in ("x", "y", "z")]
    iq = [names.index(f"platform_joint.q{i}") for i in range(4)]
    rng = np.random.default_rng(5)
    zs, ps = zip(*(form.random_point(rng) for _ in range(20)), strict=True)
    G, _, _ = form.evaluate(np.array(zs), np.array(ps))
    for z, p, g in zip(zs, ps, G, strict=True):
        d = z[ix] + B @ _quaternion_rotation(z[iq]).T - A
        ref = np.sum(d * d, axis=1) - p**2
        np.testing.assert_allclose(g[form.offset_rows], ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_planar_3rpr_rows_match_the_leg_equations_at_complex_points():
    model = load("planar_3rpr")
    form = algebraic_form(model)
    rng = np.random.default_rng(6)
    import xml.etree.ElementTree as ET

    root = ET.parse(MODELS / "planar_3rpr" / "robot.urdf").getroot()

    def xyz(joint):
        return np.array(
            [float(v) for v in root.find(f"joint[@name='{joint}']/origin").get("xyz").split()]
        )

    A = np.array([xyz(f"base_anchor_{i}_joint") for i in (1, 2, 3)])[:, :2]
    B = np.array([xyz(f"platform_anchor_{i}_joint") for i in (1, 2, 3)])[:, :2]
    n = form.rows.names
    for _ in range(10):
        z, p = form.random_point(rng)
        c, s = z[n.index("phi.c")], z[n.index("phi.s")]
        P = np.array([z[n.index("px")], z[n.index("py")]])
        d = P + B @ np.array([[c, -s], [s, c]]).T - A
        ref = np.sum(d * d, axis=1) - p**2
        G, _, _ = form.evaluate(z, p)
        np.testing.assert_allclose(G[form.offset_rows], ref, rtol=0, atol=1e-12 * np.abs(ref).max())


@pytest.mark.parametrize("name", ["planar_hexa", "stewart_gough"])
def test_compiled_backend_equals_the_virtual_machine(name):
    model = load(name)
    vm, cc = algebraic_form(model), algebraic_form(model, backend="compiled")
    assert cc.backend == "compiled" and cc is algebraic_form(model, backend="compiled")
    assert cc.content_hash() == vm.content_hash()
    rng = np.random.default_rng(7)
    zs, ps = zip(*(vm.random_point(rng) for _ in range(7)), strict=True)
    out_vm = vm.evaluate(np.array(zs), ps[0])
    out_cc = cc.evaluate(np.array(zs), ps[0])
    for a, b in zip(out_vm, out_cc, strict=True):
        np.testing.assert_allclose(b, a, rtol=1e-13, atol=1e-13)


# ---------------------------------------------------------------------- root counts


@cache
def dietmaier() -> sc.Model:
    return sc.builders.stewart_gough(DIETMAIER_BASE, DIETMAIER_PLATFORM)


def test_newton_roots_of_dietmaiers_platform_are_its_real_assembly_modes():
    """At Dietmaier's leg lengths all 40 assembly modes are real: every root Newton finds from
    300 random complex starts is real, closes the model's loops and is a distinct pose; no
    more than 40 (37 found with this seed)."""
    model = dietmaier()
    form = algebraic_form(model)
    roots = newton_roots(form, form.params(DIETMAIER_LENGTHS), 300, 100, np.random.default_rng(10))
    assert 30 <= len(roots) <= 40
    assert all(form.is_real(roots, 1e-8))
    poses = []
    for z in roots:
        y, c = form.to_model(z)
        assert model.residual(y, DIETMAIER_LENGTHS, c) <= 1e-10
        poses.append(model.configuration(y, DIETMAIER_LENGTHS, c).platform_pose)
    gaps = [np.abs(a - b).max() for i, a in enumerate(poses) for b in poses[:i]]
    assert min(gaps) > 1e-6


def test_newton_finds_at_most_40_roots_at_a_random_complex_parameter():
    """A general 6-6 platform has 40 complex assembly modes (38 found here with this seed;
    benchmarks/algebraic_newton_count.py finds all 40 with more starts)."""
    form = algebraic_form(dietmaier())
    _, p = form.random_point(np.random.default_rng(11))
    roots = newton_roots(form, p, 300, 100, np.random.default_rng(12))
    assert 30 <= len(roots) <= 40
    assert not any(form.is_real(roots, 1e-6))  # complex legs: no real pose


@pytest.mark.parametrize("name", ["five_bar", "planar_3rpr", "delta", "planar_hexa_reduced"])
def test_real_roots_are_the_assembly_modes(name):
    """The real roots of G at theta0 (random-start Newton, 200 starts) are the assembly modes
    that the SC curve follower finds (sc.assembly_modes), pose for pose."""
    model = load(name)
    form = algebraic_form(model)
    theta = model.home.theta + 0.05
    modes = sc.assembly_modes(model, theta)
    roots = newton_roots(form, form.params(theta), 200, 60, np.random.default_rng(13))
    real = [form.to_model(z) for z in roots[form.is_real(roots, 1e-8)]]
    poses = [model.configuration(y, theta, c).x for y, c in real]
    assert len(poses) == len(modes) >= 2
    for cfg in modes:
        gaps = [np.abs(x - cfg.x).max() for x in poses]
        assert min(gaps) <= 1e-9 * max(1.0, model.length_scale)


# ---------------------------------------------------------------------- mapping and errors


def test_content_hash_names_the_model():
    hashes = {algebraic_form(load(n)).content_hash() for n in ("planar_hexa", "stewart_gough")}
    assert len(hashes) == 2
    form = algebraic_form(load("planar_hexa"))
    assert form.content_hash() == form.content_hash()
    assert len(form.content_hash()) == 64


def test_batch_evaluation_equals_single_points():
    form = algebraic_form(load("hexa"))
    rng = np.random.default_rng(8)
    zs, ps = zip(*(form.random_point(rng) for _ in range(4)), strict=True)
    batch = form.evaluate(np.array(zs), np.array(ps))
    for i, (z, p) in enumerate(zip(zs, ps, strict=True)):
        for b, s in zip(batch, form.evaluate(z, p), strict=True):
            np.testing.assert_array_equal(b[i], s)


def test_is_real_and_to_model_refuse_complex_points():
    model = load("stewart_gough")
    form = algebraic_form(model)
    z, _ = form.random_point(np.random.default_rng(9))
    assert not form.is_real(z)
    z_real = form.from_model(model.home.y)
    assert form.is_real(z_real) and form.is_real(z_real + 1e-12j)
    assert list(form.is_real(np.array([z, z_real + 0j]))) == [False, True]
    with pytest.raises(InputError, match="not real"):
        form.to_model(z)


def test_bad_inputs_raise_scdk_errors():
    model = load("five_bar")
    with pytest.raises(InputError, match="backends: auto, compiled, cvodes"):
        algebraic_form(model, backend="c")
    form = algebraic_form(model)
    with pytest.raises(InputError, match=r"z must be \(N, 2\)"):
        form.evaluate(np.zeros((3, 5)), np.zeros(2))
    with pytest.raises(InputError, match="p must be"):
        form.evaluate(np.zeros((3, 2)), np.zeros((2, 2)))
    with pytest.raises(InputError, match="theta must have 2 values"):
        form.params([1.0])
    x = ca.SX.sym("x")
    with pytest.raises(AlgebraicFormError, match="no holomorphic polynomial form"):
        complexify(ca.Function("f", [x, ca.SX.sym("p", 0)], [ca.sqrt(x)]), "g")
    with pytest.raises(AlgebraicFormError, match="no holomorphic polynomial form"):
        complexify(ca.Function("f", [x, ca.SX.sym("p", 0)], [x**2.5]), "g")


@pytest.mark.parametrize("role", ["unknowns", "actuated"])
def test_a_joint_type_with_no_algebraic_form_is_refused_by_name(role):
    model = load("five_bar")
    joint = getattr(model, role)[0]
    tree = model.tree
    joints = tuple(replace(j, type="planar") if j.name == joint else j for j in tree.joints)
    other = copy.copy(model)
    other.tree = replace(tree, joints=joints)
    with pytest.raises(AlgebraicFormError, match=f"joint {joint!r} of type 'planar' has no alg"):
        polynomial_rows(other)
