"""A live one-line status on a terminal, and periodic lines in a log.

On a terminal the line is redrawn in place a few times a second, and log
messages clear it before they print, so the two never mix.  When stderr is a
file or a pipe (systemd, CI), a plain line is written every few seconds.
"""

from __future__ import annotations

import logging
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass
from typing import Sequence, TextIO


class StatusLine:
    def __init__(self, stream: TextIO | None = None, *, enabled: bool = True,
                 tty_period_s: float = 0.25, log_period_s: float = 10.0) -> None:
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.period = tty_period_s if self.tty else log_period_s
        # A log gets its first line one period after the first update (the first frame), when the
        # rate means something: opening a source or a view may take longer than a period.
        self._last: float | None = float("-inf") if self.tty else None
        self._shown = False

    @property
    def columns(self) -> int | None:
        """The terminal's width in columns, None when the stream is no terminal (a log gets
        whole lines)."""
        return terminal_columns(self.stream) if self.tty else None

    def update(self, text: str | Sequence["Field"], *, force: bool = False) -> None:
        """Show *text* (or the :class:`Field` s that fit the terminal, :func:`fit_fields`)
        unless the previous update was too recent.  On a terminal the line is cut to its
        width, so that it never wraps."""
        if not self.enabled:
            return
        now = time.monotonic()
        if self._last is None:
            self._last = now
        if not force and now - self._last < self.period:
            return
        self._last = now
        columns = self.columns
        if not isinstance(text, str):
            text = fit_fields(text, columns)
        if self.tty:
            if columns is not None and len(text) >= columns:
                text = text[:max(columns - 1, 0)]
            self.stream.write("\r" + text + "\x1b[K")
            self._shown = True
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def clear(self) -> None:
        """Erase the line (before other output, and at the end)."""
        if self._shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._shown = False


def terminal_columns(stream: TextIO) -> int:
    """The width of the terminal *stream* is on: ``$COLUMNS`` when set, else the stream's own
    terminal (stderr may be a terminal when stdout is not), else what
    :func:`shutil.get_terminal_size` says (80 by default)."""
    fallback = shutil.get_terminal_size()
    if "COLUMNS" in os.environ and fallback.columns > 0:
        return fallback.columns
    try:
        columns = os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, ValueError, OSError):
        columns = 0
    return columns if columns > 0 else fallback.columns


class StatusAwareHandler(logging.StreamHandler):
    """A stderr handler that erases the status line before each record."""

    def __init__(self, status: StatusLine) -> None:
        super().__init__(status.stream)
        self.status = status

    def emit(self, record: logging.LogRecord) -> None:
        self.status.clear()
        super().emit(record)


def format_duration(seconds: float) -> str:
    seconds = max(0.0, seconds)
    minutes, sec = divmod(seconds, 60)
    hours, minutes = divmod(int(minutes), 60)
    return f"{hours:d}:{minutes:02d}:{sec:04.1f}" if hours else f"{minutes:02d}:{sec:04.1f}"


@dataclass(frozen=True)
class Field:
    """One field of a status line: its text, a shorter form for narrow terminals (None: the
    same), and how important it is (1 most; the least important go first)."""

    text: str
    short: str | None = None
    priority: int = 1


SEPARATOR = "  "


def fit_fields(fields: Sequence[Field], width: int | None) -> str:
    """The fields joined, fitted into *width* columns less one (the last column would wrap
    the line on some terminals): every field's short form, then, from the most important
    (the earlier of equal importance first), each field that still fits; the most important
    one alone is cut to fit.  *width* None (a log, not a terminal): every field in full."""
    full = SEPARATOR.join(f.text for f in fields)
    if width is None:
        return full
    room = max(width - 1, 0)
    if len(full) <= room or not fields:
        return full[:room]
    texts = [f.text if f.short is None else f.short for f in fields]
    order = sorted(range(len(fields)), key=lambda i: (fields[i].priority, i))
    kept = {order[0]}
    for i in order[1:]:
        if len(SEPARATOR.join(texts[j] for j in sorted(kept | {i}))) <= room:
            kept.add(i)
    return SEPARATOR.join(texts[j] for j in sorted(kept))[:room]


def wrap_degrees(degrees: float) -> float:
    """An angle in degrees wrapped to (-180, 180]."""
    wrapped = math.remainder(degrees, 360.0)
    return 180.0 if wrapped == -180.0 else wrapped + 0.0  # + 0.0: no "-0.0"


def format_yaw(yaw_rad: float, decimals: int = 1) -> str:
    """"-90.0 deg (turned 270)": the heading wrapped to (-180, 180], and the total turned
    (unwrapped, whole degrees) beside it when the two differ."""
    turned = math.degrees(yaw_rad)
    wrapped = wrap_degrees(turned)
    text = f"{wrapped:.{decimals}f} deg"
    if round(turned, decimals) != round(wrapped, decimals):
        text += f" (turned {turned:.0f})"
    return text
