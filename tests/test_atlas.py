"""The atlas: every stored point against a direct sc.solve, resumption after interruptions
(client Ctrl-C, a killed `scdk atlas` process, a killed Dask worker) compared byte for byte
with an uninterrupted store, and refusal of stores written for another run.

Measured 115 s for this file with the machine's two cores at load average 13 (most of it
starting worker processes, which import the package, for the three clusters)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from factories import MODELS, SEED_X1, shipped

import scdk_sym as sc
from scdk_sym.atlases import STATUS, make_grid, open_atlas
from scdk_sym.cli import main as cli_main
from scdk_sym.errors import AtlasError, PathError, StoreMismatchError, UnknownNameError

zarr = pytest.importorskip("zarr")

#: 4 x 3 x 3 points around the paper's theta0, some beyond the start's reach (PathError).
GRID = "theta_1=1.05:1.55:4,theta_3=-3.15:-2.65:3,theta_2=-1.05:-0.55:3"
CHUNK = 8
X_TOL = 1e-12


@pytest.fixture(scope="module")
def seed():
    model = shipped("planar_hexa")
    return model, model.inverse_kinematics(SEED_X1)


@pytest.fixture(scope="module")
def reference(seed):
    """(thetas, x, status) from the package's own solve, point by point, in C order."""
    model, start = seed
    a = np.linspace(1.05, 1.55, 4)
    c = np.linspace(-3.15, -2.65, 3)
    b = np.linspace(-1.05, -0.55, 3)
    A, C, B = np.meshgrid(a, c, b, indexing="ij")  # the order the names appear
    thetas = np.stack([A.ravel(), B.ravel(), C.ravel()], axis=1)  # actuated order
    xs = np.full((len(thetas), 3), np.nan)
    status = np.zeros(len(thetas), dtype=int)
    for i, th in enumerate(thetas):
        try:
            res = sc.solve(model, th, start=start, branch="convergent")
        except PathError:
            status[i] = 1
            continue
        xs[i] = res.x
        status[i] = 4 if res.status == "singular" else 0
    assert 0 < np.sum(status == 0) < len(thetas)  # both outcomes are exercised
    return thetas, xs, status


@pytest.fixture(scope="module")
def client():
    """A LocalCluster of two worker processes, shared by the tests that need one."""
    distributed = pytest.importorskip("distributed")
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        distributed.Client(cluster) as cl,
    ):
        yield cl


@pytest.fixture(scope="module")
def serial_store(seed, tmp_path_factory):
    model, start = seed
    out = tmp_path_factory.mktemp("atlas") / "serial.zarr"
    sc.atlas(model, GRID, out, start=start, chunk=CHUNK, progress=False)
    return out


def files(store: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(store)): p.read_bytes() for p in sorted(store.rglob("*")) if p.is_file()
    }


def stop_after_two_chunks(done: int, total: int) -> None:
    """An ``on_chunk`` that interrupts a run once two chunks are written."""
    if done >= 2 * CHUNK:
        raise KeyboardInterrupt


def check_against(out: Path, reference) -> None:
    thetas, xs, status = reference
    g = open_atlas(out)
    np.testing.assert_array_equal(g["theta"][:], thetas)
    np.testing.assert_array_equal(g["status"][:], status)
    np.testing.assert_array_equal(np.isnan(g["x"][:]), np.isnan(xs))
    np.testing.assert_allclose(g["x"][:], xs, rtol=0, atol=X_TOL, equal_nan=True)
    assert np.all(g["done"][:] == 1)


def test_serial_equals_direct_solves(serial_store, reference, seed):
    model, start = seed
    check_against(serial_store, reference)
    g = open_atlas(serial_store)
    meta = g.attrs["scdk_atlas"]
    assert meta["model"]["content_hash"] == model.content_hash
    assert [a["name"] for a in meta["grid"]["axes"]] == ["theta_1", "theta_3", "theta_2"]
    assert meta["status_codes"]["1"].startswith("PathError")
    assert meta["version"]
    # det J_p: the sign of the start's side at every solved point (convergent branch)
    det = g["det_jp"][:]
    ok = g["status"][:] == 0
    y_loc, c = model.chart.to_local(start.y)
    det0 = np.linalg.det(np.array(model.kernels.jac(y_loc, start.theta, c)[0]))
    assert np.all(np.sign(det[ok]) == np.sign(det0)) and np.all(np.isnan(det[~ok]))


