"""Command-line interface: ``scdk COMMAND ...`` (also ``python -m scdk_sym``).

One module per command group: :mod:`.common` (the registry of commands and the arguments and
output they share), :mod:`.solve`, :mod:`.codegen` (``cache``, ``codegen``), :mod:`.modes`,
:mod:`.track`, :mod:`.figures` (``plot``, ``view``), :mod:`.atlas` (``atlas``, ``plot-atlas``)
and :mod:`.verify`. Each imports its heavy dependencies only when its command runs.
"""

from __future__ import annotations

import argparse
import sys
import textwrap
from collections.abc import Sequence
from importlib import import_module

from ..errors import Interrupted, ScdkError
from ..interrupts import stop_on_signals
from .common import (
    COMMANDS,
    FROM_X_HELP,
    THETA_HELP,
    Command,
    HelpFormatter,
    add_backend_arg,
    add_model_args,
    backend_of,
    command,
    dump,
    floats,
    fmt,
    header,
    label,
    load,
    one_line,
    start_configuration,
    theta_line,
)
from .track import read_thetas

#: The command modules, in the order ``scdk --help`` lists their commands (each registers its
#: commands in :data:`COMMANDS` when imported).
COMMAND_MODULES = (
    "info",
    "solve",
    "codegen",
    "modes",
    "track",
    "figures",
    "atlas",
    "verify",
    "assemble",
    "transmission",
)
for _module in COMMAND_MODULES:
    import_module(f"{__name__}.{_module}")

__all__ = [
    "COMMANDS",
    "Command",
    "EXIT_BROKEN_PIPE",
    "FROM_X_HELP",
    "HelpFormatter",
    "THETA_HELP",
    "add_backend_arg",
    "add_model_args",
    "backend_of",
    "build_parser",
    "command",
    "dump",
    "floats",
    "fmt",
    "header",
    "label",
    "load",
    "main",
    "one_line",
    "read_thetas",
    "start_configuration",
    "theta_line",
    "version",
]


def version() -> str:
    """The installed package's version (from its metadata)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as metadata_version

    try:
        return metadata_version("scdk_sym")
    except PackageNotFoundError:  # pragma: no cover - run from a source tree
        return "unknown (not installed)"


#: The ``scdk --help`` epilog: a first session.
EPILOG = """examples:
  scdk verify models/planar_hexa            # check a model against Pinocchio
  scdk solve models/planar_hexa --theta 1.292,-0.802,-2.896 --from-x 0,0,0.4 --branch both
  scdk modes models/planar_hexa --theta 1.292,-0.802,-2.896

'scdk COMMAND --help' describes a command; 'scdk COMMAND MODEL --help' states --theta and
--from-x in that model's joints, coordinates and units."""


def build_parser() -> argparse.ArgumentParser:
    """The ``scdk`` parser with one subparser per registered command."""
    parser = argparse.ArgumentParser(
        prog="scdk",
        description="Singularity-consistent direct kinematics of parallel robots: the pose of a\n"
        "closed-chain mechanism from its actuated joint values, also through singularities.",
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"scdk_sym {version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def group(item: tuple[str, Command]) -> int:  # the commands in their modules' order
        return COMMAND_MODULES.index(item[1].run.__module__.rsplit(".", 1)[-1])

    for name, cmd in sorted(COMMANDS.items(), key=group):
        p = sub.add_parser(
            name,
            help=cmd.help,
            description=textwrap.fill(cmd.help[0].upper() + cmd.help[1:] + ".", width=80),
            epilog=f"example:\n  {cmd.example}",
            formatter_class=HelpFormatter,
        )
        cmd.arguments(p)
        p.set_defaults(run=cmd.run)
    return parser


def _help_in_model_units(parser: argparse.ArgumentParser, argv: list[str]) -> None:
    """For ``scdk COMMAND MODEL --help``: state ``--theta`` and ``--from-x`` in that model's
    names and units (the generic help stays when the model cannot be loaded)."""
    if not {"-h", "--help"} & set(argv):
        return
    words = [a for a in argv if not a.startswith("-")]
    if len(words) < 2 or words[0] not in COMMANDS:
        return
    from ..robot import load_model

    try:
        model = load_model(words[1])
    except ScdkError:
        return
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    units = model.units
    joints = ", ".join(f"{a} [{units[a]}]" for a in model.actuated)
    coords = ", ".join(f"{w} [{units[w]}]" for w in model.workspace)
    for action in sub.choices[words[0]]._actions:
        if action.dest in ("theta", "thetas"):
            action.help = f"{action.help}; this model: {joints}"
        elif action.dest == "from_x":
            action.help = f"start pose (default: home); this model: {coords}"


#: Exit code after the reader of the output went away (128 + SIGPIPE, as Unix tools report).
EXIT_BROKEN_PIPE = 141


#: Exit codes after SIGINT and SIGTERM stopped a command (128 + the signal's number).
EXIT_SIGNAL = {"SIGINT": 130, "SIGTERM": 143}


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 error of the package, 2 usage, 141 when the
    reader of the output closed it early, e.g. ``| head``, which ends the command quietly;
    130 and 143 after SIGINT and SIGTERM, which stop any command within about a second with
    one line saying what was kept, see :mod:`scdk_sym.interrupts`)."""
    parser = build_parser()
    _help_in_model_units(parser, sys.argv[1:] if argv is None else list(argv))
    args = parser.parse_args(argv)
    try:
        with stop_on_signals():
            code = int(args.run(args))
        sys.stdout.flush()
        return code
    except Interrupted as stop:
        print(f"scdk {args.command}: {stop}", file=sys.stderr)
        return EXIT_SIGNAL.get(stop.signal, 130)
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except ScdkError as exc:
        print(f"scdk {args.command}: error: {one_line(exc)}", file=sys.stderr)
        return 1


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush does not fail again."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # not a real file (e.g. captured)
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
