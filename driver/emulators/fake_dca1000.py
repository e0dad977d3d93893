"""A fake DCA1000EVM: the capture card's UDP protocol on loopback, with faults.

:class:`FakeDca1000` binds real UDP sockets and behaves like the board as
``protocol.md`` describes it, so the host driver can be tested (and tried
without hardware) over the same code path it uses with a real board:

- **Config port.**  A socket bound to ``(board_ip, command_port)`` takes
  :class:`~radarodom.driver.live.dca1000_wire.Request` datagrams and answers each
  well-formed one with an 8-byte :class:`~radarodom.driver.live.dca1000_wire.Response`
  (same command code) sent *from* a second socket bound to
  ``(board_ip, source_port)`` -- the real board answers from port 1024, not
  from 4096 -- *to* the address the request came from.  Malformed requests
  get no answer and are counted (:attr:`FakeDca1000.malformed_requests`).
- **Asynchronous status** (``SYSTEM_ERROR`` responses whose status is an
  :class:`~radarodom.driver.live.dca1000_wire.AsyncStatus` bitmask) goes to the
  address the last command came from: ``RECORD_COMPLETED``
  ``record_completed_delay_s`` (2.0 s, the real capture's gap) after ``RECORD_STOP``,
  once the stream has drained, ``NO_LVDS_DATA`` once when a recording runs for
  ``no_lvds_timeout_s`` without :meth:`FakeDca1000.lvds_start`, and whatever
  :attr:`Faults.async_errors` asks for.
- **Data port.**  While recording *and* while the (fake) radar streams LVDS
  data (:meth:`~FakeDca1000.lvds_start` / :meth:`~FakeDca1000.lvds_stop`), the
  frames of a source are cut into a continuous byte stream and sent to
  ``(host_ip, host_data_port)`` from the source socket as
  :class:`~radarodom.driver.live.dca1000_wire.DataPacket` datagrams: ``seq`` from
  1 after ``RECORD_START``, ``byte_count`` = stream bytes before the packet,
  up to :data:`~radarodom.driver.live.dca1000_wire.MAX_DATA_BYTES` (1456) data
  bytes each.  Frame *k* of a recording occupies stream bytes
  ``[k * frame_bytes, (k + 1) * frame_bytes)`` and packets straddle frame
  boundaries; the bytes left over at the end of a frame wait for the next
  frame's, and when the radar stops streaming (``lvds_stop``, the end of a
  non-looping source) they wait for the recording to stop: they go out as one
  short packet ``record_completed_delay_s`` after ``RECORD_STOP``, just before
  ``RECORD_COMPLETED`` -- as in the real capture (pcaps), where the short last
  packet and ``RECORD_COMPLETED`` arrive together 2.0 s after the last full
  packet.  :attr:`Faults.burst_flush` instead ends every frame with a short packet.

Timing (``rate="paced"``): frame *k* after the stream (re)starts is due at
``start + k * frame_period_s``; its bytes leave at the board's Ethernet rate
for the configured packet delay,
:func:`~radarodom.cfg.dca1000_capacity_mbps` (UG Table 19): a packet is sent
at ``max(link free, due time of the frame that completes it)`` and holds the
link for ``data_bytes * 8 / capacity``.  Python cannot sleep a few
microseconds, so the streamer only sleeps when it is more than
:data:`PACING_BATCH_S` ahead of that schedule and sends everything due in a
burst: the average rate and the frame starts are right, single gaps are not.
``rate="max"`` sends as fast as Python can (throughput benchmarks).

Faults (:class:`Faults`, drawn from a :class:`random.Random` seeded by
``seed`` and the recording number, so a run is reproducible) hit data
packets; the ground truth of what they did is kept per recording in
:attr:`FakeDca1000.stats` and :attr:`FakeDca1000.lost_bytes_per_frame`.
Data packets are only ever emitted in stream order by one thread, so the
accounting is exact.

Differences from the real board that are on purpose (see also the notes on
each command in :meth:`FakeDca1000._execute`):

- The data bytes per packet are always 1456 (protocol.md: "full packets carry
  1456 data bytes"); ``CONFIG_PACKET_DATA``'s packet size is validated
  (48..1472) but does not change the cut, because nothing in the references
  says how the board maps it to a payload size (TI sends 1470 or 1472 and the
  capture still shows 1456-byte payloads).
- ``RECORD_START`` needs a ``CONFIG_FPGA_GEN`` since power-up or the last
  ``RESET_FPGA``; the real capture ``test_cmd.pcap`` shows a board that had
  been configured in an earlier session.
"""

