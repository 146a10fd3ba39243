"""The legged robots of Gepetto's example-parallel-robots collection, loaded with no option.

Each answer is checked on Pinocchio's own closure residuals, through the model Gepetto's loader
builds from the same files (``tests/gepetto_loader.py``, a port of that loader built on
Pinocchio alone), its ``q`` filled by :func:`scdk_sym.verify.pinocchio.pinocchio_q`.
"""

from __future__ import annotations

import re
import warnings
from functools import cache
from pathlib import Path

import gepetto_loader as gl
import numpy as np
import pinocchio as pin
import pytest
import yaml

import scdk_sym as sc
from scdk_sym.cli.assemble import write_home
from scdk_sym.errors import ModelError, ModelWarning, NotAssembledError
from scdk_sym.model.spec import parse_spec
from scdk_sym.verify.pinocchio import pinocchio_q

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "gepetto"
LEGGED = (
    "battobot_6d",
    "cassie_like",
    "digit_like",
    "digit_like_2legs",
    "digit_like_2legs_6D",
    "digit_like_2legs_old",
    "disney_like",
    "disney_robot",
    "talos_like",
    "wl16_like",
)
#: Solved on both branches in the test run (a biped one leg at a time: about 2 s cold).
SOLVED = LEGGED
#: As published, these URDFs leave loops open (prismatic actuators slide along the axis of
#: the revolute carrying them): no assembly exists.
UNCLOSABLE = ("kangaroo_like", "kangaroo_like_2legs")


@cache
def model(name: str) -> sc.Model:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        return sc.load_model(FIXTURES / name)


@cache
def gepetto(name: str) -> gl.GepettoModel:
    """Gepetto's loader on the fixture; for disney_robot on a copy whose YAML spells the left
    foot's ball joint as the URDF does (``sĥerical``: Gepetto's loader would leave it a
    revolute, over-constraining the left foot loop)."""
    directory = FIXTURES / name
    if name == "disney_robot":
        import tempfile

        directory = Path(tempfile.mkdtemp()) / name
        directory.mkdir()
        (directory / "robot.urdf").write_text((FIXTURES / name / "robot.urdf").read_text())
        text = (FIXTURES / name / "robot.yaml").read_text()
        (directory / "robot.yaml").write_text(
            text.replace("'left_spherical_free_foot'", "'left_sĥerical_free_foot'")
        )
    return gl.load(directory, free_flyer=gl.FREE_FLYER.get(name, False))


def moving_links(m: sc.Model, gm: gl.GepettoModel) -> list[str]:
    """Links placed by both models: not the intermediate bodies of revolute triples that
    Gepetto's loader merges into ball joints (frozen at zero there)."""
    names = set(gm.model.names)
    out = []
    for link in m.tree.links:
        j = m.tree.parent_joint(link)
        if j is None or not j.movable or j.name in names or j.name.endswith(("_U1", "_U2")):
            out.append(link)
    return out


@pytest.mark.parametrize("name", LEGGED)
def test_loads_with_no_option_and_closes_on_pinocchio(name: str) -> None:
    m = model(name)
    assert m.home.residual <= m.tolerance
    gm = gepetto(name)
    q = pinocchio_q(m, m.home, gm.model)
    assert gl.closure_residuals(gm, q).max() <= 1e-9
    ours, theirs = m.placements(m.home), gl.link_placements(gm, q)
    err = max(np.abs(ours[k] - theirs[k]).max() for k in moving_links(m, gm) if k in theirs)
    assert err <= 1e-9


#: The legs whose compiled kernels take minutes to build: solved with CVODES in the default
#: suite (the same answers, checked on the same references), compiled under ``SCDK_SLOW=1``.
COMPILE_HEAVY = (
    "battobot_6d",
    "digit_like_2legs",
    "digit_like_2legs_6D",
    "digit_like_2legs_old",
    "disney_robot",
    "wl16_like",
)
BRANCH_CASES = [
    *((name, "cvodes" if name in COMPILE_HEAVY else "compiled") for name in SOLVED),
    *(pytest.param(name, "compiled", marks=pytest.mark.slow) for name in COMPILE_HEAVY),
]