def test_workers_equal_direct_solves(seed, reference, serial_store, client, tmp_path):
    model, start = seed
    one, two = tmp_path / "one.zarr", tmp_path / "two.zarr"
    sc.atlas(model, GRID, one, start=start, chunk=CHUNK, workers=1, progress=False)
    sc.atlas(model, GRID, two, start=start, chunk=CHUNK, scheduler=client, progress=False)
    for out in (one, two):
        check_against(out, reference)
        assert files(out) == files(serial_store)


class _NoSweep:
    """Stands for the C tracker library with a sweep that leaves every point to sc.solve."""

    def __init__(self, model):
        self.n = len(model.workspace)

    def sweep(self, y1, c1, theta1, thetas, offset, shape, rcond_min):
        from scdk_sym.codegen.library import ERR_SINGULAR_PATH, SweepOutput

        N = len(thetas)
        nan = np.full(N, np.nan)
        codes = np.full(N, ERR_SINGULAR_PATH, dtype=np.intc)
        return SweepOutput(np.full((N, self.n), np.nan), nan, nan.copy(), codes)


def test_sweep_equals_solve_fallback(seed, reference, monkeypatch):
    """The C sweep settles every regular reachable point; with it disabled every point goes
    through sc.solve: both agree to 1e-12 and fail on the same points."""
    from scdk_sym.atlases import chunk

    model, start = seed
    thetas = reference[0]
    swept = chunk.solve_chunk(model, start, thetas, offset=0, shape=(4, 3, 3))
    assert swept.swept == np.sum(reference[2] == 0)
    monkeypatch.setattr(chunk, "_tracker", _NoSweep)
    direct = chunk.solve_chunk(model, start, thetas)
    assert direct.swept == 0
    np.testing.assert_array_equal(direct.status, swept.status)
    np.testing.assert_allclose(direct.x, swept.x, rtol=0, atol=X_TOL, equal_nan=True)
    np.testing.assert_allclose(direct.det_jp, swept.det_jp, rtol=1e-10, equal_nan=True)


def test_sweep_on_a_turning_platform_equals_solve(monkeypatch):
    """The 6-6 platform turns between the start and the points (its rotation chart is
    re-centred on each answer): the C sweep and sc.solve agree to 1e-12, det J_p in the
    chart centred on the answer to 1e-10."""
    from scdk_sym.atlases import chunk

    model = shipped("stewart_gough")
    start = model.inverse_kinematics([0.02, -0.01, 0.56, 0.1, -0.05, 0.3])
    rng = np.random.default_rng(11)
    poses = start.x + rng.uniform(-1, 1, (8, 6)) * [0.01, 0.01, 0.01, 0.1, 0.1, 0.1]
    thetas = np.array([model.inverse_kinematics(x).theta for x in poses])
    swept = chunk.solve_chunk(model, start, thetas)
    assert swept.swept == len(thetas)
    monkeypatch.setattr(chunk, "_tracker", _NoSweep)
    direct = chunk.solve_chunk(model, start, thetas)
    assert direct.swept == 0 and np.all(direct.status == 0)
    np.testing.assert_allclose(swept.x, direct.x, rtol=0, atol=X_TOL)
    np.testing.assert_allclose(swept.x, poses, rtol=0, atol=1e-9)  # the poses themselves
    np.testing.assert_allclose(swept.det_jp, direct.det_jp, rtol=1e-10)


