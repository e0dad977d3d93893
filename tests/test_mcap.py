"""The ROS 2 bag radar-capture --mcap writes (pipeline/mcap_sink.py, ros2_bag.py), read back
by libraries other than the writer's: mcap's record-level reader checks the container as
``mcap doctor`` does (CRCs, chunk and message indexes, statistics, schemas), mcap-ros2-support
decodes every message with its own CDR reader from the file's ros2msg schemas, back to the
values the pipeline gave its sinks, and rosbags reads the file with its own MCAP parser.

The expected poses are worked out with 4x4 matrices (frames_helpers.py), not with radarodom's
quaternions."""

from __future__ import annotations

import math
import os
import shutil
import struct
import subprocess
import sys
from collections import Counter, defaultdict

import numpy as np
import pytest

pytest.importorskip("rosbags.typesys")
mcap_reader = pytest.importorskip("mcap.reader")
mcap_ros2_decoder = pytest.importorskip("mcap_ros2.decoder")
zstandard = pytest.importorskip("zstandard")
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, MessageIndex, Schema, Statistics  # noqa: E402
from mcap.stream_reader import StreamReader, breakup_chunk  # noqa: E402

from frames_helpers import base_in_odom, matrix, mount_matrix, of_msg, planar, seconds  # noqa: E402

from radarodom import messages  # noqa: E402
from radarodom import ros2_messages  # noqa: E402
from radarodom.driver.sources import open_source  # noqa: E402
from radarodom.errors import CaptureExistsError, MessageError  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.mount import Mount  # noqa: E402
from radarodom.pipeline import Pipeline  # noqa: E402
from radarodom.pipeline.mcap_sink import McapSink  # noqa: E402
from radarodom.pipeline import OdometryJsonSink  # noqa: E402  (the name library.md gives)
from radarodom.pipeline.sinks import Sink  # noqa: E402
from radarodom.ros2_bag import BagWriter  # noqa: E402
from radarodom.tools.odometry_log import read_odometry_log  # noqa: E402

MOUNT = Mount(0.35, -0.12, 0.25, math.radians(12.0))
TOPICS = {"/radar/odom": "nav_msgs/msg/Odometry", "/tf": "tf2_msgs/msg/TFMessage",
          "/tf_static": "tf2_msgs/msg/TFMessage", "/radar/points": "sensor_msgs/msg/PointCloud2",
          "/radar/heatmap": "sensor_msgs/msg/Image", "/radar/heatmap/axes": "std_msgs/msg/Float32MultiArray",
          "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray", "/radar/groundtruth": "geometry_msgs/msg/PoseStamped"}


class Kept(Sink):
    """Every FrameResult the pipeline gave its sinks: what the bag must hold."""

    wants_heatmaps = True

    def __init__(self) -> None:
        self.results = []

    def write(self, result, stats) -> None:
        self.results.append(result)


def record(directory, mount: Mount, seconds: float = 1.5):
    kept = Kept()
    path = directory / "run.mcap"
    # Fast fidelity: every check here compares the bag with the results the same run gave its
    # sinks, whatever the simulator's fidelity.
    with open_source(f"sim://corridor?rate=max&fidelity=fast&duration={seconds}") as source:
        sinks = [kept, McapSink(path, source, mount=mount), OdometryJsonSink(directory / "odom.jsonl")]
        stats = Pipeline(source, estimator=EstimatorConfig(), sinks=sinks).run()
    return path, kept.results, stats


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    return record(tmp_path_factory.mktemp("mcap"), MOUNT)


def decoded(path):
    """[(topic, log_time ns, decoded message)] in file order, by mcap-ros2-support."""
    with open(path, "rb") as fh:
        reader = mcap_reader.make_reader(fh, validate_crcs=True, decoder_factories=[mcap_ros2_decoder.DecoderFactory()])
        return [(channel.topic, message.log_time, msg) for _, channel, message, msg in reader.iter_decoded_messages()]


