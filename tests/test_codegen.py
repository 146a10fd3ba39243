"""Generated C (scdk_sym.codegen): self-contained sources, kernels, the C boundary, the example."""

import re
import shutil
import subprocess

import numpy as np
import pytest
from factories import ROOT, needs_compiler, shipped

from scdk_sym.cli import main
from scdk_sym.codegen.generate import generate
from scdk_sym.follower.calls import build_follower_kernels
from scdk_sym.kernels.curve import closure_function
from scdk_sym.kernels.tracker_functions import build_tracker_kernels

EXAMPLE = ROOT / "examples" / "c"
CFLAGS = ["-std=c99", "-O2", "-Wall"]
STANDARD_HEADERS = {"math.h", "stddef.h", "stdlib.h", "string.h", "stdio.h", "time.h"}

pytestmark = [
    needs_compiler(),
    pytest.mark.skipif(shutil.which("make") is None, reason="needs make (the C example)"),
]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """Sources of models/stewart_gough and the example built by its Makefile (once)."""
    out = tmp_path_factory.mktemp("generated")
    src = generate(shipped("stewart_gough"), out)
    proc = subprocess.run(
        ["make", "-C", str(EXAMPLE), f"GENERATED={out}", f"BUILD={out / 'build'}", "all"],
        capture_output=True,
        text=True,
    )
    return src, proc


def test_sources_are_self_contained(built):
    src, _ = built
    generated = {p.name for p in (src.kernels_h, src.tracker_h, src.lu_h)}
    for path in (src.kernels_c, src.kernels_h, src.tracker_c, src.tracker_h, src.lu_h):
        text = path.read_text()
        included = set(re.findall(r'#include [<"]([^>"]+)[>"]', text))
        assert included <= STANDARD_HEADERS | generated, (path.name, included)
        assert "casadi/" not in text
    header = src.kernels_h.read_text()
    for kernel in ("closure", "pose", "tangent", "step", "predict", "newton", "polish",
                   "recentre"):  # fmt: skip
        assert f"int scdk_{kernel}(const casadi_real** arg" in header
    tracker = src.tracker_h.read_text()
    assert "#define SCDK_NY 6" in tracker and "#define SCDK_NTHETA 6" in tracker
    assert "#define SCDK_NC 9" in tracker and "#define SCDK_HAS_IK 1" in tracker


def test_home_constants_are_the_model_home(built):
    src, _ = built
    model = shipped("stewart_gough")
    text = src.tracker_c.read_text()
    for name, values in (("home_theta", model.home.theta), ("home_x", model.home.x)):
        body = re.search(rf"scdk_{name}\[SCDK_N\w+\] = \{{([^}}]*)\}}", text).group(1)
        np.testing.assert_array_equal([float(v) for v in body.split(",")], values)


