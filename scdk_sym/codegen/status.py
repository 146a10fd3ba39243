"""The status codes of the generated C tracker, stated once.

:class:`TrackerStatus` is the one table of the codes every entry point of the tracker returns:
their values, their messages (``<prefix>_status_string`` in C, :data:`STATUS` in Python) and
the one-line meanings written next to the ``#define`` of each in the generated header.
:class:`SweepCode` is the table of the codes of a point of ``<prefix>_sweep``. The generators
write the C from them (:func:`template_values` for the tracker, :func:`transmission_defines`
for the transmission's header, which adds its own :data:`TRANSMISSION_ERR_SINGULAR`): the
templates hold placeholders, never the values or the messages themselves.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Mapping

#: The longest line written into the generated C by :func:`c_cases`.
LINE_LENGTH = 100


class TrackerStatus(enum.IntEnum):
    """Status of an entry point of the generated tracker: >= 0 success, < 0 an error.

    Each member is an ``int`` (the C value of ``<PREFIX>_<name>``) with two texts:
    ``message``, what ``<prefix>_status_string`` returns for it, and ``meaning``, the comment
    of its ``#define`` in the header.
    """

    message: str
    meaning: str

    def __new__(cls, value: int, message: str, meaning: str) -> TrackerStatus:
        member = int.__new__(cls, value)
        member._value_ = value
        member.message = message
        member.meaning = meaning
        return member

    OK = 0, "ok", "continued along the solution curve (cheap step)"
    OK_PATH = (
        1,
        "ok (followed the singularity-consistent curve)",
        "followed the singularity-consistent curve (fold, jump)",
    )
    OK_PREDICTED = (
        2,
        "ok (corrected from the predicted motion)",
        "corrected from the predicted motion (near a fold)",
    )
    ERR_NULL = -1, "a required pointer is NULL", "a required pointer is NULL"
    ERR_SIZE = (
        -2,
        "an array size does not match the model",
        "an array size does not match the model",
    )
    ERR_NONFINITE = -3, "an input is NaN or infinite", "an input is NaN or infinite"
    ERR_NOT_ASSEMBLED = (
        -4,
        "the start configuration violates the closures",
        "the start configuration violates the closures",
    )
    ERR_NO_SOLUTION = (
        -5,
        "the solution curve did not reach theta within budget",
        "the curve did not reach the new theta within budget",
    )
    ERR_VERIFY = (
        -6,
        "the solution failed its residual check",
        "the solution failed its residual check",
    )
    ERR_STATE = (
        -7,
        "the tracker state is not initialised",
        "the tracker state is not initialised (or not computed)",
    )
    ERR_OPTIONS = -8, "an option is out of range", "an option is out of range"
    ERR_UNDECIDABLE = (
        -9,
        "the readings are too coarse to decide between two candidate solutions",
        "readings too coarse to decide between two candidates (R4)",
    )
    ERR_SINGULAR_PATH = (
        -10,
        "the path met a singular point before the solution (not solved in C)",
        "solve: the path met a singular point (not solved)",
    )


class SweepCode(enum.IntEnum):
    """Code of a solved point of ``<prefix>_sweep`` (a :class:`TrackerStatus` error
    otherwise); ``meaning`` is the comment of its ``#define`` in the header."""

    meaning: str

    def __new__(cls, value: int, meaning: str) -> SweepCode:
        member = int.__new__(cls, value)
        member._value_ = value
        member.meaning = meaning
        return member

    CONTINUED = 0, "continued from its neighbour"
    DIRECT = 1, "solved from the start ({p}_solve_convergent)"


#: The transmission's own code (``<PREFIX>_ERR_SINGULAR`` of the generated
#: ``<prefix>_transmission.h``), after the tracker's: the map is singular where asked.
TRANSMISSION_ERR_SINGULAR = -11

