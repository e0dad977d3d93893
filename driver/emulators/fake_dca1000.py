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
import dataclasses
import logging
import random
import socket
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Iterator

import numpy as np

from ...cfg import RadarConfig, dca1000_capacity_mbps
from ...rawframe import RawLayout
from ..live.dca1000_wire import (
    DATA_HEADER,
    MAX_DATA_BYTES,
    AsyncStatus,
    CaptureMode,
    Command,
    DataPacket,
    EepromConfig,
    FormatMode,
    FpgaConfig,
    FpgaVersion,
    LogMode,
    LvdsMode,
    PacketConfig,
    Request,
    Response,
    Status,
    TransferMode,
    WireError,
)

log = logging.getLogger(__name__)

#: The streamer sleeps only when it is this far ahead of the paced schedule, s.
PACING_BATCH_S = 0.002
#: Longest single wait of a thread, s: bounds how late a state change or close is seen.
_WAIT_SLICE_S = 0.05
#: CONFIG_PACKET_DATA packet sizes the board accepts (DG: 48..1472).
MIN_PACKET_SIZE = 48
MAX_PACKET_SIZE = 1472
#: Packet delays the DG documents, us; others are accepted with a warning.
PACKET_DELAY_RANGE_US = (5.0, 500.0)
#: Largest datagram the config socket reads (a request is at most 512 bytes).
_RECV_BYTES = 65535

_RUN, _DRAIN, _ABORT = "run", "drain", "abort"
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


def _probability(name: str, value: float) -> float:
    value = float(value)
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"Faults.{name} = {value}: expected a probability in [0, 1]")
    return value


#: The two response statuses a command gets.
_OK, _FAILURE = int(Status.SUCCESS), int(Status.FAILURE)


@dataclass(frozen=True)
class Faults:
    """What the fake board does wrong.  All off by default.

    Probabilities are per data packet and drawn independently (in a fixed
    order, so a seed reproduces a run); when several hit one packet,
    ``malformed`` wins over ``loss``, which wins over the rest.
    """

    #: Probability a data packet is not sent (a seq gap on the wire).
    loss: float = 0.0
    #: Probability a data packet is sent twice in a row.
    duplicate: float = 0.0
    #: Probability a data packet is held back and sent after the next
    #: 1..``reorder_depth`` packets (it still arrives).
    reorder: float = 0.0
    reorder_depth: int = 3
    #: Probability a data packet's data is cut to a random shorter length
    #: (1..n-1 bytes; the header is unchanged).
    truncate: float = 0.0
    #: Probability a garbage datagram shorter than a header (1..9 random bytes)
    #: is sent instead of the packet, which is lost.
    malformed: float = 0.0
    #: Probability a packet is ALSO sent from another address (``foreign_ip``):
    #: same header and length, data bitwise inverted, so a host that does not
    #: filter by source address corrupts its frames visibly.
    foreign: float = 0.0
    #: End every frame with a short packet instead of letting packets straddle frames.
    burst_flush: bool = False
    #: Command codes answered with FAILURE (and not carried out).
    fail_commands: frozenset[int] = frozenset()
    #: Command codes never answered (and not carried out, as if not heard).
    silent_commands: frozenset[int] = frozenset()
    #: (frame index in the recording, status) pairs: the async status is sent
    #: when that frame starts streaming.
    async_errors: tuple[tuple[int, int], ...] = ()

    def __post_init__(self) -> None:
        for name in ("loss", "duplicate", "reorder", "truncate", "malformed", "foreign"):
            object.__setattr__(self, name, _probability(name, getattr(self, name)))
        if int(self.reorder_depth) < 1:
            raise ValueError(f"Faults.reorder_depth = {self.reorder_depth}: expected >= 1")
        object.__setattr__(self, "reorder_depth", int(self.reorder_depth))
        object.__setattr__(self, "fail_commands", frozenset(int(c) for c in self.fail_commands))
        object.__setattr__(self, "silent_commands", frozenset(int(c) for c in self.silent_commands))
        object.__setattr__(self, "async_errors",
                           tuple((int(k), int(s)) for k, s in self.async_errors))

    @property
    def any_packet_faults(self) -> bool:
        return any((self.loss, self.duplicate, self.reorder, self.truncate, self.malformed,
                    self.foreign))


