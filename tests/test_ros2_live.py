"""The ROS 2 output's point clouds, TF tree, heatmaps and diagnostics (radarodom.ros2.Ros2Node
through the Publisher),
tested as the odometry is in test_publish.py: real Zenoh sessions on loopback subscribe to the
key expressions an rmw_zenoh_cpp subscription declares, and every sample is checked for its
key, type hash, attachment, liveliness token and CDR (decoded by rosbags) against what was
published.  /tf_static is transient local: a subscriber that joins later gets it, as
rmw_zenoh's does (zenoh's advanced subscriber asking the publisher's cache)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import zenoh
from frames_helpers import base_in_odom, mount_matrix, of_msg
from zenoh_helpers import Inbox, estimator_run, free_endpoint, peer, subscribe, wait_for

from radarodom import ros2
from radarodom.mount import Mount
from radarodom.publish import Publisher, ZenohOptions

typesys = pytest.importorskip("rosbags.typesys")

MOUNT = Mount(0.4, 0.1, 0.3, math.radians(-20.0))
TYPES = {"ros2": "nav_msgs/msg/Odometry", "ros2_points": "sensor_msgs/msg/PointCloud2",
         "ros2_tf": "tf2_msgs/msg/TFMessage", "ros2_tf_static": "tf2_msgs/msg/TFMessage",
         "ros2_heatmap": "sensor_msgs/msg/Image", "ros2_heatmap_axes": "std_msgs/msg/Float32MultiArray",
         "ros2_diagnostics": "diagnostic_msgs/msg/DiagnosticArray"}
TOPICS = {"ros2": "/radar/odom", "ros2_points": "/radar/points", "ros2_tf": "/tf", "ros2_tf_static": "/tf_static",
          "ros2_heatmap": "/radar/heatmap", "ros2_heatmap_axes": "/radar/heatmap/axes",
          "ros2_diagnostics": "/diagnostics"}
VOLATILE = [kind for kind in TYPES if kind != "ros2_tf_static"]


@pytest.fixture(scope="module")
def run():
    return estimator_run(frames=12)


@pytest.fixture(scope="module")
def store():
    return typesys.get_typestore(typesys.Stores.ROS2_JAZZY)


@pytest.fixture
def patient(tmp_path) -> str:
    """A Zenoh config (JSON5) whose links wait up to 0.2 s for room in a full queue before they drop
    a sample (Zenoh's default: 1 ms for a small one). What is under test here is what arrives, not
    the drop policy, and on a loaded machine the sending thread can miss 1 ms."""
    path = tmp_path / "patient.json5"
    path.write_text('{mode: "peer", scouting: {multicast: {enabled: false}}, transport: {link: {tx: {queue: '
                    '{congestion_control: {drop: {wait_before_drop: 200000}}}}}}}')
    return str(path)


def expected_key(store, kind: str, domain: int = 0) -> str:
    package, kind_, name = TYPES[kind].split("/")
    return f"{domain}/{TOPICS[kind].strip('/')}/{package}::{kind_}::dds_::{name}_/{store.hash_rihs01(TYPES[kind])}"


def test_point_clouds_and_the_tf_tree_reach_rmw_zenoh_subscribers(store, run, patient):
    endpoint = free_endpoint()
    options = ZenohOptions(listen=[endpoint], connect=(), ros2=True, config_file=patient)
    with Publisher(options, mount=MOUNT) as pub, peer(connect=[endpoint]) as session:
        assert pub.ros2_keys == {kind: expected_key(store, kind) for kind in TYPES}
        inboxes = {kind: subscribe(session, key) for kind, key in pub.ros2_keys.items() if kind != "ros2_tf_static"}
        # /tf_static as rmw_zenoh subscribes to a transient-local topic: its put may go before the
        # subscription is known, and the subscriber then fetches it from the publisher's cache.
        inboxes["ros2_tf_static"] = Inbox()
        static_sub = zenoh.ext.declare_advanced_subscriber(
            session, pub.ros2_keys["ros2_tf_static"], inboxes["ros2_tf_static"],
            history=zenoh.ext.HistoryConfig(detect_late_publishers=True))
        assert wait_for(lambda: all(pub._publishers[k].matching_status.matching for k in VOLATILE))
        for i, (state, points, heatmap) in enumerate(run):
            pub.odometry(state)
            pub.pointcloud(i, state.t, points)
            pub.heatmap(i, state.t, heatmap)
            assert wait_for(lambda: len(inboxes["ros2_heatmap_axes"].samples) == i + 1), \
                str((i, {k: len(v.samples) for k, v in inboxes.items()}))
        pub.status({"frames": len(run), "rate_hz": 10.0, "running": False, "latency_ms": {"p50": 12.5},
                    "incomplete_frames": 0})
        assert wait_for(lambda: len(inboxes["ros2_diagnostics"].samples) == len(run) + 1)
        assert wait_for(lambda: len(inboxes["ros2_tf"].samples) == len(run))
        assert wait_for(lambda: len(inboxes["ros2_tf_static"].samples) == 1, 10.0)
        time.sleep(0.2)  # a second copy would arrive by now
        static_sub.undeclare()
        tokens = sorted(str(r.ok.key_expr) for r in session.liveliness().get("@ros2_lv/0/**", timeout=1.0)
                        if r.ok is not None)
        zid = pub.zid
        counts = dict(pub.counts)
    assert counts["ros2"] == counts["ros2_points"] == counts["ros2_tf"] == counts["ros2_heatmap"] == len(run)
    assert counts["ros2_tf_static"] == 1 and counts["ros2_diagnostics"] == len(run) + 1

    # Point clouds: the radar's REP-103 frame, every point, its velocity, SNR and noise.
    for (_, _, payload, _), (state, points, _) in zip(inboxes["ros2_points"].samples, run):
        cloud = store.deserialize_cdr(payload, TYPES["ros2_points"])
        assert cloud.header.frame_id == "radar" and cloud.width == len(points) and cloud.height == 1
        assert cloud.header.stamp.sec + cloud.header.stamp.nanosec * 1e-9 == pytest.approx(state.t, abs=1e-9)
        offsets = {f.name: f.offset for f in cloud.fields}
        data = bytes(cloud.data)
        def column(name):
            return np.ndarray(len(points), "<f4", data, offsets[name], (cloud.point_step,))
        np.testing.assert_array_equal(column("x"), points["y"])
        np.testing.assert_array_equal(column("y"), -points["x"])
        np.testing.assert_array_equal(column("velocity"), points["velocity"])
        np.testing.assert_array_equal(column("snr"), points["snr_db"])
    # /tf: odom -> base_link, the base's pose through the mount, as the odometry's.
    for (_, _, payload, _), (_, _, odom_payload, _), (state, _, _) in zip(inboxes["ros2_tf"].samples,
                                                                       inboxes["ros2"].samples, run):
        (tf,) = store.deserialize_cdr(payload, TYPES["ros2_tf"]).transforms
        odom = store.deserialize_cdr(odom_payload, TYPES["ros2"])
        assert (tf.header.frame_id, tf.child_frame_id) == ("odom", "base_link") == \
            (odom.header.frame_id, odom.child_frame_id)
        expected = base_in_odom(state, MOUNT)
        np.testing.assert_allclose(of_msg(tf.transform.translation, tf.transform.rotation), expected, atol=1e-9)
        np.testing.assert_allclose(of_msg(odom.pose.pose.position, odom.pose.pose.orientation), expected, atol=1e-9)
    # The heatmap: dB, the farthest range in row 0, and its axes beside it.
    for (_, _, payload, _), (_, _, axes_payload, _), (_, _, heatmap) in zip(
            inboxes["ros2_heatmap"].samples, inboxes["ros2_heatmap_axes"].samples, run):
        image = store.deserialize_cdr(payload, TYPES["ros2_heatmap"])
        rows, cols = heatmap.intensity.shape
        assert (image.height, image.width, image.encoding, image.header.frame_id) == (rows, cols, "32FC1", "radar")
        pixels = np.frombuffer(bytes(image.data), "<f4").reshape(rows, cols)
        np.testing.assert_allclose(pixels, np.maximum(10 * np.log10(np.maximum(heatmap.intensity, 1e-300)), -300)[::-1],
                                   rtol=1e-6, atol=1e-4)
        axes = store.deserialize_cdr(axes_payload, TYPES["ros2_heatmap_axes"])
        np.testing.assert_array_equal(axes.data[:rows], np.asarray(heatmap.range_m, np.float32)[::-1])
    # /diagnostics: each state's flags, then the status message's figures.
    diagnostics = [store.deserialize_cdr(p, TYPES["ros2_diagnostics"]).status[0] for _, _, p, _ in
                   inboxes["ros2_diagnostics"].samples]
    for status, (state, _, _) in zip(diagnostics, run):
        assert status.name == "radarodom: odometry" and status.level == (0 if state.ok else 1)
        assert {kv.key: kv.value for kv in status.values}["flags"] == ",".join(str(f) for f in state.flags)
    assert diagnostics[-1].name == "radarodom: pipeline" and diagnostics[-1].message == "12 frames, 10.0 Hz, stopped"
    assert {kv.key: kv.value for kv in diagnostics[-1].values}["latency_ms.p50"] == "12.5"
    # /tf_static: base_link -> radar, once, before the first odometry.
    (static,) = inboxes["ros2_tf_static"].samples
    (mount_tf,) = store.deserialize_cdr(static[2], TYPES["ros2_tf_static"]).transforms
    assert (mount_tf.header.frame_id, mount_tf.child_frame_id) == ("base_link", "radar")
    np.testing.assert_allclose(of_msg(mount_tf.transform.translation, mount_tf.transform.rotation),
                               mount_matrix(MOUNT), atol=1e-12)

    # rmw_zenoh's attachment on every sample: sequence numbers from 1 per publisher, a gid each.
    gids = {}
    for kind, inbox in inboxes.items():
        fields = [ros2.ROS2_ATTACHMENT.unpack(attachment) for _, _, _, attachment in inbox.samples]
        assert [seq for seq, _, _, _ in fields] == list(range(1, len(fields) + 1)), kind
        assert {n for _, _, n, _ in fields} == {16} and all(abs(ns - time.time_ns()) < 60e9 for _, ns, _, _ in fields)
        (gids[kind],) = {gid for _, _, _, gid in fields}
    assert len(set(gids.values())) == len(TYPES)

    # The graph: the node and one publisher token per topic, with distinct entity ids and the
    # QoS tf2 uses (/tf_static transient local, keep last 1).
    node = f"@ros2_lv/0/{zid}/0/0/NN/%/%/radarodom"
    assert node in tokens and len(tokens) == 1 + len(TYPES)
    publishers = {}
    for token in tokens:
        parts = token.split("/")
        if parts[5] == "MP":
            assert len(parts) == 13 and parts[8] == "radarodom"
            publishers[parts[9].replace("%", "/")] = (parts[4], parts[10], parts[11], parts[12])
    assert set(publishers) == set(TOPICS.values())
    assert len({entity for entity, _, _, _ in publishers.values()}) == len(TYPES)
    for kind, topic in TOPICS.items():
        _, dds, type_hash, qos = publishers[topic]
        assert pub.ros2_keys[kind].split("/")[-2:] == [dds, type_hash]
        assert qos == (":1:,1:,:,:,," if topic == "/tf_static" else "::,10:,:,:,,")


def test_a_late_subscriber_gets_the_static_transform(store, run):
    endpoint = free_endpoint()
    with Publisher(ZenohOptions(listen=[endpoint], connect=(), ros2=True), mount=MOUNT) as pub:
        pub.odometry(run[0][0])  # /tf_static goes out with the first message, to nobody
        with peer(connect=[endpoint]) as session:
            inbox = Inbox()
            # What rmw_zenoh declares for a transient-local subscription.
            sub = zenoh.ext.declare_advanced_subscriber(
                session, pub.ros2_keys["ros2_tf_static"], inbox,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True))
            try:
                assert wait_for(lambda: len(inbox.samples) == 1, 10.0)
            finally:
                sub.undeclare()
    (_, _, payload, attachment) = inbox.samples[0]
    (mount_tf,) = store.deserialize_cdr(payload, TYPES["ros2_tf_static"]).transforms
    assert mount_tf.child_frame_id == "radar" and mount_tf.transform.translation.x == pytest.approx(MOUNT.x)
    assert ros2.ROS2_ATTACHMENT.unpack(attachment)[0] == 1


def test_radar_capture_ros2_publishes_points_and_tf_with_the_mount(store, patient):
    from test_cli_capture import run_capture_cli

    here = free_endpoint()
    keys = {kind: expected_key(store, kind) for kind in TYPES}
    with peer(listen=[here]) as session:
        inbox = subscribe(session, "0/**")  # one subscription for every topic, as test_cli_publish's
        proc = run_capture_cli("--source", "sim://corridor?duration=1", "--ros2", "--mount", "0.4,0.1,0.3,-20",
                               "--connect", here, "--listen", free_endpoint(), "--zenoh-config", patient, timeout=300)
        assert proc.returncode == 0, proc.stderr
        # The process has ended; its last samples may still be on their way through the callbacks:
        # wait (up to 10 s) until every topic has the count checked below. (A total of 10 * 6 + 1 + 11
        # was waited for before: 10 frames publish on 5 topics and the diagnostics, so it was never
        # reached and the wait always ran its 10 s.)
        wanted = {"ros2": 10, "ros2_points": 10, "ros2_tf": 10, "ros2_tf_static": 1, "ros2_heatmap": 10,
                  "ros2_heatmap_axes": 10, "ros2_diagnostics": 11}
        wait_for(lambda: all(sum(1 for s in list(inbox.samples) if s[0] == keys[kind]) >= n
                             for kind, n in wanted.items()), 10.0)
    samples = {kind: [s for s in inbox.samples if s[0] == key] for kind, key in keys.items()}
    counts = {kind: len(got) for kind, got in samples.items()}
    assert counts.pop("ros2_diagnostics") >= 11, counts  # each state's, and the status every second and at the end
    assert counts == {"ros2": 10, "ros2_points": 10, "ros2_tf": 10, "ros2_tf_static": 1, "ros2_heatmap": 10,
                      "ros2_heatmap_axes": 10}
    assert ", and to ROS 2 (domain 0) 10 on /radar/odom, 10 point clouds and 10 TF" in proc.stdout, proc.stdout
    points = [store.deserialize_cdr(p, TYPES["ros2_points"]) for _, _, p, _ in samples["ros2_points"]]
    assert {p.header.frame_id for p in points} == {"radar"} and sum(p.width for p in points) > 0
    stamps = [(t.header.stamp.sec, t.header.stamp.nanosec) for m in samples["ros2_tf"]
              for t in store.deserialize_cdr(m[2], TYPES["ros2_tf"]).transforms]
    assert stamps == sorted(stamps) and stamps[0] == (0, 0)
    (mount_tf,) = store.deserialize_cdr(samples["ros2_tf_static"][0][2], TYPES["ros2_tf"]).transforms
    assert (mount_tf.transform.translation.x, mount_tf.transform.translation.y,
            mount_tf.transform.translation.z) == (0.4, 0.1, 0.3)


@pytest.mark.parametrize("ros2_option", ["--ros2", "--mcap"])
def test_a_recording_timed_before_0_is_refused_before_any_output(tmp_path, store, ros2_option):
    """A ROS 2 stamp before 0 fits the message's int32 seconds, but a C++ subscriber's
    rclcpp::Time(stamp) throws on it: the live output published such stamps (a replay whose
    timestamps.txt starts before 0); then it was refused at the first frame, mid-run (exit 1),
    the --odom-out and --points-out written so far left behind.  Now before anything opens,
    naming the file the times come from."""
    from conftest import SMALL_CFG, make_capture
    from test_cli_capture import run_capture_cli

    from radarodom.cfg import RadarConfig

    rec = tmp_path / "rec"
    make_capture(rec, RadarConfig.from_text(SMALL_CFG, "small.cfg"), 3, t0=-5.0)
    here = free_endpoint()
    outputs = ["--odom-out", str(tmp_path / "o.tum"), "--points-out", str(tmp_path / "p.csv")]
    ros2 = ["--ros2", "--connect", here, "--listen", free_endpoint()] if ros2_option == "--ros2" else [
        "--mcap", str(tmp_path / "b.mcap"), "--no-publish"]
    with peer(listen=[here]) as session:
        inbox = subscribe(session, "0/**")
        proc = run_capture_cli("--source", f"replay://{rec}?rate=max", *ros2, *outputs, timeout=300)
        time.sleep(0.5)  # what was published would be on its way
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.strip().splitlines() == [
        f"radar-capture: error: {rec / 'timestamps.txt'}: the frames' times run from -5.000 s to -4.900 s, and a ROS 2 "
        "stamp holds 0 to 2147483647 s (a node's time is never negative; its seconds are 32-bit): shift the times "
        f"into that range, or leave out {ros2_option}"], proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec"]
    odom = expected_key(store, "ros2")
    assert not [s for s in inbox.samples if s[0] == odom]


def test_the_shipped_rviz_config_shows_the_published_topics_in_odom():
    yaml = pytest.importorskip("ruamel.yaml")
    from conftest import REPO

    from radarodom.publish import DEFAULT_ROS2_TOPIC

    config = yaml.YAML(typ="safe").load((REPO / "configs" / "radarodom.rviz").read_text())
    manager = config["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "odom"
    displays = {d["Class"]: d for d in manager["Displays"]}
    assert set(displays) >= {"rviz_default_plugins/TF", "rviz_default_plugins/PointCloud2",
                             "rviz_default_plugins/Odometry", "rviz_default_plugins/Image"}
    topics = {cls.rsplit("/", 1)[1]: d["Topic"]["Value"] for cls, d in displays.items() if "Topic" in d}
    assert topics == {"PointCloud2": ros2.POINTS_TOPIC, "Odometry": DEFAULT_ROS2_TOPIC, "Image": ros2.HEATMAP_TOPIC}
    cloud = displays["rviz_default_plugins/PointCloud2"]
    assert cloud["Channel Name"] == "velocity"  # a field the point cloud has
    assert all(d["Topic"]["Reliability Policy"] == "Reliable" for d in displays.values() if "Topic" in d)
