"""Zero-copy kernel calls (scdk_sym.kernels.fastcall): the values and layout of a plain call."""

import casadi as ca
import numpy as np
import pytest
from factories import shipped

from scdk_sym.follower.calls import follower_calls, follower_kernels
from scdk_sym.kernels.fastcall import Dense, model_calls


def _plain(f, *args):
    out = f(*args)
    return [np.array(o) for o in (out if isinstance(out, tuple) else (out,))]


def test_dense_matches_a_plain_call_bit_for_bit():
    x = ca.SX.sym("x", 3)
    P = ca.SX.sym("P", 3, 2)
    sparse = ca.vertcat(ca.horzcat(x[0] * x[1], 0), ca.horzcat(0, ca.sin(x[2])))
    f = ca.Function("f", [x, P], [P.T @ x, sparse, ca.dot(x, x)])
    d = Dense(f, scalars=(2,))
    rng = np.random.default_rng(0)
    M = rng.normal(size=(3, 2))
    for args in [
        (rng.normal(size=3), M),
        (rng.normal(size=(3, 1)), M),
        (rng.normal(size=3), M[:, 0]),
    ]:
        plain = _plain(f, *args)
        ours = d(*args)
        for a, b in zip(plain[:2], ours[:2], strict=True):
            assert b.shape == a.shape and b.flags["C_CONTIGUOUS"]
            np.testing.assert_array_equal(b, a)
        assert isinstance(ours[2], float) and ours[2] == float(plain[2][0, 0])
    with pytest.raises(TypeError):
        d(np.ones(3))
    with pytest.raises(ValueError):
        Dense(f, scalars=(0,))


def test_outputs_are_new_arrays():
    x = ca.SX.sym("x", 2)
    d = Dense(ca.Function("g", [x], [2 * x]))
    first = d(np.ones(2))
    d(np.zeros(2))
    np.testing.assert_array_equal(first, [[2.0], [2.0]])


def test_model_and_follower_calls_match_the_plain_kernels():
    model = shipped("planar_hexa")
    y, c = model.chart.to_local(model.home.y)
    theta = np.array(model.home.theta)
    calls = model_calls(model)
    assert not model.kernels.jac.sparsity_out(0).is_dense()
    for name in ("g", "check", "jac", "pose"):
        plain = _plain(getattr(model.kernels, name), y, theta, c)
        ours = getattr(calls, name)(y, theta, c)
        ours = ours if isinstance(ours, tuple) else (ours,)
        for a, b in zip(plain, ours, strict=True):
            np.testing.assert_array_equal(b, a)
    kern, fast = follower_kernels(model), follower_calls(model)
    q = np.append(y, 0.0)
    p = np.concatenate([theta, 0.1 * np.ones(model.k)])
    t, _J = fast.tangent(q, np.ones(model.m + 1), p, c)
    x = np.concatenate([q, t.ravel()])
    for a, b in zip(_plain(kern.steps, x, 1e-3, p, c), fast.steps(x, 1e-3, p, c), strict=True):
        np.testing.assert_array_equal(b, a)
    y_new, res = fast.polish(y, theta, c)
    y_plain, res_plain = kern.polish(y, theta, c)
    np.testing.assert_array_equal(y_new, np.array(y_plain))
    assert res == float(res_plain)