@dataclass
class StreamStats:
    """Ground truth of one recording's data stream (reset by ``RECORD_START``).

    A "packet" is a numbered data packet (one ``seq``), whatever happened to
    it; ``datagrams`` counts what was actually written to the data port from
    the board's address (first copies, duplicates, garbage).
    """

    #: Recordings started since power-up (1 for the first RECORD_START).
    recording: int = 0
    #: Data packets numbered (= the last seq), dropped and malformed ones included.
    packets_sent: int = 0
    #: ADC bytes in those packets (= the stream length so far).
    bytes_sent: int = 0
    #: Frames all of whose bytes have been packetized.
    frames_sent: int = 0
    #: Frames the radar has streamed into the board (the last one's short tail may still be
    #: held back: it goes out when the recording stops).
    frames_in: int = 0
    #: Packets not sent (``Faults.loss``).
    dropped: int = 0
    #: Packets replaced by a garbage datagram (``Faults.malformed``).
    malformed: int = 0
    truncated: int = 0
    duplicates: int = 0
    reordered: int = 0
    #: Copies sent from the foreign address.
    foreign: int = 0
    #: Datagrams sent to the data port from the board's address.
    datagrams: int = 0
    #: Stream bytes that never arrived intact in a first copy (sum of
    #: ``lost_bytes_per_frame``).
    lost_bytes: int = 0
    #: Datagrams the kernel refused (sendto errors).
    send_errors: int = 0


class _Stream:
    """Per-recording state of the data stream; touched by the streamer thread only."""

    def __init__(self, recording_id: int, abort_id: int, rng: random.Random) -> None:
        self.recording_id = recording_id
        self.abort_id = abort_id
        self.rng = rng
        self.seq = 0
        #: Bytes appended but not yet packetized, starting at stream offset buf_start.
        self.buf = bytearray()
        self.buf_start = 0
        #: Frames not fully packetized: (index, stream start, stream end).
        self.frames: collections.deque[tuple[int, int, int]] = collections.deque()
        self.frame_index = 0
        self.iterator: Iterator[Any] | None = None
        #: The board's source generation the iterator belongs to.
        self.generation = 0
        #: A frame taken from the source whose start the stream paused before.
        self.pending: bytes | None = None
        self.exhausted = False
        #: Reordered packets: [packets still to go, datagrams].
        self.held: list[list[Any]] = []
        self.epoch = 0.0
        self.epoch_frame = 0
        self.link_free = 0.0
        self.warned_late = False


def _frame_bytes(item: Any) -> bytes:
    """A source item (bytes-like, ndarray, or a Frame with ``.raw``) as bytes."""
    raw = getattr(item, "raw", item)
    if isinstance(raw, np.ndarray):
        return np.ascontiguousarray(raw).tobytes()
    return bytes(raw)


def _url_with_rate_max(url: str) -> str:
    """*url* with its ``rate`` option replaced by ``rate=max`` (the board paces)."""
    base, sep, query = url.partition("?")
    items = [q for q in query.split("&") if q and not q.startswith("rate=")] if sep else []
    return base + "?" + "&".join(items + ["rate=max"])


