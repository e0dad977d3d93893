"""The AWR1843's command line (SDK demo firmware) over its UART, via pyserial.

:class:`Awr1843Cli` opens the port with ``serial.serial_for_url`` (so a
device path, ``loop://``, ``socket://`` and ptys all work), sends each
command, and reads the echo and the reply up to the prompt
(:mod:`.awr1843_protocol`).  An error reply or a timeout raises an error that
names the cfg line and quotes the radar.  :meth:`Awr1843Cli.configure` sends
``sensorStop`` and ``flushCfg`` first, then every command of the cfg.
"""

from __future__ import annotations

import logging
import os
import time

import serial

from ...cfg import RadarConfig
from ...errors import DeviceError, DeviceTimeout, RadarCommandError, SourceError
from .awr1843_protocol import (CLI_BAUDRATE, REPEATABLE, Outcome, Reply, ReplyFramer, classify,
                               is_boot_banner, split_lines)

log = logging.getLogger(__name__)

#: Seconds to wait for an ordinary command's reply.
COMMAND_TIMEOUT_S = 2.0
#: Seconds to wait for sensorStart: the firmware calibrates before it answers.
START_TIMEOUT_S = 5.0


class SensorStartHung(DeviceTimeout):
    """sensorStart got no answer: the radar hung (typically an impossible chirp timing)."""


