"""Helpers for the tests of the live driver (``dca1000://``) against the emulated rig.

The rig (:class:`radarodom.driver.emulators.rig.EmulatedRig`) is a fake AWR1843 on
a pty and a fake DCA1000 on loopback UDP; nothing here touches hardware.  Every
iteration of a live source goes through :func:`collect`, whose watchdog calls
``source.stop()`` so that a test can fail but never hang.
"""

from __future__ import annotations

import os
import queue
import shlex
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from urllib.parse import parse_qsl

import numpy as np
from conftest import SMALL_CFG, console_command, private_zenoh
from radarodom.cfg import RadarConfig

#: SMALL_CFG with 16 loops every 10 ms: 12288-byte frames (8.4 packets each), 100 Hz.
#: Large enough that the reordering window (32 packets) spans < 4 frames, fast
#: enough that a hundred frames take one second.
LOSS_CFG = SMALL_CFG.replace("frameCfg 0 2 4 0 50 1 0", "frameCfg 0 2 16 0 10 1 0")

#: 128 loops x 3 TX x 4 RX x 1024 samples x 4 bytes = 6 MiB frames every 200 ms.
BIG_CFG = (SMALL_CFG
           .replace("profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30",
                    "profileCfg 0 77 7 6 90 0 0 40 1 1024 12500 0 0 30")
           .replace("frameCfg 0 2 4 0 50 1 0", "frameCfg 0 2 128 0 200 1 0"))

#: SMALL_CFG without raw ADC data on LVDS (what TI's own profiles ship with).
NO_LVDS_CFG = SMALL_CFG.replace("lvdsStreamCfg -1 0 1 0", "lvdsStreamCfg -1 0 0 0")

#: Seconds per board command and for sensorStart in the tests' URLs.
URL_TIMEOUTS = {"timeout": 0.3, "start_timeout": 1.0}


def cfg_line(text: str, command: str) -> int:
    """1-based line number of the first line of *command* in cfg *text*."""
    for n, line in enumerate(text.splitlines(), start=1):
        if line.split()[:1] == [command]:
            return n
    raise LookupError(command)


def config(text: str, name: str) -> RadarConfig:
    return RadarConfig.from_text(text, name)


@dataclass
class Got:
    """What a test keeps of one delivered frame (the ring buffer is reused)."""

    index: int
    timestamp: float
    missing_bytes: int
    raw: bytes
    #: time.time() when the consumer got it.
    received: float
    #: Of missing_bytes, those cut at stop.
    cut_bytes: int = 0


def collect(source, n: int, timeout: float = 5.0, *, on_frame=None) -> list[Got]:
    """Up to *n* frames from *source*; a watchdog stops the source after
    *timeout* s, so this returns (with fewer frames) instead of hanging.
    ``on_frame(frame, got_so_far)`` runs while the consumer holds the frame."""
    return _gather(source, timeout, on_frame, lambda got: len(got) >= n, stop=False)


def collect_until_stopped(source, stop_after: int, timeout: float = 10.0, *, on_frame=None) -> list[Got]:
    """Every frame of *source*: after *stop_after* frames it is asked to stop (as Ctrl-C does),
    and the frames it still delivers are taken too, to its end.  A watchdog asks it to stop
    after *timeout* s if it has not been asked yet.  ``on_frame(frame, got_so_far)`` as in
    :func:`collect`."""
    return _gather(source, timeout, on_frame, lambda got: len(got) == stop_after, stop=True)


def _gather(source, timeout: float, on_frame, enough, *, stop: bool) -> list[Got]:
    """Frames of *source* until ``enough(got)``: then break out (*stop* false) or ask the source
    to stop and take what it still delivers (*stop* true); the watchdog stops it after *timeout* s."""
    timer = threading.Timer(timeout, source.stop)
    timer.daemon = True
    timer.start()
    got: list[Got] = []
    try:
        for frame in source:
            got.append(Got(frame.index, frame.timestamp, frame.missing_bytes,
                           frame.raw.tobytes(), time.time(), frame.cut_bytes))
            if on_frame is not None:
                on_frame(frame, got)
            if enough(got):
                if not stop:
                    break
                source.stop()
    finally:
        timer.cancel()
    return got


def frame_problem(raw, expected: bytes, missing: int) -> str | None:
    """Why delivered frame bytes *raw* cannot be source frame *expected* with
    *missing* bytes lost and zero-filled (None when they can)."""
    a = np.frombuffer(raw, np.uint8)
    b = np.frombuffer(expected, np.uint8)
    if a.shape != b.shape:
        return f"{a.size} bytes, expected {b.size}"
    differ = np.flatnonzero(a != b)
    if missing == 0:
        return None if differ.size == 0 else f"complete frame differs from the source in {differ.size} bytes"
    if (a[differ] != 0).any():
        return (f"{int((a[differ] != 0).sum())} bytes differ from the source and are not zero "
                f"(misaligned or foreign data)")
    if differ.size > missing:
        return f"{differ.size} bytes differ from the source, only {missing} reported missing"
    if int((a == 0).sum()) < missing:
        return f"{missing} bytes reported missing but only {int((a == 0).sum())} zero bytes"
    return None


def assert_frames_match(got: list[Got], source_frames: list[bytes]) -> None:
    """Every delivered frame k equals source frame k % n, up to its zero-filled gaps."""
    problems = []
    for g in got:
        p = frame_problem(g.raw, source_frames[g.index % len(source_frames)], g.missing_bytes)
        if p:
            problems.append(f"frame {g.index} (missing {g.missing_bytes}): {p}")
    assert not problems, "\n".join(problems[:10])


