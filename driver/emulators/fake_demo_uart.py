"""The fake AWR1843's data port: the demo firmware's UART output on a second pseudo-terminal.

:class:`FakeDemoDataPort` serves a pty like the XDS110's interface 3.  On the fake radar's
``sensorStart`` it makes the frames of a source for the radar's configuration (``sim://`` is made
anew for it, as the fake DCA1000 does), turns each into the demo's packet
(:class:`~.demo_frames.DemoFrameMaker`) and writes it:

- paced like the chip: frame *k* after the start is sent from ``start + k * period + chirping
  time``, at the baud rate's byte rate (10 bits a byte; ``configDataPort`` in the cfg sets the
  baud, default 921600).  The first frame goes out when it has been made (a simulator's start-up
  must not make the first frames late and then burst them out).  A source slower than real time
  makes frames late, whole, with one warning;
- like the chip when a packet does not leave the UART before the next frame starts: the demo
  asserts, the CLI prints ``Obj Det DPC Exception: objectdetection.c, line 428.`` (*on_assert*)
  and the data stops until the radar is started again;
- with :class:`UartFaults`: line noise between packets, packets cut short (their tail never
  sent), runs of bytes lost inside packets; what was done to which frame number is kept in
  :attr:`FakeDemoDataPort.stats` (the ground truth the tests check the framer against).

:class:`DemoUartRig` wires a :class:`~.fake_awr1843.FakeAwr1843` to it and gives the
``tidemo://`` URL that reaches both ptys (``radar-emulate --uart``).
"""

from __future__ import annotations

import logging
import os
import random
import threading
import time
import tty
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from urllib.parse import urlencode

from ...cfg import RadarConfig
from ..tidemo.layout import BITS_PER_BYTE, DEFAULT_BAUD
from .demo_frames import DemoFrameMaker
from .awr1843_pty import write_all
from .source_url import emulated_source_url
from .fake_awr1843 import BOOT_TIME_S, CliFaults, FakeAwr1843

log = logging.getLogger(__name__)

#: What the demo's CLI prints when a frame starts before the previous packet left (SDK 3.4
#: objectdetection.c, DPC_ObjectDetection_frameStart's assert; mss_main.c's report).
ASSERT_LINE = "Obj Det DPC Exception: objectdetection.c, line 428."
#: Longest a write waits for a client that does not read before the rest of the packet is lost
#: (a UART does not wait).
WRITE_TIMEOUT_S = 0.5


@dataclass
class UartFaults:
    """Faults per packet, each a probability drawn from ``random.Random(seed)``."""

    #: Line noise before the packet: ``garbage_bytes`` random bytes (never a magic word).
    garbage: float = 0.0
    garbage_bytes: int = 24
    #: The packet is cut short: its tail, from a random byte after the magic word, is never sent.
    truncate: float = 0.0
    #: A run of 1 to ``drop_bytes`` bytes after the magic word is lost.
    drop: float = 0.0
    drop_bytes: int = 64
    seed: int = 0


@dataclass
class UartStats:
    """The ground truth of what was sent: frame numbers whole, cut short, with lost bytes; which
    whole packets had line noise right after them; bytes written and lost to a client that
    did not read."""

    whole: list[int] = field(default_factory=list)
    truncated: list[int] = field(default_factory=list)
    dropped: list[int] = field(default_factory=list)
    garbage_before: list[int] = field(default_factory=list)
    bytes_written: int = 0
    bytes_unread: int = 0
    late_frames: int = 0
    asserted: bool = False

    @property
    def packets(self) -> int:
        return len(self.whole) + len(self.truncated) + len(self.dropped)


