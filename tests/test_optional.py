"""Optional dependencies: a missing one raises the caller's error with the install command."""

from __future__ import annotations

import sys

import pytest

from scdk_sym.errors import AtlasError, PlotError, ScdkError
from scdk_sym.optional import require


def test_present_modules_are_imported_and_the_first_returned() -> None:
    mod = require(("json", "json.decoder"), needed_for="x", install="-", error=PlotError)
    assert mod is sys.modules["json"]


@pytest.mark.parametrize("error", [PlotError, AtlasError])
def test_a_missing_module_raises_the_given_error_naming_it_and_the_install(monkeypatch, error):
    monkeypatch.setitem(sys.modules, "zarr", None)  # import zarr -> ImportError
    with pytest.raises(error, match=r"zarr is not installed \(needed for the atlas\): pip x") as e:
        require(("json", "zarr"), needed_for="the atlas", install="pip x", error=error)
    assert isinstance(e.value, ScdkError)
    assert isinstance(e.value.__cause__, ImportError)