def test_a_hexapod_grid_is_swept_from_neighbours_and_equals_solve():
    """A 4^6 grid of the 6-6's leg lengths around home, in chunks of 256: nearly every point
    is continued from its grid neighbour (one direct solve per chunk), and 40 seeded points
    equal sc.solve from home to 1e-12 (x) and 1e-10 (det J_p, relative); one chunk of the
    whole grid gives the same answers."""
    from scdk_sym.atlases import chunk
    from scdk_sym.codegen.library import SWEEP_CONTINUED, tracker_library

    model = shipped("stewart_gough")
    home = model.home
    axes = [np.linspace(t - 0.04, t + 0.04, 4) for t in home.theta]
    thetas = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 6)
    shape = (4,) * 6
    parts = [
        chunk.solve_chunk(model, home, thetas[a : a + 256], offset=a, shape=shape)
        for a in range(0, len(thetas), 256)
    ]
    x = np.concatenate([p.x for p in parts])
    det = np.concatenate([p.det_jp for p in parts])
    assert all(p.swept == 256 for p in parts)
    whole = chunk.solve_chunk(model, home, thetas, offset=0, shape=shape)
    np.testing.assert_allclose(whole.x, x, rtol=0, atol=X_TOL)
    y1, c1 = model.chart.to_local(home.y)
    codes = tracker_library(model).sweep(y1, c1, home.theta, thetas, 0, shape, 1e-5).codes
    assert np.sum(codes == SWEEP_CONTINUED) == len(thetas) - 1  # the first point is direct
    rng = np.random.default_rng(5)
    for i in rng.choice(len(thetas), 40, replace=False):
        r = sc.solve(model, thetas[i], start=home, branch="convergent")
        assert r.status == "converged"
        np.testing.assert_allclose(x[i], r.x, rtol=0, atol=X_TOL)
        y_loc, c = model.chart.to_local(r.y)
        d = np.linalg.det(np.array(model.kernels.jac(y_loc, r.theta, c)[0]))
        np.testing.assert_allclose(det[i], d, rtol=1e-10)


def test_client_interrupt_resumes_identically(seed, serial_store, tmp_path):
    model, start = seed
    out = tmp_path / "interrupted.zarr"

    with pytest.raises(KeyboardInterrupt):
        sc.atlas(model, GRID, out, start=start, chunk=CHUNK, progress=False,
                 on_chunk=stop_after_two_chunks)  # fmt: skip
    assert open_atlas(out)["done"][:].tolist() == [1, 1, 0, 0, 0]
    seen = []
    run = sc.atlas(
        model,
        GRID,
        out,
        start=start,
        chunk=CHUNK,
        progress=False,
        on_chunk=lambda d, t: seen.append(d),
    )
    assert run.computed == 3 and seen[0] == 3 * CHUNK
    assert files(out) == files(serial_store)


def test_killed_cli_process_resumes_identically(serial_store, tmp_path):
    out = tmp_path / "killed.zarr"
    argv = ["atlas", str(MODELS / "planar_hexa"), "--grid", GRID, "--out", str(out),
            "--from-x", "0,0,0.4", "--chunk", str(CHUNK), "--no-progress"]  # fmt: skip
    proc = subprocess.Popen([sys.executable, "-m", "scdk_sym", *argv],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    markers = out / "done" / "c"

    def finished() -> int:  # chunks the store marks done (a marker file may be mid-write)
        if not (markers.exists() and any(markers.iterdir())):
            return 0
        try:
            return int(open_atlas(out)["done"][:].sum())
        except Exception:  # noqa: BLE001 - a chunk being written reads as anything
            return 0

    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            if finished() >= 1:
                break
            time.sleep(0.01)
        assert proc.poll() is None, "the run ended before it could be killed"
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    done = open_atlas(out)["done"][:]
    assert 1 <= done.sum() < len(done)
    assert cli_main(argv) == 0
    assert files(out) == files(serial_store)


def test_killed_worker_resumes_identically(seed, serial_store, client, tmp_path):
    model, start = seed
    out = tmp_path / "worker.zarr"
    pids = client.run(os.getpid)  # worker address -> process id
    killed = []

    def kill(done: int, total: int) -> None:
        if not killed:  # after the first chunk: a worker with a chunk in hand, if any
            busy = [w for w, tasks in client.processing().items() if tasks and w in pids]
            victim = busy[0] if busy else next(iter(pids))
            os.kill(pids[victim], signal.SIGKILL)
            killed.append(victim)

    # the lost tasks are retried elsewhere, or given up (AtlasError): the re-run completes
    with contextlib.suppress(AtlasError):
        sc.atlas(model, GRID, out, start=start, chunk=CHUNK, scheduler=client, progress=False,
                 on_chunk=kill)  # fmt: skip
    assert killed
    client.wait_for_workers(2, timeout=60)
    sc.atlas(model, GRID, out, start=start, chunk=CHUNK, scheduler=client, progress=False)
    assert files(out) == files(serial_store)


def test_store_of_another_run_is_refused(seed, serial_store, tmp_path):
    model, start = seed
    other_grid = GRID.replace(":4,", ":5,")
    with pytest.raises(StoreMismatchError, match="grid"):
        sc.atlas(model, other_grid, serial_store, start=start, chunk=CHUNK, progress=False)
    reduced = shipped("planar_hexa_reduced")
    with pytest.raises(StoreMismatchError, match="model"):
        sc.atlas(reduced, GRID, serial_store, chunk=CHUNK, progress=False)
    with pytest.raises(StoreMismatchError, match="start"):
        sc.atlas(model, GRID, serial_store, chunk=CHUNK, progress=False)  # from home
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "file.txt").write_text("not a store")
    with pytest.raises(AtlasError, match="not an atlas store"):
        sc.atlas(model, GRID, tmp_path / "junk", start=start, progress=False)
    assert (
        cli_main(
            [
                "atlas",
                str(MODELS / "planar_hexa"),
                "--grid",
                other_grid,
                "--out",
                str(serial_store),
                "--from-x",
                "0,0,0.4",
                "--no-progress",
            ]
        )
        == 1
    )


