"""The BKK root bound (scdk_sym/algebraic/rootbound.py) against independent references: mixed
volumes from volumes of Minkowski sums (inclusion-exclusion, scipy's convex hulls), Bezout
numbers of dense supports, and the known complex root counts of models (the seed robot is a
3-RPR between its elbows: 6; robot_delta: 2 per circle-circle closure and 2 per rotation row
in each of its three loops: 64)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from factories import shipped

import scdk_sym as sc
from scdk_sym.algebraic import algebraic_form
from scdk_sym.algebraic.rootbound import isotropic_rows, mixed_volume, root_bound


def volume(points: np.ndarray) -> float:
    from scipy.spatial import ConvexHull

    n = points.shape[1]
    if np.linalg.matrix_rank(points - points[0]) < n:
        return 0.0
    return float(ConvexHull(points).volume)


def minkowski(supports: list[np.ndarray]) -> np.ndarray:
    out = np.zeros((1, supports[0].shape[1]), dtype=int)
    for P in supports:
        out = np.unique((out[:, None, :] + P[None, :, :]).reshape(-1, P.shape[1]), axis=0)
    return out


def mixed_volume_by_volumes(supports: list[np.ndarray]) -> int:
    """``MV = sum over subsets S of (-1)^(n - |S|) vol(sum_S P_i)`` (origin added)."""
    n = len(supports)
    pts = [np.unique(np.vstack([np.zeros((1, n), dtype=int), P]), axis=0) for P in supports]
    total = 0.0
    for k in range(1, n + 1):
        for S in itertools.combinations(range(n), k):
            total += (-1) ** (n - k) * volume(minkowski([pts[i] for i in S]))
    return round(total)


def dense(n: int, d: int) -> np.ndarray:
    return np.array([e for e in itertools.product(range(d + 1), repeat=n) if sum(e) <= d])


def test_mixed_volume_of_dense_supports_is_the_bezout_number():
    degrees = (2, 3, 1)
    vol, *_ = mixed_volume([dense(3, d) for d in degrees], seed=1)
    assert vol == math.prod(degrees)


def test_mixed_volume_of_unit_cubes_is_n_factorial():
    cube = np.array(list(itertools.product((0, 1), repeat=3)))
    vol, *_ = mixed_volume([cube] * 3, seed=2)
    assert vol == math.factorial(3)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_mixed_volume_of_random_laurent_supports_matches_inclusion_exclusion(seed):
    rng = np.random.default_rng(seed)
    n = 3
    supports = [rng.integers(-2, 3, size=(rng.integers(3, 6), n)) for _ in range(n)]
    vol, *_ = mixed_volume(supports, seed=seed)
    assert vol == mixed_volume_by_volumes(supports)


def test_block_triangular_system_factorises():
    """x^3 = a; y^2 + x y + x^5 = b: 3 values of x, then 2 of y each."""
    A1 = np.array([[3, 0]])
    A2 = np.array([[0, 2], [1, 1], [5, 0]])
    vol, sizes, vols, _ = mixed_volume([A1, A2], seed=0)
    assert vol == 6 == mixed_volume_by_volumes([A1, A2])
    assert sizes == [1, 1] and vols == [3, 2]


def test_isotropic_rows_agree_with_the_form():
    """The rewritten rows at u = c + i s equal the form's rows at (c, s) (random complex
    point on the circles), circle rows dropped."""
    model = shipped("planar_hexa")
    form = algebraic_form(model)
    rng = np.random.default_rng(4)
    z, p = form.random_point(rng)
    polys, labels, variables = isotropic_rows(form, p)
    G, _, _ = form.evaluate(z, p)
    u = np.array([z[s.z[0]] + 1j * z[s.z[1]] for s in form.rows.slots])
    assert len(variables) == len(u) == len(polys)
    for poly, label in zip(polys, labels, strict=True):
        value = sum(c * np.prod(u ** np.array(e)) for e, c in poly.terms.items())
        assert abs(value - G[form.rows.labels.index(label)]) <= 1e-12 * (1 + abs(value))


def test_seed_robot_bound_is_its_six_assembly_modes():
    form = algebraic_form(shipped("planar_hexa"))
    _, p = form.random_point(np.random.default_rng(0))
    assert root_bound(form, p).bound == 6


def test_robot_delta_bound_is_64():
    from gepetto_reference import FIXTURE

    model = sc.load_model(FIXTURE, frame="effector")
    form = algebraic_form(model)
    _, p = form.random_point(np.random.default_rng(0))
    rb = root_bound(form, p)
    assert rb.bound == 64 and math.prod(rb.block_volumes) == 64


def test_a_support_whose_hull_is_out_of_reach_is_refused_at_once():
    """A dense support of 792 points in 7 dimensions (a degree-5 polynomial in 7 variables:
    its lower hull has too many facets for qhull, which the budget cannot interrupt) is refused
    with a HomotopyError in well under a second (the bounds of the shipped models, with
    supports of up to 16 points in 7 dimensions, are computed: see the tests above)."""
    import time

    from scdk_sym.errors import HomotopyError

    big = dense(7, 5)
    assert len(big) == math.comb(12, 7)
    t = time.process_time()
    with pytest.raises(HomotopyError, match="792 points in 7 dimensions"):
        mixed_volume([big] + [dense(7, 1)] * 6, seed=0)
    assert time.process_time() - t < 1.0
