"""JSON Schema (draft 2020-12) of every ``scdk ... --json`` output, shipped with the package.

The file ``scdk.schema.json`` next to this module defines one record shape per idea (a
configuration, a singular crossing, a solution, a failed branch) and one definition per
command output under ``$defs``: ``solve``, ``solve-both`` (``solve --branch both``),
``modes``, ``track``, ``atlas`` (the run's summary), ``codegen`` and ``verify``. Validate with any
draft 2020-12 validator, e.g. ``jsonschema.validate(record, command_schema("track"))``.
"""

from __future__ import annotations

import json
from functools import cache
from importlib.resources import files

from ..errors import InputError

#: File name of the schema inside this package.
SCHEMA_FILE = "scdk.schema.json"

#: The command outputs the schema defines (keys of its ``$defs``).
OUTPUTS = ("solve", "solve-both", "modes", "track", "atlas", "codegen", "verify")


@cache
def _text() -> str:
    return files(__package__).joinpath(SCHEMA_FILE).read_text(encoding="utf-8")


def load_schema() -> dict:
    """The whole schema (a new dict on each call): any ``--json`` output validates against it."""
    return json.loads(_text())


def command_schema(output: str) -> dict:
    """The schema of one command's ``--json`` output (the whole file, rooted at its definition).

    Args:
        output: one of :data:`OUTPUTS` (``"solve-both"`` for ``solve --branch both``).

    Raises:
        InputError: ``output`` is not one of :data:`OUTPUTS` (they are listed).
    """
    if output not in OUTPUTS:
        raise InputError(f"no schema for output {output!r}; outputs: {', '.join(OUTPUTS)}")
    schema = load_schema()
    schema.pop("anyOf")
    schema["$ref"] = f"#/$defs/{output}"
    return schema
