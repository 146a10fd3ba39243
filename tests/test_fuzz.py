"""Seeded fuzz of ``solve`` and ``track`` on every model, checked by independent references.

Every target ``theta0`` is the closed-form inverse kinematics of a drawn pose (Gepetto
fixtures: a configuration walked on the closure manifold with Pinocchio), so a solution is
known to exist. Each answer is checked by tests/references.py, never by the package's own
residual: the closure computed from the geometry (<= 1e-7), the agreement of x, the placement
and the joints, and the parity of the reported singular crossings against the signs of
``det d(closure)/dx`` (finite differences) at the start and at the answer. Asserted: no
silently wrong answer, no crash, and no refusal of a small convergent step in the start's
assembly mode; the other refusals are printed (``pytest -s``), they are figures, not failures.
The MJCF fixtures (``MJCF_NAMES``) are checked against MuJoCo itself (``MjcfReference``); the
four-bars among them have no singular surface, so they get no scenario or track across one.
The full-size run is ``python benchmarks/fuzz.py``.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from references import (
    BOX,
    GEPETTO_LEGGED,
    GEPETTO_NAMES,
    KINDS,
    MJCF_NAMES,
    NAMES,
    NO_SINGULAR,
    SHIPPED,
    SINGULAR_KINDS,
    Report,
    Scenario,
    classify,
    draw_scenarios,
    draw_tracks,
    line_curve_reaches,
    load,
    reference,
    run_solves,
    run_tracks,
    singular_point,
    wrap,
)

SEED = 20240601
#: Scenarios per kind solved on both branches.
PER_KIND = 1
#: Extra small steps in the start's assembly mode and targets just before a singular surface,
#: convergent branch only (cheap).
SMALL, NEAR = 10, 5
#: Commanded motions per model (one smooth, one through a singular surface) and samples.
TRACKS, SAMPLES = 2, 60
#: Wall-time limits per solve and per track [s] (outcome "timeout", printed).
LIMIT, TRACK_LIMIT = 5.0, 10.0


#: Models fuzzed here: the default ones and the MJCF fixtures.
FUZZED = NAMES + MJCF_NAMES


def drawable(name: str) -> tuple[str, ...]:
    """The scenario kinds that can be drawn for a model (none across a singular surface for a
    model without one)."""
    return tuple(k for k in KINDS if name not in NO_SINGULAR or k not in SINGULAR_KINDS)


@cache
def solves(name: str) -> Report:
    rep = Report()
    for i, kind in enumerate(KINDS):
        scen = draw_scenarios(name, PER_KIND, SEED + i, kinds={kind: 1.0})
        rep.solves += run_solves(scen, limit=LIMIT)
    small = draw_scenarios(name, SMALL, SEED + 10, kinds={"small": 1.0})
    near = draw_scenarios(name, NEAR, SEED + 11, kinds={"near_singular": 1.0})
    rep.solves += run_solves(small + near, branches=("convergent",), limit=LIMIT)
    return rep


def _lines(outcomes) -> str:
    return "\n".join(
        f"{o.status} ({o.scenario.kind}, {o.branch}): {o.detail[:160]}\n    "
        + o.scenario.reproducer(o.branch)
        + f"\n    ({o.scenario.known()})"
        for o in outcomes
    )


# ---------------------------------------------------------------------------- references


@pytest.mark.parametrize("name", SHIPPED)
def test_reference_agrees_with_the_package_inverse_kinematics(name: str) -> None:
    ref, model = reference(name), load(name)
    np.testing.assert_allclose(ref.home_x, model.home.x, rtol=0, atol=1e-12)
    assert np.abs(ref.closure(ref.home_x, model.home.theta)).max() <= 1e-12
    rng = np.random.default_rng(SEED)
    box = np.asarray(BOX[name])
    for _ in range(5):
        x = ref.home_x + rng.uniform(-0.5, 0.5, len(box)) * box
        cfg = model.inverse_kinematics(x)
        theta = ref.ik(x)
        assert theta is not None
        assert np.abs(ref.closure(x, theta)).max() <= 1e-12
        assert np.abs(wrap(theta - cfg.theta)).max() <= 1e-9
        assert ref.distance(cfg.x, x) <= 1e-9
        assert np.abs(ref.closure(cfg.x, cfg.theta)).max() <= 1e-12
        assert ref.consistency(cfg) <= 1e-12


@pytest.mark.parametrize(
    ("name", "xa", "xb", "where", "value"),
    [
        # the paper's singular configuration of the seed robot: x = y = 0, phi = 0.5754
        ("planar_hexa", [0, 0, 0.4], [0, 0, 0.9], 2, 0.5754),
        ("planar_hexa_reduced", [0, 0, 0.4], [0, 0, 0.9], 2, 0.5754),
        # the hexapod's singular orientation (README): yaw = pi / 2
        ("stewart_gough", [0, 0, 0.55, 0, 0, 1.4], [0, 0, 0.55, 0, 0, 1.75], 5, np.pi / 2),
    ],
)
def test_det_sign_changes_at_the_published_singular_configurations(
    name: str, xa, xb, where: int, value: float
) -> None:
    ref = reference(name)
    xa, xb = np.array(xa, dtype=float), np.array(xb, dtype=float)
    lam = singular_point(ref, xa, xb)
    assert lam is not None
    tol = 1e-4 if name.startswith("planar_hexa") else 1e-6  # the paper prints 4 decimals
    assert abs(xa[where] + lam * (xb[where] - xa[where]) - value) <= tol
    assert ref.det_sign(xa, ref.ik(xa)) == -ref.det_sign(xb, ref.ik(xb)) != 0


@pytest.mark.parametrize("name", GEPETTO_NAMES + GEPETTO_LEGGED + MJCF_NAMES)
def test_gepetto_reference_walks_on_the_closure_manifold(name: str) -> None:
    ref, model = reference(name), load(name)
    assert ref.actuated == tuple(model.actuated)
    assert np.abs(ref.closure(ref.home_q, ref.home_theta)).max() <= 1e-12
    assert ref.consistency(model.home) <= 1e-12
    rng = np.random.default_rng(SEED)
    path = ref.walk(ref.home_q, ref.tangent(ref.home_q).T @ rng.normal(size=ref.k), 10, 0.02)
    assert path is not None
    steps = np.linalg.norm(np.diff(np.array(path)[:, ref.free + ref.motors], axis=0), axis=1)
    np.testing.assert_allclose(steps, 0.02, rtol=1e-2)
    for q in path:
        assert np.abs(ref.residual_q(q)).max() <= 1e-12
    # the package solves the walked configuration's motors to the walked configuration
    import scdk_sym as sc

    res = sc.solve(model, path[-1][ref.motors], record_path=False)
    assert ref.distance(ref.coords(res), path[-1]) <= 1e-9


# ---------------------------------------------------------------------------- fuzz


@pytest.mark.parametrize("name", MJCF_NAMES)
def test_mjcf_reference_jacobian_is_the_derivative_of_its_closure(name: str) -> None:
    """MuJoCo's efc_J equality rows (the MJCF reference's Jacobian) equal the central
    differences of its efc_pos equality rows, on the closure manifold and off it."""
    ref = reference(name)
    cols = list(range(len(ref.home_q)))
    rng = np.random.default_rng(SEED)
    for q in (ref.home_q, ref.home_q + 0.5 * rng.normal(size=ref.home_q.shape)):
        h, diffs = 1e-7, []
        for i in cols:
            dq = np.zeros_like(q)
            dq[i] = h
            diffs.append((ref.residual_q(q + dq) - ref.residual_q(q - dq)) / (2 * h))
        assert np.abs(ref._jac(q, cols) - np.array(diffs).T).max() <= 1e-7


@pytest.mark.parametrize("name", MJCF_NAMES)
def test_mjcf_reference_det_sign_is_the_same_a_hinge_turn_away(name: str) -> None:
    """A whole turn of any hinge is the same configuration: the MJCF reference's closure still
    vanishes and its det keeps its sign (weld_loop: a turn of a hinge in the loop flips the
    sign of the weld's error quaternion, so of MuJoCo's rotation rows and their Jacobian;
    the reference signs those rows by it)."""
    ref = reference(name)
    q0 = ref.home_q
    ratio = ref.det_ratio(q0, ref.home_theta)
    assert abs(ratio) > 0.1
    for j in ref.free + ref.motors:
        q = q0.copy()
        q[j] += 2 * np.pi
        assert np.abs(ref.residual_q(q)).max() <= 1e-12
        assert ref.det_ratio(q, q[ref.motors]) == pytest.approx(ratio, abs=1e-9)


@pytest.mark.parametrize("name", sorted(NO_SINGULAR))
def test_a_model_without_singular_surface_keeps_its_det_sign_over_a_crank_turn(name) -> None:
    """The MJCF crank-rocker four-bars (no scenario across a singular surface is drawn for
    them): walked on MuJoCo's closures over more than a whole turn of the crank, in both
    assembly modes, the det sign never changes and |det| stays far from 0."""
    ref = reference(name)
    home_sign = ref.det_sign(ref.home_q, ref.home_theta)
    # the other assembly mode at the home crank angle: Gauss-Newton on the passive joints
    # from seeded guesses until one converges with the other det sign
    rng = np.random.default_rng(SEED)
    other = None
    for _ in range(50):
        q = ref.home_q.copy()
        q[ref.free] = rng.uniform(-np.pi, np.pi, len(ref.free))
        for _it in range(50):
            r = ref.residual_q(q)
            if np.abs(r).max() < 1e-13:
                break
            J = ref._jac(q, ref.free)[ref.rows]
            q[ref.free] -= np.linalg.lstsq(J, r[ref.rows], rcond=None)[0]
        if np.abs(ref.residual_q(q)).max() < 1e-12 and ref.det_sign(q, q[ref.motors]) == -home_sign:
            other = q
            break
    assert other is not None
    for start, sign in ((ref.home_q, home_sign), (other, -home_sign)):
        path = ref.walk(start, ref.tangent(start)[0], 250, 0.05)
        assert path is not None
        assert np.ptp(np.array(path)[:, ref.motors]) > 2 * np.pi  # more than a crank turn
        ratios = np.array([ref.det_ratio(q, q[ref.motors]) for q in path])
        assert np.all(sign * ratios > 0.5)


@pytest.mark.parametrize("name", FUZZED)
def test_fuzz_solves(name: str) -> None:
    rep = solves(name)
    print(f"\n{rep.table()}\n{rep.kind_table()}")
    refused = [o for o in rep.solves if o.status in ("refused", "timeout")]
    if refused:
        print("refusals:\n" + _lines(refused))
    near = 0 if name in NO_SINGULAR else NEAR
    assert len(rep.solves) == 2 * PER_KIND * len(drawable(name)) + SMALL + near
    wrong = rep.failures()
    assert not wrong, "silently wrong or crashed:\n" + _lines(wrong)
    must = [
        o
        for o in rep.solves
        if o.scenario.kind == "small"
        and o.branch == "convergent"
        and o.status in ("refused", "timeout")
    ]
    assert not must, "refused a small convergent step:\n" + _lines(must)


@cache
def tracks(name: str):
    return run_tracks(draw_tracks(name, TRACKS, SEED, SAMPLES), limit=TRACK_LIMIT)


@pytest.mark.parametrize("name", FUZZED)
def test_fuzz_tracks(name: str) -> None:
    outs = tracks(name)
    rep = Report(tracks=outs)
    print(f"\n{rep.track_table()}")
    kinds = {"smooth"} if name in NO_SINGULAR else {"smooth", "singular"}
    assert {o.track.kind for o in outs} == kinds
    assert len(outs) == 2 * TRACKS  # each track on both backends
    bad = [o for o in outs if o.status in ("deviation", "crash")]
    lines = "\n".join(
        f"{o.status} ({o.track.kind}, {o.backend}): {o.detail[:160]}\n    "
        + o.track.reproducer(o.backend)
        for o in bad
    )
    assert not bad, "tracks off the commanded motion or crashed:\n" + lines
    for o in outs:
        if o.status == "ok":
            assert o.error <= 1e-6


#: Divergent solves the fuzz found refused (or answered with a crossing list that does not
#: account for the answer's side) although another solution exists (seed 0 of
#: ``benchmarks/fuzz.py``): every real solution at theta0 is the last resort across the
#: nearest singular configuration. (model, kind, theta0, start (y, theta) or None for home)
DIVERGENT_CASES = [
    (
        "delta",
        "small",
        [-2.632679869281611, 0.8275108415395422, -2.6338651925552514],
        (
            [-0.0238068624828572, -0.030714384383159727, -0.1721685468766239],
            [-2.6091793552119493, 0.8023856054325447, -2.6118671371494524],
        ),
    ),
    (
        "delta",
        "near_singular",
        [0.45782286591233934, -2.6454653553058924, -2.646595330260529],
        (
            [0.03524635754189256, -0.035025176540101566, -0.15222094091098515],
            [0.04334907189640669, -2.4107961124369317, -2.4505840264832925],
        ),
    ),
    (
        "five_bar",
        "small",
        [2.288573879981142, 2.9246592203239525],
        (
            [-0.015190455969631594, 0.28425440946743724],
            [2.266923806743033, 2.9037353575881824],
        ),
    ),
    ("5bar_linkage_iso3d", "near_singular", [2.352439619767056, 0.6010503765557498], None),
    # no singular point found by descent from the start: located between the two answers
    (
        "delta",
        "large",
        [0.7495199989419495, 1.2204410238051715, -0.6046490816562436],
        [0.022852615620816856, -0.023782880885495076, -0.15947167968993983],
    ),
    # robot_delta: answered only among every real solution, once its set is certified
    (
        "robot_delta",
        "near_singular",
        [-0.2712319004065245, 0.24073596300123942],
        (
            [
                -0.05947128883342375,
                -0.03626225400395224,
                0.2196911379495835,
                -1.2495256501621876,
                0.11392177577714145,
                0.2537060306295582,
                -0.7021124682926413,
                1.4692167881118579,
                1.4875106316901017,
            ],
            [-0.17135461400634186, -0.05947128883339328],
        ),
    ),
    # Newton from the reflected guesses had not reached the tolerance within one polish
    (
        "5bar_linkage_iso6d",
        "near_singular",
        [1.161704730072306, -2.0004974584994843],
        (
            [
                0.14511505954882056,
                0.04147497254450954,
                1.4319689795921298e-15,
                0.9797009874363489,
                -3.352579210973638e-16,
                1.5707963267948948,
            ],
            [-0.19712648208212719, 0.0011889149377191353],
        ),
    ),
    (
        "stewart_gough",
        "across",
        [
            0.9775064027791656,
            0.756713735175555,
            0.9911894366128398,
            0.6836329235094618,
            0.8707071358597281,
            0.7135890845020041,
        ],
        [
            -0.03728108939218255,
            -0.034367448346293586,
            0.5834442141275744,
            -0.1626609008393647,
            0.11853128562439826,
            -0.27005882035034195,
        ],
    ),
    # targets just before a singular surface, far in theta from the singular configuration
    # nearest to the start (its mirror guesses come back to the start's sheet) and a set of
    # every real solution that is not certified: across the one nearest to the convergent answer
    (
        "5bar_linkage_iso6d",
        "near_singular",
        [1.1643702273594059, -2.007218389795203],
        (
            [
                -0.08723027297425245,
                0.1857222266061794,
                1.4380286487041442e-15,
                0.9584235565468726,
                -3.4908855418011974e-16,
                1.5707963267948948,
            ],
            [-0.009889406668901592, -0.2094440271232746],
        ),
    ),
    (
        "5bar_linkage_iso6d",
        "near_singular",
        [1.1601963223895881, -1.9986472878785426],
        (
            [
                0.09559173641006768,
                -0.06206468093224791,
                1.351293184679624e-15,
                0.8793791046137618,
                -1.217202701759338e-16,
                1.5707963267948948,
            ],
            [-0.048826693404285616, 0.10318315113097823],
        ),
    ),
    # answered with two crossings but det J_p of the other sign (the leg from the fold
    # reported one fold too many): every way's answer is parity-checked now
    (
        "planar_hexa",
        "across",
        [1.4549049042459972, -0.9839399799128237, -3.1973356870642693],
        [-1.178220357867365, 1.4130467792362997, 0.2923803190134214],
    ),
    # nor from the midpoint of the two answers (sigma_min is locally least at home): the
    # singular configuration by Gauss-Newton onto the singular manifold; answer above the base
    (
        "delta",
        "small",
        [0.0046977284362291274, 0.34331120507523755, 0.8022216960093237],
        [0.028118494040272887, -0.03505301612190848, -0.15254048785318083],
    ),
    # from the nearest singular configuration the line to theta0 leaves the other sheet at
    # once, and every solution at theta0 lies on a curve of the start's line that never
    # reaches s = 0; the path that goes round the other way (theta0 + (0, 2 pi)) reaches the
    # mirror assembly with no other guess
    (
        "5bar_linkage_iso6d",
        "near_singular",
        [-2.028240476667613, -2.0467902994465867],
        (
            [
                0.14767260870414553,
                0.08820915076331315,
                1.6274534020465172e-15,
                1.0147646969131547,
                -5.564856194929396e-16,
                1.5707963267948948,
            ],
            [-0.2393136935975033, -0.050111216164329675],
        ),
    ),
    # answered by a line aimed at the singular surface (the fuzz at seed 3): the ways before
    # it find no solution across the nearest singular configuration
    (
        "planar_hexa_reduced",
        "small",
        [1.4789816271702279, -0.6047260355536176, -2.702461848063656],
        None,
    ),
    # answered along the paper's literal straight path in the divergent direction (seed 3)
    (
        "five_bar",
        "large",
        [1.024367192600534, 2.1184175270736585],
        ([0.05072366578383509, 0.3556696827550164], [0.560760281146123, 2.444686224358607]),
    ),
    # answered along an actuator's axis (seed 5): once answered by the removed way across the
    # singular configuration nearest to the convergent answer, the same solution
    (
        "5bar_linkage_iso6d",
        "across",
        [-3.8134104470019614, -0.716828101432123],
        (
            [
                0.1944289990237489,
                0.07008026821631497,
                1.438242346555363e-15,
                1.029103469675034,
                -4.160150989224811e-16,
                1.5707963267948948,
            ],
            [-0.29092315444207695, -0.0224966313804224],
        ),
    ),
]


#: The way of the divergent branch that answers each of DIVERGENT_CASES (in order): every
#: way before it fails there (``SolveResult.strategy``). Cases once answered by ways since
#: removed (across the singular configuration nearest to the convergent answer; theta0 the
#: other way round on revolute actuators) are answered by "modes" since their sets are
#: certified.
DIVERGENT_WAYS = [
    "modes", "modes", "modes", "modes", "modes", "modes", "nearest", "paper", "modes",
    "modes", "nearest", "modes", "modes", "aimed", "straight", "along-axes",
]  # fmt: skip


@pytest.mark.parametrize(
    ("name", "kind", "theta0", "start", "way"),
    [(*case, way) for case, way in zip(DIVERGENT_CASES, DIVERGENT_WAYS, strict=True)],
)
def test_divergent_cases_found_refused_by_the_fuzz(
    name: str, kind: str, theta0, start, way: str
) -> None:
    import scdk_sym as sc
    from scdk_sym.errors import PathError

    ref, model = reference(name), load(name)
    x0 = yt = None
    if start is not None and isinstance(start, tuple):
        yt = (np.array(start[0]), np.array(start[1]))
    elif start is not None:
        x0 = np.array(start)
    cfg = (
        model.home
        if start is None
        else model.configuration(*yt)
        if yt is not None
        else model.inverse_kinematics(x0)
    )
    # target: only compared to tell the generating solution; the start's coordinates here
    scen = Scenario(name, kind, np.array(theta0), ref.coords(cfg), start_x=x0, start_yt=yt)
    res = sc.solve(model, scen.theta0, start=None if start is None else cfg, branch="divergent")
    out = classify(ref, scen, cfg, res)
    assert out.status == "ok", out.detail
    assert res.strategy == way
    assert out.residual <= 1e-7
    assert len(res.crossings) >= 1
    try:
        conv = sc.solve(model, scen.theta0, start=None if start is None else cfg)
    except PathError:  # the straight path from the start closes on itself (iso3d)
        return
    assert ref.distance(ref.coords(res), ref.coords(conv)) > 1e-6


#: Convergent refusals of the fuzz whose curve through the start closes before s = 1, and
#: solvable controls: (model, theta0, start (y, theta) or None for home, reaches s = 1).
LINE_CURVES = [
    ("5bar_linkage_iso3d", [2.352439619767056, 0.6010503765557498], None, False),
    ("5bar_linkage_iso3d", [0.3, -0.2], None, True),
    ("delta", [0.1, 0.2, 0.3], None, True),
    # the curve crosses s = 1 and folds 2e-5 past it: the step-over that left the crawl there
    # jumped past s = 1 without finishing it (refused; the package now answers)
    (
        "five_bar",
        [3.0573219379949226, 1.2086758736660448],
        ([0.0074078958402395865, 0.24494312497329934], [2.252226232473761, 0.8168306051035246]),
        True,
    ),
    # two sheets close together at s = 0.951 (the elbow sweeps at nearly constant theta):
    # CVODES crossed to the other sheet between samples and the parity check refused its
    # answer; the explicit steps stay on the curve
    (
        "five_bar",
        [1.088374930506832, 2.166819612302567],
        ([0.072275587361314, 0.29882767058670895], [0.25138209463192007, 0.6903384627108523]),
        True,
    ),
    # a Delta curve that winds round the actuators' circles down to s = -206.9 before it
    # closes (arc about 400), turning back at s = 0.697: no answer on that branch
    (
        "delta",
        [-2.7693281279737803, -2.743093234257246, 1.5139464092852974],
        (
            [0.039522467118796915, -0.010837816995548559, -0.15302956351398184],
            [-2.4016129716332872, -2.3854425495710205, 0.7661102061370832],
        ),
        False,
    ),
]


@pytest.mark.parametrize(("name", "theta0", "start", "reaches"), LINE_CURVES)
def test_the_reference_continuation_tells_a_closed_curve(name, theta0, start, reaches) -> None:
    import scdk_sym as sc
    from scdk_sym.errors import PathError

    ref, model = reference(name), load(name)
    cfg = model.home if start is None else model.configuration(*start)
    assert line_curve_reaches(ref, ref.coords(cfg), cfg.theta, theta0) is reaches
    if reaches:  # the package agrees: the convergent branch answers where the curve reaches
        res = sc.solve(model, theta0, start=cfg)
        scen = Scenario(name, "small", np.array(theta0), ref.coords(cfg))
        out = classify(ref, scen, cfg, res)
        assert out.status == "ok", out.detail
        assert out.residual <= 1e-9
    else:
        with pytest.raises(PathError, match="did not reach s = 1"):
            sc.solve(model, theta0, start=cfg)


@pytest.mark.parametrize("branch", ["convergent", "divergent"])
def test_a_refusal_is_confirmed_only_where_the_curve_closes(branch: str) -> None:
    """Both branches' "no answer" refusals on the closed curve of LINE_CURVES[0] are
    confirmed; the same refusal on a curve that reaches s = 1 (LINE_CURVES[1]), or another
    refusal, is not."""
    from references import Outcome, confirm_off_curve

    text = {
        "convergent": "PathError: convergent branch: the solution curve from the start did not "
        "reach s = 1 (theta0=[...]): the curve closed on itself",
        "divergent": "PathError: divergent branch at theta0=[...]: no solution across a "
        "singular surface was reached (...)",
    }[branch]
    for (name, theta0, _start, reaches), expected in zip(
        LINE_CURVES[:2], (True, False), strict=True
    ):
        assert reaches is not expected
        ref = reference(name)
        scen = Scenario(name, "near_singular", np.array(theta0), ref.coords(load(name).home))
        assert confirm_off_curve(Outcome(scen, branch, "refused", text)) is expected
        assert not confirm_off_curve(Outcome(scen, branch, "refused", "SolveError: other"))
        assert not confirm_off_curve(Outcome(scen, branch, "timeout", text))


def test_a_fold_sharper_than_the_reference_step_is_seen_by_its_second_look() -> None:
    """A Delta refusal of the 10^5 fuzz (seed 3): the curve through the start folds at
    s = 0.99923 and closes (s in [-16.9, 0.9992]); the reference's usual steps jump that fold
    and land on a sheet that reaches s = 1, its steps of at most LINE_H_FINE follow it. The
    refusal is confirmed (the second look), and the package refuses."""
    from references import LINE_H_FINE, Outcome, confirm_off_curve

    import scdk_sym as sc
    from scdk_sym.errors import PathError

    ref, model = reference("delta"), load("delta")
    theta0 = np.array([1.6495675767066378, -2.6519500933557576, -2.6520067145936106])
    start = model.configuration(
        [-0.008718969312934312, 0.03327347758847072, -0.1229865579168588],
        [0.6059022128981693, -1.9893231852588076, -1.9271281829695304],
    )
    u0 = ref.coords(start)
    assert line_curve_reaches(ref, u0, start.theta, theta0) is True  # the jump
    turns: list[float] = []
    assert line_curve_reaches(ref, u0, start.theta, theta0, LINE_H_FINE, turns=turns) is False
    assert 0.999 < max(turns) < 1.0
    with pytest.raises(PathError, match="did not reach s = 1") as info:
        sc.solve(model, theta0, start=start)
    scen = Scenario("delta", "across", theta0, u0, start_yt=(start.y, start.theta))
    assert confirm_off_curve(Outcome(scen, "convergent", "refused", f"PathError: {info.value}"))


def test_a_divergent_refusal_on_a_curve_without_a_fold_is_confirmed() -> None:
    """A Delta divergent refusal of the 10^5 fuzz (seed 3): the line's curve through the
    start reaches s = 1 (the convergent answer) and, followed the other way, runs the whole
    arc budget with s falling and never turning: the paper's divergent path meets no singular
    point. The package refuses, and the reference confirms the refusal (it can only by
    :func:`references.line_curve_monotone`: the curve is not closed)."""
    from references import Outcome, confirm_off_curve

    import scdk_sym as sc
    from scdk_sym.errors import PathError

    ref, model = reference("delta"), load("delta")
    theta0 = np.array([0.4214350964495318, -0.025371517831316474, 0.11867667002075927])
    x0 = np.array([0.004500597966257116, 0.01761183758453398, -0.12011669822080709])
    start = model.inverse_kinematics(x0)
    u0 = ref.coords(start)
    assert line_curve_reaches(ref, u0, start.theta, theta0) is True  # not a closed curve
    with pytest.raises(PathError, match="no solution across a singular surface") as info:
        sc.solve(model, theta0, start=start, branch="divergent")
    scen = Scenario("delta", "small", theta0, u0, start_x=x0)
    text = f"PathError: {info.value}"
    assert confirm_off_curve(Outcome(scen, "divergent", "refused", text))
    # a convergent refusal there is not confirmed: that curve reaches s = 1
    conv = "PathError: convergent branch: the solution curve from the start did not reach s = 1"
    assert not confirm_off_curve(Outcome(scen, "convergent", "refused", conv))


def test_convergent_next_to_a_fold_at_s_1_keeps_the_incoming_sheet() -> None:
    """The seed robot from home to a theta0 2e-5 rad from the singular surface (a case the
    fuzz found answered with the mirror solution and no crossing): the curve folds at
    s = 1 - 1e-8, the two solutions at theta0 are 7e-5 apart; the answer must be the one with
    the start's det sign (reference: finite-difference det of the closed-form closure)."""
    import scdk_sym as sc

    ref, model = reference("planar_hexa"), load("planar_hexa")
    theta0 = np.array([1.1500828787946733, -0.882904667438344, -3.051203418182742])
    res = sc.solve(model, theta0)
    scen = Scenario("planar_hexa", "across", theta0, ref.coords(model.home))
    out = classify(ref, scen, model.home, res)
    assert out.status == "ok", out.detail
    assert out.parity == "agree"
    assert ref.det_sign(ref.coords(res), theta0) == ref.det_sign(ref.home_x, model.home.theta)


