"""The fake AWR1843's pseudo-terminal: the plumbing under its CLI, apart from what the CLI says.

:class:`Awr1843Pty` opens a real pty (raw, the slave kept open so the master never sees EIO
between clients), reads it on a daemon thread and hands every chunk received to
:meth:`~Awr1843Pty._feed`, writes replies to it (byte by byte with ``faults.char_delay_s``, a
client that does not read losing them after :data:`WRITE_TIMEOUT_S`, as a UART overruns:
:func:`write_all`, which the demo's data port uses too), and
closes it: on :meth:`~Awr1843Pty.close`, or at once when the USB cable is pulled
(:meth:`~Awr1843Pty._disappear`).  :class:`~.fake_awr1843.FakeAwr1843` inherits it and supplies
:meth:`~Awr1843Pty._feed` (the firmware's line handling) and ``faults``.
"""

from __future__ import annotations

import logging
import os
import select
import threading
import time
import tty
from collections.abc import Callable
from typing import Protocol, TypeVar

log = logging.getLogger(__name__)

#: Longest a reply may wait for a client that does not read before it is
#: dropped (a real UART never waits: its bytes are lost).
WRITE_TIMEOUT_S = 2.0

_P = TypeVar("_P", bound="Awr1843Pty")


def write_all(fd: Callable[[], int | None], data: bytes, timeout_s: float, stopped: Callable[[], bool],
              who: str) -> int:
    """Write *data* to the non-blocking pty master ``fd()`` (None once closed), waiting while the
    client leaves it full for at most *timeout_s* in all: a UART does not wait, the rest is lost
    (logged as *who*'s). The bytes written: fewer than ``len(data)`` when ``stopped()``, closed,
    not read in time or failed."""
    deadline = time.monotonic() + timeout_s
    view = memoryview(data)
    written = 0
    while written < len(data):
        current = fd()
        if current is None or stopped():
            break
        try:
            written += os.write(current, view[written:])
        except BlockingIOError:
            left = deadline - time.monotonic()
            if left <= 0:
                log.warning("%s: the client does not read; %d bytes lost (a UART overruns)", who, len(data) - written)
                break
            select.select([], [current], [], min(left, 0.01))
        except OSError as exc:  # EINTR is retried by os.write itself (PEP 475)
            log.info("%s pty write failed: %s", who, exc)
            break
    return written


class _Pacing(Protocol):
    #: Delay after each byte sent, s (:attr:`~.fake_awr1843.CliFaults.char_delay_s`).
    char_delay_s: float


class Awr1843Pty:
    """The pty of the fake AWR1843's CLI: open, serve, write, close.

    Subclasses set ``faults`` (whose ``char_delay_s`` paces :meth:`_send`) and
    implement :meth:`_feed`, run on the serving thread with every chunk read.
    State: :attr:`path` (the slave's path, None when closed) and :attr:`disappeared`.
    """

    faults: _Pacing

    def __init__(self) -> None:
        #: Slave path of the open pty, or None.
        self.path: str | None = None
        self._disappeared = False  # read through the property: see there
        self._io_lock = threading.Lock()  # the master fd and writes to it
        self._master: int | None = None
        self._slave: int | None = None
        self._wake_r: int | None = None
        self._wake_w: int | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ pty
    def open_pty(self) -> str:
        """Create the pty, serve it on a daemon thread, return the slave's path."""
        if self._master is not None:
            raise RuntimeError(f"the fake AWR1843 already serves {self.path}")
        self._join_old_thread()  # after a disappearance the old thread is ending
        with self._io_lock:
            if self._master is not None:
                raise RuntimeError(f"the fake AWR1843 already serves {self.path}")
            master, slave = os.openpty()
            # Raw: no echo, no CR/LF translation, no signals from the line discipline.
            tty.setraw(slave)
            os.set_blocking(master, False)
            wake_r, wake_w = os.pipe()
            self._master, self._slave = master, slave  # the slave stays open so the
            self._wake_r, self._wake_w = wake_r, wake_w  # master never sees EIO between clients
            self.path = os.ttyname(slave)
            self._disappeared = False
            self._stop.clear()
            self._thread = threading.Thread(target=self._serve, args=(master, wake_r),
                                            name=f"fake-awr1843 {self.path}", daemon=True)
            self._thread.start()
        log.info("fake AWR1843 CLI on %s", self.path)
        return self.path

    @property
    def disappeared(self) -> bool:
        """True once a ``disappear_on`` fault closed the port.

        Read under the lock :meth:`_disappear` holds while it closes every fd: whoever sees
        True sees the pty gone, not a slave fd still open a moment after the flag.
        """
        with self._io_lock:
            return self._disappeared

    def close(self) -> None:
        """Stop serving and close the pty (idempotent)."""
        self._stop.set()
        with self._io_lock:
            if self._wake_w is not None:
                try:
                    os.write(self._wake_w, b"x")
                except OSError:
                    pass
        self._join_old_thread()
        with self._io_lock:
            self._close_fds()

    def _join_old_thread(self) -> None:
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=5.0)
            if thread.is_alive():  # pragma: no cover - a callback that never returns
                log.warning("fake AWR1843 thread did not stop")
        if thread is not threading.current_thread():
            self._thread = None

    def _close_fds(self) -> None:
        """Close every fd (caller holds _io_lock)."""
        self.path = None
        for attr in ("_master", "_slave", "_wake_r", "_wake_w"):
            fd = getattr(self, attr)
            setattr(self, attr, None)
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass

    def __enter__(self: _P) -> _P:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -------------------------------------------------------------- serving
    def _serve(self, master: int, wake_r: int) -> None:
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([master, wake_r], [], [])
            except (OSError, ValueError):  # closed under us
                break
            if wake_r in ready:
                break
            try:
                data = os.read(master, 4096)
            except BlockingIOError:
                continue
            except OSError as exc:
                log.info("fake AWR1843 pty read failed: %s", exc)
                break
            if not data:
                break
            self._feed(data)
            if self._disappeared:
                break
        log.debug("fake AWR1843 serving thread ends")

    def _feed(self, data: bytes) -> None:
        """Take *data* just read from the pty (on the serving thread)."""
        raise NotImplementedError

    # -------------------------------------------------------------- output
    def _send(self, data: bytes, *, slow: bool = True) -> None:
        """Write *data* to the client (byte by byte with faults.char_delay_s)."""
        delay = self.faults.char_delay_s if slow else 0.0
        with self._io_lock:
            fd = self._master
            if fd is None:
                return
            if delay > 0:
                for i in range(len(data)):
                    if not self._write_all(fd, data[i:i + 1]) or self._stop.wait(delay):
                        return
            else:
                self._write_all(fd, data)

    def _write_all(self, fd: int, data: bytes) -> bool:
        return write_all(lambda: fd, data, WRITE_TIMEOUT_S, self._stop.is_set, "fake AWR1843") == len(data)

    def _disappear(self) -> None:
        """Close the pty now, like pulling the USB cable (called on the serving thread)."""
        with self._io_lock:
            self._disappeared = True  # set before the client can see the hang-up
            self._close_fds()


__all__ = ["WRITE_TIMEOUT_S", "Awr1843Pty", "write_all"]
