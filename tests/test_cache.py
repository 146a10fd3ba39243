"""The disk cache survives what a real machine leaves in it.

A truncated or corrupted entry of every kind (kernel and follower libraries, the C tracker (with
the atlas sweep), the homotopy libraries, start systems) is rebuilt with one line on stderr,
and solve, track, modes and atlas give the same answers as on a clean cache. The runs are
subprocesses: a process never re-opens a shared library it has loaded once.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from factories import MODELS, needs_compiler

from scdk_sym.kernels.cache import (
    DIGEST_SUFFIX,
    cached_file,
    damage,
    digest_path,
    read_entry,
    write_entry,
)

#: Solve, track, modes and atlas of models/planar_3rpr with compiled backends; prints JSON.
SCRIPT = """
import json, sys
import casadi as ca
import numpy as np
import scdk_sym as sc
from scdk_sym.algebraic import krawczyk
from scdk_sym.atlases import open_atlas

m = sc.load_model(sys.argv[1])
t0 = np.asarray(m.home.theta)
r = sc.solve(m, t0 + 0.02, backend="compiled")
s = np.linspace(0.0, 1.0, 40)[:, None]
trk = sc.track(m, t0 + 0.03 * s, backend="c")
sols = sc.assembly_modes(m, t0 + 0.01, backend="compiled")
grid = {"leg_1": (t0[0] - 0.01, t0[0] + 0.01, 3), "leg_2": (t0[1] - 0.01, t0[1] + 0.01, 3)}
sc.atlas(m, grid, sys.argv[2], progress=False)
g = open_atlas(sys.argv[2])
x = ca.SX.sym("x", 2)
p = ca.SX.sym("p", 1)
f = ca.Function("f", [x, p], [ca.vertcat(x[0] ** 2 - p, x[1] * x[0] - 1)])
cert = krawczyk(f, [2**0.5, 2**-0.5], [2.0])  # a rational system: the C interval test
print(json.dumps({
    "solve": list(map(float, r.x)),
    "track": np.asarray(trk.x).tolist(),
    "modes": sorted(np.round(np.asarray(c.x, dtype=float), 9).tolist() for c in sols),
    "certified": bool(sols.certified),
    "atlas": np.asarray(g["x"][:]).tolist(),
    "krawczyk": [bool(cert.proven), np.asarray(cert.box).tolist()],
}))
"""

#: Every kind of cached artefact the script above leaves (name prefixes in the cache).
KINDS = ("compiled_", "tracker_", "algebraic_G_", "continuation_", "krawczyk_",
         "homotopy/")  # fmt: skip


def _run(cache: Path, out: Path) -> tuple[dict, str]:
    env = {**os.environ, "SCDK_CACHE_DIR": str(cache), "OMP_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(MODELS / "planar_3rpr"), str(out)],
        capture_output=True, text=True, env=env, timeout=900,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1]), done.stderr


def _entries(cache: Path) -> list[Path]:
    return sorted(p for p in cache.rglob("*") if p.is_file() and not p.name.endswith(DIGEST_SUFFIX))


@pytest.fixture(scope="module")
def clean_cache(tmp_path_factory) -> tuple[Path, dict]:
    """A cache filled by one clean run of the script, and that run's answers (each fault's
    test damages a copy)."""
    root = tmp_path_factory.mktemp("clean")
    answers, _ = _run(root / "cache", root / "a.zarr")
    return root / "cache", answers


@needs_compiler()
@pytest.mark.parametrize("fault", ["truncate", "corrupt"])
def test_damaged_entries_of_every_kind_are_rebuilt_and_answers_unchanged(
    tmp_path, fault, clean_cache
):
    cache = tmp_path / "cache"
    shutil.copytree(clean_cache[0], cache)
    clean = clean_cache[1]
    entries = _entries(cache)
    names = [p.relative_to(cache).as_posix() for p in entries]
    for kind in KINDS:
        assert any(n.startswith(kind) for n in names), (kind, names)
    rng = np.random.default_rng(3)
    for p in entries:
        data = bytearray(p.read_bytes())
        if fault == "truncate":
            data = data[: len(data) // 3]
        else:
            at = rng.integers(0, len(data), size=16)
            for i in at:
                data[i] ^= 0xFF
        p.write_bytes(bytes(data))
    again, err = _run(cache, tmp_path / "b.zarr")
    assert again == clean
    notices = [line for line in err.splitlines() if line.startswith("scdk_sym cache: ")]
    named = sorted(n for n in names if any(f" {n.split('/')[-1]} is " in x for x in notices))
    assert len(notices) == len(entries) and named == sorted(names), err
    assert all(damage(p) is None for p in _entries(cache))
    assert "Traceback" not in err


# ---------------------------------------------------------------- the entry primitives


def test_an_entry_is_sealed_and_a_foreign_or_unsealed_file_is_rebuilt(tmp_path, capsys):
    target = tmp_path / "thing.bin"
    calls: list[Path] = []

    def build(path: Path) -> None:
        calls.append(path)
        path.write_bytes(b"payload")

    assert cached_file(target, build, "test entry") == target
    assert target.read_bytes() == b"payload" and damage(target) is None
    assert calls[0] != target  # written beside it, then renamed
    cached_file(target, build, "test entry")
    assert len(calls) == 1 and capsys.readouterr().err == ""
    target.write_bytes(b"foreign")  # same length or not, another content
    cached_file(target, build, "test entry")
    assert len(calls) == 2 and target.read_bytes() == b"payload"
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "thing.bin is damaged" in err
    digest_path(target).unlink()
    cached_file(target, build, "test entry")
    assert len(calls) == 3 and "unsealed" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thing.bin", "thing.bin.sha256"]


def test_a_failed_build_leaves_no_entry_and_no_partial_file(tmp_path):
    target = tmp_path / "lib.so"

    def build(path: Path) -> None:
        path.write_bytes(b"half")
        raise RuntimeError("compiler killed")

    with pytest.raises(RuntimeError, match="compiler killed"):
        write_entry(target, build)
    assert list(tmp_path.iterdir()) == []


def test_an_unreadable_entry_is_dropped_with_one_line(tmp_path, capsys):
    target = tmp_path / "start.npz"
    write_entry(target, lambda p: p.write_bytes(b"not an npz"))

    def read(path: Path):
        with np.load(path) as f:
            return f["p"]

    assert read_entry(target, read, "start system") is None
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "start.npz is unreadable" in err
    assert not target.exists() and not digest_path(target).exists()
    assert read_entry(target, read, "start system") is None  # missing: silent
    assert capsys.readouterr().err == ""