def test_divergent_that_looped_at_a_tight_fold_returns() -> None:
    """A Delta start from which the follower's step-over kept failing while the step stayed
    below its minimum: the loop never advanced nor stopped (found by the fuzz, as a 20 s
    timeout). It must answer within a few seconds with the known solution (closed form)."""
    import time

    import scdk_sym as sc

    ref, model = reference("delta"), load("delta")
    start = model.configuration(
        np.array([0.02058123449026212, -0.03263814965704978, -0.15954757199069936]),
        np.array([-2.459550352066793, 0.43109303747141814, -2.4936438921561606]),
    )
    theta0 = np.array([-2.9055037496696925, 0.9286860037660971, -2.9707886194472635])
    known = np.array([-0.06271830096338599, 0.056443306992711356, -0.19229973661005284])
    t0 = time.process_time()
    res = sc.solve(model, theta0, start=start, branch="divergent")
    assert time.process_time() - t0 < 30.0
    scen = Scenario("delta", "across", theta0, known)
    out = classify(ref, scen, start, res)
    assert out.status == "ok", out.detail
    assert ref.distance(ref.coords(res), known) <= 1e-9


def test_convergent_fold_just_past_s_1_inside_one_step_is_not_missed() -> None:
    """A hexapod start whose convergent curve folds at s = 1 + 4.5e-8 (found by the fuzz as a
    refusal, "the curve closed on itself"): both crossings of s = 1 lie inside one step, too
    close to the fold for the step's interpolation to show them. The answer must be the first
    crossing, with the start's det sign and no singular crossing (reference: closed-form leg
    lengths and finite-difference det signs)."""
    import scdk_sym as sc

    ref, model = reference("stewart_gough"), load("stewart_gough")
    start = model.inverse_kinematics(
        [0.00878240311619109, 0.02647802522852165, 0.5453821371556559,
         -0.17098344251576178, -0.13687823734819793, 0.8936639461047436]
    )  # fmt: skip
    theta0 = np.array([0.9334252204132131, 0.6818533944602982, 0.9410317638837019,
                       0.7333402401971281, 0.9653827842700596, 0.7290066876682006])  # fmt: skip
    res = sc.solve(model, theta0, start=start)
    u = ref.coords(res)
    assert float(np.abs(ref.closure(u, theta0)).max()) <= 1e-9
    assert res.crossings == ()
    assert ref.det_sign(u, theta0) == ref.det_sign(ref.coords(start), start.theta)


