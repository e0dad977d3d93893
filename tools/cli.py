"""What every radarodom command-line program shares: ``--verbose``/``--quiet``,
logging to stderr, and the one place where exceptions become exit codes.

Exit codes: 0 success; 2 usage or configuration error (argparse, ConfigError,
UsageError, SourceError); 1 any other failure; 130 interrupted before a clean
stop was possible.  One line on stderr says what went wrong; the traceback
only with ``--verbose``.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import logging
import math
import os
import re
import signal
import sys
import traceback
from typing import Any, Callable, Iterator, Sequence

from ..errors import RadarodomError, UsageError, one_line, quoted
from ..mount import Mount, parse_mount
from ..plain_numbers import MAX_WHOLE_OPTION, plain_float, plain_int, whole_beyond
from .output_paths import (  # noqa: F401  (the programs' output checks, re-exported: cli.check_distinct)
    check_distinct, check_files_in_directories, check_new_outputs, check_new_path, check_room,
    check_writable_directory, missing_directories, read_paths, write_output)
from .standard_output import StdoutFailed, flush_stdout, stdout_failure, watched_stdout
from .status import StatusAwareHandler, StatusLine


class _Formatter(logging.Formatter):
    def __init__(self, prog: str, verbose: bool) -> None:
        super().__init__()
        self.prog = prog
        self.verbose = verbose

    def format(self, record: logging.LogRecord) -> str:
        where = f" [{record.name}]" if self.verbose else ""
        return f"{self.prog}: {record.levelname.lower()}{where}: {one_line(record.getMessage())}"


#: Largest number a float option takes unless it says otherwise: far beyond any duration in
#: seconds or distance in metres, and small enough that arithmetic on it stays finite.
MAX_FLOAT_OPTION = 1e9


def int_in(lo: int, hi: int = MAX_WHOLE_OPTION, what: str = "a whole number") -> Callable[[str], int]:
    """argparse type: a whole number (ASCII digits) in lo..hi; the error names the range."""
    def parse(text: str) -> int:
        value = plain_int(text)  # numbers as in a cfg: plain ASCII decimal
        if value is None or not lo <= value <= hi:
            too_large = whole_beyond(text, hi)
            span = f"in {lo}..{hi}" if hi < MAX_WHOLE_OPTION or too_large else f">= {lo}"
            raise argparse.ArgumentTypeError(f"expected {what} {span}, got {quoted(text)}")
        return value
    parse.__name__ = f"int_in_{lo}_{hi}"
    parse.bounds = (lo, hi, False)  # type: ignore[attr-defined]  # for tests and help texts
    return parse


def float_in(lo: float, hi: float = MAX_FLOAT_OPTION, *, lo_open: bool = False, unit: str = "",
             what: str = "a number") -> Callable[[str], float]:
    """argparse type: a finite decimal number in lo..hi (above lo when *lo_open*); the error
    names the range and unit."""
    def parse(text: str) -> float:
        value = plain_float(text)
        value = math.nan if value is None else value
        if not (lo < value <= hi if lo_open else lo <= value <= hi):
            span = f"> {lo:g} and <= {hi:g}" if lo_open else f"in {lo:g}..{hi:g}"
            units = f" {unit}" if unit else ""
            raise argparse.ArgumentTypeError(f"expected {what} {span}{units}, got {quoted(text)}")
        return value
    parse.__name__ = f"float_in_{lo:g}_{hi:g}"
    parse.bounds = (lo, hi, lo_open)  # type: ignore[attr-defined]
    return parse


#: argparse type: a whole number >= 1 (counts of frames or messages).
positive_int = int_in(1)
#: argparse type: a whole number >= 0 (seeds).
non_negative_int = int_in(0)
#: argparse type: a finite number > 0 and at most MAX_FLOAT_OPTION (seconds, metres).
positive_float = float_in(0.0, lo_open=True)
#: argparse type: a probability, 0..1.
probability = float_in(0.0, 1.0, what="a probability")
#: argparse type: a UDP port number (0: a free one).
port = int_in(0, 65535, what="a UDP port number")
#: argparse type: an angle off boresight, degrees (> 0, at most 90).
boresight_angle = float_in(0.0, 90.0, lo_open=True, unit="degrees")
#: argparse type: a ROS 2 domain id (0..232, as ROS 2 allows).
ros2_domain = int_in(0, 232, what="a ROS 2 domain id")


def mount(text: str) -> Mount:
    """argparse type: where the radar sits on the robot, ``x,y,z,yaw_deg`` (:func:`parse_mount`)."""
    try:
        return parse_mount(text)
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


#: Four numbers, not one: the numeric options' fuzz test (tests/test_fuzz_cli_options.py) leaves
#: it to radarodom.mount's own tests.
mount.not_a_number = True  # type: ignore[attr-defined]


def add_overwrite(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing output file, or an output directory radarodom wrote "
                             "(only its own files in it are removed)")


def add_verbosity(parser: argparse.ArgumentParser) -> None:
    """-v/--verbose, -q/--quiet, and --version (every program has them)."""
    from .. import __version__

    parser.add_argument("--version", action="version", version=f"radarodom {__version__}",
                        help="print radarodom's version and exit")
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


def _attach_negative_lists(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``--mount -0.3,0,0,0`` as ``--mount=-0.3,0,0,0``: argparse takes a value starting with a
    dash for an option unless it is a single negative number, and a radar behind the axle has a
    negative x."""
    lists = {name for action in parser._actions if action.type is mount for name in action.option_strings}
    out: list[str] = []
    i = 0
    while i < len(argv):
        if argv[i] in lists and i + 1 < len(argv) and re.fullmatch(r"-\.?\d[0-9.,eE+-]*", argv[i + 1]):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