def by_topic(path):
    out = defaultdict(list)
    for topic, log_time, msg in decoded(path):
        out[topic].append((log_time, msg))
    return out


# ============================================================================ the container
def test_the_file_passes_the_checks_mcap_doctor_makes(bag):
    path, results, _ = bag
    with open(path, "rb") as fh:
        records = list(StreamReader(fh, emit_chunks=True, validate_crcs=True).records)  # chunk and data CRCs
    header = records[0]
    assert isinstance(header, Header) and header.profile == "ros2" and header.library.startswith("radarodom")
    assert isinstance(records[-1], Footer)
    data_end = next(i for i, r in enumerate(records) if isinstance(r, DataEnd))
    assert records[data_end].data_section_crc != 0  # a data-section CRC was written, and StreamReader checked it
    chunks = [r for r in records[:data_end] if isinstance(r, Chunk)]
    assert len(chunks) >= 1 and all(c.compression == "zstd" for c in chunks)
    # Every message index follows its chunk and points at its channel's messages inside it, exactly.
    counts, times, schemas, channels = Counter(), [], {}, {}
    i = 0
    while i < data_end:
        chunk = records[i]
        i += 1
        if not isinstance(chunk, Chunk):
            continue
        inner = breakup_chunk(chunk, validate_crc=True)
        raw = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        assert len(raw) == chunk.uncompressed_size
        messages_in = [r for r in inner if type(r).__name__ == "Message"]
        schemas.update({r.id: r for r in inner if isinstance(r, Schema)})
        channels.update({r.id: r for r in inner if isinstance(r, Channel)})
        per_channel = Counter(m.channel_id for m in messages_in)
        indexed = Counter()
        while i < data_end and isinstance(records[i], MessageIndex):
            index = records[i]
            i += 1
            for log_time, offset in index.records:
                opcode, _, channel_id, _, record_time = struct.unpack_from("<BQHIQ", raw, offset)
                assert (opcode, channel_id, record_time) == (0x05, index.channel_id, log_time)
            indexed[index.channel_id] = len(index.records)
        assert indexed == per_channel
        for m in messages_in:
            assert chunk.message_start_time <= m.log_time <= chunk.message_end_time
            counts[m.channel_id] += 1
            times.append(m.log_time)
    with open(path, "rb") as fh:
        summary = mcap_reader.make_reader(fh, validate_crcs=True).get_summary()
    stats: Statistics = summary.statistics
    assert stats.message_count == sum(counts.values()) and dict(stats.channel_message_counts) == dict(counts)
    assert (stats.message_start_time, stats.message_end_time) == (min(times), max(times))
    assert stats.chunk_count == len(chunks) == len(summary.chunk_indexes)
    assert [(c.message_start_time, c.message_end_time) for c in chunks] == \
        [(ix.message_start_time, ix.message_end_time) for ix in summary.chunk_indexes]
    assert stats.schema_count == len(schemas) == len(summary.schemas) == len(set(TOPICS.values()))
    assert stats.channel_count == len(channels) == len(summary.channels) == len(TOPICS)
    for channel in summary.channels.values():
        assert channel.message_encoding == "cdr" and channel.schema_id in summary.schemas
        assert summary.schemas[channel.schema_id].encoding == "ros2msg"
        assert summary.schemas[channel.schema_id].name == TOPICS[channel.topic]
    assert stats.message_start_time == round(results[0].frame.timestamp * 1e9)


