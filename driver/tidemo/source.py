"""``tidemo://`` : the radar alone, through TI's demo firmware's own output on its data UART.

``tidemo://[DATA_PORT]?cli=PORT&baud=921600&max_points=64&policy=latest&buffers=8``

The AWR1843BOOST running the mmWave SDK 3.x out-of-box demo does its range, Doppler, CFAR and
angle processing on the chip and sends one packet a frame on the XDS110's data port (USB interface
3): the detected points with their side info and the azimuth static heatmap (:mod:`.wire`).  No
DCA1000 is needed.  The source:

1. works out what the demo will send for the cfg (:mod:`.layout`) and refuses, before anything is
   opened, a frame rate whose packets the UART cannot carry at *baud* with *max_points* points;
2. opens the data port (``DATA_PORT``, or found with the CLI port through discovery: :mod:`.ports`),
   configures the radar over the CLI port (``sensorStop``, ``flushCfg``, the cfg with guiMonitor set
   to points, side info and the static heatmap; ``lvdsStreamCfg`` is not needed) and starts it;
3. reads the data port on a thread of its own, so that the UART's bytes are taken in while frames
   are processed, cuts them into packets (:mod:`.framer`: garbage, lost bytes and cut packets are
   counted, never delivered), and hands on frames with their points and static antenna values
   (:mod:`.products`), through a ring of *buffers* frames (*policy* ``latest`` drops the oldest
   waiting frame when the consumer is slower, ``queue`` the newest);
4. at stop sends ``sensorStop`` and takes in the last packet still on the line.

Frame indices are the demo's frame numbers from the first one seen, so frames lost on the line
leave gaps; timestamps are the host's arrival times of each packet's first byte less the frame's
chirping time, smoothed onto the frame grid (:class:`~radarodom.driver.live.frame_clock.FrameClock`):
the demo's processing time before it sends (a few ms, not measured) is still in them.

Options: ``cli`` (the CLI port: a path or any pyserial URL), ``baud`` (the data port's, 921600;
another one adds ``configDataPort`` to the cfg), ``max_points`` (points a frame the UART budget
allows for, 64), ``policy``, ``buffers`` (8), ``cli_timeout`` (s a CLI command, 2),
``start_timeout`` (s for sensorStart, 5), ``data_timeout`` (s without a packet before the stream is
declared dead; 10 frame periods, at least 2).
"""

from __future__ import annotations

import collections
import logging
import os
import threading
import time
from typing import Iterator

import serial

from ...calibration import CALIBRATION_COMMAND, uncalibrated_note
from ...cfg import TIDEMO_CONFIG_NAME, RadarConfig, shipped_config_path
from ...errors import ConfigError, DeviceError, DeviceTimeout, RadarodomError, SourceError
from ..live.awr1843 import COMMAND_TIMEOUT_S, Awr1843Cli, SensorStartHung, port_open_error
from ..live.frame_clock import FrameClock, stream_timeout_s
from ..sources import Frame, Source
from ..url_options import UrlOptions, at_least, given_text, one_of, positive_number, whole_in
from .framer import TlvFramer
from .layout import (DEFAULT_BAUD, DEFAULT_MAX_POINTS, MAX_BAUD, MIN_BAUD, DemoGeometry, check_uart_budget,
                     demo_config, gui_selection)
from .recording import UartRecorder
from .products import PacketFrames
from .wire import Packet

log = logging.getLogger(__name__)

#: Lines of the demo's own CLI output kept (TidemoSource.cli_lines): a few minutes of measurements.
CLI_LINES_KEPT = 2000
#: Seconds a read of the data port waits; a read that gets nothing means the line is quiet.
READ_TIMEOUT_S = 0.02
POLICIES = ("latest", "queue")


class _Reader(threading.Thread):
    """Reads the data port into the framer, frames into the ring, until stopped."""

    def __init__(self, source: "TidemoSource") -> None:
        super().__init__(name="tidemo-reader", daemon=True)
        self.source = source
        self.stop_event = threading.Event()
        self.error: BaseException | None = None
        self.last_byte_monotonic = 0.0
        self._chunks: collections.deque[tuple[int, float]] = collections.deque()  # (end offset, time.time())

    def arrival(self, offset: int) -> float:
        """time.time() the byte at stream *offset* arrived."""
        while len(self._chunks) > 1 and self._chunks[0][0] <= offset:
            self._chunks.popleft()
        return self._chunks[0][1] if self._chunks else time.time()

    def run(self) -> None:
        src, port = self.source, self.source.port
        try:
            while not self.stop_event.is_set():
                data = port.read(port.in_waiting or 1)
                if data:
                    now = time.time()
                    self.last_byte_monotonic = time.monotonic()
                    self._chunks.append((src.framer.offset + len(data), now))
                    packets = src.framer.feed(data)
                else:
                    packets = src.framer.idle()
                for packet in packets:
                    src.deliver(packet)
        except (serial.SerialException, OSError) as exc:
            self.error = exc
        except RadarodomError as exc:
            self.error = exc


