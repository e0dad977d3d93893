"""The view's drawing in a process of its own (``radar-capture --view spawn``, ``web`` and
``connect:``).

What a viewer or a browser reads can hold Rerun's calls up: a viewer that stops reading (frozen,
a host that accepts the connection and reads nothing) holds Rerun's last flush up for good, and
with it the end of the process that logged; a browser connecting to the web viewer held the
logging up long enough to stall the radar's pipeline when the view drew in the radar's process
(docs/benchmarks.md).  In a process of its own that holds up the view alone, and the process can
be stopped.  The hand-over costs the pipeline's thread more wall time than a thread's queue does,
so a file, which nothing outside holds up, is drawn in a thread (:class:`~.sink.ThreadDrawer`).

The pipeline's thread pickles each frame it hands over (its tracks, point cloud and heatmap: about
0.2 MB) and writes it to a socket without blocking; what the socket does not take at once is sent
when the pipeline next asks whether the view is ready, and until it is gone no other frame is
handed over (their drawing is dropped).  A child process reads and draws: ``python -c ...
FD`` running this module's ``_child``, a fresh interpreter that inherits nothing of the radar's threads or
sockets but the one socket, and never imports the caller's main module (as multiprocessing's
spawn does: a script without a ``__main__`` guard would start itself again).  At the end, a child
still held up after the sink's close timeout is stopped, and the radar's process still ends.

Messages are pickles (protocol 5, the arrays out of band), each after a head saying the lengths.
To the child: ``(target, estimator, config, mount)`` once, then ``("draw", tracks, frame_or_None, dropped,
offered)`` and ``("end",)``; from it: ``("ready", where, unreachable)`` (*unreachable*: why the
view reaches no viewer, if it found so: :attr:`.scene.Scene.unreachable`) or ``("error", kind,
message)`` once, then ``("done", drawn, problem)`` and ``("closed", problem, never_connected)``
(*problem* then also what closing the view raised: a viewer's connection lost; *never_connected*:
Rerun said it never reached a viewer, so that none of the frames drawn was sent to one).
"""

from __future__ import annotations

import logging
import os
import pickle
import select
import signal
import socket
import struct
import subprocess
import sys
import time
from typing import TYPE_CHECKING

from ..errors import CaptureError, RadarodomError, UsageError

if TYPE_CHECKING:
    from ..cfg import RadarConfig
    from ..estimator.config import EstimatorConfig
    from ..mount import Mount
    from .frames import FramePayload, Track
    from .target import ViewTarget

log = logging.getLogger(__name__)

#: How long the child may take to import Rerun and open its target, s.
START_TIMEOUT_S = 120.0
#: How much lower the view's process is scheduled than the radar's (``nice``).
VIEW_NICENESS = 10
#: What the radar's side of the socket asks the kernel to buffer: a few frames (it may get less).
SOCKET_BUFFER = 1 << 20
#: A message's head: the pickle's length and how many buffers follow it, then each one's length.
_HEADER = struct.Struct("<QI")
_LENGTH = struct.Struct("<Q")
_ERRORS = {"UsageError": UsageError, "CaptureError": CaptureError}
#: Rerun's log filter in a ``connect:`` view's process, unless RUST_LOG is set: without its gRPC
#: client's ERROR lines (ANSI-coloured, every flush tick, for a viewer missing, lost or that is
#: none), which the view says in a line of its own (when it opens, in the run's summary).
CONNECT_RUST_LOG = "warn,re_grpc_client=off,re_sdk::recording_stream=off"


#: The child's program: this module's :func:`_child` on the socket's descriptor.
_CHILD_COMMAND = f"import sys; from {__name__} import _child; _child(int(sys.argv[1]))"


def _message(obj: object) -> list[memoryview]:
    """*obj* as the parts to send: its head, its pickle and, out of band, the arrays' own memory
    (pickle protocol 5: a frame's 0.2 MB of arrays are not copied into the pickle, only into the
    socket)."""
    buffers: list[pickle.PickleBuffer] = []
    data = pickle.dumps(obj, protocol=5, buffer_callback=buffers.append)
    views = [buffer.raw() for buffer in buffers]
    head = _HEADER.pack(len(data), len(views)) + b"".join(_LENGTH.pack(view.nbytes) for view in views)
    return [memoryview(head), memoryview(data), *views]