class FakeDemoDataPort:
    """The demo's data UART on a pty; see the module docstring.  *frames*: a source URL (opened
    for the radar's configuration with ``rate=max&loop=0``) or a callable ``(config) -> iterable of
    raw frames``.  *rate*: ``paced`` or ``max`` (no pacing: throughput)."""

    def __init__(self, frames: str | Callable[[RadarConfig], Iterable] = "sim://corridor", *,
                 faults: UartFaults | None = None, rate: str = "paced",
                 on_assert: Callable[[str], None] | None = None) -> None:
        if rate not in ("paced", "max"):
            raise ValueError(f"rate={rate!r}: expected 'paced' or 'max'")
        self.frames, self.rate, self.on_assert = frames, rate, on_assert
        #: Called with each frame's measurement line, when the cfg asks for one (the CLI prints it).
        self.on_measurement: Callable[[str], None] | None = None
        self.faults = faults if faults is not None else UartFaults()
        self.stats = UartStats()
        self.path: str | None = None
        self.config: RadarConfig | None = None
        self.maker: DemoFrameMaker | None = None
        self._rng = random.Random(self.faults.seed)
        self._cond = threading.Condition()
        self._running = False
        self._generation = 0
        self._closed = False
        self._master = self._slave = None
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ pty
    def open_pty(self) -> str:
        """Create the pty and the streaming thread; the slave's path."""
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master, self._slave, self.path = master, slave, os.ttyname(slave)
        self._thread = threading.Thread(target=self._serve, name=f"fake-demo-uart {self.path}", daemon=True)
        self._thread.start()
        log.info("fake AWR1843 data port on %s", self.path)
        return self.path

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._running = False
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout=10.0)
        for fd in (self._master, self._slave):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = None

    # ------------------------------------------------------------ the radar's side
    def start(self, config: RadarConfig) -> None:
        """The radar's sensorStart: stream *config*'s frames from now on."""
        with self._cond:
            self.config = config
            self._running = True
            self._generation += 1
            self.stats.asserted = False
            self._cond.notify_all()

    def stop(self) -> None:
        """The radar's sensorStop: the packet being sent is finished, no other follows."""
        with self._cond:
            self._running = False
            self._cond.notify_all()

    def wait_packets(self, n: int, timeout: float = 10.0) -> bool:
        """Block until *n* packets were sent (or *timeout*)."""
        deadline = time.monotonic() + timeout
        while self.stats.packets < n:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.01)
        return True

    # ------------------------------------------------------------------ streaming
    def _serve(self) -> None:
        while True:
            with self._cond:
                while not (self._running or self._closed):
                    self._cond.wait()
                if self._closed:
                    return
                config, generation = self.config, self._generation
            try:
                self._stream(config, generation)
            except Exception as exc:  # a broken source must not kill the radar
                log.exception("fake demo data port: streaming failed: %s", exc)
                with self._cond:
                    if self._generation == generation:
                        self._running = False

    def _live(self, generation: int) -> bool:
        with self._cond:
            return self._running and not self._closed and self._generation == generation

    def _stream(self, config: RadarConfig, generation: int) -> None:
        self.maker = maker = DemoFrameMaker(config)
        port = config.line_of("configDataPort")
        byte_rate = (port.value.baud_rate if port is not None else DEFAULT_BAUD) / BITS_PER_BYTE
        period, active = config.frame_period_s, config.active_frame_time_s
        source, frames = self._open(config)
        t0, number, warned = None, 1, False
        try:
            for raw in frames:
                if not self._live(generation):
                    return
                packet, _ = maker.packet(raw, number, (number - 1) * period)
                now = time.monotonic()
                t0 = now - (number - 1) * period - active if t0 is None else t0
                due = t0 + (number - 1) * period + active
                if self.rate == "paced" and not self._sleep_until(due, generation):
                    return
                if now - due > period:
                    self.stats.late_frames += 1
                    if not warned:
                        warned = True
                        log.warning("fake demo data port: frames come late: its source makes them slower than the "
                                    "%.1f ms frame period on this computer's CPU", period * 1e3)
                if maker.measurement is not None and self.on_measurement is not None:
                    self.on_measurement(maker.measurement)  # the demo prints it just before it sends the packet
                self._send_packet(packet, number, byte_rate, generation)
                if len(packet) / byte_rate > period - active:
                    self._assert(generation)
                    return
                number += 1
        finally:
            if source is not None:
                source.close()

    def _open(self, config: RadarConfig):
        if callable(self.frames):
            return None, iter(self.frames(config))
        from ..sources import open_source

        source = open_source(emulated_source_url(self.frames, defaults={"rate": "max", "loop": "0"}), config,
                             shown_url=self.frames)
        return source, (f.raw for f in source)

    def _sleep_until(self, due: float, generation: int) -> bool:
        while (left := due - time.monotonic()) > 0:
            with self._cond:
                if not (self._running and self._generation == generation) or self._closed:
                    return False
                self._cond.wait(min(left, 0.05))
        return self._live(generation)

    def _assert(self, generation: int) -> None:
        """The demo's frame start found the last packet still on the UART: it stops."""
        log.warning("fake demo: a packet outlasted the UART's time between frames; the demo asserts")
        with self._cond:
            if self._generation == generation:
                self._running = False
            self.stats.asserted = True
        if self.on_assert is not None:
            self.on_assert(ASSERT_LINE)

    def _faulted(self, packet: bytes, number: int) -> bytes:
        f, rng = self.faults, self._rng
        data = packet
        if f.truncate and rng.random() < f.truncate:
            data = packet[:rng.randrange(8, len(packet))]
            self.stats.truncated.append(number)
        elif f.drop and rng.random() < f.drop:
            run = rng.randint(1, min(f.drop_bytes, len(packet) - 8))
            at = rng.randrange(8, len(packet) - run + 1)
            data = packet[:at] + packet[at + run:]
            self.stats.dropped.append(number)
        else:
            self.stats.whole.append(number)
        if f.garbage and rng.random() < f.garbage:
            noise = bytes(rng.choice(b"\x00\x13\x37\x55\xaa\xff\x11\x7e") for _ in range(f.garbage_bytes))
            self.stats.garbage_before.append(number)
            data = noise + data
        return data

    def _send_packet(self, packet: bytes, number: int, byte_rate: float, generation: int) -> None:
        data = self._faulted(packet, number)
        chunk = max(64, int(byte_rate * 0.005))
        start = time.monotonic()
        for at in range(0, len(data), chunk):
            if self.rate == "paced":
                self._sleep_until(start + at / byte_rate, generation)  # a started packet is finished
            part = data[at:at + chunk]
            written = write_all(lambda: self._master, part, WRITE_TIMEOUT_S, lambda: False, "fake demo data port")
            self.stats.bytes_written += written
            if written < len(part):
                self.stats.bytes_unread += len(data) - at - written
                return


