"""The fake DCA1000's data port: the radar's frames cut into data packets, paced, with the
faults applied and every loss accounted (:class:`DataStreamer`, a part of
:class:`~.fake_dca1000.FakeDca1000`; its methods use the board's state, which
:class:`~.fake_dca1000.FakeDca1000` sets up)."""

from __future__ import annotations

import collections
import logging
import random
import time
from typing import Any, Iterator

import numpy as np

from ..live.dca1000_wire import DATA_HEADER, MAX_DATA_BYTES, DataPacket

log = logging.getLogger(__name__)

#: The streamer sleeps only when it is this far ahead of the paced schedule, s.
PACING_BATCH_S = 0.002
#: Longest single wait of a thread, s: bounds how late a state change or close is seen.
_WAIT_SLICE_S = 0.05

_RUN, _DRAIN, _ABORT = "run", "drain", "abort"


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


class DataStreamer:
    """The board's data port: its streamer thread packetizes the source's frames while the
    board records and the radar streams (:meth:`_run_streamer`)."""

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
            except Exception as exc:
                log.exception("fake DCA1000: the data stream failed: %s", exc)
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
