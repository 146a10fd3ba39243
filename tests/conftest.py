"""Test session setup: a private cache of compiled kernels for the whole run.

Every test (and every ``scdk`` subprocess a test starts) sees ``SCDK_CACHE_DIR`` pointing at one
temporary folder of this session: compiled kernels are reused within a run and nothing is
written to the user's cache (``~/.cache/scdk_sym``).
"""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session", autouse=True)
def private_cache(tmp_path_factory: pytest.TempPathFactory):
    """``SCDK_CACHE_DIR`` set to a temporary folder of the session (yielded)."""
    folder = tmp_path_factory.mktemp("scdk_cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SCDK_CACHE_DIR", str(folder))
        mp.setenv("XDG_CACHE_HOME", str(folder.parent / "xdg_cache"))
        yield folder
