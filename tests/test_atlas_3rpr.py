"""The 3-RPR singularity-locus atlas (examples/atlas_3rpr_singularity.py) against the
3-RPR's univariate polynomial (tests/test_modes.py: ``rpr_reference``, written from first
principles and sharing no code with the package).

The figure's claims, checked on a coarse grid of the example's slice:

* the certified mode count at every grid point equals the number of real solutions of the
  polynomial, and the slice holds regions of 2, 4 and 6 modes;
* every convergent solution is one of the polynomial's solutions, with the start's sign of
  ``det J_p``;
* the start's region ends at singular curves: every point the convergent branch cannot
  reach has a change of the real count on the straight segment from the start (the segment
  crosses a singular curve), and every solved point next to such a point lies next to a
  change of the count;
* where the count changes between two neighbours, the package's ``det J_p`` vanishes: at
  the change located by bisection on the polynomial (to 1e-6 of the grid step), the two
  merging solutions have ``|det J_p|`` below 5e-3 of the largest one at the two neighbours
  (it falls like the square root of the distance to the singular curve).

CI time (``pytest tests/test_atlas_3rpr.py``): 32-38 s of CPU in one process (2 to 6 min
wall on the two shared cores at load average 13 to 24, compiling the model's kernels in a
fresh cache and computing its start system).
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from factories import ROOT
from test_modes import pose_distance, rpr_reference

from scdk_sym.atlases import open_atlas

pytest.importorskip("zarr")

#: Grid points per axis of the slice (the example's range).
N = 7
#: Largest distance of a convergent solution from a solution of the polynomial [m, rad].
POSE_TOL = 1e-8


def load_example():
    path = ROOT / "examples" / "atlas_3rpr_singularity.py"
    spec = importlib.util.spec_from_file_location("atlas_3rpr_singularity", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def atlas_run(tmp_path_factory):
    """(example module, model, start, thetas (N, N, 3), store) of the example's slice."""
    import scdk_sym as sc

    ex = load_example()
    model = ex.build_model()
    start = model.home
    out = tmp_path_factory.mktemp("rpr") / "rpr.zarr"
    sc.atlas(model, ex.grid(N), out, start=start, modes=True, chunk=16, progress=False)
    store = open_atlas(out)
    thetas = store["theta"][:].reshape(N, N, 3)
    return ex, model, start, thetas, store


def reference_counts(ex, thetas: np.ndarray) -> np.ndarray:
    C = ex.platform_points()
    return np.array([len(rpr_reference(ex.BASE, C, th)) for th in thetas.reshape(-1, 3)])


def det_jp(model, y: np.ndarray, theta: np.ndarray) -> float:
    y_loc, c = model.chart.to_local(y)
    return float(np.linalg.det(np.array(model.kernels.jac(y_loc, theta, c)[0])))


def test_mode_counts_equal_real_roots_of_the_polynomial(atlas_run):
    ex, model, start, thetas, store = atlas_run
    counts = store["n_modes"][:]
    ref = reference_counts(ex, thetas)
    np.testing.assert_array_equal(counts, ref)
    assert {2, 4, 6} <= set(ref.tolist())  # the regions the figure shows
    np.testing.assert_array_equal(thetas[..., 0], ex.RHO1)  # the slice (actuated order)
    np.testing.assert_allclose(start.theta, ex.START_RHO, rtol=0, atol=1e-12)
    # the start is the mode of largest |det J_p| among the polynomial's solutions there
    sols = rpr_reference(ex.BASE, ex.platform_points(), start.theta)
    best = max(sols, key=lambda s: abs(det_jp(model, s, start.theta)))
    assert pose_distance(best, start.x) < POSE_TOL


def test_a_mode_map_alone_counts_the_real_roots_of_the_polynomial(atlas_run, tmp_path):
    """``solve=False``: the same counts on a finer grid (the polynomial's), in chunks of 10
    (fronts cut at chunk ends) and on the CLI; no convergent solve (status 5, x NaN)."""
    import scdk_sym as sc
    from scdk_sym.errors import InputError

    ex, model, start, _, _ = atlas_run
    out = tmp_path / "map.zarr"
    run = sc.atlas(model, ex.grid(N + 2), out, start=start, modes=True, solve=False, chunk=10,
                   progress=False)  # fmt: skip
    store = open_atlas(out)
    thetas = store["theta"][:]
    np.testing.assert_array_equal(store["n_modes"][:], reference_counts(ex, thetas))
    assert run.counts == {5: (N + 2) ** 2} and run.swept == 0
    assert np.isnan(store["x"][:]).all() and store.attrs["scdk_atlas"]["branch"] is None
    with pytest.raises(InputError, match="pass modes=True"):
        sc.atlas(model, ex.grid(N), tmp_path / "none.zarr", start=start, solve=False)


