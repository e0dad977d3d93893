"""``dca1000://`` : the live radar, configured over its UART, streamed by the DCA1000.

``dca1000://[BOARD_IP]?host=192.168.33.30&cli=/dev/ttyACM0&delay=25&policy=latest``

Options: ``host`` (this computer's address on the board's network, default
192.168.33.30), ``cli`` (the radar's CLI port: a device path or any pyserial
URL; default found automatically), ``config_port`` / ``data_port`` (host ports,
4096 / 4098), ``board_port`` (4096), ``delay`` (packet delay in us, 25),
``policy`` (``latest`` or ``queue``: which frames to drop when the consumer
is slower than the radar), ``buffers`` (frames in the ring, 8), ``timeout``
(seconds per board command, 1), ``start_timeout`` (seconds for sensorStart, 5),
``cli_timeout`` (seconds per radar CLI command, 2), ``stop_timeout`` (seconds to wait
for the board's RECORD_COMPLETED after RECORD_STOP, 3) and ``data_timeout`` (seconds without a
data packet before the stream is declared dead; 10 frame periods, at least 2).

Start order: open and flush the data socket, configure the board, configure the
radar, flush the data socket again (an earlier recording's packets that came
meanwhile), RECORD_START, sensorStart; stop in reverse.  ``sensorStop`` is sent on
every exit, errors and Ctrl-C included.
A hung sensorStart is answered with the DCA1000's RESET_AR_DEV.

Asked to stop (:meth:`Source.stop`), the source stops the radar and the recording, waits for
the board's RECORD_COMPLETED (the board holds the last frame's short packet until then), and
delivers the frames still in flight before it ends: nothing the board sent is left behind.
A frame is not given up for a pause in the stream (its last packet waits for the next
frame's bytes on the real board); lost packets are known from the stream's later bytes.
"""

from __future__ import annotations

import ipaddress
import logging
import time
from typing import Iterator

from ...calibration import uncalibrated_note
from ...cfg import RadarConfig, shipped_config_path
from ...cfg_physics import DCA1000_PACKET_DELAY_RANGE_US
from ...errors import DeviceError, DeviceTimeout, RadarodomError, SourceError
from ...rawframe import RawLayout
from .awr1843 import COMMAND_TIMEOUT_S, Awr1843Cli, SensorStartHung
from .dca1000 import Dca1000Client, Dca1000Settings
from .dca1000_receiver import Dca1000Receiver
from .dca1000_wire import BOARD_IP, DATA_PORT, HOST_IP, AsyncStatus
from .frame_clock import FrameClock, stream_timeout_s
from .frame_ring import POLICIES, FrameRing
from ..sources import Frame, Source
from ..url_options import UrlOptions, at_least, given_text, number_in, one_of, positive_number, udp_port

log = logging.getLogger(__name__)