def test_rosbags_reads_the_file_with_its_own_parser(bag):
    from rosbags.interfaces import QosDurability
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    path, results, _ = bag
    store = get_typestore(Stores.ROS2_JAZZY)
    mcap_topics = Counter(topic for topic, _, _ in decoded(path))
    with Reader(path) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == TOPICS
        assert {c.topic: c.msgcount for c in reader.connections} == dict(mcap_topics)
        qos = {c.topic: c.ext.offered_qos_profiles[0] for c in reader.connections}
        odometry = []
        for connection, timestamp, data in reader.messages():
            msg = store.deserialize_cdr(data, connection.msgtype)  # every message
            if connection.topic == "/radar/odom":
                odometry.append((timestamp, msg))
    assert qos["/tf_static"].durability == QosDurability.TRANSIENT_LOCAL and qos["/tf_static"].depth == 1
    assert qos["/radar/odom"].durability == QosDurability.VOLATILE
    states = [r.state for r in results if r.state is not None]
    assert [t for t, _ in odometry] == [round(s.t * 1e9) for s in states]
    mine = [m for _, m in by_topic(path)["/radar/odom"]]
    for (_, theirs), other in zip(odometry, mine):  # two decoders, one answer
        assert theirs.pose.pose.position.x == other.pose.pose.position.x
        np.testing.assert_array_equal(theirs.pose.covariance, np.asarray(other.pose.covariance))


# ============================================================================ every message, every value
def test_every_topic_has_one_message_per_result_at_the_frames_times(bag):
    path, results, _ = bag
    topics = by_topic(path)
    states = [r for r in results if r.state is not None]
    assert len(states) == len(results) >= 10  # the simulator gives every frame both streams
    frame_times = [round(r.frame.timestamp * 1e9) for r in results]
    for topic in ("/radar/odom", "/tf", "/radar/points", "/radar/heatmap", "/radar/heatmap/axes",
                  "/radar/groundtruth"):
        assert [t for t, _ in topics[topic]] == frame_times, topic
    assert [t for t, _ in topics["/tf_static"]] == frame_times[:1]
    # The odometry's status with every state, and the pipeline's every second and at the end.
    names = [(t, s.name) for t, m in topics["/diagnostics"] for s in m.status]
    assert [t for t, n in names if n == "radarodom: odometry"] == frame_times
    pipeline = [t for t, n in names if n == "radarodom: pipeline"]
    assert pipeline[-1] == frame_times[-1] and len(pipeline) >= 2
    stamps = {topic: [seconds(m.header.stamp) for _, m in msgs] for topic, msgs in topics.items()
              if topic not in ("/radar/heatmap/axes", "/tf", "/tf_static")}
    for topic, values in stamps.items():
        expected = [r.frame.timestamp for r in results][:len(values)] if topic != "/diagnostics" else values
        np.testing.assert_allclose(values, expected, atol=1e-9, err_msg=topic)


def test_odometry_and_tf_are_the_base_in_odom_through_the_mount(bag):
    path, results, _ = bag
    topics = by_topic(path)
    (_, static), = topics["/tf_static"]
    (mount_tf,) = static.transforms
    assert (mount_tf.header.frame_id, mount_tf.child_frame_id) == ("base_link", "radar")
    np.testing.assert_allclose(of_msg(mount_tf.transform.translation, mount_tf.transform.rotation),
                               mount_matrix(MOUNT), atol=1e-12)
    for result, (_, odom), (_, tf) in zip(results, topics["/radar/odom"], topics["/tf"]):
        state = result.state
        assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
        (transform,) = tf.transforms
        assert (transform.header.frame_id, transform.child_frame_id) == ("odom", "base_link")
        expected = base_in_odom(state, MOUNT)
        np.testing.assert_allclose(of_msg(odom.pose.pose.position, odom.pose.pose.orientation), expected, atol=1e-9)
        np.testing.assert_allclose(of_msg(transform.transform.translation, transform.transform.rotation), expected,
                                   atol=1e-9)
        # The radar's pose in odom is where the estimator says it went: odom->base->radar = M R.
        np.testing.assert_allclose(expected @ mount_matrix(MOUNT), mount_matrix(MOUNT) @ planar(state.x, state.y,
                                                                                                 state.yaw), atol=1e-9)
        # The base's twist: the radar's velocity seen in base_link, less the lever arm's part.
        w = state.yaw_rate
        radar_velocity = mount_matrix(MOUNT)[:2, :2] @ [state.vx, state.vy]
        lever = np.array([-w * MOUNT.y, w * MOUNT.x])
        twist = odom.twist.twist
        np.testing.assert_allclose([twist.linear.x, twist.linear.y], radar_velocity - lever, atol=1e-9)
        assert twist.angular.z == pytest.approx(w) and twist.linear.z == 0.0