def test_convergent_solutions_are_real_roots_with_the_start_sign(atlas_run):
    ex, model, start, thetas, store = atlas_run
    C = ex.platform_points()
    status, x, det = store["status"][:], store["x"][:], store["det_jp"][:]
    solved = np.flatnonzero(status == 0)
    assert 0 < solved.size < status.size  # the start's region and beyond it
    assert set(status.tolist()) <= {0, 1}
    sign = np.sign(det_jp(model, start.y, start.theta))
    for i in solved:
        th = thetas.reshape(-1, 3)[i]
        assert min(pose_distance(x[i], s) for s in rpr_reference(ex.BASE, C, th)) < POSE_TOL
        assert np.sign(det[i]) == sign


def test_the_start_region_ends_at_singular_curves(atlas_run):
    ex, model, start, thetas, store = atlas_run
    C = ex.platform_points()
    unsolved = (store["status"][:] != 0).reshape(N, N)
    counts = store["n_modes"][:].reshape(N, N)
    # the straight segment from the start to an unreachable point crosses a singular curve
    for i, j in zip(*np.nonzero(unsolved), strict=True):
        line = start.theta + np.linspace(0, 1, 61)[:, None] * (thetas[i, j] - start.theta)
        along = {len(rpr_reference(ex.BASE, C, th)) for th in line}
        assert len(along) > 1, (i, j)
    # a solved point next to an unreachable one lies next to a change of the count
    border = 0
    for i in range(N):
        for j in range(N):
            near = [(a, b) for a, b in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1))
                    if 0 <= a < N and 0 <= b < N]  # fmt: skip
            if unsolved[i, j] or not any(unsolved[a, b] for a, b in near):
                continue
            border += 1
            block = counts[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2]
            assert block.min() != block.max(), (i, j)
    assert border > 0


def test_det_jp_vanishes_where_the_count_changes(atlas_run):
    ex, model, start, thetas, store = atlas_run
    C = ex.platform_points()
    counts = store["n_modes"][:].reshape(N, N)
    pairs = [((i, j), (i + 1, j)) for i in range(N - 1) for j in range(N)
             if counts[i, j] != counts[i + 1, j]]  # fmt: skip
    assert pairs
    for p, q in pairs:
        a, b = thetas[p], thetas[q]
        scale = max(
            abs(det_jp(model, s, th)) for th in (a, b) for s in rpr_reference(ex.BASE, C, th)
        )
        na = len(rpr_reference(ex.BASE, C, a))
        for _ in range(20):  # bisection on the polynomial's real count
            mid = (a + b) / 2
            if len(rpr_reference(ex.BASE, C, mid)) == na:
                a = mid
            else:
                b = mid
        side = a if len(rpr_reference(ex.BASE, C, a)) > len(rpr_reference(ex.BASE, C, b)) else b
        dets = np.abs([det_jp(model, s, side) for s in rpr_reference(ex.BASE, C, side)])
        # the two solutions that merge there are nearly singular (the scale: the neighbours)
        assert len(dets) >= 2 and np.sort(dets)[1] < 5e-3 * scale, (p, q, dets, scale)


def test_a_chunk_of_mode_sets_walked_from_neighbours_equals_the_polynomial():
    """A 12 x 12 slice in chunks of 48 (4 grid lines, the second and later chunks starting
    mid-grid): each point's certified set comes from its grid neighbour's complete root set
    wherever that is known (all but one point of each chunk here), and every count equals
    the real roots of the polynomial, across the singular curves of the slice. The points
    with no real solution are PathErrors without a solve: the statuses and solutions equal
    those of the chunks solved without modes (each of those points through sc.solve)."""
    from scdk_sym.atlases import chunk, make_grid

    ex = load_example()
    model = ex.build_model()
    n = 12
    grid = make_grid(model, ex.grid(n), model.home.theta)
    thetas = grid.thetas(0, grid.size)
    with_modes, without, continued = [], [], 0
    for a in range(0, grid.size, 48):
        rows = thetas[a : a + 48]
        part = chunk.solve_chunk(model, model.home, rows, modes=True, offset=a, shape=grid.shape)
        with_modes.append(part)
        without.append(chunk.solve_chunk(model, model.home, rows, offset=a, shape=grid.shape))
        continued += part.modes_continued
    counts = np.concatenate([p.n_modes for p in with_modes])
    ref = reference_counts(ex, thetas)
    assert len(set(ref.tolist())) >= 3  # the slice crosses singular curves
    np.testing.assert_array_equal(counts, ref)
    assert continued == grid.size - grid.size // 48
    status = np.concatenate([p.status for p in with_modes])
    assert np.sum(counts == 0) > 0 and np.all(status[counts == 0] == 1)  # PathError
    np.testing.assert_array_equal(status, np.concatenate([p.status for p in without]))
    np.testing.assert_array_equal(
        np.concatenate([p.x for p in with_modes]), np.concatenate([p.x for p in without])
    )