def test_convergent_past_a_near_self_motion_point_is_followed() -> None:
    """A five-bar target 1e-6 from the point where both elbows meet (theta = (pi/3, 2 pi/3),
    where the effector turns freely on a circle): the curve turns within 1e-3 of s = 1 and
    sweeps half the circle at almost constant s. The follower's step had to shrink below the
    number of halvings after which it tried to step over, found nothing to step over and
    stopped (the fuzz's refusal "could not be followed further"). The answer: the reference
    continuation reaches s = 1, and of the two solutions at theta0 (mirror images, det signs
    opposite) the one with the start's det sign, with no crossing."""
    import scdk_sym as sc

    ref, model = reference("five_bar"), load("five_bar")
    start = model.configuration(
        [0.02529360125780586, 0.34627641756263944], [0.5283286963447011, 1.0261651021256681]
    )
    theta0 = np.array([1.047205178828321, 2.0944006855180057])
    u_start = ref.coords(start)
    assert line_curve_reaches(ref, u_start, start.theta, theta0) is True
    res = sc.solve(model, theta0, start=start)
    u = ref.coords(res)
    assert float(np.abs(ref.closure(u, theta0)).max()) <= 1e-9
    assert res.crossings == ()
    assert ref.det_sign(u, theta0) == ref.det_sign(u_start, start.theta)
    other = sc.solve(model, theta0, start=start, branch="divergent")
    assert ref.distance(ref.coords(other), u) > 0.1


