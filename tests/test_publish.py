"""Publishing over Zenoh (radarodom.publish) with real sessions on loopback: peers
with multicast scouting off on explicit tcp/127.0.0.1 endpoints on free ports.

What a subscriber gets (every odometry message of a run, in order, by schema;
point clouds and heatmaps with their encodings, exactly), the queryable for late
joiners, the liveliness token, a publisher without subscribers, a publisher whose
peer is down at start or goes away and comes back, the process exiting promptly
(also on Ctrl-C), the ROS 2 output as rmw_zenoh_cpp expects it, and the session
options and their errors."""

from __future__ import annotations

import json
import math
import re
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import zenoh
from conftest import REPO
from zenoh_helpers import Inbox, estimator_run, free_endpoint, peer, subscribe, wait_for

from radarodom import messages, ros2
from radarodom.ros2 import ros2_liveliness_keys, ros2_topic_key
from radarodom.errors import PublishConfigError, PublishError
from radarodom.pipeline import LatencyMeter
from radarodom.publish import (CONNECT_RETRY, DEFAULT_ENDPOINT, ROS2_ROUTER_ENDPOINT, Publisher, ZenohOptions,
                               open_session)


@pytest.fixture(scope="module")
def run():
    """A real estimator run to publish: [(OdometryState, points, RangeAzimuth)]."""
    return estimator_run()


@pytest.fixture
def endpoint() -> str:
    return free_endpoint()


@pytest.fixture
def publisher(endpoint):
    with Publisher(ZenohOptions(listen=[endpoint])) as pub:
        yield pub


def matched(pub: Publisher, kind: str = "odom") -> bool:
    """Wait until the publisher of *kind* knows of a subscriber (samples put before are lost)."""
    return wait_for(lambda: pub._publishers[kind].matching_status.matching)


# =========================================================================== what subscribers get
def test_a_subscriber_receives_every_odometry_message_in_order(publisher, endpoint, run):
    with peer(connect=[endpoint]) as session:
        inbox = subscribe(session, "radar/awr1843/odom")
        assert matched(publisher)
        for state, _, _ in run:
            publisher.odometry(state)
            time.sleep(0.01)  # a replay at 100 Hz
        assert wait_for(lambda: len(inbox.samples) >= len(run)), f"{len(inbox.samples)} of {len(run)}"
        time.sleep(0.05)
    assert len(inbox.samples) == len(run)
    received = [messages.parse_odometry(p) for p in inbox.payloads()]
    assert [m["frame"] for m in received] == list(range(len(run)))
    for m, (state, _, _) in zip(received, run):
        assert m == messages.odometry_dict(state)
    assert {s[0] for s in inbox.samples} == {"radar/awr1843/odom"}
    assert {s[1] for s in inbox.samples} == {"application/json"}
    assert publisher.counts["odom"] == len(run)


def test_point_clouds_and_heatmaps_arrive_with_their_encodings_exactly(publisher, endpoint, run):
    with peer(connect=[endpoint]) as session:
        clouds = subscribe(session, "radar/awr1843/pointcloud")
        heatmaps = subscribe(session, "radar/awr1843/heatmap")
        assert matched(publisher, "pointcloud") and matched(publisher, "heatmap")
        for i, (state, points, heatmap) in enumerate(run[:5]):
            # One frame at a time, sent again until both arrive: point clouds and heatmaps are
            # dropped under congestion by design, and a loaded machine may drop even one.
            for _ in range(5):
                publisher.pointcloud(i, state.t, points)
                publisher.heatmap(i, state.t, heatmap)
                if wait_for(lambda: i in _frames(clouds, messages.decode_pointcloud)
                            and i in _frames(heatmaps, messages.decode_heatmap), timeout=5.0):
                    break
            else:
                pytest.fail(f"frame {i}: point cloud or heatmap never arrived in 5 sends")
    assert {s[1] for s in clouds.samples} == {"application/octet-stream;radarodom/pointcloud/v1"}
    assert {s[1] for s in heatmaps.samples} == {"application/octet-stream;radarodom/heatmap/v1"}
    cloud_of, heatmap_of = _frames(clouds, messages.decode_pointcloud), _frames(heatmaps, messages.decode_heatmap)
    for i, (state, points, heatmap) in enumerate(run[:5]):
        header, decoded = cloud_of[i]
        assert (header["frame"], header["t"], header["count"]) == (i, state.t, len(points))
        for name in messages.POINTCLOUD_RECORD.names:
            np.testing.assert_array_equal(decoded[name], points[name])
        header, arrays = heatmap_of[i]
        assert (header["frame"], header["n_range"], header["n_azimuth"]) == (i, *heatmap.intensity.shape)
        for name in ("intensity", "static", "doppler_mps", "range_m", "azimuth_rad"):
            np.testing.assert_array_equal(arrays[name], np.float32(getattr(heatmap, name)))


def _frames(inbox: Inbox, decode) -> dict:
    """The decoded samples of *inbox* by their header's frame number (the first of each)."""
    found: dict = {}
    for sample in list(inbox.samples):
        header, body = decode(sample[2])
        found.setdefault(header["frame"], (header, body))
    return found