def test_example_builds_without_warnings_and_tracks(built):
    src, proc = built
    assert proc.returncode == 0, proc.stderr
    assert "warning" not in (proc.stdout + proc.stderr).lower()
    run = subprocess.run(
        [str(src.directory / "build" / "track_poses")], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stdout
    err = float(re.search(r"max \|x - x_pose\| = (\S+)", run.stdout).group(1))
    assert err < 1e-9
    assert re.search(r"steps: 1999 cheap", run.stdout)
    assert "status -3 (an input is NaN or infinite)" in run.stdout


BOUNDARY = r"""
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "scdk_tracker.h"

static void show(const char *what, int code) { printf("%s %d\n", what, code); }

int main(void) {
    scdk_state st, zero, before;
    scdk_options opt;
    double th[SCDK_NTHETA], y[SCDK_NY], ys[2 * SCDK_NY], J[SCDK_NY * SCDK_NY];
    double Js[SCDK_NY * SCDK_NTHETA], g[SCDK_NY], q[SCDK_NY + 1], t[SCDK_NY + 1];
    double p[2 * SCDK_NTHETA], v[SCDK_NY + 1], x[2 * SCDK_NY + 2], xn[2 * SCDK_NY + 2];
    double info[3], h = 0.01, res, corr;
    const double *arg[SCDK_SZ_ARG];
    double *out[SCDK_SZ_RES];
    casadi_int iw[SCDK_SZ_IW];
    double w[SCDK_SZ_W];
    long failed;
    int i;
    memset(&zero, 0, sizeof zero);
    for (i = 0; i < SCDK_NTHETA; ++i) th[i] = scdk_home_theta[i];
    show("init_null_state", scdk_tracker_init(NULL, scdk_home_y, SCDK_NY, scdk_home_c, SCDK_NC,
                                              scdk_home_theta, SCDK_NTHETA, NULL));
    show("init_null_theta", scdk_tracker_init(&st, scdk_home_y, SCDK_NY, scdk_home_c, SCDK_NC,
                                              NULL, SCDK_NTHETA, NULL));
    show("init_wrong_ny", scdk_tracker_init(&st, scdk_home_y, SCDK_NY - 1, scdk_home_c,
                                            SCDK_NC, scdk_home_theta, SCDK_NTHETA, NULL));
    show("step_after_failed_init", scdk_tracker_step(&st, th, SCDK_NTHETA));
    show("step_uninitialised", scdk_tracker_step(&zero, th, SCDK_NTHETA));
    for (i = 0; i < SCDK_NY; ++i) y[i] = scdk_home_y[i];
    y[2] += 0.01;
    show("init_not_assembled", scdk_tracker_init(&st, y, SCDK_NY, scdk_home_c, SCDK_NC,
                                                 scdk_home_theta, SCDK_NTHETA, NULL));
    y[2] = NAN;
    show("init_nan_y", scdk_tracker_init(&st, y, SCDK_NY, scdk_home_c, SCDK_NC,
                                         scdk_home_theta, SCDK_NTHETA, NULL));
    scdk_default_options(&opt);
    opt.max_steps = 0;
    show("init_bad_options", scdk_tracker_init(&st, scdk_home_y, SCDK_NY, scdk_home_c, SCDK_NC,
                                               scdk_home_theta, SCDK_NTHETA, &opt));
    show("init_ok", scdk_tracker_init(&st, scdk_home_y, SCDK_NY, scdk_home_c, SCDK_NC,
                                      scdk_home_theta, SCDK_NTHETA, NULL));
    th[0] += 1e-3;
    show("step_ok", scdk_tracker_step(&st, th, SCDK_NTHETA));
    before = st;
    th[1] = NAN;
    show("step_nan", scdk_tracker_step(&st, th, SCDK_NTHETA));
    show("step_inf", (th[1] = INFINITY, scdk_tracker_step(&st, th, SCDK_NTHETA)));
    th[1] = scdk_home_theta[1];
    show("step_wrong_size", scdk_tracker_step(&st, th, SCDK_NTHETA + 1));
    show("step_null", scdk_tracker_step(&st, NULL, SCDK_NTHETA));
    for (i = 0; i < SCDK_NTHETA; ++i) th[i] = 0.01; /* 1 cm legs: nothing assembles */
    show("step_unreachable", scdk_tracker_step(&st, th, SCDK_NTHETA));
    show("state_unchanged", memcmp(before.y, st.y, sizeof st.y) == 0 &&
                                memcmp(before.theta, st.theta, sizeof st.theta) == 0);
    show("get_wrong_nx", scdk_tracker_get(&st, NULL, 0, NULL, 0, y, SCDK_NX + 2));
    show("track_null_out", scdk_tracker_track(scdk_home_y, SCDK_NY, scdk_home_c, SCDK_NC,
                                              scdk_home_theta, SCDK_NTHETA, NULL, 2,
                                              scdk_home_theta, NULL, NULL, NULL, NULL, NULL,
                                              &failed));
    show("track_negative_n", scdk_tracker_track(scdk_home_y, SCDK_NY, scdk_home_c, SCDK_NC,
                                                scdk_home_theta, SCDK_NTHETA, NULL, -1,
                                                scdk_home_theta, ys, NULL, NULL, NULL, NULL,
                                                &failed));
    show("status_string_known", strcmp(scdk_status_string(SCDK_ERR_NONFINITE),
                                       "an input is NaN or infinite") == 0);
    /* the generated kernels at fixed inputs, printed for comparison with CasADi */
    arg[0] = scdk_home_y; arg[1] = scdk_home_theta; arg[2] = scdk_home_c;
    out[0] = NULL; out[1] = J; out[2] = Js;
    scdk_closure(arg, out, iw, w, 0);
    for (i = 0; i < SCDK_NY * SCDK_NY; ++i) printf("J %.17g\n", J[i]);
    for (i = 0; i < SCDK_NY * SCDK_NTHETA; ++i) printf("Js %.17g\n", Js[i]);
    for (i = 0; i < SCDK_NY; ++i) y[i] = scdk_home_y[i] + 1e-3 * (i + 1);
    arg[0] = y; out[0] = g; out[1] = NULL; out[2] = NULL;
    scdk_closure(arg, out, iw, w, 0);
    for (i = 0; i < SCDK_NY; ++i) printf("g %.17g\n", g[i]);
    out[0] = ys; out[1] = &res; out[2] = &corr;
    scdk_newton(arg, out, iw, w, 0);
    printf("newton_res %.17g\n", res);
    for (i = 0; i < SCDK_NY; ++i) printf("newton_y %.17g\n", ys[i]);
    for (i = 0; i < SCDK_NY; ++i) q[i] = scdk_home_y[i];
    q[SCDK_NY] = 0.0;
    for (i = 0; i < SCDK_NTHETA; ++i) {
        p[i] = scdk_home_theta[i];
        p[SCDK_NTHETA + i] = 1e-2 * (i % 3 - 1);
    }
    for (i = 0; i <= SCDK_NY; ++i) v[i] = i == SCDK_NY;
    arg[0] = q; arg[1] = v; arg[2] = p; arg[3] = scdk_home_c;
    out[0] = t; out[1] = NULL;
    scdk_tangent(arg, out, iw, w, 0);
    for (i = 0; i <= SCDK_NY; ++i) printf("tangent %.17g\n", t[i]);
    for (i = 0; i <= SCDK_NY; ++i) {
        x[i] = q[i];
        x[SCDK_NY + 1 + i] = t[i];
    }
    arg[0] = x; arg[1] = &h; arg[2] = p; arg[3] = scdk_home_c;
    out[0] = xn; out[1] = info; out[2] = NULL;
    scdk_step(arg, out, iw, w, 0);
    for (i = 0; i < 2 * SCDK_NY + 2; ++i) printf("step %.17g\n", xn[i]);
    for (i = 0; i < 3; ++i) printf("info %.17g\n", info[i]);
    return 0;
}
"""


@pytest.fixture(scope="module")
def boundary(built, tmp_path_factory):
    src, proc = built
    assert proc.returncode == 0, proc.stderr
    d = tmp_path_factory.mktemp("boundary")
    (d / "boundary.c").write_text(BOUNDARY)
    objects = [str(src.directory / "build" / f"scdk_{n}.o") for n in ("kernels", "tracker")]
    exe = d / "boundary"
    cc = shutil.which("gcc") or shutil.which("cc")
    cmd = [cc, *CFLAGS, f"-I{src.directory}", str(d / "boundary.c"), *objects, "-o", str(exe)]
    comp = subprocess.run([*cmd, "-lm"], capture_output=True, text=True)
    assert comp.returncode == 0 and "warning" not in comp.stderr, comp.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, check=True)
    lines = [line.split() for line in run.stdout.splitlines()]
    codes = {k: int(v) for k, v in lines if re.fullmatch(r"-?\d+", v)}
    values = {}
    for k, v in lines:
        values.setdefault(k, []).append(float(v))
    return codes, values