class ProcessDrawer:
    """A child process that opens *target* and draws what it is handed (module docstring); raises
    what opening the target raised there (UsageError, CaptureError) or RadarodomError."""

    def __init__(self, target: ViewTarget, *, estimator: EstimatorConfig | None = None,
                 config: RadarConfig | None = None, mount: Mount | None = None) -> None:
        self._target = target
        #: Why no viewer answered when the view opened (``connect:``: :func:`.target.viewer_missing`,
        #: which its opener asks while this process starts), or None.
        self.missing: str | None = None
        mine, theirs = socket.socketpair()
        with theirs:
            # -c rather than -m: the package imports this module first, and runpy warns that it
            # then runs a module already in sys.modules.
            env = None
            if target.kind == "connect" and "RUST_LOG" not in os.environ:
                env = {**os.environ, "RUST_LOG": CONNECT_RUST_LOG}
            self._process = subprocess.Popen([sys.executable, "-c", _CHILD_COMMAND, str(theirs.fileno())],
                                             pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL, env=env)
        try:
            mine.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SOCKET_BUFFER)
        except OSError:
            pass  # the kernel's default, then: about a frame
        mine.setblocking(False)
        self._sock = mine
        self._pending: list[memoryview] = []
        self._gone = False
        deadline = time.monotonic() + START_TIMEOUT_S
        reply = (self._receive(deadline) if self._send_all(_message((target, estimator, config, mount)), deadline)
                 else None)
        if reply is None or reply[0] != "ready":
            self._stop()
            if reply is None:
                status = self._process.returncode
                raise RadarodomError(f"the view's process did not open within {START_TIMEOUT_S:.0f} s" if status is None
                                     else f"the view's process ended before it opened (exit status {status}; "
                                     "its error is above)")
            raise _ERRORS.get(reply[1], RadarodomError)(reply[2])
        self.where: str = reply[1]
        self.unreachable: str | None = reply[2]

    # ------------------------------------------------------------------ the pipeline's thread
    def ready(self) -> bool:
        return self._flush() and not self._gone

    def offer(self, tracks: list[Track], frame: FramePayload, dropped: int, offered: int) -> None:
        self._pending = _message(("draw", tracks, frame, dropped, offered))
        self._flush()

    def _flush(self) -> bool:
        """Send what is pending as far as the socket takes it now; whether all of it went."""
        while self._pending:
            try:
                sent = self._sock.send(self._pending[0])
            except BlockingIOError:
                return False
            except OSError:  # the child is gone: close() says so
                self._pending, self._gone = [], True
                return True
            if sent == len(self._pending[0]):
                self._pending.pop(0)
            else:
                self._pending[0] = self._pending[0][sent:]
        return True

    # ------------------------------------------------------------------ the end
    def close(self, tracks: list[Track], dropped: int, offered: int, timeout_s: float) -> tuple[int | None, str | None]:
        deadline = time.monotonic() + timeout_s
        sent = (self._send_all([], deadline) and self._send_all(_message(("draw", tracks, None, dropped, offered)),
                                                                   deadline)
                and self._send_all(_message(("end",)), deadline))
        done = self._receive(deadline) if sent else None
        if done is None or done[0] != "done":
            status = self._process.poll()
            self._stop()
            return None, None if status is None else f"the view's process ended early (exit status {status})"
        # Rerun's last flush: a viewer that stopped reading holds it up for good, and so may none
        # (Rerun keeps trying to connect, for a viewer that starts late: docs/view.md).
        drawn, problem = done[1], done[2]
        closed = self._receive(deadline)
        if closed is None:
            if problem is None and self.missing is not None:
                from .target import reached_no_viewer

                problem = reached_no_viewer(self._target)
                drawn = 0 if problem else drawn  # drawn into Rerun, sent to no viewer
            problem = problem or f"the viewer did not take the view's last data within {timeout_s:.0f} s"
            log.warning("%s; the view's process was stopped", problem)
        else:
            problem = problem or closed[1]
            drawn = 0 if closed[2] else drawn  # Rerun never connected to a viewer
        self._stop()
        return drawn, problem

    def _send_all(self, message: list[memoryview], deadline: float) -> bool:
        """What is pending, then *message*, waiting until *deadline* at most."""
        self._pending += message
        while not self._flush():
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([], [self._sock], [], left)[1]:
                return False
        return not self._gone

    def _receive(self, deadline: float):
        """The child's next message (its replies carry no buffers), or None (it ended, or nothing
        came by *deadline*)."""
        head = self._read(_HEADER.size, deadline)
        body = None if head is None else self._read(_HEADER.unpack(head)[0], deadline)
        return None if body is None else pickle.loads(body)

    def _read(self, size: int, deadline: float) -> bytes | None:
        data = bytearray()
        while len(data) < size:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._sock], [], [], min(left, 0.2))[0]:
                if self._process.poll() is not None or left <= 0:
                    return None
                continue
            try:
                chunk = self._sock.recv(size - len(data))
            except BlockingIOError:
                continue
            except OSError:
                return None
            if not chunk:
                return None
            data += chunk
        return bytes(data)

    def _stop(self) -> None:
        for stop in (None, self._process.terminate, self._process.kill):
            if stop is not None:
                stop()
            try:
                self._process.wait(1.0 if stop is None else 5.0)
                break
            except subprocess.TimeoutExpired:
                continue
        self._sock.close()