@pytest.mark.parametrize(("name", "backend"), BRANCH_CASES)
def test_both_branches_at_home_plus_five_hundredths(name: str, backend: str) -> None:
    m = model(name)
    gm = gepetto(name)
    theta = m.home.theta + 0.05
    answers = []
    for branch in ("convergent", "divergent"):
        r = sc.solve(m, theta, branch=branch, backend=backend)
        assert r.residual <= m.tolerance
        np.testing.assert_allclose(r.theta, theta, rtol=0, atol=1e-12)
        q = pinocchio_q(m, r.configuration, gm.model)
        assert gl.closure_residuals(gm, q).max() <= 1e-9
        answers.append(m.placements(r.configuration))
    # the two branches are different assemblies of the mechanism
    assert max(np.abs(answers[0][k] - answers[1][k]).max() for k in answers[0]) > 1e-3


@pytest.mark.parametrize("name", LEGGED)
def test_convergent_answer_matches_an_independent_pinocchio_continuation(name: str) -> None:
    m, gm = model(name), gepetto(name)
    theta = m.home.theta + 0.02
    r = sc.solve(m, theta, backend="cvodes" if name in COMPILE_HEAVY else "compiled")
    q0 = pinocchio_q(m, m.home, gm.model)
    q, info = gl.continuation(gm, q0, theta)
    assert info.residual <= 1e-10
    # the foot is determined by the actuators (the rods may spin about their own axes)
    foot = gl.link_placements(gm, q)[m.frame]
    np.testing.assert_allclose(r.configuration.platform_pose, foot, rtol=0, atol=1e-7)


def test_kangaroo_refusal_names_its_welds_and_as_point_closures_the_reference_assembles(
    tmp_path: Path,
) -> None:
    with pytest.raises(NotAssembledError) as info:
        sc.load_model(FIXTURES / "kangaroo_like")
    text = str(info.value)
    assert "6d closures cannot hold at any configuration" in text
    floor = float(re.search(r"stops at ([0-9.e-]+)\)", text).group(1))
    # the reference (Gepetto's loader on Pinocchio) cannot close the welds either: its
    # least-squares point keeps a residual of the same size
    with pytest.raises(gl.ProjectionError) as ref:
        gl.assemble_from_neutral(gepetto("kangaroo_like"))
    assert 0.05 <= floor <= 0.12 and ref.value.residual > 1e-3
    # the same files with every 6D closure written 3D: the reference assembles them
    d = tmp_path / "kangaroo_3d"
    d.mkdir()
    (d / "robot.urdf").write_text((FIXTURES / "kangaroo_like" / "robot.urdf").read_text())
    data = yaml.safe_load((FIXTURES / "kangaroo_like" / "robot.yaml").read_text())
    data["type"] = ["3D" for _ in data["type"]]
    (d / "robot.yaml").write_text(yaml.safe_dump(data))
    q = gl.assemble_from_neutral(gl.load(d))
    assert np.abs(gl.closure_residuals(gl.load(d), q)).max() <= 1e-9


@pytest.mark.parametrize("name", ["kangaroo_like_2legs"])
def test_unclosable_files_are_refused_and_the_reference_agrees(name: str) -> None:
    with pytest.raises(NotAssembledError) as info:
        sc.load_model(FIXTURES / name)
    assert "add 'home'" in str(info.value)
    # the actuators named: on Pinocchio's model of the URDF, the prismatic motors whose axis is
    # collinear with that of the lone revolute carrying them (not the last of a ball)
    pm = pin.buildModelFromUrdf(str(FIXTURES / name / "robot.urdf"))
    data = pm.createData()
    pin.forwardKinematics(pm, data, pin.neutral(pm))
    motors = yaml.safe_load((FIXTURES / name / "robot.yaml").read_text())["name_mot"]
    expected = []
    for j in range(1, pm.njoints):
        parent = pm.parents[j]
        if pm.names[j] not in motors or "P" not in pm.joints[j].shortname() or parent == 0:
            continue
        ball = np.linalg.norm(pm.jointPlacements[parent].translation) < 1e-9
        axes = [
            data.oMi[i].rotation[:, "XYZ".index(pm.joints[i].shortname()[-1])] for i in (j, parent)
        ]  # the joints of these files are aligned with an axis of their frame (PZ, RZ, ...)
        along = abs(axes[0] @ axes[1]) > 1 - 1e-9
        if along and not ball:
            expected.append(f"{pm.names[j]} along the axis of revolute {pm.names[parent]}")
    assert len(expected) >= 3
    for text in expected:
        assert text in str(info.value)
    with pytest.raises(gl.ProjectionError) as ref:
        gl.assemble_from_neutral(gepetto(name))
    assert ref.value.residual > 1e-3


