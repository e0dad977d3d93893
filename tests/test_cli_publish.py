"""radar-capture publishing over Zenoh, end to end: real radar-capture processes and real
Zenoh sessions on loopback (peers, multicast scouting off, explicit endpoints on free ports).
The refusals, and a run that publishes nothing, call radar-capture's main() in this process
instead (``capture_main``: conftest's run_main).

A 3 s recording of the simulated corridor (30 frames) is made once per session (conftest's
corridor_run, shared with other modules); the runs replay it.
"""

from __future__ import annotations

import json
import signal
import subprocess
import time

import pytest
from test_cli_capture import popen_capture, run_capture_cli
from zenoh_helpers import Inbox, free_endpoint, peer, wait_for

from radarodom import messages
from radarodom.errors import MessageError

FRAMES = 30


@pytest.fixture(scope="module")
def recording(corridor_run):
    """The recording of conftest.CORRIDOR_URL (read only)."""
    assert corridor_run.proc.returncode == 0, corridor_run.proc.stderr
    return corridor_run.rec


def _odometry(inbox: Inbox) -> list[dict]:
    return [messages.parse_odometry(payload) for key, _, payload, _ in inbox.samples if key.endswith("/odom")]


def test_a_subscriber_gets_every_odometry_message_in_order(recording, tmp_path):
    here = free_endpoint()
    with peer(listen=[here]) as session:
        inbox = Inbox()
        sub = session.declare_subscriber("test/radar/**", inbox)
        try:
            # A subprocess (its subject: messages from another process), and the file's end-to-end
            # check of the installed console script.
            proc = run_capture_cli("--source", f"replay://{recording}?rate=2", "--key-prefix", "test/radar",
                                   "--connect", here, "--listen", free_endpoint(), timeout=120)
            assert proc.returncode == 0, proc.stderr
            assert wait_for(lambda: len(_odometry(inbox)) >= FRAMES, 5.0)
        finally:
            sub.undeclare()
    odom = _odometry(inbox)
    assert [m["frame"] for m in odom] == list(range(FRAMES))  # every one, in order
    assert all(m["schema"] == "radarodom/odom" and m["version"] == 1 for m in odom)
    times = [m["t"] for m in odom]
    assert times == sorted(times) and times[0] == pytest.approx(0.0, abs=1e-6)
    assert odom[-1]["x"] > 1.0  # the corridor drives forward
    encodings = {key.rsplit("/", 1)[1]: enc for key, enc, _, _ in inbox.samples}
    assert encodings["odom"] == "application/json"
    assert encodings["pointcloud"] == messages.POINTCLOUD_ENCODING
    assert encodings["heatmap"] == messages.HEATMAP_ENCODING
    status = [json.loads(p) for key, _, p, _ in inbox.samples if key.endswith("/status")]
    assert status and status[-1]["running"] is False and status[-1]["frames"] == FRAMES
    assert set(status[-1]["latency_ms"]) == {"p50", "p90", "p99", "max"}
    assert "published 30 odometry" in proc.stdout


def test_a_late_joiner_gets_the_latest_odometry_and_ctrl_c_ends_promptly(recording):
    listen = free_endpoint()
    proc = popen_capture("--source", f"replay://{recording}?rate=1&loop=0", "--listen", listen, "-q")
    try:
        time.sleep(2.5)  # about 20 frames in (later on a loaded machine: it is asked again below)
        with peer(connect=[listen]) as session:
            latest = None
            end = time.monotonic() + 30
            # Each answer is the newest odometry at that moment: it moves on until past frame 5.
            while (latest is None or latest["frame"] < 5) and time.monotonic() < end:
                replies = [r.ok for r in session.get("radar/awr1843/odom", timeout=2.0) if r.ok is not None]
                if replies:
                    latest = messages.parse_odometry(replies[0].payload.to_bytes())
                else:
                    time.sleep(0.2)
            assert latest is not None, "no answer to get()"
            assert latest["frame"] >= 5
            alive = [r.ok for r in session.liveliness().get("radar/awr1843/**", timeout=2.0) if r.ok is not None]
            assert any(str(s.key_expr) == "radar/awr1843/alive" for s in alive)
        proc.send_signal(signal.SIGINT)
        start = time.monotonic()
        out, err = proc.communicate(timeout=30)
        assert time.monotonic() - start < 20.0, "radar-capture took too long to stop"  # a hang guard
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert b"Traceback" not in err


