"""Test session setup: a private cache of compiled kernels for the whole run.

From the start of the session (before any test module is imported), ``SCDK_CACHE_DIR`` (and
``XDG_CACHE_HOME``) point at one temporary folder of this run: every test, and every ``scdk``
process a test starts, reuses the kernels compiled earlier in the run, and nothing is written
to the user's cache (``~/.cache/scdk_sym``). The folder is removed at the end of the run.

Tests marked ``@pytest.mark.slow`` (minutes each) run only with ``SCDK_SLOW=1``, the suite's
one switch for them.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

_SAVED: dict[str, str | None] = {}
_FOLDER: list[Path] = []


#: Environment variable that turns on the tests marked ``slow``.
SLOW_SWITCH = "SCDK_SLOW"


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", f"slow: runs only with {SLOW_SWITCH}=1 (minutes)")
    folder = Path(tempfile.mkdtemp(prefix="scdk_test_cache_"))
    _FOLDER.append(folder)
    for name, value in (
        ("SCDK_CACHE_DIR", folder / "scdk_sym"),
        ("XDG_CACHE_HOME", folder / "xdg"),
    ):
        _SAVED[name] = os.environ.get(name)
        os.environ[name] = str(value)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if os.environ.get(SLOW_SWITCH) == "1":
        return
    skip = pytest.mark.skip(reason=f"slow: set {SLOW_SWITCH}=1 to run it")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


def pytest_unconfigure(config: pytest.Config) -> None:
    for name, value in _SAVED.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value
    for folder in _FOLDER:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="session")
def private_cache() -> Path:
    """The session's kernel cache folder (``$SCDK_CACHE_DIR``)."""
    return _FOLDER[0] / "scdk_sym"