class TidemoSource(Source):
    """The demo's UART output as frames; see the module docstring."""

    carries_raw = False
    records_itself = True
    starts_radar = True
    estimator_preset = "tidemo"

    def __init__(self, config: RadarConfig, data_url: str, cli_url: str, *, baud: int = DEFAULT_BAUD,
                 max_points: int = DEFAULT_MAX_POINTS, policy: str = "latest", buffers: int = 8,
                 cli_timeout_s: float = COMMAND_TIMEOUT_S, start_timeout_s: float = 5.0,
                 data_timeout_s: float | None = None) -> None:
        super().__init__()
        note = uncalibrated_note(config)
        if note is not None and config.channel_measurement is None:  # not radar-calibrate's own measuring
            log.warning("%s", note)
        self.config = config
        self.data_url, self.baud, self.policy = data_url, baud, policy
        self.geometry = DemoGeometry.from_config(config)
        self.layout = self.geometry.layout(gui_selection(config))
        self.budget = check_uart_budget(config, self.layout, baud, max_points)
        self.sent_config = demo_config(config, self.layout.gui, baud)
        self.framer = TlvFramer(self.layout.packet_bytes(self.geometry.range_bins * self.geometry.doppler_bins))
        self.clock = FrameClock(config.frame_period_s)
        self.frames = PacketFrames(self.geometry, self._stamp)
        #: Seconds without a packet before the stream is declared dead.
        self.data_timeout_s = stream_timeout_s(config.frame_period_s, data_timeout_s)
        self.radar = Awr1843Cli(cli_url, start_timeout_s=start_timeout_s, command_timeout_s=cli_timeout_s)
        self.port: serial.SerialBase | None = None
        self._ring: collections.deque[Frame] = collections.deque()
        self._buffers = buffers
        self._cond = threading.Condition()
        self._reader: _Reader | None = None
        self._counts = {"delivered": 0, "dropped": 0, "over_budget": 0}
        #: describe() when the consumer left (None: it has not): what the reader takes in after,
        #: until the source closes, is not its stream's (as a live DCA1000 source's).
        self._when_left: dict | None = None
        self._last_packet = time.monotonic()
        #: The lines the demo printed on its CLI port while streaming (its exceptions, the
        #: measurements a cfg's measureRangeBiasAndRxChanPhase asks for, one a frame), in order:
        #: the last CLI_LINES_KEPT.
        self.cli_lines: collections.deque[str] = collections.deque(maxlen=CLI_LINES_KEPT)
        self._said: tuple[float, str] | None = None  # (time.monotonic(), line) of its last line not a measurement
        try:
            self._open()
        except BaseException:
            self.close()
            raise

    def _open(self) -> None:
        try:
            self.port = serial.serial_for_url(self.data_url, baudrate=self.baud, timeout=READ_TIMEOUT_S)
        except (serial.SerialException, ValueError, OSError) as exc:
            raise port_open_error("data", self.data_url, exc) from None
        self.radar.open()
        self.radar.configure(self.sent_config)

    def _stamp(self, index: int, packet: Packet) -> float:
        arrived = self._reader.arrival(packet.offset) if self._reader is not None else time.time()
        return self.clock.stamp(index, arrived - self.config.active_frame_time_s)

    def deliver(self, packet: Packet) -> None:
        """A whole packet from the reader: into the ring (by the policy when it is full)."""
        if packet.num_points > self.budget.max_points:
            self._counts["over_budget"] += 1
        frame = self.frames(packet, time.monotonic())
        with self._cond:
            self._last_packet = time.monotonic()
            if len(self._ring) >= self._buffers:
                self._counts["dropped"] += 1
                if self.policy == "queue":
                    return
                self._ring.popleft()
            self._ring.append(frame)
            self._cond.notify_all()

    def _next(self, timeout: float) -> Frame | None:
        with self._cond:
            if not self._ring:
                self._cond.wait(timeout)
            if self._ring:
                self._counts["delivered"] += 1
                return self._ring.popleft()
        return None

    def _frames(self) -> Iterator[Frame]:
        self.port.reset_input_buffer()
        self._reader = _Reader(self)
        self._reader.start()
        try:
            self.radar.start()
        except SensorStartHung as exc:  # no DCA1000 here to reset it through, as dca1000:// does
            raise SensorStartHung(f"{exc}; it stays hung until reset: press the board's reset button (NRST) or "
                                  "unplug its USB and plug it in again, then run again") from None
        self._last_packet = time.monotonic()
        try:
            yield from self._stream()
        except GeneratorExit:  # the consumer left (a frame or duration limit)
            self._when_left = self.describe()
            raise

    def _read_cli(self) -> None:
        """Take in what the demo printed on its CLI port; an exception report is warned of."""
        for line in self.radar.unsolicited_lines():
            if not line.startswith(CALIBRATION_COMMAND):
                if line not in self.cli_lines:
                    log.warning("the radar's CLI port says: %s", line)
                self._said = (time.monotonic(), line)
            self.cli_lines.append(line)

    def _stream(self) -> Iterator[Frame]:
        while not self.stop_requested:
            frame = self._next(0.1)
            self._read_cli()
            if frame is not None:
                yield frame
                continue
            if self._reader.error is not None:
                raise DeviceError(f"reading the radar's data port {self.data_url} failed ({self._reader.error}): was "
                                  "the USB cable unplugged or the board reset?")
            quiet = time.monotonic() - self._last_packet
            # What the CLI said since the last packet (a line from before it is not why the data stopped).
            said = self._said[1] if self._said is not None and self._said[0] >= self._last_packet else None
            if quiet > self.data_timeout_s and said is not None:
                why = (f": the demo stopped, as it does when a packet outlasts the frame period (more points than "
                       f"max_points={self.budget.max_points}?)" if "Exception" in said else "")
                raise DeviceTimeout(f"no packet from the demo on {self.data_url} for {quiet:.1f} s "
                                    f"(data_timeout={self.data_timeout_s:g}); its CLI port said {said!r}{why}")
            if quiet > self.data_timeout_s:
                raise DeviceTimeout(
                    f"no packet from the demo on {self.data_url} for {quiet:.1f} s (data_timeout="
                    f"{self.data_timeout_s:g}, frame period {self.config.frame_period_s:g} s): is the data port the "
                    f"radar's (USB interface 3), its baud rate {self.baud}?  A demo whose packet outlasts the frame "
                    f"period stops with 'Obj Det DPC Exception' on its CLI port (more points than "
                    f"max_points={self.budget.max_points}?)")
        # Asked to stop: the radar's last packet may still be on the line.
        self._finish()
        while (frame := self._next(0)) is not None:
            yield frame

    def _finish(self) -> None:
        """sensorStop, the line quiet, the reader stopped and the framer's last whole packets
        delivered."""
        try:
            self._stop_radar()
        except RadarodomError as exc:
            log.warning("while stopping: %s", exc)
        reader = self._reader
        if reader is None or not reader.is_alive():
            return
        quiet_s = max(0.1, 3 * self.budget.transmit_s)
        deadline = time.monotonic() + self.budget.available_s + self.config.frame_period_s + quiet_s
        while time.monotonic() < deadline and time.monotonic() - max(reader.last_byte_monotonic,
                                                                     self._last_packet) < quiet_s:
            time.sleep(0.01)
        reader.stop_event.set()
        reader.join()
        for packet in self.framer.finish():
            self.deliver(packet)

    def recorder(self, directory: str) -> UartRecorder:
        """A sink that records this stream's packets as received (:class:`.recording.UartRecorder`)."""
        return UartRecorder(directory, self.config, source=self.url, baud=self.baud)

    def describe(self) -> dict:
        """Where the demo's frames went: ``frames`` handed on, ``frames_skipped`` (frame numbers
        never handed on: rejected or lost on the line, or dropped), ``slow_drops`` (whole frames
        the consumer was too slow for, by the policy), the framer's figures (``packets``,
        ``discarded_bytes``, ``rejected_packets`` and by reason), ``over_budget`` (packets with
        more points than ``max_points``, which the UART budget was checked for), and the UART's
        load (packet time over the time it has); as they were when the consumer left, if it did."""
        if self._when_left is not None:
            return dict(self._when_left)
        return {"url": self.url, "data_port": self.data_url, "cli": self.radar.url, "baud": self.baud,
                "frames": self._counts["delivered"], "frames_skipped": self.frames.skipped + self._counts["dropped"],
                "slow_drops": self._counts["dropped"], "over_budget": self._counts["over_budget"],
                "max_points": self.budget.max_points,
                "uart_load": round(self.budget.transmit_s / self.budget.available_s, 3),
                **self.framer.stats.as_dict()}

    def summary(self) -> str:
        d = self.describe()
        rejected = ", ".join(f"{n} {k[len('rejected_'):].replace('_', ' ')}" for k, n in d.items()
                             if k.startswith("rejected_") and k != "rejected_packets")
        return (f"{d['frames']} frames from the demo; {d['frames_skipped']} frame numbers skipped "
                f"({d['rejected_packets']} packets rejected{': ' + rejected if rejected else ''}; "
                f"{d['slow_drops']} dropped by slow processing); {d['discarded_bytes']} bytes discarded"
                + (f"; {d['over_budget']} packets with more points than max_points={d['max_points']}, which the "
                   "UART budget was checked for (give a larger max_points)" if d["over_budget"] else ""))

    def _stop_radar(self) -> None:
        if self.radar.is_open and self.radar.started:
            self.radar.stop()

    def _release(self) -> None:
        for step in (self._stop_radar, self.radar.close):
            try:
                step()
            except RadarodomError as exc:
                log.warning("while stopping: %s", exc)
        if self._reader is not None:
            self._reader.stop_event.set()
            self._reader.join(timeout=2.0)
        if self.port is not None:
            self.port.close()
        if self._reader is not None:
            d = self.describe()
            lossy = d["frames_skipped"] or d["rejected_packets"] or d["discarded_bytes"] or d["over_budget"]
            log.log(logging.WARNING if lossy else logging.INFO, "%s", self.summary())