def _grid_distances(points: list[tuple[int, ...]], root: tuple[int, ...]) -> dict:
    """Steps from ``root`` to each point reachable through ``points`` (one index changed by
    one per step): relaxation until nothing changes, independent of the package's search."""
    dist = {root: 0}
    changed = True
    while changed:
        changed = False
        for q in points:
            for a in range(len(q)):
                for step in (-1, 1):
                    nb = (*q[:a], q[a] + step, *q[a + 1 :])
                    if nb in dist and dist[nb] + 1 < dist.get(q, 1 << 30):
                        dist[q], changed = dist[nb] + 1, True
    return dist


def test_continuation_tree_is_a_shortest_path_forest_of_the_chunk():
    """``continuation_tree`` against grid distances computed by plain relaxation, on chunks
    of a 3 x 1 x 4 x 2 grid and of the 40 x 40 slice starting anywhere: each point's
    neighbour is one grid step away inside the chunk and one front before it, its front is
    its distance to its part's root, one root per connected part; a chunk of 10 x 40 grid
    points has 26 fronts (its centre is 5 + 20 steps from the farthest corner)."""
    from scdk_sym.atlases.chunk import continuation_tree

    for shape, cases in (((3, 1, 4, 2), [(0, 24), (5, 1), (5, 7), (8, 16), (3, 10)]),
                         ((40, 40), [(0, 400), (35, 10), (20, 400), (1590, 10)])):  # fmt: skip
        for offset, count in cases:
            pred, depth = continuation_tree(offset, count, shape)
            pts = [tuple(int(v) for v in np.unravel_index(offset + i, shape)) for i in range(count)]
            for i in np.flatnonzero(pred >= 0).tolist():
                step = np.abs(np.subtract(pts[i], pts[pred[i]]))
                assert step.sum() == 1 and depth[pred[i]] == depth[i] - 1, (offset, count, i)
            seen: set = set()
            for r in np.flatnonzero(pred < 0).tolist():
                dist = _grid_distances(pts, pts[r])
                assert not seen & set(dist)  # one root per connected part
                seen |= set(dist)
                for q, d in dist.items():
                    assert depth[pts.index(q)] == d, (offset, count, q)
            assert seen == set(pts)
    _, depth = continuation_tree(400, 400, (40, 40))
    assert depth.max() + 1 == 26


def test_mode_sets_from_neighbours_along_a_line_are_the_polynomial_poses():
    """Along a line of 30 readings of the example's slice that crosses singular curves, each
    certified set tracked from the previous reading's complete root set holds exactly the
    real poses of the polynomial (to 1e-8), and says it came from the neighbour; all the
    readings solved at once from the same neighbours' sets give the same answers."""
    from scdk_sym.solvers.homotopy_modes import modes_from_neighbour, modes_from_neighbours

    ex = load_example()
    model = ex.build_model()
    C = ex.platform_points()
    (lo2, hi2), (lo3, hi3) = ex.LEG2, ex.LEG3
    line = [np.array([ex.RHO1, lo2 + u * (hi2 - lo2), hi3 - u * (hi3 - lo3)])
            for u in np.linspace(0.05, 0.95, 30)]  # fmt: skip
    seed, counts, seeds, walk = None, set(), [], []
    for i, theta in enumerate(line):
        seeds.append(seed)
        modes, seed, used = modes_from_neighbour(model, theta, seed)
        walk.append(modes)
        assert modes.certified and used == (i > 0)
        if used:
            assert "neighbouring point" in modes.report
        ref = rpr_reference(ex.BASE, C, theta)
        assert len(modes) == len(ref)
        for pose in ref:
            assert min(pose_distance(cfg.x, pose) for cfg in modes) <= POSE_TOL
        counts.add(len(ref))
    assert len(counts) >= 2  # the line crosses a singular curve
    # all points at once from the same neighbours' sets: the same answers, bit for bit
    together = modes_from_neighbours(model, np.array(line), seeds)
    for one, (many, _, used) in zip(walk, together, strict=True):
        assert used == (one is not walk[0]) and many.report == one.report
        assert len(many) == len(one) and len(many.certificates) == len(one.certificates)
        for a, b in zip(many, one, strict=True):
            np.testing.assert_array_equal(a.y, b.y)
            np.testing.assert_array_equal(a.x, b.x)
        for a, b in zip(many.certificates, one.certificates, strict=True):
            np.testing.assert_array_equal(a.box, b.box)