def test_the_publisher_keeps_going_while_its_peer_is_down_and_reaches_it_when_it_comes_up(recording):
    router = free_endpoint()  # nothing listens there yet
    proc = popen_capture("--source", f"replay://{recording}?rate=1&loop=0", "--connect", router,
                         "--listen", free_endpoint(), "-q")
    try:
        time.sleep(1.5)
        assert proc.poll() is None, proc.communicate()
        with peer(listen=[router]) as session:
            inbox = Inbox()
            sub = session.declare_subscriber("radar/awr1843/odom", inbox)
            try:
                assert wait_for(lambda: len(_odometry(inbox)) >= 3, 8.0), "nothing arrived after the peer came up"
            finally:
                sub.undeclare()
        frames = [m["frame"] for m in _odometry(inbox)]
        assert frames == sorted(frames)
        assert proc.poll() is None  # and it is still running
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0


def test_no_publish_opens_no_session(recording, capture_main):
    # A few frames are as good as the 30: a session is opened (or not) before the first.
    proc = capture_main("--source", f"replay://{recording}?rate=max&frames=3", "--no-publish")
    assert proc.returncode == 0, proc.stderr
    assert "published" not in proc.stdout


def test_a_bad_zenoh_option_fails_before_the_source_opens(recording, tmp_path, capture_main):
    bad = tmp_path / "zenoh.json5"
    bad.write_text("{ this is not json5 }")  # closed: an unclosed '{' is named where it opens instead
    proc = capture_main("--source", f"replay://{recording}?rate=max", "--zenoh-config", bad)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and str(bad) in proc.stderr
    # One line, saying where in the file: zenoh's own report is a multi-line drawing.
    assert proc.stderr.splitlines() == [f"radar-capture: error: zenoh config {bad}:1:1: "
                                        "expected array, boolean, null, number, object, or string"]


def test_status_of_a_live_capture_carries_the_board_state(recording):
    """radar-capture on the emulated rig (fake AWR1843 on a pty, fake DCA1000 on UDP):
    the status messages report rates, drops, lost packets, latency and the board's state."""
    from live_helpers import Emulator

    here = free_endpoint()
    with Emulator("--capture", recording) as emu, peer(listen=[here]) as session:
        inbox = Inbox()
        sub = session.declare_subscriber("radar/awr1843/status", inbox)
        try:
            proc = subprocess.run(emu.capture_argv("--frames", "25", "--connect", here, "--listen", free_endpoint()),
                                  stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120)
            assert proc.returncode == 0, proc.stderr
            assert wait_for(lambda: any(json.loads(p)["running"] is False for p in inbox.payloads()), 5.0)
        finally:
            sub.undeclare()
    status = [json.loads(p) for p in inbox.payloads()]
    last = status[-1]
    assert last["frames"] == 25 and last["packets_lost"] == 0
    # A consumer too slow for the radar (a busy machine) drops whole frames: counted, not zero.
    assert last["frames_dropped"] == last["source"]["frames_dropped"] >= 0
    # Every missing byte has its cause: lost on the way or cut at stop (none here).
    assert last["missing_bytes"] == last["lost_bytes"] + last["cut_bytes"] == 0
    source = last["source"]
    assert source["packets_lost"] == source["truncated_packets"] == source["late_packets"] == 0, source
    assert source["frames_complete"] + source["frames_incomplete"] == 25, source
    assert last["source"]["url"].startswith("dca1000://") and last["source"]["fpga"]
    assert isinstance(last["source"]["async_status"], dict)  # the board's status counts
    latency = last["latency_ms"]  # its percentiles in order (their size is a machine's speed: bench/)
    assert 0 < latency["p50"] <= latency["p90"] <= latency["p99"] <= latency["max"] and last["rate_hz"] > 0
    assert len(status) >= 2  # about once a second while running, and a last one


