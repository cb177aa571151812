"""The ``gracenav`` command line: a thin layer over the library.

Every error a user can cause is printed as one line, ``gracenav: error: ...``,
and the command exits with status 2 (status 1 for an unexpected failure).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import NoReturn

from gracenav.errors import GracenavError

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    """Argument parser whose errors are a single line."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with all sub-commands."""
    from gracenav.cli import palette_cmd, plot_cmd, run_cmd, simulate_cmd

    parser = _Parser(
        prog="gracenav",
        description=(
            "Graceful navigation of balancing mobile robots (the ballbot): "
            "models, controllers, motion policies, planning and simulation."
        ),
    )
    from gracenav import __version__

    parser.add_argument("--version", action="version", version=f"gracenav {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    run_cmd.register(sub)
    simulate_cmd.register(sub)
    palette_cmd.register(sub)
    plot_cmd.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        status: int = args.func(args)
    except GracenavError as exc:
        message = " ".join(str(exc).split())  # always one line
        print(f"gracenav: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("gracenav: interrupted", file=sys.stderr)
        return 130
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