def test_status_messages(publisher, endpoint):
    with peer(connect=[endpoint]) as session:
        inbox = subscribe(session, "radar/awr1843/status")
        assert matched(publisher, "status")
        publisher.status({"rate_hz": 10.0, "dropped": 0})
        assert wait_for(lambda: inbox.samples)
    assert messages.parse_status(inbox.samples[0][2]) == {"schema": "radarodom/status", "version": 1,
                                                          "rate_hz": 10.0, "dropped": 0}
    assert inbox.samples[0][1] == "application/json"


def test_status_figures_not_known_yet_go_out_as_null(publisher, endpoint):
    """Regression (issue 18): a status holds NaN before the first frame (the latency meter's
    percentiles); it is sent as standard JSON with null there, never NaN, and never lost."""
    p50, p99 = LatencyMeter().percentiles_ms(50, 99)
    assert math.isnan(p50)
    with peer(connect=[endpoint]) as session:
        inbox = subscribe(session, "radar/awr1843/status")
        assert matched(publisher, "status")
        publisher.status({"latency_ms": {"p50": p50, "p99": p99}, "rate_hz": np.float64(np.inf),
                          "frames": np.int64(3), "ok": np.bool_(True), "gains": np.array([1.0, np.nan])})
        assert wait_for(lambda: inbox.samples)
    payload = inbox.samples[0][2]
    assert json.loads(payload, parse_constant=pytest.fail) == messages.parse_status(payload) == {
        "schema": "radarodom/status", "version": 1, "latency_ms": {"p50": None, "p99": None}, "rate_hz": None,
        "frames": 3, "ok": True, "gains": [1.0, None]}


def test_a_late_joiner_gets_the_latest_odometry_by_query(publisher, endpoint, run):
    with peer(connect=[endpoint]) as session:
        assert wait_for(lambda: list(session.info.peers_zid()))
        # Before any odometry the queryable has nothing to say.
        assert [r for r in session.get("radar/awr1843/odom", timeout=1.0) if r.ok is not None] == []
    for state, _, _ in run[:4]:
        publisher.odometry(state)  # nobody listens
    with peer(connect=[endpoint]) as late:
        assert wait_for(lambda: list(late.info.peers_zid()))
        replies = [r.ok for r in late.get("radar/awr1843/odom", timeout=2.0) if r.ok is not None]
    assert len(replies) == 1
    assert str(replies[0].key_expr) == "radar/awr1843/odom" and str(replies[0].encoding) == "application/json"
    assert messages.parse_odometry(replies[0].payload.to_bytes())["frame"] == run[3][0].frame


def test_the_liveliness_token_lives_as_long_as_the_publisher(endpoint):
    with peer(listen=[endpoint]) as session:
        pub = Publisher(ZenohOptions(listen=(), connect=[endpoint]))
        try:
            assert wait_for(lambda: [str(r.ok.key_expr) for r in session.liveliness().get("radar/**", timeout=1.0)
                                     if r.ok is not None] == ["radar/awr1843/alive"])
        finally:
            pub.close()
        assert wait_for(lambda: [r for r in session.liveliness().get("radar/**", timeout=0.5)
                                 if r.ok is not None] == [])


def test_the_publisher_keeps_running_without_subscribers(publisher, endpoint, run):
    state = run[-1][0]
    started = time.monotonic()
    for i in range(300):
        publisher.odometry(state)
        publisher.pointcloud(i, state.t, run[-1][1])
        publisher.heatmap(i, state.t, run[-1][2])
    # Puts drop on congestion rather than wait: nothing blocks (a hang guard, not a speed figure).
    assert time.monotonic() - started < 60.0
    assert publisher.counts == {"odom": 300, "pointcloud": 300, "heatmap": 300, "status": 0}
    with peer(connect=[endpoint]) as session:  # ... and a subscriber that joins then gets what follows
        inbox = subscribe(session, "radar/awr1843/odom")
        assert matched(publisher)
        publisher.odometry(state)
        assert wait_for(lambda: inbox.samples)


def _publish_until(pub: Publisher, state, inbox: Inbox, timeout: float) -> float | None:
    """Publish every 50 ms until *inbox* gets something; the seconds it took, or None."""
    started = time.monotonic()
    while time.monotonic() - started < timeout:
        pub.odometry(state)
        if inbox.samples:
            return time.monotonic() - started
        time.sleep(0.05)
    return None


def test_a_peer_that_is_down_at_start_and_goes_away_is_joined_when_it_comes_up(endpoint, run):
    state = run[-1][0]
    # Told to connect to a peer that is not there: opens anyway, and publishes into nothing.
    with Publisher(ZenohOptions(listen=(), connect=[endpoint])) as pub:
        for _ in range(10):
            pub.odometry(state)
            time.sleep(0.05)
        for attempt in ("comes up", "comes back"):
            with peer(listen=[endpoint]) as session:
                inbox = subscribe(session, "radar/awr1843/odom")
                took = _publish_until(pub, state, inbox, timeout=5.0)
                assert took is not None, f"nothing received within 5 s after the peer {attempt}"
            # The peer is gone again: publishing goes on without error.
            for _ in range(10):
                pub.odometry(state)
                time.sleep(0.02)


# =========================================================================== the process exits
PUBLISHER_SCRIPT = """
import sys, time
from radarodom.estimator.odometry import OdometryState
from radarodom.publish import Publisher, ZenohOptions
with Publisher(ZenohOptions(listen=(), connect=[sys.argv[1]])) as pub:
    print("ready", flush=True)
    i = 0
    while sys.argv[2] == "forever" or i < int(sys.argv[2]):
        pub.odometry(OdometryState(t=float(i), frame=i))
        i += 1
        time.sleep(0.01)
print("closed", flush=True)
"""


