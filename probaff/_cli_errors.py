"""One way for every command-line entry point to report a user error: one line, exit status 2.

`probaff.cli` and the study scripts in ``inference/`` share it, so a bad flag never prints a
traceback. Errors probaff raises on purpose (`probaff.errors.ProbaffError`) name the argument
and the fix; argparse reports its own errors and exits 2 by itself. Anything else is a bug and
keeps its traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

from probaff._checks import check_output_dir
from probaff.errors import ProbaffError

__all__ = ["check_output_flags", "report_error", "run_cli"]

EXIT_USER_ERROR = 2


class _MalformedError(Exception):
    """A command line `check_output_flags` leaves to the script's own parser."""


class _QuietParser(argparse.ArgumentParser):
    """A parser that raises instead of printing usage and exiting."""

    def error(self, message: str) -> NoReturn:
        raise _MalformedError(message)


def report_error(prog: str, exc: BaseException) -> int:
    """Print ``PROG: error: MESSAGE`` as one line on stderr.

    Args:
        prog: The command as the user typed it (e.g. ``"probaff generate"``).
        exc: The error; its message's line breaks are folded into spaces.

    Returns:
        The exit status for a user error, 2 (as argparse uses).
    """
    message = " ".join(str(exc).split()) or type(exc).__name__
    print(f"{prog}: error: {message}", file=sys.stderr)
    return EXIT_USER_ERROR


def check_output_flags(flags: Sequence[str], argv: Sequence[str] | None = None) -> None:
    """Check the output folders given on a command line before any work starts.

    A study writes its first file only after minutes of work; an output path under a regular
    file (``--out /etc/passwd/x``) must fail at once. Only flags present on the command line
    are checked (a script's default folder is its own business).

    Args:
        flags: Option names holding an output folder, e.g. ``("--out",)``.
        argv: The arguments; defaults to ``sys.argv[1:]``.

    Raises:
        InputError: Naming the flag, for a path that cannot become a folder (see
            `probaff._checks.check_output_dir`).
    """
    parser = _QuietParser(add_help=False)
    for flag in flags:
        parser.add_argument(flag, action="append", default=[])
    try:
        known, _ = parser.parse_known_args(sys.argv[1:] if argv is None else list(argv))
    except _MalformedError:
        return  # e.g. ``--out`` without a value: the script's own parser reports it
    for flag in flags:
        for value in getattr(known, flag.lstrip("-").replace("-", "_")):
            check_output_dir(flag, value)


def run_cli(
    main: Callable[[], Any], prog: str | None = None, output_flags: Sequence[str] = ("--out",)
) -> int:
    """Run a script's `main`, turning a `ProbaffError` into one line and exit status 2.

    Use as ``sys.exit(run_cli(main))`` under ``if __name__ == "__main__":``.

    Args:
        main: The script's entry point (it parses ``sys.argv`` itself).
        prog: Name for the message; defaults to the script's file name.
        output_flags: Options naming output folders, checked by `check_output_flags` before
            `main` runs.

    Returns:
        0 on success (or `main`'s own integer status), 2 for a probaff error.
    """
    try:
        check_output_flags(output_flags)
        status = main()
    except ProbaffError as exc:
        return report_error(prog or Path(sys.argv[0]).name, exc)
    return status if isinstance(status, int) and not isinstance(status, bool) else 0