def open_tidemo(path: str, options: UrlOptions, config: RadarConfig | None) -> TidemoSource:
    from .ports import demo_ports  # pyusb and sysfs only when needed

    cli = options.take("cli", given_text, None, "the radar's CLI port (path or pyserial URL)")
    baud = options.take("baud", whole_in(MIN_BAUD, MAX_BAUD), DEFAULT_BAUD, "the data port's baud rate")
    max_points = options.take("max_points", at_least(0), DEFAULT_MAX_POINTS, "points a frame the UART must carry")
    policy = options.take("policy", one_of(*POLICIES), "latest", " or ".join(POLICIES))
    buffers = options.take("buffers", at_least(2), 8, "a whole number of frames >= 2")
    cli_timeout = options.take("cli_timeout", positive_number, COMMAND_TIMEOUT_S, "seconds per radar CLI command")
    start_timeout = options.take("start_timeout", positive_number, 5.0, "seconds for sensorStart")
    data_timeout = options.take("data_timeout", positive_number, None, "seconds without a packet")
    options.finish()
    cfg = config if config is not None else RadarConfig.from_file(shipped_config_path(TIDEMO_CONFIG_NAME))
    # The UART budget and the antenna layout are checked before any port is looked for or opened.
    try:
        check_uart_budget(cfg, DemoGeometry.from_config(cfg).layout(gui_selection(cfg)), baud, max_points)
    except ConfigError as exc:
        if config is None:  # the user gave none: say it is the shipped one, and what to do
            raise ConfigError(f"{exc.message} (no cfg was given, so the shipped {TIDEMO_CONFIG_NAME} was used: give "
                              "one the UART carries with --cfg; docs/tidemo.md says how to make it)", path=exc.path,
                              line=exc.line, command=exc.command, field=exc.field) from None
        raise
    for what, port in (("data port", path), ("CLI port", cli)):
        # A device path (not a pyserial URL, nor a bare name such as COM3) that is not there.
        if port and "/" in port and "://" not in port and not os.path.exists(port):
            slash = what == "data port" and not port.startswith("/") and os.path.exists("/" + port)
            raise SourceError(f"{options.url}: no {what} {port} "
                              + (f"(a device path takes a third slash: tidemo:///{port})" if slash
                                 else "(radar-devices lists what is connected)"))
    cli, data = demo_ports(cli, path or None)
    same = cli == data if "://" in cli + data else os.path.realpath(cli) == os.path.realpath(data)
    if same:
        raise SourceError(f"{options.url}: the CLI port and the data port are both {data}: the board has two (the "
                          "CLI on USB interface 0, the data on interface 3; radar-devices lists them)")
    return TidemoSource(cfg, data, cli, baud=baud, max_points=max_points, policy=policy, buffers=buffers,
                        cli_timeout_s=cli_timeout, start_timeout_s=start_timeout, data_timeout_s=data_timeout)