def _decodable_odometry(inbox: Inbox) -> list[dict]:
    out = []
    for payload in inbox.payloads():
        try:
            out.append(messages.parse_odometry(payload))
        except MessageError:
            pass
    return out


def test_radar_capture_keeps_every_frame_while_a_peer_floods_its_keys(recording):
    """Issue 18: any peer may put anything on radar-capture's keys and query its odometry
    without end.  radar-capture processes and publishes every frame all the same, on time in
    stream order, and says nothing about the flood (it subscribes to nothing)."""
    here = free_endpoint()
    hostile = [b"[" * 1000, b"\xff\xfe", b'{"schema":"radarodom/odom","version":1,"t":NaN}', b"RPC1" + b"\x00" * 60,
               b"x" * (2 << 20)]
    with peer(listen=[here]) as session:
        inbox = Inbox()
        sub = session.declare_subscriber("test/radar/odom", inbox)
        publishers = [session.declare_publisher(f"test/radar/{kind}") for kind in ("odom", "status", "pointcloud",
                                                                                    "heatmap")]
        proc = popen_capture("--source", f"replay://{recording}?rate=2", "--key-prefix", "test/radar",
                             "--connect", here, "--listen", free_endpoint(), text=True)
        sent = queries = 0
        try:
            while proc.poll() is None:
                for pub in publishers:
                    for payload in hostile:
                        pub.put(payload)
                        sent += 1
                for _ in session.get("test/radar/odom", timeout=0.5):
                    pass
                queries += 1
            out, err = proc.communicate(timeout=30)
            assert wait_for(lambda: len(_decodable_odometry(inbox)) >= FRAMES, 5.0)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
            sub.undeclare()
    assert sent > 100 and queries > 5, (sent, queries)  # the flood ran the whole time
    assert proc.returncode == 0, err
    assert err == "", err
    assert "published 30 odometry" in out, out
    odom = _decodable_odometry(inbox)
    # The hostile puts on the same key reach this subscriber too: radar-capture's own messages
    # are the 30 that decode, every frame once and in order.
    assert [m["frame"] for m in odom] == list(range(FRAMES))


@pytest.mark.parametrize("option", [["--ros2"], ["--connect", "tcp/127.0.0.1:17999"], ["--zenoh-config", "z.json5"],
                                    ["--key-prefix", "robot/radar"], ["--ros2-domain", "3"]])
def test_a_publishing_option_with_no_publish_is_refused_not_ignored(recording, option, capture_main):
    proc = capture_main("--source", f"replay://{recording}?rate=max", "--no-publish", *option)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr == (f"radar-capture: error: {option[0]} is about publishing over Zenoh, which --no-publish "
                           "turns off: drop one\n")


@pytest.mark.parametrize("option, message", [
    (["--ros2-topic", "/robot/odom"], "--ros2-topic names the ROS 2 odometry topic: add --ros2 (publish it) or --mcap "
                                     "FILE (write it to a bag)"),
    (["--ros2-domain", "3"], "--ros2-domain is the ROS 2 domain of --ros2's messages: add --ros2")])
def test_a_ros2_option_without_ros2_is_refused_not_ignored(recording, option, message, capture_main):
    # It published the radarodom messages alone, the option silently unused.
    proc = capture_main("--source", f"replay://{recording}?rate=max", *option)
    assert proc.returncode == 2 and proc.stdout == "" and proc.stderr == f"radar-capture: error: {message}\n"