from __future__ import annotations

import collections
import logging
import socket
import threading
from typing import Any, Callable, Iterable

from ...cfg import RadarConfig
from ...errors import UsageError
from ...rawframe import RawLayout
from ..live.dca1000_wire import EepromConfig, FpgaConfig, FpgaVersion, PacketConfig
from .dca1000_commands import CommandPort
from .dca1000_faults import Faults, StreamStats
from .dca1000_inspection import BoardInspection
from .dca1000_streamer import DataStreamer, _frame_bytes
from .source_url import emulated_source_url, no_raw_frames_message

log = logging.getLogger(__name__)

#: Seconds from RECORD_STOP to the held-back short packet and RECORD_COMPLETED: the real capture
#: (pcaps, test_one_frame.pcap) has both 2.000 s after the last full data packet.  Whether a
#: host's RECORD_STOP starts that wait or the board ends a recording by itself 2 s after its LVDS
#: data stop is not in the references; here the wait starts at RECORD_STOP.
RECORD_COMPLETED_DELAY_S = 2.0
#: Seconds of recording without LVDS data before NO_LVDS_DATA.  Undocumented: TI's DCA1000 CLI
#: calls CONFIG_FPGA_GEN's last byte (30) the "timeout for LVDS data", units not given, and users
#: report the status "after a few seconds"; 3 s is within that.
NO_LVDS_TIMEOUT_S = 3.0
#: READ_FPGA_VERSION's answer by default: the real board's 2.8, record image (pcaps).
DEFAULT_FPGA_VERSION = FpgaVersion(2, 8, False)


def _url_with_rate_max(url: str) -> str:
    """*url* with its ``rate`` option replaced by ``rate=max`` (the board paces)."""
    return emulated_source_url(url, replaced={"rate": "max"})


