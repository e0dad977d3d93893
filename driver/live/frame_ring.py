"""A ring of preallocated frame buffers between the capture thread and the consumer.

The capture side takes a free buffer (:meth:`FrameRing.acquire`), fills it,
and publishes it; the consumer takes published frames in order
(:meth:`FrameRing.get`) and gives each buffer back (:meth:`FrameRing.release`)
when done.  A buffer the consumer holds is never written: when the consumer
is slower than the radar and no buffer is free, whole frames are dropped and
counted, by policy:

- ``latest``: the oldest frame still waiting for the consumer is dropped, so
  the consumer always gets the freshest data (live odometry);
- ``queue``: the new frame is dropped, so the consumer gets an unbroken run of
  older frames (it is the one falling behind).
"""

from __future__ import annotations

import collections
import threading
from dataclasses import dataclass

import numpy as np

from ...errors import UsageError

POLICIES = ("latest", "queue")


@dataclass
class RingFrame:
    """A frame in the ring: its buffer slot and what the assembler knows of it."""

    slot: int
    #: Frame number since RECORD_START (stream byte offset // frame bytes).
    index: int
    #: The frame's bytes, uint8 (frame_bytes,); gaps are zero.
    data: np.ndarray
    #: Bytes that never arrived (zero-filled).
    missing_bytes: int
    #: Host time (time.time()) the first packet touching the frame arrived.
    first_packet_time: float
    #: time.monotonic() when the frame was completed or given up on (its last packet, or
    #: the packet that proved it would not complete): the start of its end-to-end latency.
    done_monotonic: float = 0.0
    #: Of missing_bytes, those the stream had not reached when the frame was handed on (cut at
    #: stop).
    cut_bytes: int = 0
    #: Of missing_bytes, those the packet headers show were sent and never came (lost on the
    #: way), counted from sequence and byte-count gaps: missing_bytes = lost_bytes + cut_bytes.
    lost_bytes: int = 0


class FrameRing:
    """``slots`` buffers of ``frame_bytes``; thread-safe."""

    def __init__(self, frame_bytes: int, slots: int = 8, policy: str = "latest") -> None:
        if policy not in POLICIES:
            raise UsageError(f"drop policy {policy!r}: use {' or '.join(POLICIES)}")
        if slots < 2:
            raise UsageError("the frame ring needs at least 2 buffers")
        self.frame_bytes = frame_bytes
        self.policy = policy
        self._buffers = np.zeros((slots, frame_bytes), np.uint8)
        self._free = collections.deque(range(slots))
        self._ready: collections.deque[RingFrame] = collections.deque()
        self._cond = threading.Condition()
        self._closed = False
        #: Frames dropped because the consumer was too slow.
        self.dropped_frames = 0

    @property
    def slots(self) -> int:
        return len(self._buffers)

    def acquire(self) -> int | None:
        """A free buffer slot (zeroed), or None when the policy drops the new frame."""
        with self._cond:
            if self._free:
                slot = self._free.popleft()
            elif self.policy == "latest" and self._ready:
                slot = self._ready.popleft().slot  # the oldest waiting frame makes room
                self.dropped_frames += 1
            else:
                self.dropped_frames += 1
                return None
        self._buffers[slot].fill(0)
        return slot

    def buffer(self, slot: int) -> np.ndarray:
        return self._buffers[slot]

    def publish(self, frame: RingFrame) -> None:
        with self._cond:
            self._ready.append(frame)
            self._cond.notify()

    def discard(self, slot: int) -> None:
        """Give back a slot that was acquired but will not be published."""
        self.release(slot)

    def get(self, timeout: float | None = None) -> RingFrame | None:
        """The next published frame, or None after *timeout* s or once closed and empty."""
        with self._cond:
            if not self._ready and not self._closed:
                self._cond.wait(timeout)
            return self._ready.popleft() if self._ready else None

    def release(self, slot: int) -> None:
        with self._cond:
            self._free.append(slot)

    @property
    def waiting(self) -> int:
        """Frames published and not yet taken."""
        with self._cond:
            return len(self._ready)

    def close(self) -> None:
        """Wake a waiting consumer; :meth:`get` returns what is left, then None."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
