"""What every command shares: the registry of commands, parsing of numbers, the model
arguments, the backend option and the text and JSON output."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .. import backends
from ..errors import InputError


@dataclass(frozen=True)
class Command:
    """One subcommand of ``scdk``.

    Attributes:
        help: one line saying what the command does (``scdk --help`` and the command's help).
        arguments: adds the command's options to its parser.
        run: runs the command on the parsed namespace; returns the exit code.
        example: one command line a newcomer can run (the help's epilog).
    """

    help: str
    arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]
    example: str


#: Subcommand name -> its :class:`Command`; filled by the command modules.
COMMANDS: dict[str, Command] = {}


def command(
    name: str, help: str, arguments: Callable[[argparse.ArgumentParser], None], example: str
):
    """Register a subcommand: the decorated function takes the parsed namespace, returns 0."""

    def deco(run: Callable[[argparse.Namespace], int]):
        COMMANDS[name] = Command(help, arguments, run, example)
        return run

    return deco


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Help with the epilog's example kept as written and every option's default stated
    (appended when its help does not state it already)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (
            action.option_strings
            and "default" not in text
            and default is not None
            and default is not False
            and default is not argparse.SUPPRESS
        ):
            text += " (default: %(default)s)"
        return text


def floats(text: str, what: str = "value") -> np.ndarray:
    """Parse 'a,b,c' into floats.

    Raises:
        InputError: a field is empty or not a number (the option and the text named).
    """
    fields = text.replace(" ", "").split(",")
    if any(f == "" for f in fields):
        hint = "; values are separated by commas" if ";" in text else ""
        raise InputError(
            f"{what}: empty value in {text!r} (field {fields.index('') + 1}); expected "
            f"comma-separated numbers such as 1.0,-2,3e-1{hint}"
        )
    try:
        values = [float(v) for v in fields]
    except ValueError as exc:
        hint = "; values are separated by commas" if ";" in text else ""
        raise InputError(f"{what}: expected comma-separated numbers, got {text!r}{hint}") from exc
    return np.array(values)


def fmt(values, digits: int = 6) -> str:
    """Format numbers for people (round-off below 1e-12 printed as 0)."""
    vals = [0.0 if abs(v) < 1e-12 else v for v in np.asarray(values, float).ravel()]
    return "[" + ", ".join(f"{v:.{digits}g}" for v in vals) + "]"


#: Help of ``--theta``: the units come from the model (``length_unit`` of its YAML).
THETA_HELP = (
    "actuated joint values, one per actuated joint in the model's order, in the model's units: "
    "rad for revolute joints, the model's length unit (robot.yaml length_unit, default m; "
    "planar_hexa: cm) for prismatic ones; the text output states each unit (write "
    "--theta=-1,2,3 when the first value is negative)"
)
#: Help of ``--from-x``.
FROM_X_HELP = (
    "start pose in workspace coordinates (default: home), lengths in the model's length unit, "
    "angles in rad"
)
#: Help of ``--thetas``.
THETAS_HELP = (
    "CSV file of joint readings: one row per sample, one comma-separated value per actuated "
    "joint (the model's units, as --theta); an optional first line names the joints"
)
#: How the help shows the values of ``--theta`` and ``--from-x``.
THETA_METAVAR = "T1,T2,..."
FROM_X_METAVAR = "X1,X2,..."


def add_backend_arg(p: argparse.ArgumentParser, function: str, default: str | None = None) -> None:
    """``--backend``: the names ``function`` offers, each with its line of the registry.

    Args:
        p: the subcommand's parser.
        function: a key of :data:`scdk_sym.backends.OFFERS`.
        default: how the default is stated when it is not ``DEFAULTS[function]`` (the option's
            default is then None and the command chooses).
    """
    p.add_argument(
        "--backend",
        default=None if default else backends.DEFAULTS[function],
        metavar="{" + ",".join(backends.offered(function)) + "}",
        help=backends.help_text(function, default),
    )


def backend_of(name: str, function: str) -> str:
    """The concrete backend ``function`` runs for ``--backend name`` (validated by the
    registry, ``auto`` resolved; a deprecated name noted on stderr).

    Raises:
        InputError: ``function`` does not offer ``name`` (the names it offers listed).
    """
    if name in backends.ALIASES:
        new = backends.ALIASES[name]
        print(f"note: --backend {name} is deprecated; use --backend {new}", file=sys.stderr)
        name = new
    return backends.resolve(name, function)


def add_model_args(p: argparse.ArgumentParser) -> None:
    """The model argument and the options every model command takes (``--frame``, ``-v``)."""
    p.add_argument(
        "model",
        help="model directory (robot.urdf + robot.yaml), its YAML file, or an MJCF .xml file",
    )
    p.add_argument(
        "--frame",
        metavar="LINK",
        help="link whose pose is reported (default: the YAML's platform)",
    )
    p.add_argument(
        "--inputs",
        metavar="J1,J2",
        help="joints given as theta instead of the model's actuated ones (motors plus "
        "measured springs, or output joints so that the motors become unknowns)",
    )
    p.add_argument(
        "--lock",
        metavar="J=V,...",
        help="joints held at values [rad or length unit] (an MJCF file's springs are held at "
        "springref unless named here or in --inputs)",
    )
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="print notes about the model on stderr (e.g. how its closure system was reduced)",
    )


def load(args: argparse.Namespace):
    """The model named on the command line (a note on its reduction with ``--verbose``)."""
    from ..robot import load_model

    inputs = getattr(args, "inputs", None)
    names = [n.strip() for n in inputs.split(",") if n.strip()] if inputs else None
    choices: dict = {"inputs": names, "locked": _locks(args)}
    model = load_model(args.model, frame=args.frame, **{k: v for k, v in choices.items() if v})
    if getattr(args, "verbose", False):
        held = ", ".join(f"{k} = {v:g}" for k, v in model.held.items())
        notes = [model.reduction, model.assembly, *getattr(model.source, "notes", ())]
        notes.append(f"joints held (springs at springref, --lock): {held}" if held else "")
        for note in filter(None, notes):
            print(f"note: {note}", file=sys.stderr)
    return model


def _locks(args: argparse.Namespace) -> dict[str, float] | None:
    """``--lock J=V,...`` as a mapping."""
    text = getattr(args, "lock", None)
    if not text:
        return None
    out = {}
    for item in text.split(","):
        name, eq, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            eq = ""
        if not eq or not name.strip():
            raise InputError(f"--lock: expected NAME=VALUE pairs separated by commas, got {item!r}")
    return out


def label(model) -> str:
    """The model's robot name, and its folder when that differs."""
    from pathlib import Path

    if model.path:
        folder = Path(model.path).absolute().parent.name
        if folder != model.name:
            return f"{model.name} ({folder})"
    return model.name


def header(model) -> str:
    """First line of the text output: the model, its workspace coordinates and their units."""
    units = model.units
    ws = ", ".join(model.workspace)
    unit_list = ", ".join(units[w] for w in model.workspace)
    return f"model {label(model)}: x = ({ws}) [{unit_list}] of {model.frame!r}"


def theta_line(model) -> str:
    """The actuated joints and their units."""
    return "theta = (" + ", ".join(f"{a} [{model.units[a]}]" for a in model.actuated) + ")"


def start_configuration(model, args: argparse.Namespace):
    """The start of the path: ``--from-x`` assembled by inverse kinematics, else home."""
    if getattr(args, "from_x", None):
        return model.inverse_kinematics(floats(args.from_x, "--from-x"))
    return model.home


def dump(obj) -> None:
    """Print ``obj`` as one line of JSON."""
    print(json.dumps(obj, default=float))


def one_line(exc: Exception) -> str:
    """The message of an exception on one line."""
    return " ".join(str(exc).split())
