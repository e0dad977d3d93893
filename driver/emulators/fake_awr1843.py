"""A fake AWR1843 running the mmWave SDK 3.x demo firmware, seen from its CLI UART.

:class:`FakeAwr1843` serves the demo's command line on a real pseudo-terminal,
so a client opens it exactly like the XDS110's CLI port::

    with FakeAwr1843() as radar:
        port = serial.serial_for_url(radar.open_pty(), baudrate=115200, timeout=1)
        port.write(b"sensorStop\\n")
        port.read_until(PROMPT)
        # b'sensorStop\\nIgnored: Sensor is already stopped\\n\\rDone\\n\\rmmwDemo:/>'

Per received line (ended by ``\\n`` or ``\\r\\n``, in any chunking) it echoes
the line, prints its reply lines ending in ``\\n\\r`` and then the prompt, as
the real trace in protocol.md shows.  Configuration commands are checked
with the same argument counts and ranges as :mod:`radarodom.cfg_commands`;
``sensorStart`` builds a :class:`~radarodom.cfg.RadarConfig` from the stored
lines and hands it to :attr:`FakeAwr1843.on_sensor_start` (a fake DCA1000
uses it to stream frames of the right size).  :class:`CliFaults` injects the
failures users of real boards report: error replies, commands that hang until
a reset, a ``sensorStart`` that never answers, line noise, a slow UART and a
port that disappears.

This module holds what the firmware does with what it receives; the pty under it (opening
it, the serving thread, paced writes, closing) is :class:`~.awr1843_pty.Awr1843Pty`, which
:class:`FakeAwr1843` inherits, and what the firmware prints of itself is :mod:`.demo_cli_text`.
The demo's data port, its UART output of points and heatmaps on a second pty, is
:mod:`.fake_demo_uart` (it takes :attr:`FakeAwr1843.on_sensor_start` as a DCA1000 does).

Importing this module also registers the pyserial URL scheme
``fakeawr1843://`` (see :class:`~.awr1843_url.FakeAwr1843Serial`, exported here too).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from ... import cfg_commands as cc
from ...cfg import RadarConfig
from ...errors import ConfigError
from ..live.awr1843_protocol import (
    ALREADY_STARTED,
    ALREADY_STOPPED,
    DONE,
    FIRMWARE_EOL,
    FULL_CONFIG_NEEDED,
    NOT_ALLOWED_AFTER_START,
    NOT_RECOGNIZED,
    PROMPT,
    SKIPPED,
)
from .awr1843_pty import WRITE_TIMEOUT_S, Awr1843Pty  # noqa: F401 (WRITE_TIMEOUT_S re-exported: it was here)
from .awr1843_url import (  # noqa: F401 (URL_SCHEME, serial_class_for_url re-exported: they were here)
    _NAMED, URL_SCHEME, FakeAwr1843Serial, register_url_handler, serial_class_for_url)
from .demo_cli_text import (BOOT_BANNER, EXTRA_COMMANDS, INVALID_USAGE, RUNTIME_COMMANDS, SDK_VERSION, VERSION_LINES,
                            known_commands, usage)

log = logging.getLogger(__name__)

#: Sensor states ``queryDemoStatus`` reports (the SDK demo's enum).
_STATE_OPENED, _STATE_STARTED, _STATE_STOPPED = 1, 2, 3

#: Seconds from a reset (RESET_AR_DEV) to the boot banner, during which the radar answers
#: nothing and what it is sent is lost.  No TI document gives the xWR18xx's boot time from
#: flash; it lies between the 22 ms after nRESET at which TI's E2E forum has the AWR1642 start
#: reading its flash and the 1 s pyRadar waits after RESET_AR_DEV before talking to a CLI that
#: then answers.  A client that talks to it sooner sees its first command lost, as on a board.
BOOT_TIME_S = 0.5


@dataclass
class CliFaults:
    """Failures to inject; all off by default.  Change them at any time."""

    #: Command name -> N: the command answers ``Error <N>`` instead of Done (and has no effect).
    error_on: dict[str, int] = field(default_factory=dict)
    #: Command names that are echoed and then never answered: the CLI hangs until reset().
    silent_on: set[str] = field(default_factory=set)
    #: sensorStart is echoed and then never answered until reset() (like an invalid chirp timing).
    hang_on_start: bool = False
    #: Bytes sent before the echo of every reply (line noise, a stale boot message).
    garbage: bytes = b""
    #: When this command arrives, the pty master is closed at once (the USB cable is pulled).
    disappear_on: str | None = None
    #: Delay after each byte sent, s (a slow UART; exercises a client's framing).
    char_delay_s: float = 0.0


class FakeAwr1843(Awr1843Pty):
    """The demo firmware's CLI on a pseudo-terminal (:class:`~.awr1843_pty.Awr1843Pty`).

    State (read it from any thread): :attr:`started`, :attr:`config` (the
    last started :class:`RadarConfig`, None until the first start and after
    :meth:`reset`), :attr:`received` (every line received, decoded, without
    its line end), :attr:`faults`.  Callbacks (run on the serving thread,
    before the reply's ``Done`` is sent): :attr:`on_sensor_start` ``(config)``
    and :attr:`on_sensor_stop` ``()``.
    """

    def __init__(
        self,
        faults: CliFaults | None = None,
        *,
        on_sensor_start: Callable[[RadarConfig], None] | None = None,
        on_sensor_stop: Callable[[], None] | None = None,
        name: str | None = None,
        boot_time_s: float = BOOT_TIME_S,
        expects_lvds: bool = True,
    ) -> None:
        super().__init__()  # the pty: path, disappeared and the fds, closed
        self.faults = faults if faults is not None else CliFaults()
        #: Whether a DCA1000 takes the raw ADC data (False: the demo's UART output is used).
        self.expects_lvds = expects_lvds
        #: Seconds a reset takes before the banner (:data:`BOOT_TIME_S`).
        self.boot_time_s = float(boot_time_s)
        self._booted_at = 0.0  # time.monotonic() a reset's boot ends
        self.on_sensor_start = on_sensor_start
        self.on_sensor_stop = on_sensor_stop
        self.started = False
        self.config: RadarConfig | None = None
        self.received: list[str] = []
        self.name = name
        self._stored: list[str] = []  # configuration lines accepted since boot / flushCfg
        self._ever_started = False
        self._hung = False
        self._inbuf = bytearray()
        self._lock = threading.RLock()  # firmware state
        if name is not None:
            _NAMED[name] = self

    # ---------------------------------------------------------------- reset
    def reset(self) -> None:
        """What the DCA1000's RESET_AR_DEV does: reboot the radar.

        Stops the sensor (calling :attr:`on_sensor_stop` if it ran), forgets
        the configuration and recovers from a hang at once; then boots for
        :attr:`boot_time_s`, answering nothing (what it is sent meanwhile is
        lost), and prints the boot banner and a prompt, unsolicited, like a
        real reset.  Returns at once.
        """
        with self._lock:
            was_started = self.started
            self.started = False
            self.config = None
            self._stored.clear()
            self._ever_started = False
            self._hung = False
            self._inbuf.clear()
            self._booted_at = time.monotonic() + self.boot_time_s
        log.info("fake AWR1843 reset%s; booting for %g s", " (sensor was running)" if was_started else "",
                 self.boot_time_s)
        if was_started:
            self._call(self.on_sensor_stop)
        timer = threading.Timer(self.boot_time_s, self._boot_done)
        timer.daemon = True
        timer.start()

    @property
    def booting(self) -> bool:
        """True while a reset's boot lasts (nothing is answered)."""
        return time.monotonic() < self._booted_at

    def _boot_done(self) -> None:
        with self._lock:
            self._inbuf.clear()  # what arrived during the boot is lost
        banner = "".join(ln + FIRMWARE_EOL for ln in ("", *BOOT_BANNER)).encode() + PROMPT
        self._send(banner, slow=False)

    # -------------------------------------------------------------- serving
    def _feed(self, data: bytes) -> None:
        """Cut *data* into lines and answer each complete one (nothing while booting)."""
        with self._lock:
            if self.booting:
                log.debug("fake AWR1843 is booting; %d bytes lost", len(data))
                return
            self._inbuf += data
        while True:
            with self._lock:
                at = self._inbuf.find(b"\n")
                if at < 0:
                    return
                raw = bytes(self._inbuf[:at])
                del self._inbuf[: at + 1]
            if raw.endswith(b"\r"):
                raw = raw[:-1]
            self._handle_line(raw)
            if self._disappeared:
                return

    def _handle_line(self, raw: bytes) -> None:
        text = raw.decode("ascii", errors="replace")
        self.received.append(text)
        with self._lock:
            if self._hung:
                log.debug("fake AWR1843 is hung; ignoring %r", text)
                return
        faults = self.faults
        tokens = text.split()
        if not tokens:  # an empty line: just the prompt again
            self._send(PROMPT)
            return
        name = tokens[0]
        if faults.disappear_on is not None and name == faults.disappear_on:
            log.info("fake AWR1843: %r arrived; the port disappears", name)
            self._disappear()
            return
        echo = faults.garbage + raw + b"\n"
        hang = name in faults.silent_on or (name == "sensorStart" and faults.hang_on_start)
        if hang:
            with self._lock:
                self._hung = True
            log.info("fake AWR1843 hangs on %r until reset()", text)
            self._send(echo)
            return
        if text.lstrip().startswith("%"):
            lines, after = [SKIPPED], None
        elif name in faults.error_on:
            lines, after = [f"Error {faults.error_on[name]}"], None
        else:
            lines, after = self._execute(name, tokens[1:])
        if after is not None:
            after()
        reply = echo + "".join(ln + FIRMWARE_EOL for ln in lines).encode() + PROMPT
        self._send(reply)

    # ------------------------------------------------------------- commands
    def _execute(self, name: str, args: list[str]) -> tuple[list[str], Callable[[], None] | None]:
        """The reply lines of command *name*, and a callback to run before sending them."""
        counts = EXTRA_COMMANDS.get(name) or cc.VERBATIM_COMMANDS.get(name)
        if counts is None and name not in cc.TYPED_COMMANDS:
            return [f"'{name}' {NOT_RECOGNIZED}"], None
        with self._lock:
            if self.started and name not in RUNTIME_COMMANDS:
                return [NOT_ALLOWED_AFTER_START, DONE], None
            problem = self._check_args(name, args, counts)
            if problem is not None:
                return [f"{INVALID_USAGE}: {problem}", "Error -1"], None
            if name == "sensorStop":
                return self._sensor_stop()
            if name == "sensorStart":
                return self._sensor_start(args)
            if name == "flushCfg":
                self._stored.clear()
                return [DONE], None
            if name == "version":
                return [*VERSION_LINES, DONE], None
            if name == "help":
                return [*self._help_lines(), DONE], None
            if name == "queryDemoStatus":
                state = (_STATE_STARTED if self.started
                         else _STATE_STOPPED if self._ever_started else _STATE_OPENED)
                return [f"Sensor State: {state}", "Data port baud rate: 921600", DONE], None
            self._store(name, args)
            return [DONE], None

    @staticmethod
    def _check_args(name: str, args: list[str], counts: tuple[int, ...] | None) -> str | None:
        """Why the arguments of *name* are refused, or None."""
        if name in cc.TYPED_COMMANDS:
            try:
                cc.parse_args(name, args)
            except ConfigError as exc:
                return f"{exc.field}: {exc.message}" if exc.field else exc.message
            return None
        if counts is not None and len(args) not in counts:
            return f"expected {' or '.join(map(str, counts))} arguments, got {len(args)}"
        return None

    def _store(self, name: str, args: list[str]) -> None:
        """Keep a configuration line; a repeated command replaces the earlier one,
        as the firmware overwrites its settings (chirpCfg adds a chirp)."""
        line = " ".join((name, *args))
        if name != "chirpCfg":
            key_field = {"cfarCfg": 1, "cfarFovCfg": 1}.get(name)  # procDirection token
            for i, old in enumerate(self._stored):
                old_tokens = old.split()
                if old_tokens[0] != name:
                    continue
                if key_field is None or (len(old_tokens) > key_field + 1 and len(args) > key_field
                                         and old_tokens[key_field + 1] == args[key_field]):
                    self._stored[i] = line
                    return
        self._stored.append(line)

    def _sensor_stop(self) -> tuple[list[str], Callable[[], None] | None]:
        if not self.started:
            return [ALREADY_STOPPED, DONE], None
        self.started = False
        log.info("fake AWR1843 sensor stopped")
        return [DONE], lambda: self._call(self.on_sensor_stop)

    def _sensor_start(self, args: list[str]) -> tuple[list[str], Callable[[], None] | None]:
        if self.started:
            return [ALREADY_STARTED, DONE], None
        reconfigure = not args or _atoi(args[0]) != 0
        if not reconfigure:
            if self.config is None:
                return [FULL_CONFIG_NEEDED, "Error -1"], None
            config = self.config
        elif not self._stored:  # nothing configured (or flushed): the board's own answer
            return [FULL_CONFIG_NEEDED, "Error -1"], None
        else:
            try:
                config = RadarConfig.from_text("".join(ln + "\n" for ln in self._stored),
                                               "fake-awr1843")
            except ConfigError as exc:
                log.info("fake AWR1843 refuses sensorStart: %s", exc)
                if not self._ever_started and exc.message.startswith("missing"):
                    return [FULL_CONFIG_NEEDED, "Error -1"], None
                return [f"Error: {exc}", "Error -1"], None
        self.started = True
        self._ever_started = True
        self.config = config
        if self.expects_lvds and not config.streams_raw_adc:
            log.warning("fake AWR1843 started without raw ADC on LVDS (lvdsStreamCfg); "
                        "a DCA1000 would receive no data")
        log.info("fake AWR1843 sensor started: %d bytes/frame every %g ms",
                 config.frame_bytes, config.frame.frame_period_ms)
        return [DONE], lambda: self._call(self.on_sensor_start, config)

    def _help_lines(self) -> list[str]:
        lines = ["help: Display the usage of the CLI commands"]
        lines += [f"{name}: {usage(name)}" for name in known_commands() if name != "help"]
        return lines

    @staticmethod
    def _call(callback: Callable | None, *args) -> None:
        if callback is None:
            return
        try:
            callback(*args)
        except Exception:  # a broken test double must not kill the firmware
            log.exception("fake AWR1843 callback %r failed", callback)

    # -------------------------------------------------------------- output
    def announce(self, line: str) -> None:
        """Print *line* unasked, as the firmware's CLI_write does (an exception report)."""
        self._send((line + FIRMWARE_EOL).encode(), slow=False)


def _atoi(token: str) -> int:
    """C atoi: leading integer digits, 0 when there are none."""
    digits = ""
    for i, ch in enumerate(token.strip()):
        if ch.isdigit() or (i == 0 and ch in "+-"):
            digits += ch
        else:
            break
    try:
        return int(digits)
    except ValueError:
        return 0


# fakeawr1843:// makes a FakeAwr1843 (awr1843_url.py serves the board but does not import it).
FakeAwr1843Serial.make_fake = FakeAwr1843
register_url_handler()


__all__ = ["BOOT_BANNER", "BOOT_TIME_S", "SDK_VERSION", "VERSION_LINES", "CliFaults", "FakeAwr1843",
           "FakeAwr1843Serial", "known_commands", "register_url_handler"]
