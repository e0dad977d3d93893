"""How a ``connect:`` view tells a program that is no viewer from a slow viewer
(view/target.py, ``not_a_viewer``): by Rerun's words first, by the time the flush took only for
other errors.  The view's process runs niced: on a busy machine it heard of a connection a web
server broke at once seconds late, and took the web server for a slow viewer.

Rerun's recording is stood in for by one whose flush fails as late and in the words given; what
listens at the address is a real socket that answers HTTP/2's greeting (what does not answer it in
kind is judged before any flush: test_view.py's web server and listener that closes).
"""

from __future__ import annotations

import socket
import threading
import time

import pytest

pytest.importorskip("rerun")

from radarodom.view import target as view_target  # noqa: E402
from radarodom.view.target import CONNECT_PROBE_TRIES, ViewTarget, not_a_viewer  # noqa: E402

#: The flush's timeout the probe is run with here (the library's is 2 s): its verdicts go by a
#: fraction of it (a flush that took 0.9 of it timed out), so the stand-in flushes below sleep
#: fractions of it, and each verdict is the same at any length.  Long enough that the greeting
#: (answered at once by a thread of this process) comes well within its timeout, the probe's
#: length times its tries (3 s here).
PROBE_S = 1.0


@pytest.fixture(autouse=True)
def probe_length(monkeypatch):
    monkeypatch.setattr(view_target, "CONNECT_PROBE_S", PROBE_S)
    assert PROBE_S * CONNECT_PROBE_TRIES >= 3.0


class LateRecording:
    """Rerun's RecordingStream as far as ``not_a_viewer`` uses it: its flush fails after
    *delay_s* with Rerun's words *said*."""

    def __init__(self, delay_s: float, said: str) -> None:
        self.delay_s, self.said = delay_s, said
        self.disconnected = False

    def flush(self, timeout_sec: float) -> None:
        time.sleep(self.delay_s)
        raise RuntimeError(self.said)

    def disconnect(self) -> None:
        self.disconnected = True


@pytest.fixture
def port():
    """Something on loopback that answers HTTP/2's greeting as a gRPC server does (an empty
    SETTINGS frame), so that Rerun's flush is what judges it."""
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        held = []

        def greet() -> None:
            while True:
                try:
                    conn, _ = listener.accept()
                except OSError:  # closed: the test is over
                    return
                held.append(conn)
                conn.sendall(bytes([0, 0, 0, 4, 0, 0, 0, 0, 0]))

        threading.Thread(target=greet, daemon=True).start()
        yield listener.getsockname()[1]
    for conn in held:
        conn.close()


def probe(port: int, delay_s: float, said: str) -> tuple[str | None, LateRecording]:
    recording = LateRecording(delay_s, said.format(url=f"rerun+http://127.0.0.1:{port}/proxy"))
    return not_a_viewer(recording, ViewTarget("connect", address=f"127.0.0.1:{port}")), recording


SEVERED = "gRPC connection severed: Failed to send messages: Unknown error, uri: {url}"


@pytest.mark.parametrize("delay_s", [0.0, 0.95 * PROBE_S])
def test_a_broken_connection_is_no_viewer_however_late_it_is_said(port, delay_s):
    why, recording = probe(port, delay_s, SEVERED)
    url = f"rerun+http://127.0.0.1:{port}/proxy"
    assert why == (f"what answers at {url} is not a Rerun viewer: it broke the connection "
                   "(gRPC connection severed: Failed to send messages: Unknown error)")
    assert recording.disconnected


def test_the_other_way_rerun_says_a_broken_connection(port):
    why, _ = probe(port, 0.95 * PROBE_S, "gRPC connection is open, but flush still failed, uri: {url}")
    assert why is not None and "is not a Rerun viewer" in why


def test_a_flush_that_timed_out_is_a_slow_viewer_not_a_refusal(port):
    why, recording = probe(port, 0.95 * PROBE_S, "gRPC flush timed out after 2s, uri: {url}")
    assert why is None and not recording.disconnected