class LiveSource(Source):
    starts_radar = True

    def __init__(self, config: RadarConfig, settings: Dca1000Settings, cli_url: str, *,
                 policy: str = "latest", buffers: int = 8, start_timeout_s: float = 5.0,
                 cli_timeout_s: float = COMMAND_TIMEOUT_S, data_timeout_s: float | None = None) -> None:
        super().__init__()
        config.check_raw_capture()
        note = uncalibrated_note(config)
        if note is not None:
            log.warning("%s", note)
        self.config = config
        self.settings = settings
        self.layout = RawLayout.from_config(config)
        self.ring = FrameRing(config.frame_bytes, buffers, policy)
        self.board = Dca1000Client(settings)
        self.receiver = Dca1000Receiver(settings, config.frame_bytes, self.ring, frame_period_s=config.frame_period_s)
        self.radar = Awr1843Cli(cli_url, start_timeout_s=start_timeout_s, command_timeout_s=cli_timeout_s)
        self.clock = FrameClock(config.frame_period_s)
        #: Seconds without any data packet before the stream is declared dead.
        self.data_timeout_s = stream_timeout_s(config.frame_period_s, data_timeout_s)
        self.fpga_version = None
        #: Frames handed to the consumer: whole, with zero-filled bytes, and those bytes
        #: (all of them; of them, lost on the way and cut at stop, each counted on its own).
        self._delivered = {"complete": 0, "incomplete": 0, "missing": 0, "lost": 0, "cut": 0}
        #: The frames dropped when the consumer left (None: it has not): those after are not its.
        self._dropped_when_left: int | None = None
        self._recording = False
        self._record_stopped = False
        self._radar_stopped = False
        self._frame_end_stop = False  # sensorStop answered: the radar finished its frame
        try:
            self._prepare()
        except BaseException:
            self.close()
            raise

    def _prepare(self) -> None:
        self.receiver.open()
        self.board.open()
        self.board.connect()
        self.fpga_version = self.board.read_fpga_version()
        log.info("DCA1000 FPGA %s", self.fpga_version)
        if self.fpga_version.playback:
            raise DeviceError(f"the DCA1000 runs its playback FPGA image ({self.fpga_version}); "
                              f"switch it to record mode")
        self.board.reset_fpga()
        self.board.configure_fpga()
        self.board.configure_packets()
        self.radar.open()
        self.radar.configure(self.config)

    def _reset_radar(self) -> str:
        """RESET_AR_DEV through the board; says what happened, for messages."""
        try:
            self.board.reset_radar()
            self.radar.started = False
            return "radarodom reset it through the DCA1000 (RESET_AR_DEV)"
        except RadarodomError:
            return "resetting it through the DCA1000 failed too: power-cycle the radar"

    def _frames(self) -> Iterator[Frame]:
        # Packets of an earlier recording that came while the board and the radar were set up
        # would be taken for this one's (a board left streaming by a run killed before it stopped).
        self.receiver.flush()
        self.board.start_recording()
        self._recording = True
        self.receiver.start()
        try:
            self.radar.start()
        except SensorStartHung as exc:
            raise SensorStartHung(f"{exc}; {self._reset_radar()}") from None
        except BaseException:  # Ctrl-C while the radar starts: leave it usable
            log.warning("interrupted during sensorStart: %s", self._reset_radar())
            raise
        held = None
        started = time.monotonic()
        next_poll = 0.0
        try:
            while not self.stop_requested:
                frame = self.ring.get(timeout=0.1)
                if held is not None:  # the consumer is done with the previous frame
                    self.ring.release(held)
                    held = None
                now = time.monotonic()
                if now >= next_poll:  # the board's status messages, about 5 times a second
                    self.board.poll_async()
                    next_poll = now + 0.2
                if frame is None:
                    if self.receiver.error is not None:
                        raise DeviceError(f"receiving DCA1000 data failed: {self.receiver.error}")
                    self._check_data_flows(now, started)
                    continue
                held = frame.slot
                yield self._frame(frame)
            # Asked to stop: what the board has already sent is the consumer's too.
            if held is not None:
                self.ring.release(held)
                held = None
            self._finish()
            while (frame := self.ring.get(timeout=0)) is not None:
                held = frame.slot
                yield self._frame(frame)
                self.ring.release(held)
                held = None
        except GeneratorExit:  # the consumer left (a frame limit): what comes after is not its
            self._dropped_when_left = self.ring.dropped_frames
            raise
        finally:
            if held is not None:
                self.ring.release(held)

    def _frame(self, frame) -> Frame:
        d = self._delivered
        if frame.missing_bytes:
            d["incomplete"] += 1
            d["missing"] += frame.missing_bytes
            d["lost"] += frame.lost_bytes
            d["cut"] += frame.cut_bytes
        else:
            d["complete"] += 1
        stamp = self.clock.stamp(frame.index, frame.first_packet_time, first_packet=self.receiver.first_packet)
        return Frame(index=frame.index, timestamp=stamp,
                     raw=frame.data, layout=self.layout, missing_bytes=frame.missing_bytes,
                     ready_monotonic=frame.done_monotonic, cut_bytes=frame.cut_bytes)

    def _finish(self) -> None:
        """Stop as the boards want it, and take in what they still send: the radar ends its
        frame and stops; the board, told to stop recording, sends the last frame's short packet
        it held back and then RECORD_COMPLETED (pcaps: 2 s later), waited for up to
        Dca1000Settings.stop_timeout_s; then the receiver hands on every frame still open."""
        for step in (self._stop_radar, self._stop_recording):
            try:
                step()
            except RadarodomError as exc:
                log.warning("while stopping: %s", exc)
        done = False
        if self._record_stopped:
            done = self._await_record_completed()
            if not done:
                log.warning("the DCA1000 did not report RECORD_COMPLETED within %g s of RECORD_STOP: "
                            "frames still open are handed on as they are, their missing bytes counted "
                            "as cut at stop (stop_timeout= in the URL waits longer)",
                            self.settings.stop_timeout_s)
        # A radar that answered sensorStop ended its last frame, so the stream ends at a frame's end.
        self.receiver.stop(sent_all=done and self._frame_end_stop)

    def _await_record_completed(self) -> bool:
        """Whether the board reported RECORD_COMPLETED within stop_timeout_s of RECORD_STOP.

        The first such message may be an earlier recording's: one aborted without waiting for it
        (a second Ctrl-C) and followed at once by this one gets its message up to 2 s later, after
        this recording's RECORD_STOP.  The board's own comes with the last frame's held-back
        packet, so after a radar that stopped at a frame's end the end is taken once the stream is
        whole too, or at a second message; a message that came counts by the timeout, whole or
        not (the held-back packet was lost)."""
        board, bit = self.board, AsyncStatus.RECORD_COMPLETED
        before = board.async_count(bit)
        deadline = time.monotonic() + self.settings.stop_timeout_s
        while True:
            came = board.async_count(bit) - before
            if came >= 2 or came and (not self._frame_end_stop or self.receiver.assembler.open_frames == 0):
                return True
            left = deadline - time.monotonic()
            if left <= 0:
                return came > 0
            board.await_async(bit, min(left, 0.05))

    def _check_data_flows(self, now: float, started: float) -> None:
        last = self.receiver.last_packet_monotonic or started
        if now - last <= self.data_timeout_s:
            return
        s, stats = self.settings, self.receiver.stats
        if self.board.async_status.counts.get("NO_LVDS_DATA"):
            hint = " The board reported no LVDS data: check lvdsStreamCfg and the DCA1000's switches."
        elif stats.packets:
            hint = " Was the radar reset, or its cable moved?"
        elif stats.malformed_packets or stats.stale_packets:
            hint = (f" The board sent {stats.malformed_packets} datagrams that are not data packets and "
                    f"{stats.stale_packets} of an earlier recording, none of this one's.")
        elif stats.foreign_packets:
            hint = (f" {stats.foreign_packets} datagrams came from other addresses: is the board at "
                    f"{s.board_ip} (the URL's address)?")
        else:  # the board answered its commands, so it sends its data elsewhere, or it is dropped
            hint = (f" The board sends its data to the host address and port stored in its EEPROM "
                    f"({HOST_IP}:{DATA_PORT} unless changed): check the URL's host= and data_port=, and that no "
                    f"firewall drops UDP to port {s.data_port}.")
        what = (f"no data from the DCA1000 for {now - last:.1f} s since its last packet" if stats.packets else
                f"no data packet of the DCA1000's reached {s.host_ip}:{s.data_port} in {now - started:.1f} s "
                "since the radar started")
        raise DeviceTimeout(f"{what} (data_timeout={self.data_timeout_s:g}, frame period "
                            f"{self.config.frame_period_s:g} s).{hint}")

    def describe(self) -> dict:
        """The live stream's accounting, where every frame and every missing byte went.

        Frames handed to the consumer: ``frames_complete``, ``frames_incomplete`` (with
        zero-filled bytes); ``frames_dropped``: whole frames the consumer was too slow for
        (policy).  Once a stop (:meth:`stop`) has delivered the rest, their sum is every frame
        the radar sent.  Zero-filled bytes of the frames handed on: ``missing_bytes`` (what the
        frames did not receive) = ``lost_bytes`` (what the packet headers show was sent and
        never came: sequence and byte-count gaps, from lost, truncated or late packets, and
        after a confirmed end the packets that never came) + ``cut_bytes`` (never sent before
        the stream stopped); the first two are counted independently.  Packets: ``packets``
        received, ``packets_lost`` = ``seq_gaps`` (sequence numbers never received) +
        ``tail_packets_lost`` (after the last one received, sent by the board's confirmed
        end), ``truncated_packets``, ``late_packets`` (after their frame was handed on, its
        missing bytes counted in ``lost_bytes``), and ignored ones: ``duplicate_packets``,
        ``foreign_packets`` (another address), ``malformed_packets``, ``stale_packets`` (an earlier
        recording's: waiting when this one started, or beyond what it can have sent).  Also the board's status
        messages (``async_status``) and the receive buffer granted (``rcvbuf_bytes``)."""
        r, a, d = self.receiver.stats, self.receiver.assembler.stats, self._delivered
        seq_gaps = self.receiver.gaps.lost
        return {
            "url": self.url, "fpga": str(self.fpga_version),
            "frames_complete": d["complete"], "frames_incomplete": d["incomplete"],
            "frames_dropped": (self.ring.dropped_frames if self._dropped_when_left is None
                               else self._dropped_when_left),
            "missing_bytes": d["missing"], "lost_bytes": d["lost"], "cut_bytes": d["cut"],
            "packets": r.packets, "packets_lost": seq_gaps + a.tail_packets_lost, "seq_gaps": seq_gaps,
            "tail_packets_lost": a.tail_packets_lost,
            "truncated_packets": r.truncated_packets, "late_packets": a.late_packets,
            "duplicate_packets": a.duplicate_packets, "foreign_packets": r.foreign_packets,
            "malformed_packets": r.malformed_packets, "stale_packets": r.stale_packets,
            "async_status": dict(self.board.async_status.counts), "rcvbuf_bytes": r.rcvbuf_bytes,
        }

    def _release(self) -> None:
        """Stop in reverse order; every step is tried, the first failure is reported."""
        failures = []
        for step in (self._stop_radar, self._stop_recording, self.receiver.close,
                     self.radar.close, self.board.close):
            try:
                step()
            except RadarodomError as exc:
                failures.append(exc)
                log.warning("while stopping: %s", exc)
        if failures:
            log.debug("%d step(s) failed while stopping", len(failures))

    def _stop_radar(self) -> None:
        if not self.radar.is_open or self._radar_stopped:
            return
        self._radar_stopped = True
        try:
            self.radar.stop()
            self._frame_end_stop = True
        except DeviceTimeout:
            # A radar that no longer answers (hung, or interrupted mid-command)
            # is reset so that the next session finds it usable.
            raise DeviceTimeout(f"the radar did not answer sensorStop; {self._reset_radar()}") from None

    def _stop_recording(self) -> None:
        if self._recording:
            self._recording = False
            self.board.stop_recording()
            self._record_stopped = True