def test_grid_names_and_order(seed):
    model, start = seed
    g = make_grid(model, "theta_2=0:1:2,theta_1=5:7:3", start.theta)
    th = g.thetas(0, g.size)
    assert g.shape == (2, 3) and th.shape == (6, 3)
    np.testing.assert_array_equal(th[:, 1], [0, 0, 0, 1, 1, 1])
    np.testing.assert_array_equal(th[:, 0], [5, 6, 7, 5, 6, 7])
    np.testing.assert_array_equal(th[:, 2], start.theta[2])  # not named: the start's value
    np.testing.assert_array_equal(g.thetas(2, 5), th[2:5])
    with pytest.raises(UnknownNameError, match="theta_1, theta_2, theta_3"):
        make_grid(model, "theta_9=0:1:2", start.theta)
    assert set(STATUS) == {0, 1, 2, 3, 4, 5}


def test_plot_atlas(serial_store, tmp_path):
    image = pytest.importorskip("matplotlib.image")
    png = tmp_path / "atlas.png"
    assert (
        cli_main(
            [
                "plot-atlas",
                str(serial_store),
                "--out",
                str(png),
                "--axes",
                "theta_1,theta_2",
                "--at",
                "theta_3=-2.9",
            ]
        )
        == 0
    )
    rgb = image.imread(str(png))[:, :, :3]
    blue = np.array([0x4C, 0x9B, 0xE8]) / 255  # solved / det J_p > 0
    assert np.sum(np.max(np.abs(rgb - blue), axis=2) < 0.02) > 500


def test_modes_counted_and_method_recorded(seed, tmp_path):
    model, start = seed
    out = tmp_path / "modes.zarr"
    grid = "theta_1=1.3:1.3:1"  # one point: a mode search costs a second or more
    sc.atlas(model, grid, out, start=start, modes=True, progress=False)
    g = open_atlas(out)
    sols = [sc.assembly_modes(model, th, backend="compiled") for th in g["theta"][:]]
    assert all(s.certified for s in sols)
    assert g["n_modes"][:].tolist() == [len(s) for s in sols]
    assert g["status"][:].tolist() == [0] and len(sols[0]) >= 1
    assert "certified complete" in g.attrs["scdk_atlas"]["n_modes_method"]


def test_temporary_files_of_unfinished_writes_are_removed_on_resume(seed, serial_store, tmp_path):
    """A worker killed between Zarr's write of a chunk's temporary file and its rename leaves
    ``<key>.<hex>.partial`` in the store: the next run on the store deletes it (the store then
    equals a clean run's, file for file), and a finished run leaves none."""
    model, start = seed
    out = tmp_path / "partial.zarr"

    with pytest.raises(KeyboardInterrupt):
        sc.atlas(model, GRID, out, start=start, chunk=CHUNK, progress=False,
                 on_chunk=stop_after_two_chunks)  # fmt: skip
    stale = out / "theta" / "c" / "2" / "0.aade6aa5bba94838bed8755b29099be8.partial"
    stale.parent.mkdir(parents=True, exist_ok=True)
    stale.write_bytes(b"")
    sc.atlas(model, GRID, out, start=start, chunk=CHUNK, progress=False)
    assert not stale.exists()
    assert files(out) == files(serial_store)
    assert not list(serial_store.rglob("*.partial"))