class FakeDca1000(CommandPort, DataStreamer, BoardInspection):
    """A DCA1000EVM on loopback UDP.  See the module docstring.

    Construct, then :meth:`start` (or use ``with``); :meth:`close` stops the
    threads and closes the sockets.  *frames* is a zero-argument callable
    returning an iterable of frames (bytes-like, uint8 arrays, or objects
    with ``.raw``); it is called at the first frame of each recording and
    again whenever the iterable ends (the source loops forever unless
    ``loop=False``, in which case the stream ends with the source).  Without
    *frames* the board answers commands but never streams.
    """

    def __init__(
        self,
        *,
        host_data_port: int,
        frames: Callable[[], Iterable[Any]] | None = None,
        frame_period_s: float = 0.1,
        board_ip: str = "127.0.0.2",
        command_port: int = 0,
        source_port: int = 0,
        host_ip: str = "127.0.0.1",
        faults: Faults | None = None,
        seed: int = 0,
        fpga_version: FpgaVersion = DEFAULT_FPGA_VERSION,
        rate: str = "paced",
        loop: bool = True,
        record_completed_delay_s: float = RECORD_COMPLETED_DELAY_S,
        no_lvds_timeout_s: float = NO_LVDS_TIMEOUT_S,
        foreign_ip: str = "127.0.0.3",
        on_reset_ar_dev: Callable[[], Any] | None = None,
    ) -> None:
        if rate not in ("paced", "max"):
            raise ValueError(f"rate={rate!r}: expected 'paced' or 'max'")
        if rate == "paced" and not frame_period_s > 0:
            raise ValueError(f"frame_period_s={frame_period_s}: expected > 0 when paced")
        self.board_ip = board_ip
        self.host_ip = host_ip
        self.host_data_port = int(host_data_port)
        self.frame_period_s = float(frame_period_s)
        self.faults = faults if faults is not None else Faults()
        self.seed = seed
        self.fpga_version = fpga_version
        self.rate = rate
        self.loop = loop
        self.record_completed_delay_s = float(record_completed_delay_s)
        self.no_lvds_timeout_s = float(no_lvds_timeout_s)
        self.foreign_ip = foreign_ip
        #: Called on RESET_AR_DEV (e.g. to reset a fake radar); an exception answers FAILURE.
        self.on_reset_ar_dev = on_reset_ar_dev
        #: The radar configuration of the source (set by :meth:`from_url`; the radar's, once it
        #: starts with another one).
        self.config: RadarConfig | None = None
        self._source_url: str | None = None
        self._frames = frames
        self._frames_generation = 0  # bumped when the source is replaced: the stream restarts it
        self._owned: list[Any] = []  # closed by close()
        self._async_by_frame: dict[int, list[int]] = collections.defaultdict(list)
        for k, status in self.faults.async_errors:
            self._async_by_frame[k].append(status)

        # State shared by the threads, under _cond.
        self._cond = threading.Condition()
        self._closed = False
        self._started = False
        self._recording = False
        self._lvds = False
        self._lvds_seen = False  # lvds_start since RECORD_START
        self._recording_id = 0  # bumped by RECORD_START: a new stream and new ground truth
        self._abort_id = 0  # bumped by RECORD_START and RESET_FPGA: cut the stream now
        self._streamer_busy = False
        self._fpga_config: FpgaConfig | None = None
        self._packet_config = PacketConfig()
        self._eeprom_config: EepromConfig | None = None
        self._host_config_address: tuple[str, int] | None = None
        self._events: list[tuple[float, str, int]] = []  # (due, kind, recording id)
        #: Recording id -> when its held-back tail goes out (RECORD_STOP + record_completed_delay_s).
        self._tail_due: dict[int, float] = {}
        #: (recording id, bytes) of the short packet the streamer holds back.
        self._held_tail = (0, 0)
        self._stats = StreamStats()
        self._lost: dict[int, int] = {}
        self._async_log: list[int] = []
        self._malformed_requests = 0
        self._commands: collections.Counter[int] = collections.Counter()

        self._cmd_sock = self._src_sock = self._foreign_sock = None
        try:
            self._cmd_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self._cmd_sock.bind((board_ip, command_port))
            self._src_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self._src_sock.bind((board_ip, source_port))
            self._src_sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 22)
            if self.faults.foreign > 0:
                self._foreign_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                self._foreign_sock.bind((foreign_ip, 0))
        except OSError:
            self._close_sockets()
            raise
        self.command_port: int = self._cmd_sock.getsockname()[1]
        self.source_port: int = self._src_sock.getsockname()[1]
        self._threads: list[threading.Thread] = []

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_url(cls, url: str, config: RadarConfig | None = None, **kw: Any) -> "FakeDca1000":
        """A board streaming the frames of source *url* (``replay://``, ``sim://``),
        looped forever.  The source is opened with ``rate=max`` (the board
        paces), *config* is passed to it, ``frame_period_s`` defaults to the
        source's configuration, and the source is closed with the board."""
        from ..sources import open_source

        source = open_source(_url_with_rate_max(url), config, shown_url=url)
        try:
            if not source.carries_raw:
                raise UsageError(no_raw_frames_message(url))
            kw.setdefault("frame_period_s", source.config.frame_period_s)
            board = cls(frames=lambda: (f.raw for f in source), **kw)
        except BaseException:
            source.close()
            raise
        board.config = source.config
        board._source_url = url
        board._owned.append(source)
        return board

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> "FakeDca1000":
        """Start answering commands and the streamer.  Idempotent."""
        with self._cond:
            if self._closed:
                raise RuntimeError("FakeDca1000 is closed")
            if self._started:
                return self
            self._started = True
        self._threads = [
            threading.Thread(target=self._serve_commands, name="fake-dca1000-config", daemon=True),
            threading.Thread(target=self._run_streamer, name="fake-dca1000-data", daemon=True),
        ]
        for t in self._threads:
            t.start()
        log.debug("fake DCA1000 at %s:%d (replies from port %d), data to %s:%d",
                  self.board_ip, self.command_port, self.source_port, self.host_ip,
                  self.host_data_port)
        return self

    def close(self) -> None:
        """Stop the threads (joined) and close the sockets and an owned source.  Idempotent."""
        with self._cond:
            already = self._closed
            self._closed = True
            self._cond.notify_all()
        if already:
            return
        for t in self._threads:
            t.join()
        self._close_sockets()
        for obj in self._owned:
            try:
                obj.close()
            except Exception:  # pragma: no cover - a source's close failing is not ours
                log.exception("closing %r failed", obj)
        self._owned.clear()

    def _close_sockets(self) -> None:
        for sock in (self._cmd_sock, self._src_sock, self._foreign_sock):
            if sock is not None:
                sock.close()

    def __enter__(self) -> "FakeDca1000":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ------------------------------------------------------------------ fake radar side
    def lvds_start(self, config: RadarConfig | None = None) -> None:
        """The radar starts streaming LVDS data (its ``sensorStart``).

        *config* is the radar's configuration, as a fake radar's
        ``on_sensor_start(config)`` hands it over.  The board then streams that
        configuration's frames where it can: a simulator source (``sim://``)
        makes them anew (any TX order, size, period); a recording's TX slots are
        put in the configured order when only that differs.  Otherwise a
        warning says what differs and the stream is the source's."""
        if config is not None and self.config is not None and config != self.config:
            self._follow(config)
        with self._cond:
            self._lvds = True
            self._lvds_seen = True
            self._cond.notify_all()

    def _follow(self, config: RadarConfig) -> None:
        """Stream *config*'s frames from now on (see :meth:`lvds_start`)."""
        old = self.config
        url = self._source_url
        if url is not None and url.startswith("sim:"):
            from ..sources import open_source

            source = open_source(_url_with_rate_max(url), config, shown_url=url)
            self._replace_source(lambda: (f.raw for f in source), config, source)
            log.info("fake DCA1000: the simulator now makes the radar's frames (TX order %s, %d bytes)",
                     " ".join(f"TX{t}" for t in config.tx_order), config.frame_bytes)
        elif (old.cube_shape == config.cube_shape and old.rx_indices == config.rx_indices
              and sorted(old.tx_order) == sorted(config.tx_order) and len(set(old.tx_order)) == len(old.tx_order)):
            if old.tx_order != config.tx_order:
                order = [old.tx_order.index(t) for t in config.tx_order]
                source_layout, radar_layout = RawLayout.from_config(old), RawLayout.from_config(config)
                frames = self._frames
                self._replace_source(lambda: (radar_layout.encode(source_layout.decode(_frame_bytes(f))[:, order])
                                              for f in frames()), config, None)
                log.info("fake DCA1000: the recording's TX slots %s streamed in the radar's order %s",
                         old.tx_order, config.tx_order)
        elif old.frame_bytes != config.frame_bytes:
            log.warning("fake DCA1000: the radar streams %d-byte frames but the board's source "
                        "has %d-byte frames", config.frame_bytes, old.frame_bytes)
        else:
            log.warning("fake DCA1000: the radar's configuration differs from the recording's (cube %s, "
                        "TX %s against %s, TX %s): the recording is streamed as it is", config.cube_shape,
                        config.tx_order, old.cube_shape, old.tx_order)

    def _replace_source(self, frames: Callable[[], Iterable[Any]], config: RadarConfig, owned: Any) -> None:
        with self._cond:
            self._frames = frames
            self.config = config
            self.frame_period_s = config.frame_period_s
            self._frames_generation += 1
            if owned is not None:
                stale, self._owned = self._owned, [owned]
            else:
                stale = []
        for obj in stale:
            obj.close()

    def lvds_stop(self) -> None:
        """The radar stops streaming (its ``sensorStop``): the frame being sent is
        finished, the leftover bytes go out as a short packet, then the stream pauses."""
        with self._cond:
            self._lvds = False
            self._cond.notify_all()


__all__ = ["DEFAULT_FPGA_VERSION", "NO_LVDS_TIMEOUT_S", "RECORD_COMPLETED_DELAY_S", "FakeDca1000", "Faults",
           "StreamStats"]
