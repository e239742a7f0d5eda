"""The ``clothsim`` command: parses arguments and wires the library together.

One module per subcommand (``simulate``, ``render``, ``sweep``, ``view``,
``scenes``), each with ``add_parser(sub)`` and ``run(args)``; what they share
(the scene options, value parsers, progress bar and summary) is in
:mod:`clothsim.cli.common`. Building the parser imports no numba, numpy or GL
library, so ``clothsim --help`` and ``--version`` answer at once; each
``run`` imports what its work needs.

Every :class:`~clothsim.errors.ClothsimError` becomes one line on stderr
and exit code 2 (argparse's own usage errors too, see :class:`Parser`);
every :class:`~clothsim.errors.SceneWarning` one line
``clothsim: warning: ...`` on stderr, each time it is raised.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Sequence

from .. import __version__
from ..errors import ClothsimError, SceneWarning, UsageError
from . import render, scenes, simulate, sweep, view
from .stopping import EXIT_CODES, Terminated, handling_stops, stopped_by

SUBCOMMANDS = (simulate, render, sweep, view, scenes)
"""in the order ``--help`` lists them"""


class Parser(argparse.ArgumentParser):
    """argparse's own usage errors (an unknown option, a missing argument, a bad
    choice) as a :class:`~clothsim.errors.UsageError`: one line naming the
    subcommand and where its help is, instead of the usage block. Subparsers
    are made of the same class (argparse's default); ``--help`` is untouched."""

    def error(self, message: str):
        raise UsageError(_usage_message(self.prog, message))

    def parse_args(self, args=None, namespace=None):
        """as argparse's, but arguments left over name the subcommand they came after"""
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            command = getattr(parsed, "command", None)
            prog = f"{self.prog} {command}" if command else self.prog
            raise UsageError(_usage_message(prog, f"unrecognized arguments: {' '.join(extras)}"))
        return parsed


def _usage_message(prog: str, message: str) -> str:
    command = prog.partition(" ")[2]
    return f"{command + ': ' if command else ''}{message} (see '{prog} --help')"


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="clothsim", description="Mass-spring cloth simulator with GLSL rendering.")
    parser.add_argument("--version", action="version", version=f"clothsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in SUBCOMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    try:
        # the stops are handled from the start: a Ctrl-C while the arguments are
        # parsed ends the run like one later; a value parser and Parser.error raise
        # UsageError, one line like every other error
        with handling_stops(), warnings.catch_warnings():  # restores the filters and showwarning on the way out
            args = build_parser().parse_args(argv)
            warnings.simplefilter("always", SceneWarning)
            warnings.showwarning = _one_line(warnings.showwarning)
            return args.func(args)
    except ClothsimError as exc:
        print(error_line(exc), file=sys.stderr)
        return 2
    except (KeyboardInterrupt, Terminated, SystemError) as exc:
        stop = stopped_by(exc)
        if stop is None:
            raise
        print("clothsim: interrupted", file=sys.stderr)
        return EXIT_CODES[stop]


def _one_line(show):
    """``warnings.showwarning`` that prints a SceneWarning as one line and leaves the others to ``show``."""
    def showwarning(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, SceneWarning):
            print(f"clothsim: warning: {printable(str(message))}", file=sys.stderr, flush=True)
        else:
            show(message, category, filename, lineno, file, line)
    return showwarning


def printable(text: str) -> str:
    """``text`` with every character that is not printable (a newline, a form feed,
    a control character in a key from the scene) shown as its escape, so that a
    message is one line on any terminal."""
    return "".join(ch if ch.isprintable() else ascii(ch)[1:-1] for ch in text)


def error_line(exc: BaseException) -> str:
    """``clothsim: error: MESSAGE`` on one line (see :func:`printable`)."""
    return f"clothsim: error: {printable(str(exc))}"


__all__ = ["build_parser", "main"]
