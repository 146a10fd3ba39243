"""Faults around an atlas run: SIGINT/SIGTERM stop it within 2 s, in-process or with two
workers, and the rerun resumes; a store has one writer (a second run refuses in one line or
waits, and the store equals one clean run; a stale lock is taken over)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest
from factories import MODELS

from scdk_sym.atlases.lock import lock_path, store_lock
from scdk_sym.atlases.store import done_mask
from scdk_sym.errors import StoreLockedError

pytest.importorskip("zarr")

#: 10^8 points around the paper's start: far more than a test can solve.
BIG = "theta_1=1.0:1.6:1000,theta_2=-1.1:-0.5:1000,theta_3=-3.0:-2.8:100"


#: 4,000 points: a run of a few seconds, long enough for a second run to meet its lock.
MID = "theta_1=1.0:1.6:40,theta_2=-1.1:-0.5:20,theta_3=-3.0:-2.8:5"


def _argv(out, grid: str = BIG, chunk: int = 64, *extra: str) -> list[str]:
    return ["atlas", str(MODELS / "planar_hexa"), "--grid", grid, "--out", str(out),
            "--from-x", "0,0,0.4", "--chunk", str(chunk), "--no-progress", *extra]  # fmt: skip


def _start(out, grid: str = BIG, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "scdk_sym", *_argv(out, grid, 64, *extra)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip


def _files(store) -> dict[str, bytes]:
    return {str(p.relative_to(store)): p.read_bytes()
            for p in sorted(store.rglob("*")) if p.is_file()}  # fmt: skip


def _done(out, chunks: int) -> int:
    try:
        return int(done_mask(out, chunks).sum())
    except OSError:
        return 0


@pytest.mark.parametrize(
    ("sig", "workers"), [(signal.SIGINT, None), (signal.SIGTERM, None), (signal.SIGINT, "2")]
)
def test_a_signal_stops_a_big_atlas_within_2s_and_the_rerun_resumes(tmp_path, sig, workers):
    out = tmp_path / "big.zarr"
    chunks = -(-(10**8) // 64)
    counts = []
    extra = () if workers is None else ("--workers", workers)
    for _ in range(2):
        proc = _start(out, BIG, *extra)
        try:
            deadline = time.monotonic() + 180
            while time.monotonic() < deadline and proc.poll() is None:
                if _done(out, chunks) >= (counts[-1] + 2 if counts else 2):
                    break
                time.sleep(0.02)
            assert proc.poll() is None, proc.communicate()[1][-2000:]
            proc.send_signal(sig)
            sent = time.monotonic()
            _, err = proc.communicate(timeout=30)
            took = time.monotonic() - sent
        finally:
            if proc.poll() is None:
                proc.kill()
        assert took < 2.0, took
        assert proc.returncode == 128 + sig, err
        assert "run the same command again to resume" in err and "Traceback" not in err
        assert not lock_path(out).exists()
        counts.append(_done(out, chunks))
    assert 2 <= counts[0] < counts[1] < chunks  # the rerun kept the first run's chunks


def test_two_runs_on_one_store_end_cleanly_and_the_store_equals_one_clean_run(tmp_path):
    out = tmp_path / "shared.zarr"
    first = _start(out, MID)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and first.poll() is None and not lock_path(out).exists():
            time.sleep(0.01)
        assert first.poll() is None, first.communicate()[1][-2000:]
        refused, waiting = _start(out, MID), _start(out, MID, "--wait")
        _, err = refused.communicate(timeout=120)
        assert first.poll() is None  # the refusal was met while the first run was writing
        assert refused.returncode == 1, err
        assert err.count("\n") == 1 and f"being written by process {first.pid} " in err, err
        assert "--wait" in err and "Traceback" not in err
        _, err_wait = waiting.communicate(timeout=300)
        _, err_first = first.communicate(timeout=300)
    finally:
        for proc in (first, refused, waiting):
            if proc.poll() is None:
                proc.kill()
    assert first.returncode == 0, err_first
    assert waiting.returncode == 0 and f"waiting for process {first.pid} " in err_wait, err_wait
    assert not lock_path(out).exists()
    clean = tmp_path / "clean.zarr"
    single = subprocess.run([sys.executable, "-m", "scdk_sym", *_argv(clean, MID)],
                            capture_output=True, text=True, timeout=300)  # fmt: skip
    assert single.returncode == 0, single.stderr
    assert _files(out) == _files(clean)  # byte for byte: no chunk written twice differently


def test_a_second_writer_refuses_in_one_line_and_a_stale_lock_is_taken_over(tmp_path, capsys):
    out = tmp_path / "s.zarr"
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from scdk_sym.atlases.lock import store_lock\n"
         f"with store_lock({str(out)!r}):\n    print('held', flush=True); time.sleep(60)"],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        with pytest.raises(StoreLockedError) as info, store_lock(out):
            pass
        assert f"process {holder.pid} " in str(info.value) and "\n" not in str(info.value)
        assert info.value.holder["pid"] == holder.pid
    finally:
        holder.kill()
        holder.wait()
    # killed while holding: its lock file stays, stale; the next writer takes it over
    assert json.loads(lock_path(out).read_text())["pid"] == holder.pid
    with store_lock(out) as previous:
        assert previous["pid"] == holder.pid
        assert json.loads(lock_path(out).read_text())["pid"] == os.getpid()
    assert "stale lock" in capsys.readouterr().err and not lock_path(out).exists()


def test_dask_loggers_with_their_own_level_are_quiet_while_a_cluster_closes():
    """Dask's configuration sets ``tornado.application`` to ERROR on its own: silencing the
    parent loggers alone let a stop print the traceback of Dask's cancelled future."""
    import logging

    pytest.importorskip("distributed")
    from scdk_sym.atlases.distributed import _quiet_distributed

    child = logging.getLogger("tornado.application")
    before = child.level
    child.setLevel(logging.ERROR)  # what Dask's configuration gives it
    try:
        with _quiet_distributed():
            assert not child.isEnabledFor(logging.ERROR)
            assert not logging.getLogger("distributed.client").isEnabledFor(logging.ERROR)
        assert child.level == logging.ERROR
    finally:
        child.setLevel(before)