def assert_drops_accounted(indices: list[int], frames_dropped: int) -> None:
    """The delivered frames (*indices*) come in order, and every frame of the stream they skip
    is counted in *frames_dropped* (a loaded machine's consumer may be too slow for some)."""
    assert indices == sorted(set(indices)), f"frame indices {indices}"
    skipped = indices[-1] + 1 - len(indices)
    assert frames_dropped >= skipped, f"{skipped} frames skipped, {frames_dropped} counted as dropped: {indices}"


def assert_continuous(indices: list[int], start: int | None = 0) -> None:
    first = indices[0] if start is None else start
    assert indices == list(range(first, first + len(indices))), f"frame indices {indices}"


def port_is_free(ip: str, port: int) -> bool:
    """True when a UDP socket (without SO_REUSEADDR) can bind *ip*:*port*: no
    socket of this process or another holds it."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind((ip, port))
        except OSError:
            return False
        return True


def fds_open_on(path: str) -> int:
    """How many file descriptors of this process are open on *path* (a pty), the
    pty still there or gone: once its master closes, Linux shows its slave's fds
    as "*path* (deleted)", and a driver still holding a vanished port holds one."""
    n = 0
    for fd in os.listdir("/proc/self/fd"):
        try:
            if os.readlink(f"/proc/self/fd/{fd}") in (path, f"{path} (deleted)"):
                n += 1
        except OSError:
            pass
    return n


def receiver_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "dca1000-receiver" and t.is_alive()]


def wait_until(predicate, timeout: float, interval: float = 0.02) -> bool:
    deadline = time.monotonic() + timeout
    while True:
        if predicate():
            return True
        if time.monotonic() > deadline:
            return False
        time.sleep(interval)


# ------------------------------------------------------------------ subprocesses
class CpuHogs:
    """*n* processes spinning on the CPU while the ``with`` block runs: real contention for
    the cores (the scheduler's, not a sleep).  After the block, :attr:`cpu_s` holds the CPU
    seconds each got, as the kernel counted them (Linux ``/proc``)."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.procs: list[subprocess.Popen] = []
        self.cpu_s: list[float] = []

    def __enter__(self) -> CpuHogs:
        for _ in range(self.n):
            self.procs.append(subprocess.Popen([sys.executable, "-c", "while True: pass"],
                                               stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL))
        return self

    def __exit__(self, *exc) -> None:
        tick = os.sysconf("SC_CLK_TCK")
        for proc in self.procs:
            try:
                with open(f"/proc/{proc.pid}/stat") as f:  # utime, stime: fields 14, 15
                    fields = f.read().rpartition(")")[2].split()
                self.cpu_s.append((int(fields[11]) + int(fields[12])) / tick)
            except OSError:
                self.cpu_s.append(0.0)
            proc.kill()
            proc.wait(5)


class _LineReader:
    """Reads a text pipe on a thread, so waiting for a line has a timeout."""

    def __init__(self, pipe) -> None:
        self.lines: list[str] = []
        self._queue: queue.Queue[str | None] = queue.Queue()
        self._thread = threading.Thread(target=self._run, args=(pipe,), daemon=True)
        self._thread.start()

    def _run(self, pipe) -> None:
        for line in pipe:
            self.lines.append(line)
            self._queue.put(line)
        self._queue.put(None)

    def wait_for(self, predicate, timeout: float) -> str | None:
        """The first new line satisfying *predicate*, or None after *timeout* s or at EOF."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            try:
                line = self._queue.get(timeout=left)
            except queue.Empty:
                return None
            if line is None:
                return None
            if predicate(line):
                return line

    def text(self, join_timeout: float = 5.0) -> str:
        self._thread.join(join_timeout)
        return "".join(self.lines)


class Process:
    """A console program run in the background, its stdout and stderr read by threads."""

    def __init__(self, argv: list[str]) -> None:
        self.argv = argv
        self.proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        self.stdout = _LineReader(self.proc.stdout)
        self.stderr = _LineReader(self.proc.stderr)

    def interrupt(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)

    def wait(self, timeout: float) -> int | None:
        """The exit code, or None if still running after *timeout* s."""
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(5)

    def output(self) -> tuple[str, str]:
        return self.stdout.text(), self.stderr.text()


class Emulator(Process):
    """``radar-emulate`` in the background; :attr:`command` is the radar-capture
    command line it printed.  Use ``with``: leaving stops it with SIGINT."""

    def __init__(self, *args: str) -> None:
        super().__init__([*console_command("radar-emulate"), *map(str, args)])
        line = self.stdout.wait_for(lambda ln: ln.startswith("radar-capture "), timeout=30)
        if line is None:
            self.kill()
            out, err = self.output()
            raise AssertionError(f"radar-emulate printed no radar-capture command:\n{out}\n{err}")
        self.command_line = line.strip()
        self.command = shlex.split(self.command_line)
        url = self.command[self.command.index("--source") + 1]
        #: The fake radar's CLI port (the pty radar-capture is told to use).
        self.cli_path = dict(parse_qsl(url.partition("?")[2]))["cli"]

    def capture_argv(self, *extra: str, url_extra: str = "") -> list[str]:
        """The printed command, run with the installed radar-capture, plus *extra*
        arguments and *url_extra* appended to the --source URL."""
        argv = list(self.command)
        if url_extra:
            i = argv.index("--source") + 1
            argv[i] += "&" + url_extra
        return [*console_command("radar-capture"), *private_zenoh([*argv[1:], *extra])]

    def stop(self, timeout: float = 10.0) -> int | None:
        """SIGINT, then the exit code (None: it did not stop, and was killed)."""
        self.interrupt()
        code = self.wait(timeout)
        if code is None:
            self.kill()
        return code

    def __enter__(self) -> Emulator:
        return self

    def __exit__(self, *exc) -> None:
        if self.proc.poll() is None:
            self.stop()
