"""A live one-line status on a terminal, and periodic lines in a log.

On a terminal the line is redrawn in place a few times a second, and log
messages clear it before they print, so the two never mix.  When stderr is a
file or a pipe (systemd, CI), a plain line is written every few seconds.
"""

from __future__ import annotations

import collections
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


class RateMeter:
    """Events per second over a sliding window of wall time."""

    def __init__(self, window_s: float = 2.0) -> None:
        self.window = window_s
        self._times: collections.deque[float] = collections.deque()

    def tick(self, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        self._times.append(now)
        while self._times and now - self._times[0] > self.window:
            self._times.popleft()

    @property
    def rate_hz(self) -> float:
        if len(self._times) < 2:
            return 0.0
        span = self._times[-1] - self._times[0]
        return (len(self._times) - 1) / span if span > 0 else 0.0


def format_duration(seconds: float) -> str:
    seconds = max(0.0, seconds)
    minutes, sec = divmod(seconds, 60)
    hours, minutes = divmod(int(minutes), 60)
    return f"{hours:d}:{minutes:02d}:{sec:04.1f}" if hours else f"{minutes:02d}:{sec:04.1f}"


class LatencyMeter:
    """Recent latencies (s) and their percentiles, over the last *size* samples."""

    def __init__(self, size: int = 300) -> None:
        self._values: collections.deque[float] = collections.deque(maxlen=size)
        self.count = 0

    def add(self, seconds: float) -> None:
        self._values.append(seconds)
        self.count += 1

    def percentiles_ms(self, *qs: float) -> tuple[float, ...]:
        """The *qs* percentiles (0-100) of the recent latencies, ms; NaN when there are none."""
        if not self._values:
            return tuple(float("nan") for _ in qs)
        values = sorted(self._values)
        last = len(values) - 1
        return tuple(1e3 * values[min(last, int(round(q / 100.0 * last)))] for q in qs)