#: The most memory the frames waiting for the pipeline may take (``buffers=`` times a frame).
MAX_RING_BYTES = 2**31


def open_live(path: str, options: UrlOptions, config: RadarConfig | None) -> LiveSource:
    defaults = Dca1000Settings()
    board = path.strip("/") or defaults.board_ip
    host = options.take("host", given_text, defaults.host_ip, "this host's IP address on the board's network")
    cli = options.take("cli", given_text, None, "the radar's CLI port (path or pyserial URL)")
    config_port = options.take("config_port", udp_port, defaults.config_port, "a UDP port")
    data_port = options.take("data_port", udp_port, defaults.data_port, "a UDP port")
    board_port = options.take("board_port", udp_port, defaults.board_port, "a UDP port")
    delay = options.take("delay", number_in(*DCA1000_PACKET_DELAY_RANGE_US), defaults.packet_delay_us,
                         "packet delay in us")
    policy = options.take("policy", one_of(*POLICIES), "latest", " or ".join(POLICIES))
    buffers = options.take("buffers", at_least(2), 8, "a whole number of frames >= 2")
    timeout = options.take("timeout", positive_number, defaults.timeout_s, "seconds per board command")
    start_timeout = options.take("start_timeout", positive_number, 5.0, "seconds for sensorStart")
    cli_timeout = options.take("cli_timeout", positive_number, COMMAND_TIMEOUT_S, "seconds per radar CLI command")
    stop_timeout = options.take("stop_timeout", positive_number, defaults.stop_timeout_s,
                                "seconds to wait for RECORD_COMPLETED after RECORD_STOP")
    data_timeout = options.take("data_timeout", positive_number, None, "seconds without a data packet")
    options.finish()
    for what, address, every_interface in (("board address", board, False), ("host", host, True)):
        _check_ipv4(options.url, what, address, every_interface)
    if data_port == 0:  # a free port of this host's, which the board cannot know (config_port=0 is fine)
        raise SourceError(f"{options.url}: data_port=0: the board sends its data to the port stored in its EEPROM "
                          f"({defaults.data_port} unless changed): give that port, or leave data_port out")
    if config_port and config_port == data_port:  # the one socket would hold both, and the second bind fail
        raise SourceError(f"{options.url}: config_port and data_port are both {data_port}: this host's ports "
                          f"for the board's answers and its data must differ (the board's defaults: "
                          f"{defaults.config_port} and {defaults.data_port})")
    if cli is None:
        from .discovery import default_cli_port  # pyusb and sysfs only when needed

        cli = default_cli_port()
        if cli is None:
            raise SourceError(f"{options.url}: no AWR1843 CLI port found; give it with cli=/dev/ttyACM0 "
                              f"(radar-devices lists what is connected)")
    settings = Dca1000Settings(host_ip=host, board_ip=board, config_port=config_port, board_port=board_port,
                               data_port=data_port, packet_delay_us=delay, timeout_s=timeout,
                               stop_timeout_s=stop_timeout)
    cfg = config if config is not None else RadarConfig.from_file(shipped_config_path())
    if buffers * cfg.frame_bytes > MAX_RING_BYTES:
        raise SourceError(f"{options.url}: option buffers={buffers}: {buffers} frames of {cfg.frame_bytes} bytes "
                          f"need {buffers * cfg.frame_bytes / 2**30:.1f} GiB of memory; at most "
                          f"{MAX_RING_BYTES // cfg.frame_bytes} with this cfg")
    return LiveSource(cfg, settings, cli, policy=policy, buffers=buffers, start_timeout_s=start_timeout,
                      cli_timeout_s=cli_timeout, data_timeout_s=data_timeout)


def _check_ipv4(url: str, what: str, address: str, every_interface: bool) -> None:
    """The DCA1000 speaks UDP over IPv4 to fixed addresses (its EEPROM's): a name or a port
    here is a mistake, said before any board is looked for, as is an address of no one machine
    (0.0.0.0 taken only where *every_interface*: this host listening on all of its own)."""
    try:
        ip = ipaddress.IPv4Address(address)
    except ValueError:
        hint = ("; give ports as config_port=, data_port=, board_port=" if ":" in address
                else f" (the board's default: {BOARD_IP}, this host's: {HOST_IP})")
        raise SourceError(f"{url}: {what} {address!r} is not an IPv4 address{hint}") from None
    if ip.is_multicast or ip == ipaddress.IPv4Address("255.255.255.255") or (ip.is_unspecified and not every_interface):
        raise SourceError(f"{url}: {what} {address} is no one machine's address (the board's default: {BOARD_IP}, "
                          f"this host's: {HOST_IP})")
