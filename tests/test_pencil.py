"""The trace test on the curve of an offset line (scdk_sym.algebraic.pencil).

References: the 40 postures of the general 6-6 platform (Dietmaier's platform, the known root
count), and for a Gepetto leg (talos_like's ankle, a 6R loop) a random-start complex Newton at
the start system's own parameters, independent of monodromy and of any trace.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from polynomial_systems import StewartGough
from roots import newton_roots
from stewart import DIETMAIER_BASE, DIETMAIER_PLATFORM

from scdk_sym.algebraic import monodromy_solve, trace_test
from scdk_sym.algebraic.pencil import collinear_residual, pencil_residual, pencil_trace_test

GEPETTO = Path(__file__).parent / "fixtures" / "gepetto"


@pytest.fixture(scope="module")
def dietmaier():
    system = StewartGough(DIETMAIER_BASE, DIETMAIER_PLATFORM)
    start = monodromy_solve(system, seed=0, progress=False)
    assert start.root_count == 40  # the root count of the general 6-6 platform
    return system, start


def test_collinear_residual_cancelling_bends_and_a_missing_point():
    rng = np.random.default_rng(0)
    ts = np.array([0.0, 0.3 + 0.2j, -0.1 + 0.4j])
    a, b, c = rng.normal(size=(3, 5, 3)) + 1j * rng.normal(size=(3, 5, 3))
    c -= c.mean(axis=0)  # the bends cancel in the sum: a complete fibre
    paths = [a + t * b + t**2 * c for t in ts]
    assert collinear_residual(paths, ts) < 1e-14
    # without a point, its bend is left: of the order of 1 / R of the bends
    assert collinear_residual([f[1:] for f in paths], ts) > 1e-2
    # a far-away point does not hide a missing one near the origin
    far = [np.vstack([f, 1e6 * (1 + t) * np.ones((1, 3))]) for f, t in zip(paths, ts, strict=True)]
    assert collinear_residual([f[1:] for f in far], ts) > 1e-2
    # straight paths: the test cannot tell
    assert collinear_residual([a + t * b for t in ts], ts) == np.inf


@pytest.mark.parametrize("coords", [[0], [3, 4, 5, 6]])
def test_dietmaier_complete_set_passes_and_a_missing_posture_fails(dietmaier, coords):
    system, start = dietmaier
    full = pencil_trace_test(
        system, start.solutions, start.p, start.b, np.random.default_rng(1), coords=coords
    )
    assert full.passed and full.residual < 1e-9 and full.witnesses >= 1
    short = pencil_residual(
        system, start.solutions[1:], start.p, start.b, full, np.random.default_rng(2)
    )
    assert short > 1e-4


def _talos_form():
    import scdk_sym as sc
    from scdk_sym.algebraic import algebraic_form
    from scdk_sym.algebraic.scaled import scaled_form
    from scdk_sym.backends import resolve

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = sc.load_model(GEPETTO / "talos_like")
    return scaled_form(algebraic_form(model, resolve("auto", "modes")))


def test_talos_ankle_start_system_is_the_random_start_set_and_only_the_pencil_proves_it():
    form = _talos_form()
    rng = np.random.default_rng(3)
    # loops until the count is stable, no completeness test
    start = monodromy_solve(form, seed=2, progress=False, test=lambda s, p, b: 0.0)
    reference = newton_roots(form, start.p, 1500, 60, np.random.default_rng(5), b=start.b)
    assert len(reference) == start.root_count == 16  # the generic 6R loop's count
    for r in reference:
        assert np.abs(start.solutions - r).max(axis=1).min() < 1e-8
    # the offset trace of the frames' placements is no polynomial of degree 1 here
    from scdk_sym.solvers.form_maps import frame_trace_map

    tmap = frame_trace_map(form, start.p)
    offset = trace_test(form, start.solutions, start.p, start.b, rng, trace_map=tmap)
    assert offset > 1e-7
    coords = list(form.rows.slots[0].z)
    proof = pencil_trace_test(
        form, start.solutions, start.p, start.b, np.random.default_rng(4), coords=coords
    )
    assert proof.passed and proof.residual < 1e-9
    assert (
        pencil_residual(
            form, start.solutions[:-1], start.p, start.b, proof, np.random.default_rng(5)
        )
        > 1e-4
    )