def test_assembled_home_written_back_reloads_the_same(tmp_path: Path) -> None:
    m = model("wl16_like")
    assert m.assembly is not None and "continuation" in m.assembly
    d = tmp_path / "wl16"
    d.mkdir()
    for f in ("robot.urdf", "robot.yaml"):
        (d / f).write_text((FIXTURES / "wl16_like" / f).read_text())
    write_home(d / "robot.yaml", m.file_joints(m.home))
    again = sc.load_model(d)
    assert again.assembly is None
    ours, theirs = m.placements(m.home), again.placements(again.home)
    assert max(np.abs(ours[k] - theirs[k]).max() for k in ours) <= 1e-12


def test_gepetto_keys_and_closure_types_in_either_case() -> None:
    spec = parse_spec(
        "closed_loop: [[a, b]]\ntype: ['3D']\nname_mot: [m]\n"
        "joint_name: [j1, j2]\njoint_type: [spherical, UJOINT_XY]\n"
    )
    assert spec.closures[0].type == "3d"
    assert spec.joint_edits == (("j1", "SPHERICAL"), ("j2", "UJOINT_XY"))
    with pytest.raises(ModelError, match="unknown joint type 'BALL'"):
        parse_spec(
            "closed_loop: [[a, b]]\ntype: [6d]\nname_mot: [m]\njoint_name: [j]\n"
            "joint_type: [BALL]\n"
        )