#: The comments of the tracker's codes in ``<prefix>_transmission.h``, where its functions
#: return them (``{p}``: the transmission's prefix).
TRANSMISSION_MEANINGS: dict[TrackerStatus, str] = {
    TrackerStatus.OK: "success (forward, inverse: a cheap continuation step)",
    TrackerStatus.OK_PATH: "forward, inverse: followed the singularity-consistent curve",
    TrackerStatus.OK_PREDICTED: "forward, inverse: corrected from the predicted motion",
    TrackerStatus.ERR_SIZE: "an array size does not match",
    TrackerStatus.ERR_NO_SOLUTION: "the solution curve did not reach the reading",
    TrackerStatus.ERR_STATE: "not initialised ({p}_transmission_init)",
    TrackerStatus.ERR_OPTIONS: "a tracker option is out of range",
    TrackerStatus.ERR_UNDECIDABLE: "readings too coarse to decide between two candidates",
    TrackerStatus.ERR_SINGULAR_PATH: "(not returned by these functions)",
}

#: The messages of the tracker's codes, by value (``<prefix>_status_string``).
STATUS: dict[int, str] = {int(code): code.message for code in TrackerStatus}


def c_defines(macro_prefix: str, codes: Iterable[tuple[str, int, str]]) -> str:
    """``#define`` lines of codes, their comments aligned.

    Args:
        macro_prefix: the upper-case C prefix (``SCDK``): the macros are
            ``<macro_prefix>_<name>``.
        codes: (name, value, one-line meaning) of each, in order.

    Returns:
        The lines, each ending with a newline but the last; a negative value in parentheses.
    """
    heads = [
        (f"#define {macro_prefix}_{name} {value if value >= 0 else f'({value})'}", meaning)
        for name, value, meaning in codes
    ]
    width = max(len(head) for head, _ in heads) + 1
    return "\n".join(f"{head:<{width}}/* {meaning} */" for head, meaning in heads)


def _tracker_codes(
    prefix: str, meanings: Mapping[TrackerStatus, str]
) -> list[tuple[str, int, str]]:
    """(name, value, meaning) of each tracker code, a meaning of ``meanings`` replacing the
    code's own (``{p}`` in it stands for ``prefix``)."""
    return [
        (code.name, int(code), meanings.get(code, code.meaning).format(p=prefix))
        for code in TrackerStatus
    ]


def status_defines(prefix: str) -> str:
    """The ``#define`` lines of the tracker's codes (:class:`TrackerStatus`) for the C prefix
    ``prefix`` (``<PREFIX>_OK``, ...)."""
    return c_defines(prefix.upper(), _tracker_codes(prefix, {}))


def transmission_defines(prefix: str) -> str:
    """The ``#define`` lines of the codes of ``<prefix>_transmission.h``: the tracker's, with
    :data:`TRANSMISSION_MEANINGS`, and its own :data:`TRANSMISSION_ERR_SINGULAR`."""
    singular = (
        "ERR_SINGULAR",
        TRANSMISSION_ERR_SINGULAR,
        "the map is singular here: margin <= SINGULAR_MARGIN",
    )
    codes = [*_tracker_codes(prefix, TRANSMISSION_MEANINGS), singular]
    return c_defines(prefix.upper(), codes)


def sweep_defines(prefix: str) -> str:
    """The ``#define`` lines of the codes of a point of the sweep (:class:`SweepCode`)."""
    return c_defines(
        f"{prefix.upper()}_SWEEP",
        [(code.name, int(code), code.meaning.format(p=prefix)) for code in SweepCode],
    )


def c_cases(macro_prefix: str, indent: str = "    ") -> str:
    """The ``case`` lines of a C ``switch`` returning the message of each tracker code (the
    body of ``<prefix>_status_string``); a case longer than :data:`LINE_LENGTH` returns on a
    line of its own."""
    lines = []
    for code in TrackerStatus:
        label = f"{indent}case {macro_prefix}_{code.name}:"
        ret = f'return "{code.message}";'
        one = f"{label} {ret}"
        lines.append(one if len(one) <= LINE_LENGTH else f"{label}\n{indent * 2}{ret}")
    return "\n".join(lines)


def template_values(prefix: str) -> dict[str, str]:
    """The placeholders of the tracker's templates that state the codes, for the C prefix
    ``prefix``: ``STATUS_DEFINES`` and ``SWEEP_DEFINES`` (the header), ``STATUS_CASES`` (the
    ``switch`` of ``<prefix>_status_string``)."""
    return {
        "STATUS_DEFINES": status_defines(prefix),
        "SWEEP_DEFINES": sweep_defines(prefix),
        "STATUS_CASES": c_cases(prefix.upper()),
    }