def test_covariances_are_carried_through_the_mount(bag):
    path, results, _ = bag
    for result, (_, odom) in zip(results, by_topic(path)["/radar/odom"]):
        state = result.state
        pose_cov = np.asarray(odom.pose.covariance).reshape(6, 6)
        twist_cov = np.asarray(odom.twist.covariance).reshape(6, 6)
        assert pose_cov[2, 2] == pose_cov[3, 3] == pose_cov[4, 4] == 1e6
        # The Jacobian of (x, y, yaw) -> the base's planar pose, by finite differences here.
        def base(v):
            m = base_in_odom(type("S", (), {"x": v[0], "y": v[1], "yaw": v[2]}), MOUNT)
            return np.array([m[0, 3], m[1, 3], math.atan2(m[1, 0], m[0, 0])])
        x0, eps = np.array([state.x, state.y, state.yaw]), 1e-6
        jacobian = np.column_stack([(base(x0 + eps * e) - base(x0 - eps * e)) / (2 * eps) for e in np.eye(3)])
        planar_cov = pose_cov[np.ix_([0, 1, 5], [0, 1, 5])]
        np.testing.assert_allclose(planar_cov, jacobian @ state.pose_covariance @ jacobian.T, atol=1e-9)
        rot = mount_matrix(MOUNT)[:2, :2]
        j_twist = np.eye(3)
        j_twist[:2, :2], j_twist[:2, 2] = rot, [MOUNT.y, -MOUNT.x]
        np.testing.assert_allclose(twist_cov[np.ix_([0, 1, 5], [0, 1, 5])],
                                   j_twist @ state.twist_covariance @ j_twist.T, atol=1e-12)


def test_point_clouds_hold_every_point_in_the_radars_rep103_frame(bag):
    path, results, _ = bag
    total = 0
    for result, (_, cloud) in zip(results, by_topic(path)["/radar/points"]):
        points = result.points
        assert cloud.header.frame_id == "radar" and (cloud.height, cloud.width) == (1, len(points))
        assert not cloud.is_bigendian and cloud.row_step == cloud.point_step * cloud.width
        fields = {f.name: f for f in cloud.fields}
        assert list(fields) == ["x", "y", "z", "velocity", "snr", "noise"]
        assert {(f.datatype, f.count) for f in cloud.fields} == {(7, 1)}  # FLOAT32
        data = bytes(cloud.data)
        def column(name):
            return np.ndarray(len(points), "<f4", data, fields[name].offset, (cloud.point_step,))
        np.testing.assert_array_equal(column("x"), points["y"])  # ahead: the TI boresight
        np.testing.assert_array_equal(column("y"), -points["x"])  # left: TI's x is right
        np.testing.assert_array_equal(column("z"), points["z"])
        np.testing.assert_array_equal(column("velocity"), points["velocity"])
        np.testing.assert_array_equal(column("snr"), points["snr_db"])
        np.testing.assert_array_equal(column("noise"), points["noise_db"])
        total += len(points)
    assert total > 0