class FakeDca1000:
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

        source = open_source(_url_with_rate_max(url), config)
        try:
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

            source = open_source(_url_with_rate_max(url), config)
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

    # ------------------------------------------------------------------ inspection
    @property
    def command_address(self) -> tuple[str, int]:
        """Where the host sends requests (the real board's 192.168.33.180:4096)."""
        return (self.board_ip, self.command_port)

    @property
    def source_address(self) -> tuple[str, int]:
        """Where replies, async status and data come from (the real board's port 1024)."""
        return (self.board_ip, self.source_port)

    @property
    def foreign_address(self) -> tuple[str, int] | None:
        """Where ``Faults.foreign`` copies come from (None without that fault)."""
        return None if self._foreign_sock is None else self._foreign_sock.getsockname()

    @property
    def recording(self) -> bool:
        return self._recording

    @property
    def lvds_active(self) -> bool:
        return self._lvds

    @property
    def fpga_config(self) -> FpgaConfig | None:
        """The accepted CONFIG_FPGA_GEN (None since power-up or RESET_FPGA)."""
        return self._fpga_config

    @property
    def packet_config(self) -> PacketConfig:
        """The accepted CONFIG_PACKET_DATA (the board default before one)."""
        return self._packet_config

    @property
    def eeprom_config(self) -> EepromConfig | None:
        """The last CONFIG_EEPROM (stored only; the fake keeps its addresses)."""
        return self._eeprom_config

    @property
    def host_config_address(self) -> tuple[str, int] | None:
        """Where async status goes: the address the last command came from."""
        return self._host_config_address

    @property
    def link_rate_mbps(self) -> float:
        """The paced data rate at the configured packet delay, Mbit/s of ADC data."""
        return dca1000_capacity_mbps(self._packet_config.delay_us)

    @property
    def stats(self) -> StreamStats:
        """A snapshot of the current (or last) recording's ground truth."""
        with self._cond:
            return dataclasses.replace(self._stats)

    @property
    def lost_bytes_per_frame(self) -> dict[int, int]:
        """Frame index -> bytes of it that never arrived intact in a first copy
        (dropped, malformed, truncated away; duplicates restore nothing,
        reordered packets arrive).  Only frames with losses are listed; bytes of
        a frame cut short by RESET_FPGA or close() count as lost."""
        with self._cond:
            return dict(self._lost)

    @property
    def async_sent(self) -> list[int]:
        """Async statuses sent so far, in order (ints of AsyncStatus bits)."""
        with self._cond:
            return list(self._async_log)

    @property
    def malformed_requests(self) -> int:
        """Config datagrams that were not well-formed requests (not answered)."""
        with self._cond:
            return self._malformed_requests

    @property
    def commands(self) -> dict[int, int]:
        """Well-formed requests received, by command code."""
        with self._cond:
            return dict(self._commands)

    def wait_frames(self, n: int, timeout: float = 5.0, *, streamed: bool = False) -> bool:
        """Wait until the current recording has packetized *n* frames (with *streamed*: until
        the radar has streamed *n* frames into the board, the last one's tail perhaps held
        back); False on timeout."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while (self._stats.frames_in if streamed else self._stats.frames_sent) < n:
                left = deadline - time.monotonic()
                if left <= 0 or self._closed:
                    return False
                self._cond.wait(min(left, _WAIT_SLICE_S))
            return True

    # ------------------------------------------------------------------ config port
    def _serve_commands(self) -> None:
        sock = self._cmd_sock
        while not self._closed:
            with self._cond:
                next_due = min((e[0] for e in self._events), default=None)
            timeout = _WAIT_SLICE_S if next_due is None else \
                min(_WAIT_SLICE_S, max(next_due - time.monotonic(), 0.0005))
            try:
                sock.settimeout(timeout)
                payload, addr = sock.recvfrom(_RECV_BYTES)
            except socket.timeout:
                pass
            except OSError:
                if self._closed:
                    break
                log.exception("fake DCA1000: config socket error")
                time.sleep(_WAIT_SLICE_S)
            else:
                try:
                    self._handle_request(payload, addr)
                except Exception:
                    log.exception("fake DCA1000: handling a request failed")
            self._run_due_events()

    def _handle_request(self, payload: bytes, addr: tuple[str, int]) -> None:
        try:
            request = Request.parse(payload)
        except WireError as exc:
            with self._cond:
                self._malformed_requests += 1
            log.warning("fake DCA1000: malformed request from %s:%d ignored: %s", *addr, exc)
            return
        code = request.command
        with self._cond:
            self._host_config_address = addr
            self._commands[code] += 1
        name = _command_name(code)
        if code in self.faults.silent_commands:
            log.info("fake DCA1000: %s not answered (fault)", name)
            return
        if code in self.faults.fail_commands:
            log.info("fake DCA1000: %s answered FAILURE (fault)", name)
            status = int(Status.FAILURE)
        else:
            status = self._execute(request)
        log.debug("fake DCA1000: %s -> status 0x%04X", name, status)
        self._send(self._src_sock, Response(code, status).pack(), addr)

    def _execute(self, request: Request) -> int:
        """Carry out one command; returns the response status."""
        handler = self._handlers.get(request.command)
        if handler is None:  # PLAYBACK_*, CONFIG_DATA_MODE_AR_DEV, INIT_FPGA_PLAYBACK, unknown codes
            log.warning("fake DCA1000: %s is not supported: FAILURE", _command_name(request.command))
            return _FAILURE
        return handler(request.data)

    @property
    def _handlers(self) -> dict[int, Callable[[bytes], int]]:
        return {Command.SYSTEM_CONNECT: self._system_connect, Command.READ_FPGA_VERSION: self._read_fpga_version,
                Command.SYSTEM_ERROR: self._system_error, Command.RESET_FPGA: self._reset_fpga,
                Command.RESET_AR_DEV: self._reset_ar_dev, Command.CONFIG_FPGA_GEN: self._config_fpga_gen,
                Command.CONFIG_PACKET_DATA: self._config_packet_data, Command.CONFIG_EEPROM: self._config_eeprom,
                Command.RECORD_START: self._record_start, Command.RECORD_STOP: self._record_stop}

    def _system_connect(self, data: bytes) -> int:
        return _OK

    def _read_fpga_version(self, data: bytes) -> int:
        return self.fpga_version.to_status()

    def _system_error(self, data: bytes) -> int:
        # The real board answers a host's SYSTEM_ERROR query with status 0,
        # even after an LVDS timeout (test_cmd.pcap; mmwave-capture-std notes).
        return _OK

    def _reset_fpga(self, data: bytes) -> int:
        with self._cond:
            if self._recording:
                log.info("fake DCA1000: RESET_FPGA stops the recording")
            self._recording = False
            self._abort_id += 1
            self._fpga_config = None
            self._packet_config = PacketConfig()
            self._events = [e for e in self._events if e[1] != "no_lvds"]
            self._cond.notify_all()
        return _OK

    def _reset_ar_dev(self, data: bytes) -> int:
        self.lvds_stop()  # a radar in reset streams nothing
        callback = self.on_reset_ar_dev
        if callback is not None:
            try:
                callback()
            except Exception:
                log.exception("fake DCA1000: on_reset_ar_dev failed")
                return _FAILURE
        return _OK

    def _config_fpga_gen(self, data: bytes) -> int:
        try:
            cfg = FpgaConfig.parse(data)
        except WireError as exc:
            log.warning("fake DCA1000: CONFIG_FPGA_GEN refused: %s", exc)
            return _FAILURE
        problem = _fpga_config_problem(cfg)
        if problem:
            log.warning("fake DCA1000: CONFIG_FPGA_GEN refused: %s", problem)
            return _FAILURE
        with self._cond:
            self._fpga_config = cfg
        return _OK

    def _config_packet_data(self, data: bytes) -> int:
        try:
            pkt = PacketConfig.parse(data)
        except WireError as exc:
            log.warning("fake DCA1000: CONFIG_PACKET_DATA refused: %s", exc)
            return _FAILURE
        if not MIN_PACKET_SIZE <= pkt.packet_size <= MAX_PACKET_SIZE:
            log.warning("fake DCA1000: CONFIG_PACKET_DATA refused: packet size %d outside "
                        "%d..%d", pkt.packet_size, MIN_PACKET_SIZE, MAX_PACKET_SIZE)
            return _FAILURE
        lo, hi = PACKET_DELAY_RANGE_US
        if not lo <= pkt.delay_us <= hi:
            log.warning("fake DCA1000: packet delay %.3f us is outside the documented "
                        "%g..%g us", pkt.delay_us, lo, hi)
        with self._cond:
            self._packet_config = pkt
        return _OK

    def _config_eeprom(self, data: bytes) -> int:
        try:
            eeprom = EepromConfig.parse(data)
        except WireError as exc:
            log.warning("fake DCA1000: CONFIG_EEPROM refused: %s", exc)
            return _FAILURE
        with self._cond:
            self._eeprom_config = eeprom
        return _OK

    def _record_start(self, data: bytes) -> int:
        with self._cond:
            if self._fpga_config is None:
                log.warning("fake DCA1000: RECORD_START refused: no CONFIG_FPGA_GEN since "
                            "power-up or RESET_FPGA")
                return _FAILURE
            if self._recording:
                log.info("fake DCA1000: RECORD_START while recording restarts the stream")
            self._recording = True
            self._recording_id += 1
            self._abort_id += 1
            self._stats = StreamStats(recording=self._recording_id)
            self._lost = {}
            self._lvds_seen = self._lvds
            self._events = [e for e in self._events if e[1] != "no_lvds"]
            if not self._lvds:
                self._events.append((time.monotonic() + self.no_lvds_timeout_s, "no_lvds",
                                     self._recording_id))
            self._cond.notify_all()
        log.info("fake DCA1000: recording %d started", self._recording_id)
        return _OK

    def _record_stop(self, data: bytes) -> int:
        with self._cond:
            if self._recording:
                self._recording = False
                due = time.monotonic() + self.record_completed_delay_s
                self._tail_due[self._recording_id] = due
                self._events.append((due, "record_completed", self._recording_id))
                self._cond.notify_all()
                log.info("fake DCA1000: recording %d stopped", self._recording_id)
        return _OK

    def _run_due_events(self) -> None:
        now = time.monotonic()
        send: list[int] = []
        with self._cond:
            keep = []
            for due, kind, rec in self._events:
                if due > now:
                    keep.append((due, kind, rec))
                elif kind == "record_completed":
                    still_sending = self._streamer_busy or self._held_tail[0] == rec and self._held_tail[1] > 0
                    if still_sending and not self._recording and rec == self._recording_id:
                        keep.append((now + 0.01, kind, rec))  # the stream or its tail is still going out
                    else:
                        send.append(int(AsyncStatus.RECORD_COMPLETED))
                elif kind == "no_lvds":
                    if self._recording and rec == self._recording_id and not self._lvds_seen:
                        send.append(int(AsyncStatus.NO_LVDS_DATA))
            self._events = keep
        for status in send:
            self._send_async(status)

    def _send_async(self, status: int) -> None:
        addr = self._host_config_address
        if addr is None:
            log.warning("fake DCA1000: async status 0x%04X dropped: no host has sent a command",
                        status)
            return
        with self._cond:
            self._async_log.append(int(status))
        log.info("fake DCA1000: async status %s", AsyncStatus(status))
        self._send(self._src_sock, Response(Command.SYSTEM_ERROR, int(status)).pack(), addr)

    def _send(self, sock: socket.socket, payload: bytes, addr: tuple[str, int]) -> bool:
        try:
            sock.sendto(payload, addr)
            return True
        except OSError as exc:
            log.debug("fake DCA1000: sendto %s:%d failed: %s", *addr, exc)
            with self._cond:
                self._stats.send_errors += 1
            return False

    # ------------------------------------------------------------------ data stream
    def _state(self, st: _Stream) -> str:
        if self._closed or self._abort_id != st.abort_id:
            return _ABORT
        if not (self._recording and self._lvds):
            return _DRAIN
        return _RUN

    def _run_streamer(self) -> None:
        st: _Stream | None = None
        while True:
            flush = False
            with self._cond:
                while not self._closed:
                    if self._recording and self._lvds and not (
                            st is not None and st.recording_id == self._recording_id and st.exhausted):
                        break
                    due = None if st is None else self._tail_due.get(st.recording_id)
                    if due is not None and time.monotonic() >= due and st.buf and st.abort_id == self._abort_id:
                        flush = True
                        break
                    self._cond.wait(_WAIT_SLICE_S)
                if self._closed:
                    return
                if not flush and (st is None or st.recording_id != self._recording_id):
                    rng = random.Random(f"{self.seed}:{self._recording_id}")
                    st = _Stream(self._recording_id, self._abort_id, rng)
                self._streamer_busy = True
            try:
                if flush:  # the recording stopped: the held-back tail goes out now
                    if self._send_buffer(st, final=True, available=time.monotonic()) == _ABORT:
                        self._abort(st)
                    self._release_held(st, all_=True)
                else:
                    self._pump(st)
            except Exception:
                log.exception("fake DCA1000: the data stream failed")
                st.exhausted = True
            finally:
                with self._cond:
                    self._held_tail = (st.recording_id, len(st.buf))
                    self._streamer_busy = False
                    self._cond.notify_all()

    def _wait_until(self, st: _Stream, due: float, interrupt_on_drain: bool) -> str:
        """Sleep until *due* (monotonic); returns the stream state that ended the wait."""
        while True:
            state = self._state(st)
            if state == _ABORT or (state == _DRAIN and interrupt_on_drain):
                return state
            left = due - time.monotonic()
            if left <= 0:
                return state
            with self._cond:
                self._cond.wait(min(left, _WAIT_SLICE_S))

    def _pump(self, st: _Stream) -> None:
        """Stream frames until the stream pauses (drain), is cut (abort) or ends."""
        paced = self.rate == "paced"
        st.epoch = st.link_free = time.monotonic()
        st.epoch_frame = st.frame_index
        while True:
            state = self._state(st)
            if state == _ABORT:
                return self._abort(st)
            if state == _DRAIN:  # the radar or the recording stopped: the short tail waits
                if self._send_buffer(st, final=self.faults.burst_flush, available=time.monotonic()) == _ABORT:
                    return self._abort(st)
                return self._release_held(st, all_=True)
            frame = st.pending if st.pending is not None else self._next_frame(st)
            st.pending = None
            if st.frame_index == st.epoch_frame:
                # The radar's frames start once it chirps: a source's start-up (a simulator
                # building its scene) delays the first frame, not the period of the rest.
                st.epoch = st.link_free = time.monotonic()
            if frame is None:
                st.exhausted = True
                log.info("fake DCA1000: source ended after %d frames", st.frame_index)
                if self._send_buffer(st, final=self.faults.burst_flush, available=time.monotonic()) == _ABORT:
                    return self._abort(st)
                return self._release_held(st, all_=True)
            due = time.monotonic()
            if paced:
                due = st.epoch + (st.frame_index - st.epoch_frame) * self.frame_period_s
                if self._wait_until(st, due, interrupt_on_drain=True) != _RUN:
                    st.pending = frame  # not begun: sent when the stream resumes
                    continue
                late = time.monotonic() - due
                if late > self.frame_period_s and not st.warned_late:
                    st.warned_late = True
                    self._warn_late(st, late, len(frame))
            k = st.frame_index
            st.frame_index += 1
            with self._cond:
                if self._recording_id == st.recording_id:
                    self._stats.frames_in += 1
                    self._cond.notify_all()
            for status in self._async_by_frame.get(k, ()):
                self._send_async(status)
            start = st.buf_start + len(st.buf)
            st.frames.append((k, start, start + len(frame)))
            st.buf += frame
            if self._send_buffer(st, final=self.faults.burst_flush, available=due) == _ABORT:
                return self._abort(st)

    def _warn_late(self, st: _Stream, late: float, frame_bytes: int) -> None:
        """Say why frame st.frame_index is *late* s late: the link (its frames do not fit the
        period at the packet delay) or this computer (the source makes them too slowly)."""
        link_s = frame_bytes * 8 / (self.link_rate_mbps * 1e6)
        if link_s > self.frame_period_s:
            log.warning("fake DCA1000: frame %d is %.3f s late: the link, %.1f Mbit/s at %.1f us packet delay, "
                        "needs %.1f ms for a %d-byte frame, more than the %.1f ms frame period", st.frame_index,
                        late, self.link_rate_mbps, self._packet_config.delay_us, link_s * 1e3, frame_bytes,
                        self.frame_period_s * 1e3)
        else:
            log.warning("fake DCA1000: frame %d is %.3f s late: its source makes frames slower than the %.1f ms "
                        "frame period on this computer's CPU (the %.1f Mbit/s link needs %.1f ms a frame); the "
                        "frames still arrive whole, later", st.frame_index, late, self.frame_period_s * 1e3,
                        self.link_rate_mbps, link_s * 1e3)

    def _next_frame(self, st: _Stream) -> bytes | None:
        if self._frames is None:
            return None
        if st.generation != self._frames_generation:  # a new source: from its first frame
            st.iterator, st.generation = None, self._frames_generation
        for _ in range(2):
            if st.iterator is None:
                st.iterator = iter(self._frames())
            try:
                return _frame_bytes(next(st.iterator))
            except StopIteration:
                st.iterator = None
                if not self.loop:
                    return None
        return None  # the source yields nothing even when restarted

    def _send_buffer(self, st: _Stream, *, final: bool, available: float) -> str:
        """Packetize st.buf: full packets, and the short rest too when *final*."""
        buf = st.buf
        paced = self.rate == "paced"
        seconds_per_byte = 8 / (self.link_rate_mbps * 1e6)
        pos = 0
        state = _RUN
        while len(buf) - pos >= MAX_DATA_BYTES or (final and len(buf) > pos):
            n = min(MAX_DATA_BYTES, len(buf) - pos)
            if self._closed or self._abort_id != st.abort_id:
                state = _ABORT
                break
            if paced:
                t_send = max(st.link_free, available)
                st.link_free = t_send + n * seconds_per_byte
                if t_send - time.monotonic() > PACING_BATCH_S:
                    if self._wait_until(st, t_send, interrupt_on_drain=False) == _ABORT:
                        state = _ABORT
                        break
            if not self._emit(st, st.buf_start + pos, bytes(buf[pos: pos + n])):
                state = _ABORT
                break
            pos += n
        del buf[:pos]
        st.buf_start += pos
        return state

    def _emit(self, st: _Stream, start: int, data: bytes) -> bool:
        """Number one data packet, apply the faults, account for it and send it.
        False when the recording changed under us (nothing sent)."""
        f = self.faults
        n = len(data)
        dropped = malformed = duplicate = foreign = False
        keep = n
        reorder_after = 0
        if f.any_packet_faults:
            rng = st.rng
            # Every draw is made for every packet, so a seed reproduces a run.
            malformed = rng.random() < f.malformed
            dropped = rng.random() < f.loss
            cut = rng.random() < f.truncate
            keep_draw = rng.randint(1, n - 1) if n > 1 else n
            duplicate = rng.random() < f.duplicate
            reorder_draw = rng.random() < f.reorder
            after_draw = rng.randint(1, f.reorder_depth)
            foreign = rng.random() < f.foreign
            if malformed or dropped:
                dropped = not malformed
            else:
                keep = keep_draw if cut else n
                reorder_after = after_draw if reorder_draw else 0
        seq = st.seq + 1
        if malformed:
            datagrams = [st.rng.randbytes(st.rng.randint(1, DATA_HEADER.size - 1))]
        elif dropped:
            datagrams = []
        else:
            wire = DataPacket(seq, start, data[:keep]).pack()
            datagrams = [wire, wire] if duplicate else [wire]
        lost_from = start if (malformed or dropped) else start + keep
        with self._cond:
            if self._recording_id != st.recording_id:
                return False
            st.seq = seq
            s = self._stats
            s.packets_sent += 1
            s.bytes_sent += n
            s.datagrams += len(datagrams)
            if malformed:
                s.malformed += 1
            elif dropped:
                s.dropped += 1
            else:
                s.truncated += keep < n
                s.duplicates += duplicate
                s.reordered += reorder_after > 0
            s.foreign += foreign
            end = start + n
            if lost_from < end:
                self._account_loss(st, lost_from, end)
            while st.frames and st.frames[0][2] <= end:
                st.frames.popleft()
                s.frames_sent += 1
                self._cond.notify_all()
        if reorder_after and datagrams:
            self._release_held(st)
            st.held.append([reorder_after, datagrams])
        else:
            self._send_data(datagrams)
            self._release_held(st)
        if foreign:
            inverted = (np.frombuffer(data, np.uint8) ^ 0xFF).tobytes()
            self._send(self._foreign_sock, DataPacket(seq, start, inverted).pack(),
                       (self.host_ip, self.host_data_port))
        return True

    def _account_loss(self, st: _Stream, lo: int, hi: int) -> None:
        """Add stream bytes [lo, hi) to the lost bytes of their frames (under _cond)."""
        for k, fs, fe in st.frames:
            if fe <= lo:
                continue
            if fs >= hi:
                break
            n = min(hi, fe) - max(lo, fs)
            self._lost[k] = self._lost.get(k, 0) + n
            self._stats.lost_bytes += n

    def _release_held(self, st: _Stream, all_: bool = False) -> None:
        """Count one more packet for the held (reordered) ones and send those whose
        turn it is; all of them when *all_*."""
        if not st.held:
            return
        due, keep = [], []
        for entry in st.held:
            entry[0] -= 1
            (due if all_ or entry[0] <= 0 else keep).append(entry)
        st.held = keep
        for _, datagrams in due:
            self._send_data(datagrams)

    def _send_data(self, datagrams: list[bytes]) -> None:
        addr = (self.host_ip, self.host_data_port)
        for payload in datagrams:
            self._send(self._src_sock, payload, addr)

    def _abort(self, st: _Stream) -> None:
        """The stream is cut (RESET_FPGA, a new RECORD_START, close): the bytes
        not yet packetized are lost; held packets still go out."""
        with self._cond:
            if self._recording_id == st.recording_id and st.buf:
                self._account_loss(st, st.buf_start, st.buf_start + len(st.buf))
        st.buf_start += len(st.buf)
        st.buf.clear()
        st.frames.clear()
        st.exhausted = True
        self._release_held(st, all_=True)


def _fpga_config_problem(cfg: FpgaConfig) -> str:
    """Why the fake refuses a CONFIG_FPGA_GEN ('' when it accepts it): only raw
    Ethernet capture of 16-bit samples over 2 LVDS lanes (the AWR1843) is supported."""
    wanted = (("log mode", cfg.log_mode, LogMode.RAW), ("LVDS mode", cfg.lvds_mode, LvdsMode.TWO_LANE),
              ("transfer mode", cfg.transfer_mode, TransferMode.CAPTURE),
              ("capture mode", cfg.capture_mode, CaptureMode.ETHERNET),
              ("format mode", cfg.format_mode, FormatMode.BIT16))
    bad = [f"{name} {value} (expected {int(want)} = {want.name})"
           for name, value, want in wanted if value != want]
    return "; ".join(bad)


def _command_name(code: int) -> str:
    try:
        return Command(code).name
    except ValueError:
        return f"command 0x{code:04X}"