#: Actions an option may be given more than once for: a flag, a count, a list.
_REPEATABLE = (argparse._StoreConstAction, argparse._AppendAction, argparse._AppendConstAction, argparse._CountAction,
               argparse._HelpAction, argparse._VersionAction)
#: Characters of a repeated option's value quoted (a path whole, as typed).
_QUOTED_VALUE = 300
#: The namespace attribute that holds, while argv is parsed, what each option given once was given.
_GIVEN = "_radarodom_given_once"


@functools.cache
def _once(base: type) -> type:
    """*base* (an argparse action class) refusing its option a second time: the later value would
    silently replace the earlier (``--odom-out a.tum --odom-out b.tum`` writes b.tum alone)."""

    class Once(base):  # type: ignore[misc, valid-type]
        def __call__(self, parser, namespace, values, option_string=None) -> None:
            given = namespace.__dict__.setdefault(_GIVEN, {})
            if self.dest in given:
                first, name = given[self.dest]
                parser.error(f"argument {option_string}: given twice ({name} {first}, then "
                             f"{quoted(values, _QUOTED_VALUE)}): give it once")
            given[self.dest] = (quoted(values, _QUOTED_VALUE), option_string)
            super().__call__(parser, namespace, values, option_string)

    Once.__name__ = Once.__qualname__ = f"Once{base.__name__}"
    Once.given_once = True
    return Once


def _refuse_repeats(parser: argparse.ArgumentParser) -> None:
    """Options that take one value refuse a second (every action but flags, counts and lists)."""
    for action in parser._actions:
        if action.option_strings and not isinstance(action, _REPEATABLE) and not getattr(action, "given_once", False):
            action.__class__ = _once(type(action))