def test_heatmaps_are_images_in_db_with_their_axes(bag):
    path, results, _ = bag
    topics = by_topic(path)
    for result, (_, image), (_, axes) in zip(results, topics["/radar/heatmap"], topics["/radar/heatmap/axes"]):
        hm = result.heatmap
        rows, cols = hm.intensity.shape
        assert (image.height, image.width, image.encoding, image.step) == (rows, cols, "32FC1", 4 * cols)
        assert image.header.frame_id == "radar" and not image.is_bigendian
        pixels = np.frombuffer(bytes(image.data), "<f4").reshape(rows, cols)
        # Row 0 the farthest range, column 0 the leftmost bearing (most negative TI azimuth).
        expected = 10 * np.log10(np.maximum(hm.intensity.astype(np.float64), 1e-300))[::-1]
        np.testing.assert_allclose(pixels, np.maximum(expected, -300.0), rtol=1e-6, atol=1e-4)
        dims = [(d.label, d.size) for d in axes.layout.dim]
        assert dims == [("range_m", rows), ("bearing_rad", cols)]
        values = np.asarray(axes.data, np.float32)
        np.testing.assert_array_equal(values[:rows], hm.range_m.astype(np.float32)[::-1])
        np.testing.assert_array_equal(values[rows:], -hm.azimuth_rad.astype(np.float32))


def test_diagnostics_carry_the_flags_and_the_pipeline_status(bag):
    path, results, stats = bag
    topics = by_topic(path)
    odometry = [s for _, m in topics["/diagnostics"] for s in m.status if s.name == "radarodom: odometry"]
    for result, status in zip(results, odometry):
        state = result.state
        values = {kv.key: kv.value for kv in status.values}
        flags = [str(f) for f in state.flags]
        assert values["flags"] == ",".join(flags) and values["frame"] == str(state.frame)
        assert status.level == (0 if state.ok else 1) and status.message == (", ".join(flags) or "ok")
    last = [s for _, m in topics["/diagnostics"] for s in m.status if s.name == "radarodom: pipeline"][-1]
    values = {kv.key: kv.value for kv in last.values}
    assert values["running"] == "false" and values["frames"] == str(stats.frames)
    assert "latency_ms.p50" in values and values["incomplete_frames"] == "0"


def test_ground_truth_is_the_bases_true_pose_from_the_first_frame(bag):
    path, results, _ = bag
    truth = by_topic(path)["/radar/groundtruth"]
    first = matrix(*results[0].frame.pose[:3], results[0].frame.pose[3:])
    m = mount_matrix(MOUNT)
    for result, (_, msg) in zip(results, truth):
        radar = matrix(*result.frame.pose[:3], result.frame.pose[3:])
        expected = m @ np.linalg.inv(first) @ radar @ np.linalg.inv(m)
        assert msg.header.frame_id == "odom"
        np.testing.assert_allclose(of_msg(msg.pose.position, msg.pose.orientation), expected, atol=1e-9)


def test_without_a_mount_the_odometry_is_the_estimators_own(tmp_path):
    path, results, _ = record(tmp_path, Mount(), seconds=0.5)
    topics = by_topic(path)
    (_, static), = topics["/tf_static"]
    t = static.transforms[0].transform
    assert (t.translation.x, t.translation.y, t.translation.z, t.rotation.w) == (0.0, 0.0, 0.0, 1.0)
    for result, (_, odom) in zip(results, topics["/radar/odom"]):
        s = result.state
        assert (odom.pose.pose.position.x, odom.pose.pose.position.y) == (s.x, s.y)
        assert (odom.twist.twist.linear.x, odom.twist.twist.linear.y) == (s.vx, s.vy)
        cov = np.asarray(odom.pose.covariance).reshape(6, 6)
        np.testing.assert_array_equal(cov[np.ix_([0, 1, 5], [0, 1, 5])], s.pose_covariance)


# ============================================================================ the JSON-lines sink
def test_the_odometry_json_lines_are_the_published_messages_and_radar_eval_reads_them(bag):
    path, results, _ = bag
    lines = (path.parent / "odom.jsonl").read_bytes().splitlines()
    states = [r.state for r in results if r.state is not None]
    assert lines == [messages.odometry_json(s) for s in states]
    assert [messages.parse_odometry(line)["frame"] for line in lines] == [s.frame for s in states]
    timeline = read_odometry_log(path.parent / "odom.jsonl")
    assert len(timeline) == len(states)
    assert list(timeline.flags) == [tuple(str(f) for f in s.flags) for s in states]