@pytest.mark.parametrize("name", ["stewart_gough", "planar_3rpr"])
def test_mapped_calls_equal_single_calls_and_configurations_equal_configuration(name):
    """Kernels mapped over 7 points: each column bit for bit a single call's; a batch of
    configurations equals ``configuration`` point by point (to rounding: the chart maps of
    a stack)."""
    model = shipped(name)
    rng = np.random.default_rng(11)
    y0, c0 = model.chart.to_local(model.home.y)
    ys = y0 + 0.05 * rng.normal(size=(7, model.m))
    cs = np.tile(c0, (7, 1))
    theta = model.home.theta
    calls = model_calls(model)
    G = calls.mapped("g", 7)(ys.T, theta, cs.T)
    T, x = calls.mapped("pose", 7)(ys.T, theta, cs.T)
    Jp = calls.mapped("jac", 7)(ys.T, theta, cs.T)[0]
    for i in range(7):
        np.testing.assert_array_equal(G[:, i], calls.g(ys[i], theta, cs[i]).ravel())
        T1, x1 = calls.pose(ys[i], theta, cs[i])
        np.testing.assert_array_equal(T[:, 4 * i : 4 * i + 4], T1)
        np.testing.assert_array_equal(x[:, i], x1.ravel())
        np.testing.assert_array_equal(Jp[:, model.m * i : model.m * (i + 1)],
                                      calls.jac(ys[i], theta, cs[i])[0])  # fmt: skip
    many = model.configurations(ys, theta, cs)
    assert len(many) == 7
    for cfg, y, c in zip(many, ys, cs, strict=True):
        one = model.configuration(y, theta, c)
        np.testing.assert_allclose(cfg.y, one.y, rtol=0, atol=1e-14)
        np.testing.assert_array_equal(cfg.x, one.x)
        np.testing.assert_array_equal(cfg.platform_pose, one.platform_pose)
        assert cfg.residual == one.residual > 0  # off the closure manifold: rows not zero
        assert cfg.joints.keys() == one.joints.keys()
        assert max(abs(cfg.joints[j] - one.joints[j]) for j in one.joints) <= 1e-14
    assert model.configurations(np.zeros((0, model.m)), theta, np.zeros((0, c0.size))) == []
    # the table's stacked fields: the configurations' own rows, read-only
    table, y_all, x_all = model.configuration_table(ys, theta, cs)
    one_by_one = [model.configuration(y, theta, c).y for y, c in zip(ys, cs, strict=True)]
    np.testing.assert_allclose(y_all, np.array(one_by_one), rtol=0, atol=1e-14)
    np.testing.assert_array_equal(x_all, np.array([cfg.x for cfg in many]))
    assert not (y_all.flags.writeable or x_all.flags.writeable)
    assert all(cfg.y.base is y_all and cfg.x.base is x_all for cfg in table)
    # one theta per point
    thetas = theta * (1 + 0.01 * rng.normal(size=(7, model.k)))
    for cfg, y, th, c in zip(model.configurations(ys, thetas, cs), ys, thetas, cs, strict=True):
        one = model.configuration(y, th, c)
        np.testing.assert_array_equal(cfg.theta, th)
        np.testing.assert_array_equal(cfg.x, one.x)
        assert cfg.residual == one.residual


@pytest.mark.parametrize("name", ["planar_hexa", "stewart_gough"])
def test_verify_equals_the_pose_check_and_jacobian_kernels_bit_for_bit(name):
    """The fused verification call (one kernel call) returns the values of the three
    kernels' own calls at seeded points near home."""
    model = shipped(name)
    rng = np.random.default_rng(5)
    calls = model_calls(model)
    y0, c0 = model.chart.to_local(model.home.y)
    for _ in range(5):
        y = y0 + 0.05 * rng.normal(size=model.m)
        theta = model.home.theta + 0.05 * rng.normal(size=model.k)
        T, x, residual, Jp = calls.verify(y, theta, c0)
        T1, x1 = calls.pose(y, theta, c0)
        np.testing.assert_array_equal(T, T1)
        np.testing.assert_array_equal(x, x1.ravel())
        assert residual == float(np.abs(calls.check(y, theta, c0)).max()) > 0
        np.testing.assert_array_equal(Jp, calls.jac(y, theta, c0)[0])
        assert T.flags["C_CONTIGUOUS"] and Jp.flags["C_CONTIGUOUS"]
    nan = np.full(model.m, np.nan)
    assert np.isnan(calls.verify(nan, model.home.theta, c0)[2])  # NaN rows are not hidden
