"""Where the view goes (a viewer spawned here, the web viewer served, a viewer elsewhere, an
.rrd file) and the layout the viewer opens with.  Rerun is imported when a view opens."""

from __future__ import annotations

import os
import re
import shutil
import socket
import sys
import threading
import time
import urllib.parse
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..errors import CaptureError, UsageError, why_not_written
from ..host_names import host_problem

if TYPE_CHECKING:
    from ..cfg import RadarConfig
    from ..estimator.config import EstimatorConfig
    from ..mount import Mount

#: Rerun's application id: the viewer groups recordings by it.
APPLICATION = "radarodom"
#: The web viewer's page when no port is given; its data (gRPC) is on the next port.
DEFAULT_WEB_PORT = 9090
#: A spawned viewer's port (Rerun's default: a viewer already running there is reused).
SPAWN_PORT = 9876
KINDS = ("spawn", "web", "connect", "save")
#: Rerun's batching period for the web viewer, s (its default, 0.2 s, for the others).
WEB_FLUSH_TICK_S = 1.0


@dataclass(frozen=True)
class ViewTarget:
    """*kind* "spawn" (open a viewer on this machine, listening on *port*; one already there is
    reused), "web" (serve the web viewer on *port* and the data on *port* + 1), "connect" (send to
    the viewer at *address*, a Rerun gRPC URL) or "save" (write the .rrd file *path*).  *port*
    not given: :data:`SPAWN_PORT` or :data:`DEFAULT_WEB_PORT`."""

    kind: str
    port: int | None = None
    address: str = ""
    path: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise UsageError(f"a view goes to one of {', '.join(KINDS)}, not {self.kind!r}")
        if self.port is None:
            object.__setattr__(self, "port", SPAWN_PORT if self.kind == "spawn" else DEFAULT_WEB_PORT)
        if self.kind == "web" and not 1 <= self.port < 65535:
            raise UsageError(f"the web viewer's port must be 1..65534 (its data uses the next), got {self.port}")
        if self.kind == "spawn" and not 1 <= self.port < 65536:
            raise UsageError(f"the viewer's port must be 1..65535, got {self.port}")

    @property
    def data_port(self) -> int:
        """The web viewer's data (gRPC) port."""
        return self.port + 1


def grpc_url(address: str) -> str:
    """A Rerun gRPC URL (``rerun+http(s)://HOST:PORT/proxy``) from ``HOST:PORT`` (an IPv6 address
    in brackets) or such a URL as it is; UsageError for what Rerun cannot connect to (it would fail
    in a thread of its own, the view's frames counted as drawn)."""
    wrong = f"a viewer's address is HOST:PORT or a rerun+http://HOST:PORT/proxy URL, got {address!r}"
    url = "://" in address
    if url:
        parts = urllib.parse.urlsplit(address)
        if parts.scheme not in ("rerun+http", "rerun+https") or parts.path != "/proxy":
            web = parts.scheme in ("http", "https") and re.fullmatch(r"[^/@]+:\d+", parts.netloc)
            raise UsageError(wrong + (f" (a viewer's gRPC address is no web page: give {parts.netloc})" if web else ""))
        host, _, port = parts.netloc.rpartition(":")
    else:
        host, _, port = address.rpartition(":")
    if not host or "@" in host or not port.isascii() or not port.isdigit() or not 0 < int(port) < 65536:
        raise UsageError(wrong)
    problem = host_problem(host, lambda example: f"{example}:{port}")
    if problem:
        raise UsageError(f"a viewer's address {address!r}: {problem}")
    return address if url else f"rerun+http://{host}:{int(port)}/proxy"


#: How long a --view connect: viewer may take to accept a connection before the view says none does, s.
CONNECT_PROBE_S = 2.0
#: Flushes of that length the probe of what answers at a ``connect:`` address tries before it takes
#: their timing out as a slow viewer: on a loaded machine the niced view's process may hear a broken
#: connection only seconds later.
CONNECT_PROBE_TRIES = 3

#: How a ``connect:`` view's summary ends when no viewer got its frames (they count as dropped).
SENT_TO_NONE = "the frames were sent to no viewer"
#: How Rerun (0.41) begins the error of a flush that gave up while its gRPC client was still
#: trying to connect, as it had since the view opened: it never reached a viewer.
_NEVER_CONNECTED = "gRPC has been unable to connect"
#: How Rerun (0.41) begins the error of a flush whose connection the other end broke (a web server
#: or any other program that is no viewer): "gRPC connection severed: ..." or "gRPC connection is
#: open, but flush still failed ...".
_SEVERED = "gRPC connection "