# ============================================================================ refusals
def test_an_existing_file_is_never_overwritten(tmp_path):
    from rosbags.typesys import Stores, get_typestore

    path = tmp_path / "run.mcap"
    path.write_bytes(b"mine")
    with pytest.raises(CaptureExistsError, match="already exists"):
        BagWriter(path, get_typestore(Stores.ROS2_JAZZY))
    with pytest.raises(CaptureExistsError, match="already exists"):
        OdometryJsonSink(path)
    assert path.read_bytes() == b"mine"


def test_a_time_a_bag_cannot_hold_is_refused_with_the_topic(tmp_path):
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    writer = BagWriter(tmp_path / "run.mcap", store)
    writer.topic("/x", "std_msgs/msg/Float32MultiArray")
    msg = store.types["std_msgs/msg/Float32MultiArray"](
        layout=store.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0), data=np.zeros(1, np.float32))
    with pytest.raises(MessageError, match="/x: time -1.0 s"):
        writer.write("/x", msg, -1.0)
    # Past 2038 a ROS 2 stamp's 32-bit seconds overflow: it was rosbags' "'i' format requires ...".
    with pytest.raises(MessageError, match=r"/x: time 3000000000.0 s is outside what a bag holds \(0 to 2147483647 s"):
        writer.write("/x", msg, 3e9)
    with pytest.raises(MessageError, match="its seconds are a 32-bit integer"):
        ros2_messages.stamp(2.0**31)
    assert ros2_messages.stamp(2.0**31 - 0.5) == (2**31 - 1, 500_000_000)
    writer.write("/x", msg, 1.0)
    writer.close()
    writer.close()
    assert Counter(t for t, _, _ in decoded(tmp_path / "run.mcap")) == {"/x": 1}


# ============================================================================ other tools open it
def test_rerun_checks_the_file_and_turns_its_topics_into_points_transforms_and_images(bag, tmp_path):
    """Rerun's own MCAP importer (its CLI, shipped in rerun-sdk's wheel), analytics off."""
    rerun = shutil.which("rerun", path=os.pathsep.join([os.path.dirname(sys.executable), os.environ["PATH"]]))
    if rerun is None:
        pytest.skip("no rerun command (pip install rerun-sdk)")
    env = {**os.environ, "XDG_CONFIG_HOME": str(tmp_path), "RERUN_ANALYTICS": "0"}

    def run(*args):
        proc = subprocess.run([rerun, *map(str, args)], env=env, capture_output=True, text=True, timeout=300,
                              stdin=subprocess.DEVNULL)
        assert proc.returncode == 0, proc.stderr
        return proc.stdout
    run("analytics", "disable")
    path, results, _ = bag
    check = run("mcap", "check", path)
    rows = [line.split() for line in check.splitlines() if line.split()[:1] in (["ok"], ["PROBLEM"])]
    assert sorted(row[3] for row in rows) == sorted(TOPICS) and {row[0] for row in rows} == {"ok"}
    run("mcap", "convert", path, "-o", tmp_path / "run.rrd")
    run("rrd", "verify", tmp_path / "run.rrd")
    printed = run("rrd", "print", tmp_path / "run.rrd")
    rows_by = Counter()
    for line in printed.splitlines():
        if " - /" in line and "data columns:" in line:
            count = int(line.split(" with ")[1].split()[0])
            entity, columns = line.split(" - ")[1], line.split("data columns: ")[1]
            for archetype in ("Points3D:positions", "Transform3D:translation", "DepthImage:buffer",
                              "InstancePoses3D:translations"):
                if archetype in columns:
                    rows_by[(entity, archetype.split(":")[0])] += count
    n = len(results)
    assert rows_by == {("/radar/points", "Points3D"): n, ("/tf", "Transform3D"): n, ("/tf_static", "Transform3D"): 1,
                       ("/radar/heatmap", "DepthImage"): n, ("/radar/groundtruth", "InstancePoses3D"): n}