class Awr1843Cli:
    """One CLI session with the radar."""

    def __init__(self, url: str, *, baudrate: int = CLI_BAUDRATE,
                 command_timeout_s: float = COMMAND_TIMEOUT_S,
                 start_timeout_s: float = START_TIMEOUT_S) -> None:
        self.url = url
        self.baudrate = baudrate
        self.command_timeout_s = command_timeout_s
        self.start_timeout_s = start_timeout_s
        self._port: serial.SerialBase | None = None
        self._framer = ReplyFramer()
        #: True between a successful sensorStart and sensorStop.
        self.started = False
        #: Whether anything at all came back on the port since it was opened.
        self._heard_any = False

    def open(self) -> "Awr1843Cli":
        try:
            self._port = serial.serial_for_url(self.url, baudrate=self.baudrate, timeout=0.05,
                                               write_timeout=self.command_timeout_s)
        except (serial.SerialException, ValueError, OSError) as exc:
            raise port_open_error("CLI", self.url, exc) from None
        self._port.reset_input_buffer()
        self._heard_any = False
        return self

    @property
    def is_open(self) -> bool:
        return self._port is not None

    def close(self) -> None:
        if self._port is not None:
            try:
                self._port.close()
            except (serial.SerialException, OSError):
                pass
            self._port = None

    def __enter__(self) -> "Awr1843Cli":
        return self.open() if self._port is None else self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ talk
    def send(self, line: str, timeout_s: float | None = None) -> Reply:
        """Send one command line and return the classified reply."""
        if self._port is None:
            self.open()
        timeout_s = self.command_timeout_s if timeout_s is None else timeout_s
        command = line.strip()
        try:
            self._port.write((command + "\n").encode("ascii", errors="replace"))
            deadline = time.monotonic() + timeout_s
            resent = command not in REPEATABLE
            while True:
                for text in self._framer.feed(self._port.read(self._port.in_waiting or 1)):
                    self._heard_any = True
                    if _belongs_to(text, command):
                        reply = classify(text, command)
                        log.debug("%s -> %s %s", command, reply.outcome.value, reply.text)
                        return reply
                    if is_boot_banner(text) and not resent:
                        # A radar that was booting (a reset moments ago) dropped the command; a
                        # stale banner in front of the echo instead gets the command answered twice.
                        log.info("the radar on %s has just booted; sending %r again", self.url, command)
                        self._port.write((command + "\n").encode("ascii", errors="replace"))
                        deadline, resent = time.monotonic() + timeout_s, True
                        continue
                    log.debug("unsolicited text from the radar: %r", text[:200])
                if time.monotonic() > deadline:
                    raise DeviceTimeout(f"the radar did not answer {command.split()[0]!r} within "
                                        f"{timeout_s:g} s on {self.url}{self._what_came()}")
        except serial.SerialTimeoutException:  # a write the port did not take within the command's time
            raise DeviceTimeout(f"the radar's CLI port {self.url} did not take {command.split()[0]!r} within "
                                f"{timeout_s:g} s (cli_timeout=): is another program holding the port, or the "
                                "time too short?") from None
        except (serial.SerialException, OSError) as exc:
            raise self._port_failed(exc) from None

    def _what_came(self) -> str:
        """What a command's timeout says of what came back on the port instead of its answer."""
        pending = self._framer.pending
        text = pending.decode("ascii", "replace")
        if pending and sum(ch == "\ufffd" or not (ch.isprintable() or ch.isspace()) for ch in text) > len(text) / 4:
            return (f" (it sent {len(pending)} bytes that are no text: is it the radar's CLI port (the board's "
                    "first, USB interface 0; radar-devices lists them) rather than its data port, at the "
                    f"CLI's {self.baudrate} baud?)")
        heard = " ".join(split_lines(text))[:200]
        if heard:
            return f" (it said: {heard!r})"
        if self._heard_any:
            return ""
        return (": nothing has come back on it since it was opened; is it the radar's CLI port (the board's "
                "first, USB interface 0; radar-devices lists them), the board powered and running the demo "
                "firmware?")

    def _port_failed(self, exc: BaseException) -> DeviceError:
        return DeviceError(f"the radar's CLI port {self.url} failed ({exc}): was the USB cable unplugged or the "
                           "board reset?")

    def unsolicited_lines(self) -> list[str]:
        """The whole lines the firmware printed unasked since the last call, without waiting:
        while the sensor runs, the demo prints its measurements (``compRangeBiasAndRxChanPhase
        ...``) and its exceptions (``Obj Det DPC Exception: ...``) on this port.  A line still
        coming is kept for the next call.  Call it only between commands."""
        if self._port is None:
            return []
        try:
            waiting = self._port.in_waiting
            data = self._port.read(waiting) if waiting else b""
        except (serial.SerialException, OSError) as exc:
            raise self._port_failed(exc) from None
        lines = [ln for text in self._framer.feed(data) for ln in split_lines(text)]
        pending = self._framer.pending
        end = max(pending.rfind(b"\n"), pending.rfind(b"\r"))
        if end >= 0:
            lines += split_lines(pending[:end + 1].decode("ascii", errors="replace"))
            self._framer.clear()
            self._framer.feed(pending[end + 1:])
        if lines:
            self._heard_any = True
        return lines

    def configure(self, cfg: RadarConfig) -> None:
        """sensorStop, flushCfg, then every cfg command; raises on the first refusal."""
        self.stop()
        self._expect(self.send("flushCfg"), "flushCfg")
        for ln in cfg.commands_to_send():
            try:
                reply = self.send(str(ln))
            except DeviceError as exc:  # a timeout, or the port gone: say which line it hit
                raise type(exc)(f"{cfg.path}:{ln.line}: {ln.text}: {exc}") from None
            if reply.outcome in (Outcome.ERROR, Outcome.UNKNOWN_COMMAND, Outcome.UNCLEAR):
                raise RadarCommandError(f"{cfg.path}:{ln.line}: {ln.text}: the radar refused it: "
                                        f"{reply.text or 'no Done'}")

    def start(self) -> None:
        """sensorStart; a radar that does not answer raises :class:`SensorStartHung`."""
        try:
            reply = self.send("sensorStart", self.start_timeout_s)
        except DeviceTimeout:
            raise SensorStartHung(
                f"sensorStart got no answer within {self.start_timeout_s:g} s: the radar hung, which an "
                f"impossible chirp or frame timing does (check the cfg with radar-cfg)") from None
        self._expect(reply, "sensorStart")
        self.started = True

    def stop(self) -> None:
        """sensorStop (an already stopped sensor is fine)."""
        self._expect(self.send("sensorStop"), "sensorStop")
        self.started = False

    @staticmethod
    def _expect(reply: Reply, what: str) -> None:
        if reply.outcome not in (Outcome.DONE, Outcome.IGNORED):
            raise RadarCommandError(f"{what}: the radar answered: {reply.text or 'nothing but the prompt'}")


def port_open_error(which: str, url: str, exc: BaseException) -> DeviceError | SourceError:
    """Why the radar's *which* ("CLI", "data") port at *url* did not open, and what to do: a path
    to a file or a folder is no serial port (pyserial says "Inappropriate ioctl for device"), a
    mistake in what was given (exit 2, as a port that is not there), not the device's."""
    if os.path.isfile(url) or os.path.isdir(url):
        kind = "a folder" if os.path.isdir(url) else "a regular file"
        return SourceError(f"the radar's {which} port {url} is {kind}, not a serial port: give the XDS110's "
                           f"port (/dev/ttyACM0, COM3; radar-devices lists them)")
    return DeviceError(f"cannot open the radar's {which} port {url}: {exc}. Is the AWR1843BOOST plugged in, "
                       f"and may you open the port (radar-devices tells)?")


def _belongs_to(text: str, command: str) -> bool:
    """True when a reply's text answers *command* (its echo is among the lines;
    garbage before the echo does not matter)."""
    return any(ln.endswith(command) for ln in split_lines(text))
