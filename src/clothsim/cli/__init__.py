"""The ``clothsim`` command: parses arguments and wires the library together.

One module per subcommand (``simulate``, ``render``, ``sweep``, ``view``,
``scenes``), each with ``add_parser(sub)`` and ``run(args)``; what they share
(the scene options, value parsers, progress bar and summary) is in
:mod:`clothsim.cli.common`. Building the parser imports no numba, numpy or GL
library, so ``clothsim --help`` and ``--version`` answer at once; each
``run`` imports what its work needs.

Every :class:`~clothsim.errors.ClothsimError` becomes one line on stderr
and exit code 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from .. import __version__
from ..errors import ClothsimError
from . import render, scenes, simulate, sweep, view

SUBCOMMANDS = (simulate, render, sweep, view, scenes)
"""in the order ``--help`` lists them"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="clothsim", description="Mass-spring cloth simulator with GLSL rendering.")
    parser.add_argument("--version", action="version", version=f"clothsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in SUBCOMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ClothsimError as exc:
        print(f"clothsim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("clothsim: interrupted", file=sys.stderr)
        return 130
    except SystemError as exc:
        # an interrupt that lands while numba loads or calls compiled code comes
        # back as a SystemError whose cause is the KeyboardInterrupt
        if not _interrupted(exc):
            raise
        print("clothsim: interrupted", file=sys.stderr)
        return 130


def _interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` was caused, at any depth, by a KeyboardInterrupt."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


__all__ = ["build_parser", "main"]