def _child(fd: int) -> None:
    """The view's process: open the target it is sent, draw until told to end (or the radar's
    process is gone)."""
    # Ctrl-C in a terminal reaches the whole process group: the radar's process decides when the
    # view ends (it hands over what it has first).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # When cores are short the radar's processes come first: woken by each frame, the view would
    # otherwise take the core from the pipeline's thread as it hands the frame over (a batch
    # process does not preempt the one that woke it).
    os.nice(VIEW_NICENESS)
    if hasattr(os, "SCHED_BATCH"):
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    from .sink import Drawing
    from .target import lost_viewer, never_connected, open_scene

    sock = socket.socket(fileno=fd)
    sock.setblocking(True)
    try:
        target, estimator, config, mount = _read_message(sock)
        scene, where = open_scene(target, estimator=estimator, config=config, mount=mount)
    except RadarodomError as exc:
        _reply(sock, ("error", type(exc).__name__, str(exc)))
        return
    except Exception as exc:  # noqa: BLE001 (said to the parent, which raises it)
        _reply(sock, ("error", "RadarodomError", f"the view could not open: {type(exc).__name__}: {exc}"))
        return
    _reply(sock, ("ready", where, scene.unreachable))
    drawing = Drawing(scene)
    while True:
        try:
            message = _read_message(sock)
        except (EOFError, OSError):
            break
        if message[0] == "end":
            break
        drawing.draw(*message[1:])
    _reply(sock, ("done", drawing.drawn, drawing.failure))
    drawing.close(lost_viewer(target))
    _reply(sock, ("closed", drawing.failure, never_connected(drawing.close_error)))


def _read_message(sock: socket.socket):
    size, count = _HEADER.unpack(_read_exactly(sock, _HEADER.size))
    lengths = [_LENGTH.unpack_from(_read_exactly(sock, _LENGTH.size))[0] for _ in range(count)]
    data = _read_exactly(sock, size)
    return pickle.loads(data, buffers=[_read_exactly(sock, length) for length in lengths])


def _read_exactly(sock: socket.socket, size: int) -> bytearray:
    data = bytearray(size)
    view, got = memoryview(data), 0
    while got < size:
        n = sock.recv_into(view[got:])
        if not n:
            raise EOFError("the radar's process closed the view's socket")
        got += n
    return data


def _reply(sock: socket.socket, message: tuple) -> None:
    try:
        for part in _message(message):
            sock.sendall(part)
    except OSError:
        pass  # the radar's process is gone