def check(target: ViewTarget) -> None:
    """What can be known before Rerun starts: Rerun turned on, a display to spawn a viewer on,
    free ports."""
    if os.environ.get("RERUN", "").strip().lower() in ("0", "off", "false"):  # Rerun's own switch
        raise UsageError(f"the environment turns Rerun off (RERUN={os.environ['RERUN']}), so the view would "
                         "show and save nothing: unset RERUN (or set RERUN=on), or leave --view out")
    if target.kind == "spawn" and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise UsageError("spawn opens a viewer window, and this session has no display (neither DISPLAY nor "
                         "WAYLAND_DISPLAY is set): serve the web viewer instead (--view web[:PORT]) and open it "
                         "from a browser, or save the view (--view save:FILE.rrd)")
    if target.kind == "web":
        _check_free(target)


def viewer_missing(target: ViewTarget, wait_s: float = CONNECT_PROBE_S) -> str | None:
    """For ``connect:``, why no viewer takes the view yet (nothing accepted a connection within
    *wait_s*, a viewer still starting given that long), or None.  Rerun keeps the view's data and
    keeps trying to connect, for a viewer that comes later (docs/view.md says how far that goes),
    and at the end waits for one: a program says so when the view opens, rather than in silence
    at the end."""
    if target.kind != "connect":
        return None
    why = _no_answer(target, wait_s)
    return None if why is None else f"no Rerun viewer answers at {grpc_url(target.address)} ({why})"


def reached_no_viewer(target: ViewTarget) -> str | None:
    """For a ``connect:`` view that found no viewer when it opened (:func:`viewer_missing`) and
    whose last data nothing took by the close's timeout: that its frames reached no viewer, when
    nothing answers at its address still (a TCP connection's attempt), or None (something answers:
    a viewer that came and stopped reading).  A viewer that came during the run and went away
    makes Rerun's last flush fail instead (:func:`lost_viewer`): it does not wait."""
    why = _no_answer(target, 0.0)
    if why is None:
        return None
    return (f"no Rerun viewer answered at {grpc_url(target.address)} when the view opened nor when it closed "
            f"({why}); {SENT_TO_NONE}")


def never_connected(exc: Exception | None) -> bool:
    """Whether Rerun's error *exc* (of the view's last flush) says that it never connected to a viewer."""
    return exc is not None and str(exc).startswith(_NEVER_CONNECTED)


def _no_answer(target: ViewTarget, wait_s: float) -> str | None:
    """Why nothing accepted a TCP connection at a ``connect:`` target's address within *wait_s*
    (the system's words), or None."""
    parts = urllib.parse.urlsplit(grpc_url(target.address))
    host, port = parts.hostname, parts.port or (443 if parts.scheme.endswith("https") else 80)
    deadline = time.monotonic() + wait_s
    while True:
        try:
            with socket.create_connection((host, port), timeout=max(0.1, deadline - time.monotonic())):
                return None
        except OSError as exc:
            if time.monotonic() >= deadline:
                return str(exc.strerror or exc)
            time.sleep(0.1)


def open_scene(target: ViewTarget, *, estimator: EstimatorConfig | None = None, config: RadarConfig | None = None,
               mount: Mount | None = None):
    """A :class:`~.scene.Scene` drawing into a new Rerun recording sent to *target*, and where
    to look at it (in this process: the view's own, or a notebook's)."""
    import rerun as rr

    from .scene import Scene

    check(target)
    # A browser takes a few large chunks far faster than many small ones (Rerun batches what is
    # logged within a tick into one chunk per entity; measured in docs/view.md).
    batching = rr.ChunkBatcherConfig(flush_tick=WEB_FLUSH_TICK_S) if target.kind == "web" else None
    recording = rr.RecordingStream(APPLICATION, batcher_config=batching)
    connecting = None
    if target.kind == "connect":
        where, connecting = _connect(recording, target, layout())
    else:
        where = _OPENERS[target.kind](recording, target, layout())
    scene = Scene(recording, estimator=estimator, config=config, mount=mount, connecting=connecting)
    scene.note(f"radarodom's view, sent to {where}", static=True)
    if target.kind == "connect" and connecting is None:  # else nothing listened: the close's timeout judges
        scene.unreachable = not_a_viewer(recording, target)
        if scene.unreachable:
            where = f"nothing ({grpc_url(target.address)} is not a Rerun viewer)"
    return scene, where