def test_universal_joints_are_split_as_gepetto_names_them() -> None:
    m = model("battobot_6d")
    names = {j.name: j for j in m.tree.joints}
    first, second = names["free_knee_left_Y"], names["free_knee_left_Z"]
    assert (first.type, second.type) == ("revolute", "revolute")
    assert second.parent == first.child
    np.testing.assert_array_equal(first.axis, [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(second.axis, [0.0, 0.0, 1.0])
    gm = gepetto("battobot_6d")
    assert {"free_knee_left_Y", "free_knee_left_Z"} <= set(gm.model.names)


def test_a_misspelt_joint_edit_is_applied_to_its_near_miss_with_a_warning() -> None:
    with pytest.warns(ModelWarning, match="sĥerical"):
        m = sc.load_model(FIXTURES / "disney_robot")
    assert m.tree.joint("left_sĥerical_free_foot").type == "spherical"


@pytest.mark.parametrize("name", ("battobot_6d", "disney_robot"))
def test_ball_and_universal_joints_match_pinocchio(name: str) -> None:
    # the Pinocchio model of the edited tree: spherical joints (quaternions), universal joints
    from scdk_sym.verify.pinocchio import closure_residuals, placement_error

    m = model(name)
    rng = np.random.default_rng(2)
    y = m.home.y + rng.normal(scale=0.1, size=m.m)
    assert placement_error(m, y, m.home.theta) <= 1e-12
    assert closure_residuals(m, m.home.joints).max() <= 1e-9


def test_verify_passes_on_a_legged_model() -> None:
    report = sc.verify_model(model("talos_like"), samples=1, seed=0)
    assert report.passed, [c for c in report.checks if not c.passed]


def test_a_biped_splits_into_its_legs() -> None:
    m = model("digit_like_2legs")
    assert [s.m for s in m.blocks] == [18, 18]
    # independent blocks: a finite difference of the closure rows of one leg's unknowns
    # leaves the other leg's rows unchanged (checked numerically, not on the sparsity)
    from scdk_sym.kernels.fastcall import model_calls

    calls = model_calls(m)
    y, c = m.chart.to_local(m.home.y)
    g0 = np.array(calls.g(y, m.home.theta, c)).ravel()
    first = m.blocks[0].block[1]
    other = [r for r in range(m.m) if r not in first.rows]
    for i in first.unknowns:
        dy = np.zeros(m.m)
        dy[i] = 1e-6
        g = np.array(calls.g(y + dy, m.home.theta, c)).ravel()
        assert np.abs(g[other] - g0[other]).max() == 0.0


def test_the_legs_solved_apart_give_the_dense_answer() -> None:
    m = model("digit_like_2legs")
    theta = m.home.theta + 0.05
    apart = sc.solve(m, theta)
    dense = sc.load_model(FIXTURES / "digit_like_2legs")
    dense.blocks = (dense,)  # the whole 36 x 36 system at once
    together = sc.solve(dense, theta)
    np.testing.assert_allclose(apart.y, together.y, rtol=0, atol=1e-10)
    gm = gepetto("digit_like_2legs")
    q = pinocchio_q(m, apart.configuration, gm.model)
    assert gl.closure_residuals(gm, q).max() <= 1e-9


@pytest.mark.parametrize("backend", ("cvodes", "c"))
def test_track_a_biped_along_400_samples(backend: str) -> None:
    m = model("digit_like_2legs")
    s = np.linspace(0.0, 1.0, 400)
    thetas = m.home.theta + 0.1 * np.sin(2 * np.pi * s)[:, None] * np.linspace(1, -1, m.k)
    r = sc.track(m, thetas, backend=backend)
    assert r.y.shape == (400, 36)
    assert r.residual.max() <= m.tolerance
    for i in (0, 137, 399):  # samples re-checked on the model itself
        cfg = m.configuration(r.y[i], thetas[i])
        assert cfg.residual <= m.tolerance
        np.testing.assert_allclose(cfg.x, r.x[i], rtol=0, atol=1e-12)
    # no jump: consecutive samples close together (readings 1.6e-3 rad apart), and the
    # closed motion (back to home's readings) ends on home's assembly
    assert np.abs(np.diff(r.y, axis=0)).max() < 0.05
    np.testing.assert_allclose(r.y[-1], m.home.y, rtol=0, atol=1e-8)


def _motion_through_a_fold(m: sc.Model) -> tuple[np.ndarray, np.ndarray, int]:
    """A 400-sample motion of one motor through a fold of the leg (the example's arc-length
    continuation of the closure curve): (ys, thetas, sample of the fold)."""
    import sys

    sys.path.insert(0, str(FIXTURES.parents[2] / "examples"))
    from biped_ankle_singularity import closure_curve

    for step in (0.02, 0.04):
        for motor in m.actuated:
            ys, thetas = closure_curve(m, motor, 400, step=step)
            j = m.actuated.index(motor)
            fold = int(np.argmax(thetas[:, j]))
            if 20 < fold < 380 and thetas[-1, j] < thetas[fold, j] - 0.05:
                return ys, thetas, fold
    raise AssertionError(f"no motor of {m.name} passes a fold within 400 samples")


@pytest.mark.parametrize("name", ("talos_like", "cassie_like", "digit_like", "digit_like_2legs"))
def test_track_follows_a_motion_through_a_fold(name: str) -> None:
    m = model(name)
    ys, thetas, fold = _motion_through_a_fold(m)
    gm = gepetto(name)
    for i in (fold - 40, fold + 40):  # the motion itself closes on Pinocchio
        q = pinocchio_q(m, m.configuration(ys[i], thetas[i]), gm.model)
        assert gl.closure_residuals(gm, q).max() <= 1e-9
    for backend in ("cvodes", "c"):
        r = sc.track(m, thetas, backend=backend)
        assert r.residual.max() <= m.tolerance
        np.testing.assert_allclose(r.y, ys, rtol=0, atol=1e-8)  # every sample, no jump
        assert [c.kind for c in r.crossings] == ["fold"]
        assert abs(r.crossings[0].index - fold) <= 1


@pytest.mark.parametrize("backend", ("cvodes", "c"))
def test_a_leg_is_tracked_knee_then_ankle_as_the_whole_system(backend: str) -> None:
    """digit_like tracked one block of its block-triangular decomposition after the other
    (the knee four-bar, then the ankle mechanism reading the knee's samples) through its ankle
    fold: every sample and the crossing those of the whole 18 x 18 system tracked at once."""
    m = model("digit_like")
    assert [(s.m, s.k) for s in m.stages] == [(6, 4), (12, 7)]  # the ankle reads 1 knee angle
    _, thetas, _ = _motion_through_a_fold(m)
    staged = sc.track(m, thetas, backend=backend)
    whole = sc.load_model(FIXTURES / "digit_like")
    whole.stages = (whole,)
    ref = sc.track(whole, thetas, backend=backend)
    np.testing.assert_allclose(staged.y, ref.y, rtol=0, atol=1e-9)
    np.testing.assert_allclose(staged.x, ref.x, rtol=0, atol=1e-9)
    assert [(c.index, c.kind) for c in staged.crossings] == [
        (c.index, c.kind) for c in ref.crossings
    ]
    assert abs(staged.crossings[0].s - ref.crossings[0].s) <= 1e-6


def random_start_assemblies(gm: gl.GepettoModel, theta: np.ndarray, links: list[str],
                            starts: int, seed: int) -> list[np.ndarray]:  # fmt: skip
    """Distinct real assemblies at ``theta`` by Pinocchio projections from random ``q``: the
    motors held, every other joint uniform (balls: uniform rotations), each assembly the
    origins of ``links``."""
    import pinocchio as pin

    pin.seed(int(seed))
    found: list[np.ndarray] = []
    nq = gm.model.nq
    for _ in range(starts):
        q = pin.randomConfiguration(gm.model, -np.pi * np.ones(nq), np.pi * np.ones(nq))
        q[list(gm.motor_q_indices)] = theta
        try:
            q = gl.project(gm, q, fixed_q_indices=gm.motor_q_indices, max_iter=100)
        except gl.ProjectionError:
            continue
        places = gl.link_placements(gm, q)
        key = np.concatenate([places[k][:3, 3] for k in links])
        if all(np.abs(key - f).max() > 1e-6 for f in found):
            found.append(key)
    return found


@pytest.mark.parametrize(
    ("name", "blocks", "count"),
    # cassie and digit: the knee, then the ankle; digit's ankle has two rods between balls
    [("talos_like", 0, 2), ("cassie_like", 2, 4), ("digit_like", 2, 8)],
)
def test_assembly_modes_certified_equal_to_a_random_start_reference(
    name: str, blocks: int, count: int
) -> None:
    m, gm = model(name), gepetto(name)
    theta = m.home.theta + 0.05
    sols = sc.assembly_modes(m, theta)
    assert sols.certified, sols.report
    assert len({id(b.block) for b in sols.blocks}) == blocks
    assert all(b.modes.certified for b in sols.blocks)
    for cfg in sols:
        assert m.residual(cfg.y, cfg.theta) <= m.tolerance
    import pinocchio as pin

    # links not carried by a ball joint of Gepetto's model: a rod's spin about its own axis
    # (free there, locked here) moves the bodies it carries off that axis
    pm = gm.model
    balls = {i for i, j in enumerate(pm.joints) if j.nq == 4}
    carried = {f.name for f in pm.frames if set(pm.supports[f.parentJoint].tolist()) & balls}
    bodies = gl.link_placements(gm, pin.neutral(pm))
    links = [k for k in moving_links(m, gm) if k in bodies and k not in carried]
    assert m.frame in links
    keys = [np.concatenate([m.placements(c)[k][:3, 3] for k in links]) for c in sols]
    reference = random_start_assemblies(gm, theta, links, 120, seed=7)
    # each assembly of the links once: a rod between balls is solved as the distance it
    # keeps, not once per angle triple of its balls
    assert len(sols) == len(reference) == count
    for key in reference:
        assert min(np.abs(key - o).max() for o in keys) < 1e-7
    assert min(np.abs(a - b).max() for i, a in enumerate(keys) for b in keys[:i]) > 1e-6


@pytest.mark.parametrize(("name", "sizes"), [("cassie_like", [6, 6]), ("digit_like", [6, 12])])
def test_a_leg_is_block_triangular_as_finite_differences_see_it(name: str, sizes) -> None:
    """The knee block's rows do not move with the ankle's unknowns; the ankle's rows move
    with the knee's only through its inputs (finite differences of g at home)."""
    from scdk_sym.robot.blocks import triangular_blocks, triangular_models

    m = model(name)
    blocks = triangular_blocks(m)
    assert [len(b.unknowns) for b in blocks] == sizes
    assert m.chart.size == 0  # revolute unknowns only: y is its own chart
    y0, theta, g = m.home.y, m.home.theta, m.kernels.g
    base = np.array(g(y0, theta, np.zeros(0))).ravel()
    moved = np.zeros((m.m, m.m), dtype=bool)  # moved[row, unknown]
    for j in range(m.m):
        y = y0.copy()
        y[j] += 1e-6
        moved[:, j] = np.abs(np.array(g(y, theta, np.zeros(0))).ravel() - base) > 1e-12
    seen: set[int] = set()
    for b in blocks:
        rows, own = list(b.rows), set(b.unknowns)
        allowed = own | set(b.inputs)
        assert set(b.inputs) <= seen  # the inputs are solved by earlier blocks
        for j in range(m.m):
            if j not in allowed:
                assert not moved[rows, j].any(), (b, m.unknowns[j])
        assert moved[np.ix_(rows, sorted(own))].any(axis=0).all()
        seen |= own
    subs = triangular_models(m)
    assert [s.m for s in subs] == sizes
    assert subs[1].actuated[-len(blocks[1].inputs) :] == tuple(
        m.unknowns[i] for i in blocks[1].inputs
    )


def test_modes_certified_per_block_say_so_in_json() -> None:
    m = model("cassie_like")
    sols = sc.assembly_modes(m, m.home.theta + 0.05)
    d = sols.to_dict()
    assert d["certified"] and d["count"] == len(sols) == 4
    assert all(s["certified"] for s in d["solutions"])
    assert d["report"].startswith("certified complete per block")


def test_a_cassie_divergent_case_is_answered_only_along_an_actuator_axis() -> None:
    """A divergent scenario of the legged fuzz (seed 0) that every earlier way of the
    divergent branch misses (``sigma_min`` has a non-singular valley around the start): the
    answer comes from across the singular surface met along an actuator's own axis, closes on
    Pinocchio's constraint models, has crossed a singular point and is not the convergent
    answer."""
    m, gm = model("cassie_like"), gepetto("cassie_like")
    y = [
        1.3412320580837307, 1.7669490846797022, -1.1549934211647916, -0.045429722317925365,
        -1.7318940741309958, -2.0679038160013308, 1.509014213553823, -1.851644235810635,
        -0.9606034990360778, 2.3008867859233355, 1.4216765962757352, -2.967538538731432,
    ]  # fmt: skip
    theta = [0.05565591055954592, 0.07895369343606344, 0.03140850208113244,
             0.0794177160665419, 0.01444626963915542]  # fmt: skip
    theta0 = np.array([-0.17853360511709696, -0.3428930082426849, 0.3001110582813621,
                       0.2562388743718417, 0.006872097217738451])  # fmt: skip
    start = m.configuration(np.array(y), np.array(theta))
    r = sc.solve(m, theta0, start=start, branch="divergent")
    assert r.strategy == "along-axes" and len(r.crossings) >= 1
    q = pinocchio_q(m, r.configuration, gm.model)
    assert gl.closure_residuals(gm, q).max() <= 1e-9
    conv = sc.solve(m, theta0, start=start)
    assert np.abs(conv.y - r.y).max() > 1e-3
