"""Faults around an atlas run: SIGINT/SIGTERM stop it within 2 s and the rerun resumes;
a store has one writer (a second run refuses in one line, a stale lock is taken over)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest
from factories import MODELS

from scdk_sym.atlas.lock import lock_path, store_lock
from scdk_sym.atlas.store import done_mask
from scdk_sym.errors import StoreLockedError

pytest.importorskip("zarr")

#: 10^8 points around the paper's start: far more than a test can solve.
BIG = "theta_1=1.0:1.6:1000,theta_2=-1.1:-0.5:1000,theta_3=-3.0:-2.8:100"


def _start(out, chunk: int = 64) -> subprocess.Popen:
    argv = ["atlas", str(MODELS / "planar_hexa"), "--grid", BIG, "--out", str(out),
            "--from-x", "0,0,0.4", "--chunk", str(chunk), "--no-progress"]  # fmt: skip
    return subprocess.Popen([sys.executable, "-m", "scdk_sym", *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip


def _done(out, chunks: int) -> int:
    try:
        return int(done_mask(out, chunks).sum())
    except OSError:
        return 0


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_stops_a_big_in_process_atlas_within_2s_and_the_rerun_resumes(tmp_path, sig):
    out = tmp_path / "big.zarr"
    chunks = -(-(10**8) // 64)
    counts = []
    for _ in range(2):
        proc = _start(out)
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


def test_a_second_writer_refuses_in_one_line_and_a_stale_lock_is_taken_over(tmp_path, capsys):
    out = tmp_path / "s.zarr"
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from scdk_sym.atlas.lock import store_lock\n"
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