def not_a_viewer(recording, target: ViewTarget) -> str | None:
    """Why what accepts connections at a ``connect:`` target's address is no Rerun viewer, or None
    (a viewer; nothing there yet, whose data waits for one; no answer in time, which the close's
    timeout judges).  Rerun's gRPC client only logs that what it reached broke the connection (a
    web server, any other program on the port), in ANSI-coloured lines every flush tick, and the
    view counted its frames as drawn.  So the address is first greeted in HTTP/2, which a
    viewer's gRPC server answers in kind; then the flush of the view's first data raises what
    Rerun heard.  The recording is then disconnected (nothing more is sent, nor logged by Rerun)."""
    if viewer_missing(target, wait_s=0.0):
        return None
    url = grpc_url(target.address)
    verdict = _http2_verdict(target)
    if verdict == _NO_ANSWER:
        return None  # a viewer too slow to greet, or a program that never answers: the close's timeout judges
    if verdict:
        recording.disconnect()
        return f"what answers at {url} is not a Rerun viewer: {verdict}"
    for _ in range(CONNECT_PROBE_TRIES):
        started = time.monotonic()
        try:
            recording.flush(timeout_sec=CONNECT_PROBE_S)
            return None
        except RuntimeError as exc:
            # Rerun's words say a broken connection; only other errors are judged by the time they
            # took (a flush that timed out: slow, not refused, so flushed again).  The view's
            # process runs niced, and on a busy machine a connection broken at once may be said
            # seconds later.
            if not str(exc).startswith(_SEVERED) and time.monotonic() - started >= 0.9 * CONNECT_PROBE_S:
                continue
            recording.disconnect()
            return f"what answers at {url} is not a Rerun viewer: it broke the connection ({_rerun_said(exc, url)})"
    return None


#: What a client opens an HTTP/2 connection with when it knows the server speaks it, as gRPC over
#: plain TCP does (RFC 9113 section 3.4): the preface and an empty SETTINGS frame.
_H2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
#: An HTTP/2 frame header's length and where its type is; a server's first frame is its SETTINGS.
_H2_FRAME_HEADER, _H2_TYPE_AT, _H2_SETTINGS = 9, 3, 4
#: What :func:`_http2_verdict` says of an address that took the connection and said nothing in time.
_NO_ANSWER = "no answer"


def _http2_verdict(target: ViewTarget) -> str | None:
    """Whether what answers at a plain ``rerun+http://`` target's address speaks HTTP/2, as a
    viewer's gRPC server does (it answers a client's preface with its SETTINGS frame; a web server
    with an HTTP/1 error page): None if it does or was not asked (TLS, or no connection: Rerun's
    flush judges), :data:`_NO_ANSWER` if it said nothing in time, else how it showed it does not.
    Asked on a connection of its own, whose answer comes whole however late: Rerun's gRPC client
    reports its first data flushed without waiting for the server's first frame."""
    parts = urllib.parse.urlsplit(grpc_url(target.address))
    if parts.scheme != "rerun+http":
        return None
    try:
        conn = socket.create_connection((parts.hostname, parts.port or 80),
                                        timeout=CONNECT_PROBE_S * CONNECT_PROBE_TRIES)
    except OSError:
        return None
    answer = b""
    with conn:
        try:
            conn.sendall(_H2_PREFACE)
            while len(answer) < _H2_FRAME_HEADER:
                chunk = conn.recv(_H2_FRAME_HEADER - len(answer))
                if not chunk:
                    break
                answer += chunk
        except TimeoutError:
            return _NO_ANSWER if not answer else None
        except OSError:  # reset: it took the connection and threw it away
            pass
    if len(answer) == _H2_FRAME_HEADER and answer[_H2_TYPE_AT] == _H2_SETTINGS:
        return None
    if not answer:
        return "it closed the connection when greeted in HTTP/2, which a viewer's gRPC speaks"
    began = answer.decode("ascii", "backslashreplace")
    return f"it does not speak HTTP/2, which a viewer's gRPC does (its answer began {began!r})"


def lost_viewer(target: ViewTarget):
    """How a ``connect:`` view says that its last flush failed, a function of Rerun's error: a
    viewer went away during the run (or never came), and Rerun, which only logs a lost connection,
    gives no way to tell which frames it took; unless Rerun says it never connected
    (:func:`never_connected`).  None for the other targets."""
    if target.kind != "connect":
        return None
    url = grpc_url(target.address)

    def said(exc: Exception) -> str:
        if never_connected(exc):
            return (f"no Rerun viewer answered at {url}: Rerun never connected to it ({_rerun_said(exc, url)}); "
                    f"{SENT_TO_NONE}")
        return (f"the view's data did not all reach {url} ({_rerun_said(exc, url)}): the frames "
                "drawn after the viewer went away, or all if none came, were not seen")
    return said


def _rerun_said(exc: Exception, url: str) -> str:
    """Rerun's error *exc* about *url* without the URL it ends with (the message says it once)."""
    return str(exc).removesuffix(f", uri: {url}")


def viewer_hint(target: ViewTarget) -> str:
    """What to do about a ``connect:`` target that is not a Rerun viewer."""
    port = urllib.parse.urlsplit(grpc_url(target.address)).port
    return f"start a Rerun viewer there (rerun --port {port}) or give a viewer's address"