def _refuse_empty_values(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """An empty argument (``--record "$OUT"`` with OUT unset) is a usage error, not "no output":
    no option or argument of radarodom's programs takes an empty string."""
    for action in parser._actions:
        value = getattr(args, action.dest, None) if action.dest != argparse.SUPPRESS else None
        values = value if isinstance(value, list) else [value]
        if any(isinstance(v, str) and not v.strip() for v in values):
            name = "/".join(action.option_strings) or action.metavar or action.dest
            parser.error(f"argument {name}: empty value (an unset shell variable?)")


def _say(text: str) -> None:
    """One line on stderr; one that cannot be written (2>/dev/full) is lost, and the exit code
    still says what happened (it was 1 for every failure, a traceback's)."""
    try:
        print(text, file=sys.stderr)
    except OSError:
        pass


@contextlib.contextmanager
def _stderr_for_the_run() -> Iterator[None]:
    """A program started with stderr closed (2>&-: Python's ``sys.stderr`` is None) says nothing:
    ``print(file=None)`` would put its messages on stdout, among what the program prints there."""
    if sys.stderr is not None:
        yield
        return
    with open(os.devnull, "w") as nowhere:
        sys.stderr = nowhere
        try:
            yield
        finally:
            sys.stderr = None


def run(
    main: Callable[[argparse.Namespace], int | None],
    parser: argparse.ArgumentParser,
    argv: Sequence[str] | None = None,
    *,
    handler: logging.Handler | None = None,
) -> int:
    """Parse *argv*, run *main*, and turn what it raises into an exit code."""
    with _stderr_for_the_run(), watched_stdout():
        try:
            return _run(main, parser, argv, handler)
        except StdoutFailed as failed:  # what is printed goes to a full disk: said, not a bug
            _say(stdout_failure(parser.prog, failed))
            return 1


def _run(main: Callable[[argparse.Namespace], int | None], parser: argparse.ArgumentParser,
         argv: Sequence[str] | None, handler: logging.Handler | None) -> int:
    parser.error = _option_error(parser)  # type: ignore[method-assign]
    try:
        _refuse_repeats(parser)
        args = parser.parse_args(_attach_negative_lists(parser, sys.argv[1:] if argv is None else list(argv)))
        vars(args).pop(_GIVEN, None)
        _refuse_empty_values(parser, args)
    except SystemExit as exc:  # argparse: --help (0) or a usage error (2)
        flush_stdout()
        return int(exc.code or 0)
    prog = parser.prog
    setup_logging(prog, args, handler)
    verbose = getattr(args, "verbose", False)
    try:
        with _sigterm_interrupts():
            status = int(main(args) or 0)
            flush_stdout()
            return status
    except StdoutFailed:
        raise
    except _Terminated as exc:  # a service manager's stop: what Ctrl-C does (the radar stopped), then 143
        _say(f"{prog}: terminated")
        _print_notes(prog, exc)
        return 128 + signal.SIGTERM
    except RadarodomError as exc:
        if handler is not None:
            handler.flush()
        _say(f"{prog}: error: {one_line(str(exc))}")
        _print_notes(prog, exc)
        if verbose:
            traceback.print_exc()
        return exc.exit_code
    except KeyboardInterrupt as exc:
        _say(f"{prog}: interrupted")
        _print_notes(prog, exc)
        return 130
    except BrokenPipeError:
        return 1
    except Exception as exc:
        if _interrupted(exc):  # a Ctrl-C that Python wrapped (raised in a class being made)
            _say(f"{prog}: interrupted")
            _print_notes(prog, exc)
            return 130
        # A bug: say so in one line, details on request.
        _say(f"{prog}: internal error: {type(exc).__name__}: {one_line(str(exc))}"
             + ("" if verbose else " (run with --verbose for the traceback)"))
        _print_notes(prog, exc)
        if verbose:
            traceback.print_exc()
        return 1


def _interrupted(exc: BaseException) -> bool:
    """Whether *exc* was caused by a Ctrl-C: Python wraps one raised while a class is made (a lazy
    import's, in ``__set_name__``) in a RuntimeError."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _option_error(parser: argparse.ArgumentParser) -> Callable[[str], None]:
    """argparse's error, but one line for an option's bad value ("argument --mount: ..."): the
    usage above it (a dozen lines) is for a command line of the wrong shape (a missing or an
    unknown argument), where it helps."""
    usage_error = parser.error

    def error(message: str) -> None:
        if not message.startswith("argument "):
            usage_error(one_line(message))
        parser.exit(2, f"{parser.prog}: error: {one_line(message)}\n")
    return error


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is, so that its cleanup runs as for Ctrl-C."""


def _raise_terminated(signum, frame) -> None:
    raise _Terminated()


@contextlib.contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """SIGTERM raises :class:`_Terminated` while the block runs (a program streaming installs
    its own stop handler, :func:`on_stop_signals`, and this one is back after it).  SIGINT
    inherited ignored (a program a script started with ``&``) raises KeyboardInterrupt too: the
    streaming handler takes it anyway, and ``kill -INT`` ignored until then looked like a hang."""
    try:
        previous = signal.signal(signal.SIGTERM, _raise_terminated)
    except ValueError:  # not the main thread (a program run from a test's or a notebook's thread)
        yield
        return
    ignored = signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    if ignored:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
        if ignored:
            signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextlib.contextmanager
def on_stop_signals(handler: Callable[[int, Any], None]) -> Iterator[None]:
    """*handler* for SIGINT (Ctrl-C) and SIGTERM while the block runs; the previous handlers after."""
    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _print_notes(prog: str, exc: BaseException) -> None:
    """What failed after *exc* (closing the outputs: errors.add_note), a warning line each."""
    for note in getattr(exc, "__notes__", ()):
        _say(f"{prog}: warning: {one_line(str(note))}")


def run_with_status(
    main: Callable[[argparse.Namespace, StatusLine], int | None],
    parser: argparse.ArgumentParser,
    argv: Sequence[str] | None = None,
) -> int:
    """:func:`run` for programs with a live status line on stderr; log records
    erase the line before they print."""
    with _stderr_for_the_run():
        status = StatusLine(sys.stderr)
        return run(lambda args: main(args, status), parser, argv, handler=StatusAwareHandler(status))