def _start_publisher_process(endpoint: str, count: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", PUBLISHER_SCRIPT, endpoint, count], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "ready", proc.stderr.read()
    return proc


def test_a_publishing_process_exits_promptly_at_its_end(endpoint):
    with peer(listen=[endpoint]) as session:
        inbox = subscribe(session, "radar/awr1843/odom")  # someone is listening while it runs
        proc = _start_publisher_process(endpoint, "50")
        try:
            out, err = proc.communicate(timeout=30)
        finally:
            proc.kill()
    assert proc.returncode == 0, err
    assert out.strip() == "closed"
    assert inbox.samples  # it did publish


def test_a_publishing_process_exits_promptly_on_ctrl_c(endpoint):
    with peer(listen=[endpoint]) as session:
        inbox = subscribe(session, "radar/awr1843/odom")
        proc = _start_publisher_process(endpoint, "forever")
        try:
            assert wait_for(lambda: len(inbox.samples) > 3)
            proc.send_signal(signal.SIGINT)
            started = time.monotonic()
            _, err = proc.communicate(timeout=30)
        finally:
            proc.kill()
    assert time.monotonic() - started < 20.0  # a hang guard (under the communicate timeout), not a speed figure
    # Python's own exit on an unhandled Ctrl-C: it dies of SIGINT, after the with block closed the session.
    assert proc.returncode == -signal.SIGINT and "KeyboardInterrupt" in err


def test_close_leaves_no_thread_that_would_hold_the_interpreter(endpoint):
    before = set(threading.enumerate())
    with Publisher(ZenohOptions(listen=[endpoint])) as pub:
        pub.status({"n": 1})
    assert wait_for(lambda: not [t for t in threading.enumerate() if t not in before and not t.daemon])


def test_closing_stops_publishing_and_can_be_repeated(endpoint, run):
    pub = Publisher(ZenohOptions(listen=[endpoint]))
    pub.close()
    pub.close()
    assert pub.closed
    with pytest.raises(PublishError, match="closed"):
        pub.odometry(run[0][0])


# =========================================================================== ROS 2
def test_ros2_odometry_reaches_an_rmw_zenoh_subscriber(endpoint, run):
    typesys = pytest.importorskip("rosbags.typesys")
    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    type_hash = store.hash_rihs01("nav_msgs/msg/Odometry")
    key = f"0/radar/odom/nav_msgs::msg::dds_::Odometry_/{type_hash}"
    options = ZenohOptions(listen=[endpoint], connect=(), ros2=True)
    with Publisher(options) as pub, peer(connect=[endpoint]) as session:
        assert pub.ros2_key == key
        inbox = subscribe(session, key)  # what an rmw_zenoh_cpp subscription declares
        assert matched(pub, "ros2")
        for i, (state, _, _) in enumerate(run[:6]):
            pub.odometry(state)
            assert wait_for(lambda: len(inbox.samples) == i + 1), (i, len(inbox.samples))
        tokens = sorted(str(r.ok.key_expr) for r in session.liveliness().get("@ros2_lv/0/**", timeout=1.0)
                        if r.ok is not None)
        zid = pub.zid
    sequences, gids = [], set()
    for (_, _, payload, attachment), (state, _, _) in zip(inbox.samples, run):
        msg = store.deserialize_cdr(payload, "nav_msgs/msg/Odometry")
        assert msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 == pytest.approx(state.t, abs=1e-9)
        assert (msg.pose.pose.position.x, msg.pose.pose.position.y) == (state.x, state.y)
        assert 2 * math.atan2(msg.pose.pose.orientation.z, msg.pose.pose.orientation.w) == \
            pytest.approx(math.remainder(state.yaw, 2 * math.pi))
        assert msg.twist.twist.linear.x == state.vx and msg.twist.twist.angular.z == state.yaw_rate
        assert len(attachment) == 33
        seq, stamp_ns, n, gid = ros2.ROS2_ATTACHMENT.unpack(attachment)
        assert n == 16 and abs(stamp_ns - time.time_ns()) < 60e9
        sequences.append(seq)
        gids.add(gid)
    assert sequences == list(range(sequences[0], sequences[0] + 6)) and len(gids) == 1
    # The node's and the odometry publisher's (the point cloud's and the transforms':
    # tests/test_ros2_live.py).
    odometry_tokens = [t for t in tokens if t.endswith("/NN/%/%/radarodom") or "%radar%odom/" in t]
    assert odometry_tokens == sorted(ros2_liveliness_keys(0, zid, "/radar/odom", type_hash))
    for token in odometry_tokens:
        _check_rmw_zenoh_token(token)


def _check_rmw_zenoh_token(token: str) -> None:
    """What rmw_zenoh_cpp's Entity::make(keyexpr) checks before it accepts a graph token."""
    parts = token.split("/")
    assert parts[0] == "@ros2_lv" and all(parts), token
    assert parts[5] in ("NN", "MP")
    if parts[5] == "NN":
        assert len(parts) == 9
        return
    assert len(parts) == 13
    qos = parts[12].split(":")
    assert len(qos) == 6 and len(qos[2].split(",")) == 2 and len(qos[5].split(",")) == 3
    assert parts[9].replace("%", "/") == "/radar/odom" and parts[10] == "nav_msgs::msg::dds_::Odometry_"


def test_ros2_keys_follow_rmw_zenoh():
    assert ros2_topic_key(3, "/robot/radar/odom", "RIHS01_ab") == \
        "3/robot/radar/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_ab"
    node, pub = ros2_liveliness_keys(3, "f00d", "/robot/odom", "RIHS01_ab")
    assert node == "@ros2_lv/3/f00d/0/0/NN/%/%/radarodom"
    assert pub == "@ros2_lv/3/f00d/0/10/MP/%/%/radarodom/%robot%odom/nav_msgs::msg::dds_::Odometry_/RIHS01_ab/::,10:,:,:,,"


def test_ros2_without_rosbags_says_what_to_install(monkeypatch, endpoint):
    monkeypatch.setitem(sys.modules, "rosbags", None)  # as if it were not installed
    monkeypatch.setitem(sys.modules, "rosbags.typesys", None)
    with pytest.raises(PublishConfigError, match=r'pip install "radarodom\[ros2\]"') as info:
        Publisher(ZenohOptions(listen=[endpoint], ros2=True))
    assert info.value.exit_code == 2


# =========================================================================== session options
def _config(options: ZenohOptions) -> dict:
    config = options.to_config()
    return {key: json.loads(config.get_json(key)) for key in
            ("mode", "listen/endpoints", "connect/endpoints", "scouting/multicast/enabled", "connect/retry")}


def test_the_default_session_is_a_local_peer_without_multicast():
    config = _config(ZenohOptions())
    assert config["mode"] == "peer" and config["scouting/multicast/enabled"] is False
    assert config["listen/endpoints"] == [DEFAULT_ENDPOINT] == ["tcp/127.0.0.1:7448"]
    assert config["connect/endpoints"] == []
    assert config["connect/retry"] == {"period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2.0}
    assert "period_max_ms: 1000" in CONNECT_RETRY
    assert _config(ZenohOptions(ros2=True))["connect/endpoints"] == [ROS2_ROUTER_ENDPOINT]
    assert _config(ZenohOptions(ros2=True, connect=["tcp/10.0.0.1:7447"]))["connect/endpoints"] == ["tcp/10.0.0.1:7447"]
    client = _config(ZenohOptions(mode="client", connect="tcp/10.0.0.1:7447"))
    assert client["mode"] == "client" and client["listen/endpoints"] == []


def test_subscribers_connect_to_the_publishers_default_endpoint_and_never_take_it():
    sub = ZenohOptions().for_subscriber()
    assert (sub.listen, sub.connect) == ((), (DEFAULT_ENDPOINT,))
    sub = ZenohOptions(connect=["tcp/10.0.0.1:7448"]).for_subscriber()
    assert (sub.effective_listen, sub.effective_connect) == ((), ("tcp/10.0.0.1:7448",))
    sub = ZenohOptions(listen=["tcp/0.0.0.0:7500"]).for_subscriber()
    assert (sub.effective_listen, sub.effective_connect) == (("tcp/0.0.0.0:7500",), ())
    from_file = ZenohOptions(config_file="zenoh.json5")
    assert from_file.for_subscriber() is from_file


def test_a_config_file_comes_first_and_options_override_it(tmp_path):
    path = tmp_path / "zenoh.json5"
    path.write_text("{ mode: 'peer', // comments are JSON5\n"
                    "  listen: { endpoints: ['tcp/127.0.0.1:7999'] },\n"
                    "  scouting: { multicast: { enabled: true } } }")
    config = _config(ZenohOptions(config_file=path))
    assert config["listen/endpoints"] == ["tcp/127.0.0.1:7999"]
    assert config["scouting/multicast/enabled"] is True  # the file's, not the built-in default
    overridden = _config(ZenohOptions(config_file=path, listen=["tcp/127.0.0.1:7001"], mode="client",
                                      connect=["tcp/127.0.0.1:7002"]))
    assert overridden["listen/endpoints"] == ["tcp/127.0.0.1:7001"] and overridden["mode"] == "client"


def test_an_endpoint_given_twice_is_refused():
    # Zenoh found the first listener there and said "another program listens there".
    with pytest.raises(PublishConfigError, match="listen: tcp/127.0.0.1:7001 is given twice") as info:
        ZenohOptions(listen=["tcp/127.0.0.1:7001", "tcp/127.0.0.1:7001"])
    assert info.value.exit_code == 2
    with pytest.raises(PublishConfigError, match="connect: tcp/127.0.0.1:7002 is given twice"):
        ZenohOptions(connect=["tcp/127.0.0.1:7002", "tcp/127.0.0.1:7002"])


@pytest.mark.parametrize("name, endpoints", [
    ("listen", ["tcp/0.0.0.0:7001", "tcp/127.0.0.1:7001"]),  # every interface holds 127.0.0.1:7001 already
    ("listen", ["tcp/127.0.0.1:7001", "tcp/[::]:7001"]),
    ("listen", ["tcp/localhost:7001", "ws/127.0.0.1:7001"]),  # ws is on TCP too
    ("listen", ["udp/127.0.0.1:7001", "quic/127.0.0.1:7001"]),
])
def test_two_endpoints_on_one_socket_are_refused(name, endpoints):
    # Zenoh's second listener found the first there and said "another program listens there".
    with pytest.raises(PublishConfigError, match=f"{name}: .* are the same socket.*: give one") as info:
        ZenohOptions(**{name: endpoints})
    assert info.value.exit_code == 2
    wildcard = any(w in e for e in endpoints for w in ("0.0.0.0", "[::]"))
    assert ("every IPv4 address" in str(info.value)) == wildcard  # the note only where it explains


def test_endpoints_on_different_sockets_are_taken():
    listen = ["tcp/127.0.0.1:7001", "udp/127.0.0.1:7001", "tcp/127.0.0.2:7001", "tcp/0.0.0.0:7002",
              "tcp/127.0.0.1:0", "tcp/0.0.0.0:0",  # port 0: a free port each
              "tcp/[::1]:7002"]  # 0.0.0.0 takes IPv4 addresses only
    connect = ["tcp/10.0.0.1:7447", "tcp/10.0.0.2:7447", "tcp/[::1]:7447", "tcp/robot.local:7447",
               "tcp/[fe80::1%1]:7447",
               "tcp/10.0.0.1:7447?prio=1-3", "tcp/10.0.0.1:7447?prio=4-7"]  # two links to one peer
    assert ZenohOptions(listen=listen, connect=connect).listen == tuple(listen)
    assert ZenohOptions(connect=["tcp/localhost:7002", "tcp/127.0.0.1:7002"]).connect


def test_a_unix_socket_path_holding_the_users_file_is_refused_and_one_zenoh_left_is_taken(tmp_path):
    """Hunt 4: Zenoh deletes what lies at a unixsock-stream listen path, and PATH.lock, to make its
    socket: a user's file there (a recording's capture.json) was gone without a word, a directory
    was "another program listens there"."""
    mine = tmp_path / "notes.txt"
    mine.write_text("keep\n")
    (tmp_path / "d").mkdir()
    (tmp_path / "s.sock.lock").write_text("keep\n")
    for path, words in ((mine, f"{mine} is there and is not the socket a Zenoh session leaves"),
                        (tmp_path / "d", "is not the socket a Zenoh session leaves"),
                        (tmp_path / "s.sock", "s.sock.lock is there and is not the empty lock file"),
                        (tmp_path / "none" / "s.sock", "no directory .* make it first, or give a path in one")):
        with pytest.raises(PublishConfigError, match=words) as info:
            ZenohOptions(listen=[f"unixsock-stream/{path}"])
        assert info.value.exit_code == 2 and str(info.value).startswith("listen: "), info.value
    assert mine.read_text() == (tmp_path / "s.sock.lock").read_text() == "keep\n"
    # What a killed session leaves (its socket, an empty lock file) is Zenoh's to take again; a
    # connect endpoint is not checked so (it makes nothing).
    with socket.socket(socket.AF_UNIX) as left:
        left.bind(str(tmp_path / "left.sock"))
    (tmp_path / "left.sock.lock").touch()
    for path in (tmp_path / "left.sock", tmp_path / "new.sock"):
        assert ZenohOptions(listen=[f"unixsock-stream/{path}"]).listen == (f"unixsock-stream/{path}",)
    assert ZenohOptions(connect=[f"unixsock-stream/{mine}"]).connect


def test_a_link_local_address_names_its_interface_by_number():
    # Zenoh looked "fe80::1%lo" up as a host name and retried the connect endpoint for ever.
    number = socket.if_nametoindex("lo")
    expected = re.escape(f"tcp/[fe80::1%{number}]:7447 (lo is interface {number} here)")
    with pytest.raises(PublishConfigError, match=expected):
        ZenohOptions(connect=["tcp/[fe80::1%lo]:7447"])
    with pytest.raises(PublishConfigError, match="no interface named 'nosuch0'; `ip link` lists them"):
        ZenohOptions(listen=["tcp/[fe80::1%nosuch0]:7447"])


@pytest.mark.parametrize("text, words", [
    # A text cut short or mis-closed: zenoh said "expected boolean or null" somewhere else.
    ("{ mode: 'peer', listen: { endpoints: [ }",
     r"zenoh\.json5:1:40: this '\}' closes the '\[' opened at 1:38, which needs '\]'"),
    ('{ mode: "peer",\n  listen: { endpoints: ["tcp/127.0.0.1:0"] }\n',
     r"zenoh\.json5:1:1: this '\{' is never closed \(the text ends first\)"),
    ("{ mode: 'peer }", r"zenoh\.json5:1:9: this string has no closing ' on its line"),
    ('{ mode: "peer" }}', r"zenoh\.json5:1:17: this '\}' closes nothing"),
    ("{ /* mode: 'peer' }", r"zenoh\.json5:1:3: this /\* comment is never closed by \*/"),
    ("{ mode: 'banana' }", r"zenoh\.json5:1:9: unknown variant 'banana', expected one of 'router', 'peer'"),
    ("{ moed: 'peer' }", r"zenoh\.json5:1:3: unknown field 'moed'"),
    ('{ listen: { endpoints: "tcp/127.0.0.1:7001" } }', r"zenoh\.json5:1:\d+: invalid type: string"),
    ("[]", r"zenoh\.json5: not a JSON5 object"),  # zenoh took it for an empty config
    ("", r"zenoh\.json5: not a JSON5 object"),
])
def test_a_bad_config_file_is_an_option_error_naming_it(tmp_path, text, words):
    path = tmp_path / "zenoh.json5"
    _check_bad_config_file(path, text, words)


@pytest.mark.parametrize("text, words", [  # they came as Rust's debug form: YAML error: Error("...", line: 1, ...)
    ("mode: [peer\n", r"zenoh\.yaml:1:7: mode: invalid type: sequence, expected either 'router', 'peer'"),
    ("mode: banana\n", r"zenoh\.yaml:1:7: mode: unknown variant 'banana', expected one of 'router', 'peer'"),
    ('mode: peer\nconnect:\n  endpoints:\n   - "tcp/127.0.0.1:7447\n',  # Error { kind: SCANNER, problem: ...
     r"zenoh\.yaml:5:1: found unexpected end of stream while scanning a quoted scalar begun at 4:6"),
])
def test_a_bad_yaml_config_file_is_named_by_line_and_column(tmp_path, text, words):
    _check_bad_config_file(tmp_path / "zenoh.yaml", text, words)


def _check_bad_config_file(path, text, words):
    tmp_path = path.parent
    path.write_text(text)
    with pytest.raises(PublishConfigError, match=words) as info:
        ZenohOptions(config_file=path).to_config()
    assert info.value.exit_code == 2
    assert ".rs:" not in str(info.value)  # zenoh's source locations are left out
    assert "Message {" not in str(info.value)  # nor the Rust error's debug form
    with pytest.raises(PublishConfigError, match="no such file"):
        ZenohOptions(config_file=tmp_path / "missing.json5").to_config()


@pytest.mark.parametrize("text, words", [
    # Zenoh retried a connect endpoint it could not parse for ever without a word.
    ('{ mode: "peer",\n  connect: { endpoints: ["tcp/127.0.0.1:99999"] } }',
     r"zenoh\.json5:2: connect/endpoints: 'tcp/127\.0\.0\.1:99999': port 99999 is above 65535"),
    # A listen endpoint's bad port failed the session, naming no endpoint.
    ("{ listen: { endpoints: ['tcp/127.0.0.1:70000'] } }",
     r"zenoh\.json5:1: listen/endpoints: 'tcp/127\.0\.0\.1:70000': port 70000 is above 65535"),
    ("{ listen: { endpoints: { peer: ['tcp/exa mple:7447'] } } }", "'exa mple' is not a host name"),
    ("{ listen: { endpoints: ['tcp/0.0.0.0:17001', 'tcp/127.0.0.1:17001'] } }",
     r"zenoh\.json5: listen/endpoints: tcp/0\.0\.0\.0:17001 and tcp/127\.0\.0\.1:17001 are the same socket"),
    ("{ mode: 'client', scouting: { multicast: { enabled: false } } }",
     r"zenoh\.json5: mode \"client\" with multicast scouting off needs a Zenoh router's endpoint to connect to"),
    ("{ mode: 'client', scouting: { multicast: { enabled: false } },\n"
     "  connect: { endpoints: { peer: ['tcp/127.0.0.1:7447'] } } }", "needs a Zenoh router's"),
    # The line is that of the endpoint under its key, not of its text in a comment or another key.
    ("{ // once 'tcp/127.0.0.1:99999'\n  listen: { endpoints: ['tcp/127.0.0.1:99999'] },\n"
     "  connect: { endpoints: ['tcp/127.0.0.1:99999'] } }", r"zenoh\.json5:2: listen/endpoints: "),
    ("{ connect: { endpoints: { router: ['tcp/127.0.0.1:7447'],\n  peer: ['tcp/127.0.0.1:0'] } } }",
     r"zenoh\.json5:2: connect/endpoints/peer: 'tcp/127\.0\.0\.1:0': port 0 is no port"),
])
def test_a_config_files_endpoints_and_mode_are_checked_as_the_options_are(tmp_path, text, words):
    path = tmp_path / "zenoh.json5"
    path.write_text(text)
    with pytest.raises(PublishConfigError, match=words) as info:
        ZenohOptions(config_file=path).to_config()
    assert info.value.exit_code == 2


def test_a_config_files_endpoints_that_options_replace_are_not_checked(tmp_path):
    path = tmp_path / "zenoh.json5"
    path.write_text("{ mode: 'client', connect: { endpoints: ['tcp/127.0.0.1:99999'] } }")
    config = _config(ZenohOptions(config_file=path, connect=["tcp/127.0.0.1:7447"]))
    assert config["connect/endpoints"] == ["tcp/127.0.0.1:7447"] and config["mode"] == "client"
    _config(ZenohOptions(config_file=path, connect=[]))  # it finds its router by multicast scouting
    path.write_text("{ mode: 'client', scouting: { multicast: { enabled: false } } }")
    with pytest.raises(PublishConfigError, match="needs a Zenoh router's"):
        ZenohOptions(config_file=path, connect=[]).to_config()
    # a peer has no router to find
    assert _config(ZenohOptions(config_file=path, mode="peer"))["mode"] == "peer"


def test_a_config_file_with_a_bom_is_read(tmp_path):
    path = tmp_path / "zenoh.json5"
    path.write_bytes(b"\xef\xbb\xbf{ mode: 'peer' }")  # as some Windows editors save it
    ZenohOptions(config_file=path).to_config()


@pytest.mark.parametrize("make, words", [
    (lambda tmp_path: "/dev/zero", "/dev/zero: not a regular file"),  # zenoh read it for ever
    (lambda tmp_path: tmp_path, "not a regular file"),
    (lambda tmp_path: _big(tmp_path / "big.json5"), "more than the 1048576"),
])
def test_a_config_file_zenoh_cannot_read_whole_is_refused_first(tmp_path, make, words):
    with pytest.raises(PublishConfigError, match=words) as info:
        ZenohOptions(config_file=make(tmp_path)).to_config()
    assert info.value.exit_code == 2


def _big(path):
    path.write_text("{ mode: 'peer' }" + " " * (1 << 20))
    return path


@pytest.mark.parametrize("options, words", [
    (dict(mode="router"), "mode must be one of peer, client"),
    (dict(connect=["localhost:7447"]), "not an endpoint"),
    (dict(connect=["tcp/192.168.1.5"]), "needs HOST:PORT"),
    (dict(listen=["tcp/127.0.0.1:99999"]), "port 99999 is above 65535"),
    (dict(listen=["tcp/999.0.0.1:17452"]), "999.0.0.1 is not an IPv4 address"),
    (dict(connect=["udp/10.0.0.256:7447"]), "10.0.0.256 is not an IPv4 address"),
    # Zenoh took these and retried them for ever without a word.
    (dict(connect=["tcp/exa mple:17453"]), "'exa mple' is not a host name or an IP address"),
    (dict(connect=["tcp/[::1:17453"]), r"\[::1 is not an IPv6 address in brackets, e\.g\. tcp/\[::1\]:17453"),
    (dict(connect=["tcp/::1:17453"]), r"an IPv6 address goes in brackets, e\.g\. tcp/\[::1\]:17453"),
    (dict(connect=["tcp/127.0.0.1:0"]), "port 0 is no port to connect to"),
    (dict(listen=[7447]), "not an endpoint"),
    (dict(key_prefix=""), "non-empty"),
    (dict(key_prefix="radar/*"), "wildcards"),
    (dict(key_prefix="/radar"), "not a Zenoh key expression"),
    (dict(key_prefix="radar//awr"), "not a Zenoh key expression"),
    (dict(ros2_domain=233), "domain"),
    (dict(ros2_topic="radar/odom"), "absolute ROS name"),
    (dict(ros2_topic="/radar//odom"), "absolute ROS name"),
    (dict(mode="client"), "needs --connect"),
    (dict(mode="client", connect=["tcp/127.0.0.1:7447"], listen=["tcp/127.0.0.1:7448"]), "does not listen"),
])
def test_bad_options_are_refused_with_exit_code_2(options, words):
    with pytest.raises(PublishConfigError, match=words) as info:
        ZenohOptions(**options)
    assert info.value.exit_code == 2


def test_an_endpoint_protocol_zenoh_does_not_have_is_a_usage_error_naming_where(tmp_path):
    """'tcpx/...' (a typo) opened no session: a run-time failure, exit 1, naming neither the option
    nor the file."""
    port = free_endpoint().rsplit(":", 1)[1]
    for options, where in [(dict(listen=[f"tcpx/127.0.0.1:{port}"], connect=[]), f"--listen tcpx/127.0.0.1:{port}"),
                           (dict(listen=[], connect=[f"tcpx/127.0.0.1:{port}"]), f"--connect tcpx/127.0.0.1:{port}")]:
        with pytest.raises(PublishConfigError) as info:
            open_session(ZenohOptions(**options))
        assert str(info.value).startswith(f"{where}: Zenoh has no 'tcpx' protocol (") and info.value.exit_code == 2
    config = tmp_path / "zenoh.json5"
    config.write_text(f'{{mode: "peer", listen: {{endpoints: ["tcpx/127.0.0.1:{port}"]}}, '
                      '"scouting": {"multicast": {"enabled": false}}}')
    with pytest.raises(PublishConfigError) as info:
        open_session(ZenohOptions(config_file=config))
    assert str(info.value).startswith(f"zenoh config {config}: Zenoh has no 'tcpx' protocol (")


@pytest.mark.parametrize("protocol", ["tls", "quic"])
def test_a_tls_endpoint_without_certificates_says_where_they_go(protocol):
    """Zenoh's own words ("Missing TLS private key") named no fix."""
    endpoint = f"{protocol}/{free_endpoint().split('/', 1)[1]}"
    with pytest.raises(PublishError) as info:
        open_session(ZenohOptions(listen=[endpoint], connect=[]))
    assert "TLS private key" in str(info.value) and str(info.value).endswith(
        "(tls/ and quic/ endpoints need TLS certificates, given in a Zenoh config file (--zenoh-config) under "
        "transport/link/tls: listen_certificate and listen_private_key to listen, root_ca_certificate to "
        "connect; or use tcp/)"), str(info.value)


def test_the_odometry_topic_is_never_another_radarodom_topic(tmp_path):
    # Before any session or file opens: the odometry on /tf would be TF messages of another type.
    pytest.importorskip("rosbags.typesys")
    from radarodom.driver.sources import open_source
    from radarodom.pipeline.mcap_sink import McapSink

    for topic in ros2.OTHER_TOPICS:
        with pytest.raises(PublishConfigError, match="one of radarodom's other topics") as info:
            Publisher(ZenohOptions(ros2=True, ros2_topic=topic, listen=[free_endpoint()], connect=[]))
        assert info.value.exit_code == 2
    with open_source("sim://calibration?rate=max&duration=0.2") as source:
        with pytest.raises(PublishConfigError, match="/tf is one of"):
            McapSink(tmp_path / "x.mcap", source, odom_topic="/tf")
    assert not (tmp_path / "x.mcap").exists()


def test_the_odometry_topic_is_never_one_of_ros2s_own():
    """/rosout and /parameter_events carry rcl_interfaces messages that every ROS 2 tool reads."""
    for topic, kind in (("/rosout", "rcl_interfaces/msg/Log"), ("/parameter_events", "rcl_interfaces/msg/ParameterEvent")):
        with pytest.raises(PublishConfigError) as info:
            ros2.check_odometry_topic(topic)
        assert str(info.value) == f"{topic} is ROS 2's own topic ({kind}, which every ROS 2 node and tool uses): give " \
                                  "the odometry its own"
        assert info.value.exit_code == 2
    assert ros2.check_odometry_topic("/rosout2") == "/rosout2"


def test_a_client_without_its_router_fails_to_open_with_a_hint(endpoint):
    with pytest.raises(PublishError, match="router running") as info:
        Publisher(ZenohOptions(mode="client", connect=[endpoint]))
    assert info.value.exit_code == 1 and endpoint in str(info.value)


def test_a_chosen_listen_endpoint_in_use_is_an_error(endpoint):
    with peer(listen=[endpoint]):
        with pytest.raises(PublishError, match="already in use") as info:
            Publisher(ZenohOptions(listen=[endpoint]))
    assert info.value.exit_code == 1



def test_the_default_endpoint_in_use_falls_back_to_a_free_port(warnings_log, default_endpoint):
    holder = socket.socket()  # a program that is not Zenoh holds the port
    holder.bind(("127.0.0.1", int(default_endpoint.rsplit(":", 1)[1])))
    holder.listen()
    try:
        pub = Publisher()
        try:
            fallback = pub.options.listen[0]
            assert fallback != default_endpoint and fallback.startswith("tcp/127.0.0.1:")
            assert default_endpoint in pub.options.connect
            with peer(connect=[fallback]) as session:
                inbox = subscribe(session, "radar/awr1843/status")
                assert matched(pub, "status")
                pub.status({"ok": True})
                assert wait_for(lambda: inbox.samples)
        finally:
            started = time.monotonic()
            pub.close()
    finally:
        holder.close()
    # The holder accepts TCP but never answers Zenoh's handshake: closing waits for that at most
    # 2 s (HANDSHAKE_TIMEOUT_MS), not zenoh's default 10 s; the rest is slack for a loaded machine.
    assert time.monotonic() - started < 8.0
    assert any(f"{default_endpoint} is in use" in r.getMessage() and fallback in r.getMessage()
               for r in warnings_log.records)


def test_default_subscribers_find_default_publishers_even_a_second_one(default_endpoint):
    """Two publishers with default options (two radars): the second falls back to a free
    port and joins the first; a subscriber with default options hears both."""
    with Publisher() as first, Publisher(ZenohOptions(key_prefix="radar/second")) as second:
        assert first.options.effective_listen == (default_endpoint,) != second.options.effective_listen
        session, used = open_session(ZenohOptions().for_subscriber())
        try:
            assert used.connect == (default_endpoint,) and used.listen == ()
            inbox = subscribe(session, "radar/**")
            assert matched(first, "status") and matched(second, "status")
            first.status({"radar": 1})
            second.status({"radar": 2})
            assert wait_for(lambda: len(inbox.samples) == 2)
        finally:
            session.close()
    assert sorted(s[0] for s in inbox.samples) == ["radar/awr1843/status", "radar/second/status"]


def test_zenoh_is_closed_by_a_with_block_even_on_errors(endpoint):
    with pytest.raises(RuntimeError):
        with Publisher(ZenohOptions(listen=[endpoint])) as pub:
            raise RuntimeError("boom")
    assert pub.closed
    with Publisher(ZenohOptions(listen=[endpoint])):  # the port is free again
        pass


def test_keys_are_under_the_prefix():
    assert ZenohOptions().key("odom") == "radar/awr1843/odom"
    assert ZenohOptions(key_prefix="robot1/radar").key("heatmap") == "robot1/radar/heatmap"
    assert isinstance(zenoh.KeyExpr(ZenohOptions().key("status")), zenoh.KeyExpr)


@pytest.mark.parametrize("page", ["README.md", "docs/messages.md"])
def test_the_documented_subscriber_example_receives_odometry(run, page):
    """The dozen-line subscriber of the README and of docs/messages.md, pointed at this test's publisher."""
    text = (REPO / page).read_text()
    section = text[text.index("A subscriber in a dozen lines"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert DEFAULT_ENDPOINT in code and "time.sleep(60)" in code
    endpoint = free_endpoint()
    code = code.replace(DEFAULT_ENDPOINT, endpoint).replace("time.sleep(60)", "time.sleep(1.5)")
    with Publisher(ZenohOptions(listen=[endpoint])) as pub:
        proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        try:
            while proc.poll() is None:
                pub.odometry(run[5][0])
                time.sleep(0.05)
            out, err = proc.communicate(timeout=30)
        finally:
            proc.kill()
    assert proc.returncode == 0, err
    assert re.match(r"1000\.500 x -?\d+\.\d\d y -?\d+\.\d\d yaw -?\d+\.\d{3} \[\]", out), out