def _spawn(recording, target: ViewTarget, blueprint) -> str:
    import rerun as rr

    # Rerun looks for its viewer on PATH: a virtual environment's, not activated, is beside Python.
    # (The module's spawn takes the viewer's path; a RecordingStream's own spawn does not.)
    here = os.pathsep.join([os.path.dirname(sys.executable), os.environ.get("PATH", "")])
    rr.spawn(port=target.port, default_blueprint=blueprint, executable_path=shutil.which("rerun", path=here),
             recording=recording)
    return f"a Rerun viewer on this machine (port {target.port})"


def _web(recording, target: ViewTarget, blueprint) -> str:
    import rerun as rr

    # The page comes from target.port and fetches the data from the next port: a browser
    # elsewhere (a laptop) sends that page's origin, which the data server must allow.
    data = recording.serve_grpc(grpc_port=target.data_port, default_blueprint=blueprint,
                                cors_allow_origin=[f"http://*:{target.port}", f"https://*:{target.port}"])
    try:
        rr.serve_web_viewer(web_port=target.port, open_browser=False, connect_to=data)
    except RuntimeError as exc:
        recording.disconnect()
        raise UsageError(f"cannot serve the web viewer on port {target.port}: {exc}") from None
    return f"the web viewer: open {web_page_url(socket.gethostname(), target)} (from this machine: localhost)"


def web_page_url(host: str, target: ViewTarget) -> str:
    """The page a browser opens to see the view served by *target* on *host*."""
    data = f"rerun+http://{host}:{target.data_port}/proxy"
    return f"http://{host}:{target.port}/?url={urllib.parse.quote(data, safe='')}"


def _connect(recording, target: ViewTarget, blueprint) -> tuple[str, threading.Thread | None]:
    """Where the view goes, and the thread still connecting to it (None: connected)."""
    url = grpc_url(target.address)
    where = f"the Rerun viewer at {url}"
    if _no_answer(target, 0.0) is None:
        recording.connect_grpc(url, default_blueprint=blueprint)
        return where, None
    # Where nothing listens, Rerun's connect_grpc (0.41) returns only when its first attempt has
    # given up, 5 s later: the view would start that late.  What is logged meanwhile is kept and
    # sent on to a viewer that comes later, as is what is logged after.
    connecting = threading.Thread(target=recording.connect_grpc, args=(url,),
                                  kwargs={"default_blueprint": blueprint}, name="rerun-connect", daemon=True)
    connecting.start()
    return where, connecting


def _save(recording, target: ViewTarget, blueprint) -> str:
    try:  # before Rerun: a save it fails leaves a stream that prints its own warning at exit
        with open(target.path, "ab"):
            pass
    except OSError as exc:  # the kernel's words alone name neither the directory nor the fix
        raise CaptureError(f"cannot write the view to {target.path}: {why_not_written(exc, target.path)}") from None
    try:
        recording.save(target.path, default_blueprint=blueprint)
    except RuntimeError as exc:
        raise CaptureError(f"cannot write the view to {target.path}: {exc}") from None
    return f"{target.path} (open it with: rerun {target.path})"


_OPENERS = {"spawn": _spawn, "web": _web, "save": _save}


def _check_free(target: ViewTarget) -> None:
    """Rerun's gRPC server only logs a port in use; say so before anything starts."""
    for port in (target.port, target.data_port):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                sock.bind(("0.0.0.0", port))
            except OSError as exc:
                raise UsageError(f"web:{target.port} serves the page on port {target.port} and its data on "
                                 f"{target.data_port}, and port {port} is taken ({exc.strerror}); choose another "
                                 "port (--view web:PORT)") from None


def free_web_port() -> int:
    """A port for ``ViewTarget("web", port=...)`` with it and the next free right now (a
    benchmark's or a test's web viewer beside whatever else runs)."""
    for _ in range(100):
        with socket.socket() as sock:
            sock.bind(("0.0.0.0", 0))
            port = sock.getsockname()[1]
        try:
            _check_free(ViewTarget("web", port=port))
        except UsageError:
            continue
        return port
    raise UsageError("found no two adjacent free ports for the web viewer")


def layout():
    """The viewer's layout: the 3-D scene in the odometry frame on the left; the polar heatmap,
    the time series and the flags on the right; Rerun's side panels folded away."""
    import rerun.blueprint as rrb

    plots = [rrb.TimeSeriesView(origin=f"plots/{name}", name=title)
             for name, title in (("speed", "speed, m/s"), ("yaw_rate", "yaw rate, deg/s"),
                                 ("counts", "points, features, ICP matches"), ("time_ms", "latency, estimator, ms"))]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="odom frame (REP-103: x ahead, y left, z up)"),
            rrb.Vertical(rrb.Spatial2DView(origin="heatmap",
                                           name="range-azimuth heatmap: range across, azimuth down (left at the top)"),
                         rrb.Grid(*plots), rrb.TextLogView(origin="log", name="quality flags, view"),
                         row_shares=[3, 4, 2]),
            column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"))
