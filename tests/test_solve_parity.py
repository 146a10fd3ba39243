"""Python/C parity over the fuzz's seeded scenarios: ``solve(backend="c")`` (the generated C
follower, :mod:`scdk_sym.solvers.solve_c`) against the compiled Python follower
(``backend="compiled"``) on both branches of every shipped model and Gepetto fixture.

The two are separate implementations of one rule (the C template takes the follower's and the
tracking rule's constants from :mod:`scdk_sym.follower.curve` and
:mod:`scdk_sym.follower.track_rule`); any drift between them shows here as a different answer
(x and y beyond 1e-9), a different crossing (kind, or s beyond 1e-6), a different status or
branch sign, or a refusal on one side only. Where the C call hands a query over to the
compiled solve, the hand-over is reported in ``fallback`` (never silent) and the answers are
compared all the same.
"""

from __future__ import annotations

import numpy as np
import pytest
from factories import needs_compiler
from references import NAMES, draw_scenarios, load
from test_solve_c import assert_same_answer

import scdk_sym as sc
from scdk_sym.codegen import library as clib

pytestmark = needs_compiler()

#: The fuzz's seed (benchmarks/fuzz.py --seed 3) and scenarios drawn per model.
SEED = 3
PER_MODEL = 12


@pytest.mark.parametrize("name", NAMES)
def test_c_and_python_followers_answer_alike_on_the_fuzz_scenarios(name: str) -> None:
    model = load(name)
    solved_in_c = 0
    for scen in draw_scenarios(name, PER_MODEL, SEED):
        start = scen.start(model)
        for branch in ("convergent", "divergent"):
            kw = {"start": start, "branch": branch, "record_path": False}
            try:
                ref = sc.solve(model, scen.theta0, backend="compiled", **kw)
            except sc.ScdkError as exc:
                with pytest.raises(type(exc)):
                    sc.solve(model, scen.theta0, backend="c", **kw)
                continue
            res = sc.solve(model, scen.theta0, backend="c", **kw)
            assert_same_answer(model, res, ref, branch)
            assert res.backend in ("c", "compiled")
            assert (res.backend == "compiled") == bool(res.fallback), res.fallback
            solved_in_c += res.backend == "c"
    # the comparison is not vacuous: a quarter of the solves at least (both branches) came
    # from the C follower itself (robot_delta: 10 of 40 with 20 scenarios)
    assert solved_in_c >= PER_MODEL // 2, solved_in_c


def test_the_c_follower_is_the_one_compared() -> None:
    """The raw C convergent call answers the seed scenario of planar_hexa by itself (the parity
    above compares two followers, not one follower twice)."""
    model = load("planar_hexa")
    scen = draw_scenarios("planar_hexa", 1, SEED)[0]
    start = scen.start(model)
    y1, c1 = model.chart.to_local(start.y)
    out = clib.tracker_library(model).solve_convergent(y1, c1, start.theta, scen.theta0)
    ref = sc.solve(model, scen.theta0, start=start, backend="compiled", record_path=False)
    assert out.status == clib.OK_PATH
    np.testing.assert_allclose(out.x, ref.x, rtol=0, atol=1e-9)