class DemoUartRig:
    """A fake AWR1843 with its CLI pty and its data-port pty, streaming *frames* (a source URL or
    a callable, as :class:`FakeDemoDataPort` takes) on sensorStart."""

    def __init__(self, frames: str | Callable[[RadarConfig], Iterable] = "sim://corridor", *,
                 faults: UartFaults | None = None, cli_faults: CliFaults | None = None, rate: str = "paced",
                 boot_time_s: float = BOOT_TIME_S) -> None:
        self.data = FakeDemoDataPort(frames, faults=faults, rate=rate)
        self.radar = FakeAwr1843(cli_faults, on_sensor_start=self.data.start, on_sensor_stop=self.data.stop,
                                 boot_time_s=boot_time_s, expects_lvds=False)
        self.data.on_assert = self.data.on_measurement = self.radar.announce
        try:
            self.cli_path = self.radar.open_pty()
            self.data_path = self.data.open_pty()
        except BaseException:
            self.close()
            raise

    def url(self, **extra) -> str:
        """The ``tidemo://`` URL of this rig (extra options appended)."""
        return f"tidemo://{self.data_path}?{urlencode({'cli': self.cli_path, **extra})}"

    def close(self) -> None:
        self.radar.close()
        self.data.close()

    def __enter__(self) -> "DemoUartRig":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
