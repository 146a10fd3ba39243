"""The BKK root bound (scdk_sym/algebraic/rootbound/) against independent references: mixed
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
from scdk_sym.algebraic.rootbound import (
    isotropic_rows,
    mixed_volume,
    multihomogeneous_bezout,
    root_bound,
)


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
    vol, sizes, vols, *_ = mixed_volume([A1, A2], seed=0)
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


def multidense(degrees: list[int], sizes: list[int]) -> np.ndarray:
    """Every monomial of degree at most ``degrees[j]`` in each group of ``sizes[j]`` variables."""
    parts = [dense(n, d) for n, d in zip(sizes, degrees, strict=True)]
    return np.array([np.concatenate(c) for c in itertools.product(*parts)])


def expanded_coefficient(D: np.ndarray, sizes: list[int]) -> int:
    """The coefficient of prod a_j^(n_j) in prod_i sum_j D_ij a_j, by expanding the product."""
    poly = {tuple(0 for _ in sizes): 1}
    for row in D:
        nxt: dict[tuple[int, ...], int] = {}
        for e, c in poly.items():
            for j, d in enumerate(row):
                f = e[:j] + (e[j] + 1,) + e[j + 1 :]
                nxt[f] = nxt.get(f, 0) + c * int(d)
        poly = nxt
    return poly.get(tuple(sizes), 0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_multihomogeneous_bezout_is_the_coefficient_of_the_expanded_product(seed):
    rng = np.random.default_rng(seed)
    sizes = [2, 1, 2]
    n = sum(sizes)
    groups = [[0, 1], [2], [3, 4]]
    D = rng.integers(0, 3, size=(n, len(sizes)))
    supports = [multidense(list(row), sizes) for row in D]
    assert multihomogeneous_bezout(supports, groups) == expanded_coefficient(D, sizes)


def test_multihomogeneous_bezout_of_dense_bilinear_rows_is_their_mixed_volume():
    """Four rows of bidegree (1, 1) in two pairs of variables: C(4, 2) = 6 roots (the
    2-homogeneous Bezout number, which the mixed volume of dense supports equals), where the
    total degree counts 16."""
    supports = [multidense([1, 1], [2, 2])] * 4
    assert multihomogeneous_bezout(supports, [[0, 1], [2, 3]]) == 6
    assert multihomogeneous_bezout(supports, [[0, 1, 2, 3]]) == 16
    assert mixed_volume(supports, seed=0)[0] == 6


def test_a_block_out_of_reach_is_bounded_by_bezout():
    """The support whose hull is out of reach, given the variables' names: its block is
    bounded by the least Bezout number (the total degree 5 x 1^6) at once."""
    import time

    big = dense(7, 5)
    t = time.process_time()
    names = [f"v{i}.x" for i in range(7)]
    bound, sizes, vols, _, bezout = mixed_volume([big] + [dense(7, 1)] * 6, seed=0, names=names)
    assert (bound, sizes, vols, bezout) == (5, [7], [5], [0])
    assert time.process_time() - t < 1.0


def test_a_spent_budget_leaves_a_bezout_bound_no_smaller_than_the_roots():
    """The seed robot with no time for its mixed volume: the bound falls back to Bezout, is
    said so, and still bounds its 6 assembly modes (its BKK bound)."""
    form = algebraic_form(shipped("planar_hexa"))
    _, p = form.random_point(np.random.default_rng(0))
    rb = root_bound(form, p, budget=0.0)
    assert rb.bezout and "Bezout" in rb.kind
    assert rb.bound >= root_bound(form, p).bound == 6
