"""What every radarodom command-line program shares: ``--verbose``/``--quiet``,
logging to stderr, and the one place where exceptions become exit codes.

Exit codes: 0 success; 2 usage or configuration error (argparse, ConfigError,
UsageError, SourceError); 1 any other failure; 130 interrupted before a clean
stop was possible.  One line on stderr says what went wrong; the traceback
only with ``--verbose``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import traceback
from typing import Callable, Sequence

from ..errors import RadarodomError
from .status import StatusAwareHandler, StatusLine


class _Formatter(logging.Formatter):
    def __init__(self, prog: str, verbose: bool) -> None:
        super().__init__()
        self.prog = prog
        self.verbose = verbose

    def format(self, record: logging.LogRecord) -> str:
        where = f" [{record.name}]" if self.verbose else ""
        return f"{self.prog}: {record.levelname.lower()}{where}: {record.getMessage()}"


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    return _whole(text, 1)


def non_negative_int(text: str) -> int:
    """argparse type: a whole number >= 0."""
    return _whole(text, 0)


def _whole(text: str, minimum: int) -> int:
    try:
        value = int(text)
    except ValueError:
        value = minimum - 1
    if value < minimum:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum}, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0 (seconds, rates)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def check_new_path(path: str, *, is_dir: bool = False) -> None:
    """Refuse an output that exists (a file; a directory is checked by its writer) or cannot be
    created (no parent directory): radarodom never overwrites what a user has."""
    import os

    from ..errors import CaptureError, CaptureExistsError

    if not is_dir and os.path.exists(path):
        raise CaptureExistsError(f"{path} already exists; choose a new file")
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        raise CaptureError(f"cannot create {path}: no directory {parent}")


def add_verbosity(parser: argparse.ArgumentParser) -> None:
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-v", "--verbose", action="store_true",
                       help="debug messages, and a traceback on errors")
    group.add_argument("-q", "--quiet", action="store_true",
                       help="only errors and the final summary")


def setup_logging(prog: str, args: argparse.Namespace,
                  handler: logging.Handler | None = None) -> logging.Handler:
    """Send the ``radarodom`` logger's records to stderr for a CLI run."""
    handler = handler or logging.StreamHandler(sys.stderr)
    handler.setFormatter(_Formatter(prog, getattr(args, "verbose", False)))
    logger = logging.getLogger("radarodom")
    for old in [h for h in logger.handlers if getattr(h, "_radarodom_cli", False)]:
        logger.removeHandler(old)
    handler._radarodom_cli = True  # type: ignore[attr-defined]
    logger.addHandler(handler)
    if getattr(args, "verbose", False):
        logger.setLevel(logging.DEBUG)
    elif getattr(args, "quiet", False):
        logger.setLevel(logging.ERROR)
    else:
        logger.setLevel(logging.WARNING)
    return handler


def run(
    main: Callable[[argparse.Namespace], int | None],
    parser: argparse.ArgumentParser,
    argv: Sequence[str] | None = None,
    *,
    handler: logging.Handler | None = None,
) -> int:
    """Parse *argv*, run *main*, and turn what it raises into an exit code."""
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help (0) or a usage error (2)
        return int(exc.code or 0)
    prog = parser.prog
    setup_logging(prog, args, handler)
    verbose = getattr(args, "verbose", False)
    try:
        return int(main(args) or 0)
    except RadarodomError as exc:
        if handler is not None:
            handler.flush()
        print(f"{prog}: error: {exc}", file=sys.stderr)
        if verbose:
            traceback.print_exc()
        return exc.exit_code
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 1
    except Exception as exc:  # a bug: say so in one line, details on request
        print(f"{prog}: internal error: {type(exc).__name__}: {exc}"
              + ("" if verbose else " (run with --verbose for the traceback)"), file=sys.stderr)
        if verbose:
            traceback.print_exc()
        return 1


def run_with_status(
    main: Callable[[argparse.Namespace, StatusLine], int | None],
    parser: argparse.ArgumentParser,
    argv: Sequence[str] | None = None,
) -> int:
    """:func:`run` for programs with a live status line on stderr; log records
    erase the line before they print."""
    status = StatusLine(sys.stderr)
    return run(lambda args: main(args, status), parser, argv, handler=StatusAwareHandler(status))