def test_the_reference_sees_a_turn_of_s_next_to_the_level_inside_a_step() -> None:
    """The reference's own guard against a closed-curve verdict over a hidden pair: a step
    whose ends lie below s = 1 while s turns inside it (cubic Hermite of s) at 1 - 5e-5 or
    past 1 is flagged; one that turns at 1 - 1e-2 is not."""
    from references import _turn_near

    # s(u) = 1 - e - (u - 1/2)^2 c over the step: ends 1 - e - c/4, slopes +-c
    for e, flagged in ((5e-5, True), (-1e-8, True), (1e-2, False)):
        c = 0.01
        end = 1 - e - c / 4
        assert _turn_near(end, end, c, -c, 1.0) is flagged


def test_analytic_reference_jacobian_equals_central_differences(monkeypatch) -> None:
    """wl16_like's reference Jacobian (Pinocchio's frame Jacobians through Jlog6) equals
    the central differences of its closure residuals, on and off the manifold."""
    import references

    ref = reference("wl16_like")
    cols = ref.free + ref.motors
    rng = np.random.default_rng(5)
    for q in (ref.home_q, ref.home_q + 0.1 * rng.normal(size=ref.home_q.shape)):
        analytic = ref._jac(q, cols)
        monkeypatch.setattr(references, "ANALYTIC_JACOBIANS", frozenset())
        differences = ref._jac(q, cols)
        monkeypatch.undo()
        assert np.abs(analytic - differences).max() <= 1e-7
        assert np.abs(analytic).max() > 0.1
