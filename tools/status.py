"""A live one-line status on a terminal, and periodic lines in a log.

On a terminal the line is redrawn in place a few times a second, and log
messages clear it before they print, so the two never mix.  When stderr is a
file or a pipe (systemd, CI), a plain line is written every few seconds.
"""

from __future__ import annotations

import logging
import sys
import time
from typing import TextIO


class StatusLine:
    def __init__(self, stream: TextIO | None = None, *, enabled: bool = True,
                 tty_period_s: float = 0.25, log_period_s: float = 10.0) -> None:
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.period = tty_period_s if self.tty else log_period_s
        # A log gets its first line one period in, when the rate means something.
        self._last = float("-inf") if self.tty else time.monotonic()
        self._shown = False

    def update(self, text: str, *, force: bool = False) -> None:
        """Show *text* unless the previous update was too recent."""
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._last < self.period:
            return
        self._last = now
        if self.tty:
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