@pytest.mark.parametrize(
    ("call", "code"),
    [
        ("init_null_state", -1),
        ("init_null_theta", -1),
        ("init_wrong_ny", -2),
        ("step_after_failed_init", -7),
        ("step_uninitialised", -7),
        ("init_not_assembled", -4),
        ("init_nan_y", -3),
        ("init_bad_options", -8),
        ("init_ok", 0),
        ("step_ok", 0),
        ("step_nan", -3),
        ("step_inf", -3),
        ("step_wrong_size", -2),
        ("step_null", -1),
        ("step_unreachable", -5),
        ("state_unchanged", 1),
        ("get_wrong_nx", -2),
        ("track_null_out", -1),
        ("track_negative_n", -2),
        ("status_string_known", 1),
    ],
)
def test_c_boundary_returns_error_codes(boundary, call, code):
    codes, _ = boundary
    assert codes[call] == code


def test_generated_kernels_equal_the_casadi_functions(boundary):
    _, values = boundary
    model = shipped("stewart_gough")
    kern = build_tracker_kernels(model.symbolic, model.chart.rotations, "ref")
    y, c = model.chart.to_local(model.home.y)
    theta = model.home.theta
    _, J, Js = (np.array(a).ravel(order="F") for a in kern.closure(y, theta, c))
    np.testing.assert_allclose(values["J"], J, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(values["Js"], Js, rtol=1e-13, atol=1e-15)
    yp = y + 1e-3 * np.arange(1, 7)
    g = np.array(kern.closure(yp, theta, c)[0]).ravel()
    np.testing.assert_allclose(values["g"], g, rtol=1e-12, atol=1e-16)
    y_new, res, _ = (np.array(v).ravel() for v in kern.newton(yp, theta, c))
    np.testing.assert_allclose(values["newton_y"], y_new, rtol=1e-12, atol=1e-15)
    # two Newton iterations: quadratic convergence from a 6 mm residual
    assert np.max(np.abs(g)) > 1e-3 and values["newton_res"][0] < 1e-7
    assert values["newton_res"][0] == pytest.approx(float(res[0]), rel=1e-6)
    p = np.concatenate([theta, 1e-2 * (np.arange(6) % 3 - 1)])
    q = np.append(y, 0.0)
    t = np.array(kern.tangent(q, np.eye(7)[6], p, c)[0]).ravel()
    np.testing.assert_allclose(values["tangent"], t, rtol=1e-12, atol=1e-15)
    assert t[-1] > 0  # oriented by v = e_s: s increases
    xn, info, _ = (np.array(a).ravel() for a in kern.step(np.append(q, t), 0.01, p, c))
    np.testing.assert_allclose(values["step"], xn, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(values["info"], info, rtol=1e-9, atol=1e-15)
    # one step of arc length 0.01 along the curve: the tracker's kernel is the follower's
    follower = build_follower_kernels(model.symbolic)
    ref = np.array(follower.step(np.append(q, t), 0.01, p, c)[0]).ravel()
    np.testing.assert_allclose(xn, ref, rtol=1e-13, atol=1e-15)
    assert xn[6] > 0 and info[2] > 0.99
    # against the model's own kernels: t spans the null space of H = [J_p, -J_s dtheta] with
    # unit length in the arc-length metric, and the step lands on the curve 0.01 along it
    dtheta = p[6:]
    Jp, Js = (np.array(a) for a in model.kernels.jac(y, theta, c))
    np.testing.assert_allclose(Jp @ t[:6] - (Js @ dtheta) * t[6], 0.0, atol=1e-12)
    assert t[:6] @ t[:6] + (dtheta @ dtheta) * t[6] ** 2 == pytest.approx(1.0, rel=1e-12)
    g_new = np.array(model.kernels.g(xn[:6], theta + xn[6] * dtheta, c)).ravel()
    assert np.max(np.abs(g_new)) < 1e-12
    d = xn[:7] - q
    assert d[:6] @ d[:6] + (dtheta @ dtheta) * d[6] ** 2 == pytest.approx(1e-4, rel=1e-3)


@pytest.mark.parametrize("name", ["planar_hexa", "planar_3rpr"])
def test_tracker_kernels_are_dense_at_the_c_boundary(name):
    """CasADi's C reads and writes nonzeros only; the tracker indexes dense column-major arrays.

    These models' J_p has structural zeros (a closure involves some of the joints only).
    """
    model = shipped(name)
    assert not model.kernels.jac.sparsity_out(0).is_dense()
    kern = build_tracker_kernels(model.symbolic, model.chart.rotations, "ref")
    for f in kern.all():
        assert all(f.sparsity_in(i).is_dense() for i in range(f.n_in())), f.name()
        assert all(f.sparsity_out(i).is_dense() for i in range(f.n_out())), f.name()
    y, c = model.chart.to_local(model.home.y)
    theta = model.home.theta
    ref = (model.kernels.g(y, theta, c), *model.kernels.jac(y, theta, c))
    for ours, want in zip(kern.closure(y, theta, c), ref, strict=True):
        np.testing.assert_array_equal(np.array(ours), np.array(want))


@pytest.mark.parametrize("name", ["planar_hexa", "stewart_gough"])
def test_curve_kernels_calling_the_dense_closure_compute_what_the_sparse_one_gives(name):
    """The tracker's closure kernel has dense outputs; its other kernels call it through a view
    in the model's sparsity: bit for bit what they compute calling the sparse closure."""
    model = shipped(name)
    sym = model.symbolic
    kern = build_tracker_kernels(sym, model.chart.rotations, "ref")
    ref = build_follower_kernels(sym, inline=False, closure=closure_function(sym))
    rng = np.random.default_rng(3)
    y, c = model.chart.to_local(model.home.y)
    m, k = model.m, model.k
    for _ in range(3):
        yp = y + 1e-2 * rng.normal(size=m)
        theta = model.home.theta + 1e-2 * rng.normal(size=k)
        dtheta = 1e-2 * rng.normal(size=k)
        p = np.concatenate([theta, dtheta])
        q = np.append(yp, 0.1)
        v = np.append(rng.normal(size=m), 1.0)
        calls = [
            ("newton", (yp, theta, c)),
            ("polish", (yp, theta, c)),
            ("predict", (yp, theta, dtheta, c)),
            ("tangent", (q, v, p, c)),
        ]
        t = np.array(ref.tangent(q, v, p, c)[0]).ravel()
        calls.append(("step", (np.append(q, t), 1e-3, p, c)))
        for kernel, args in calls:
            ours = getattr(kern, kernel).call(list(args))
            want = getattr(ref, kernel).call(list(args))
            for a, b in zip(ours, want, strict=True):
                np.testing.assert_array_equal(np.array(a).ravel(), np.array(b).ravel(), kernel)


def test_cli_writes_sources_with_a_prefix(tmp_path, capsys):
    assert main(["codegen", str(ROOT / "models" / "planar_3rpr"), "--out", str(tmp_path),
                 "--prefix", "rpr", "--no-shared", "--json"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    names = sorted(p.name for p in tmp_path.iterdir())
    generated = ["rpr_kernels.c", "rpr_kernels.h", "rpr_tracker.c", "rpr_tracker.h"]
    assert names == [*generated, "scdk_lu.h"]
    assert '"library": null' in out
    header = (tmp_path / "rpr_tracker.h").read_text()
    assert "#define RPR_NC 0" in header and "int rpr_tracker_step(rpr_state *st" in header


def test_cli_refuses_a_bad_prefix(tmp_path, capsys):
    rc = main(["codegen", str(ROOT / "models" / "planar_3rpr"), "--out", str(tmp_path),
               "--prefix", "9bad", "--no-shared"])  # fmt: skip
    assert rc == 1 and "C prefix" in capsys.readouterr().err


def test_split_sources_hold_one_copy_of_the_closures_and_of_each_solve(tmp_path):
    """Kernels call the closure Function and the linear solves: one definition per source."""
    model = shipped("stewart_gough")
    src = generate(model, tmp_path / "split", split=True)
    one = generate(model, tmp_path / "one")
    assert len(src.parts) == 3 and src.unoptimised == (src.parts[2],)
    defined = re.compile(r"^/\* (scdk_closure|scdk_solve\d+_[0-9a-f]+):\(", re.M)
    for path in (*src.parts, one.kernels_c):
        names = defined.findall(path.read_text())
        assert len(names) == len(set(names)), (path.name, names)
    assert defined.findall(one.kernels_c.read_text()).count("scdk_closure") == 1
    # the kernels that evaluate the closures share one source: one copy of them in all
    split = [name for part in src.parts for name in defined.findall(part.read_text())]
    assert split.count("scdk_closure") == 1


def test_sources_without_the_inverse_kinematics(tmp_path):
    """The library Python loads leaves the inverse kinematics out (its ik_solve refuses)."""
    src = generate(shipped("stewart_gough"), tmp_path, split=True, inverse_kinematics=False)
    assert len(src.parts) == 2 and src.unoptimised == ()
    assert "#define SCDK_HAS_IK 0" in src.tracker_h.read_text()
    for path in (*src.parts, src.kernels_h):
        assert "scdk_ik_step" not in path.read_text(), path.name


def test_cli_writes_a_tracker_per_stage_that_chained_track_as_the_model(tmp_path, capsys):
    """digit_like's knee, then its ankle: each stage's library tracks its part of a motion,
    the ankle reading the knee's samples, and the two equal the model's own track (the
    Python tracker on CasADi SX kernels, not the C tracker) to 1e-8."""
    import json
    import warnings

    import scdk_sym as sc
    from scdk_sym.codegen.library import CTracker

    directory = ROOT / "tests" / "fixtures" / "gepetto" / "digit_like"
    assert main(["codegen", str(directory), "--out", str(tmp_path), "--prefix", "dg",
                 "--stages", "--json"]) == 0  # fmt: skip
    import jsonschema

    from scdk_sym.schema import command_schema

    out = json.loads(capsys.readouterr().out)
    jsonschema.Draft202012Validator(command_schema("codegen")).validate(out)
    stages = out["stages"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = sc.load_model(directory)
    assert [s["unknowns"] for s in stages] == [list(p.unknowns) for p in m.stages]
    rng = np.random.default_rng(3)
    thetas = m.home.theta + np.linspace(0, 1, 25)[:, None] * rng.uniform(-0.1, 0.1, m.k)
    ys = np.tile(m.home.y, (len(thetas), 1))
    for i, (part, entry) in enumerate(zip(m.stages, stages, strict=True)):
        lib = CTracker(entry["library"], part.m, part.k, part.chart.size, len(part.workspace),
                       prefix=f"dg_s{i}")  # fmt: skip
        readings = np.array([[th[m.actuated.index(a)] if a in m.actuated
                              else y[m.unknowns.index(a)] for a in part.actuated]
                             for th, y in zip(thetas, ys, strict=True)])  # fmt: skip
        y0, c0 = part.chart.to_local(part.home.y)
        out = lib.track(y0, c0, part.home.theta, readings)
        ys[:, [m.unknowns.index(u) for u in part.unknowns]] = out.y
    ref = sc.track(m, thetas, backend="cvodes")
    assert np.abs(ys - ref.y).max() < 1e-8
