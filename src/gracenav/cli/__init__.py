"""The ``gracenav`` command line: a thin layer over the library.

Every error a user can cause is printed as one line, ``gracenav: error: ...``, and the
command exits with status 2 (status 1 for a fall of the simulated robot, a run whose
footprint touched an obstacle, or a failure of the machine, such as a full disk). Inputs
are checked before any heavy work; progress bars appear on a terminal only, on their own
line.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from collections.abc import Sequence
from typing import Any, NoReturn

from gracenav._util.io import note_signal, pending_signal
from gracenav.errors import GracenavError

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    """Argument parser whose errors are a single line."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"gracenav: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with all sub-commands."""
    from gracenav.cli import (
        campaign_cmd,
        palette_cmd,
        plot_cmd,
        ros_cmd,
        run_cmd,
        simulate_cmd,
    )

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
    campaign_cmd.register(sub)
    ros_cmd.register(sub)
    return parser


class _Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C: outputs being written are discarded."""


def _on_sigterm(signum: int, frame: Any) -> None:
    note_signal(signum)
    raise _Terminated()


def _on_sigint(signum: int, frame: Any) -> None:
    note_signal(signum)
    raise KeyboardInterrupt


def _quiet_interrupts(previous: Any) -> Any:
    """An unraisable hook that drops the KeyboardInterrupt of our signal handlers when
    Python ignores it (it ran in a callback: an import lock's, a weak reference's);
    :func:`note_signal` has recorded the signal and :func:`main` reports it. Left to
    the default hook, such an exception makes the interpreter kill itself with SIGINT
    at exit (status -2 instead of 130)."""

    def hook(unraisable: Any) -> None:
        if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
            return
        previous(unraisable)

    return hook


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    Errors a user can cause print one line ``gracenav: error: ...`` on standard error and
    return 2; a fall of the simulated robot prints ``gracenav: fell: ...`` and returns 1;
    SIGINT and SIGTERM stop the command, discard its unfinished outputs and return 130
    or 143.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    previous = previous_int = None
    note_signal(None)
    previous_hook = sys.unraisablehook
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
        previous_int = signal.signal(signal.SIGINT, _on_sigint)
        sys.unraisablehook = _quiet_interrupts(previous_hook)
    try:
        status: int = args.func(args)
        if pending_signal() is not None:  # its exception was swallowed on the way
            raise KeyboardInterrupt
    except GracenavError as exc:
        print(f"gracenav: error: {_one_line(str(exc))}", file=sys.stderr)
        return 2
    except _Terminated:
        print("gracenav: terminated; unfinished outputs discarded", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        if pending_signal() == signal.SIGTERM:
            print("gracenav: terminated; unfinished outputs discarded", file=sys.stderr)
            return 143
        print("gracenav: interrupted; unfinished outputs discarded", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `gracenav palette show | head -1`
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except MemoryError:
        print("gracenav: error: out of memory; use a smaller problem", file=sys.stderr)
        return 1
    except OSError as exc:
        where = f" {exc.filename}" if exc.filename else ""
        print(
            f"gracenav: error: cannot access{where}: {_one_line(exc.strerror or str(exc))}",
            file=sys.stderr,
        )
        return 1
    finally:
        sys.unraisablehook = previous_hook
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        if previous_int is not None:
            signal.signal(signal.SIGINT, previous_int)
    return status


def entry() -> None:
    """The ``gracenav`` command: :func:`main`, then exit with its status.

    After SIGINT or SIGTERM the process ends at once (``os._exit``, streams flushed):
    CPython kills itself with SIGINT at exit when the signal's KeyboardInterrupt passed
    through code run by ``exec`` (a dataclass being created while a module is imported),
    even though :func:`main` handled it, which would turn status 130 into −2.
    """
    import os

    status = main()
    if pending_signal() is not None:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    sys.exit(status)


if __name__ == "__main__":  # pragma: no cover
    entry()
