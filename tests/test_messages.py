"""The wire schemas (radarodom.messages): round trips of every format, the byte
layouts read back as the module docstring documents them (with struct, as a user
without radarodom would), and refusal of bad messages and unencodable values."""

from __future__ import annotations

import json
import math
import struct
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from radarodom import messages, ros2
from radarodom.dsp.heatmap import RangeAzimuth
from radarodom.dsp.processor import POINT_DTYPE
from radarodom.errors import MessageError, RadarodomError
from radarodom.estimator.odometry import OdometryState
from radarodom.tools import radar_echo

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
FLAGS = st.lists(st.sampled_from(["first_frame", "velocity_failed", "velocity_held", "icp_failed", "yaw_held"]),
                 max_size=3, unique=True).map(tuple)


def state(**kw) -> OdometryState:
    base = dict(t=1000.25, frame=7, x=1.5, y=-0.25, yaw=0.3, vx=0.8, vy=0.01, yaw_rate=0.1,
                pose_covariance=np.diag([1e-3, 2e-3, 3e-4]), twist_covariance=np.diag([4e-3, 5e-3, 6e-3]),
                flags=("velocity_held",), features=180, compute_s=0.0041)
    base.update(kw)
    return OdometryState(**base)


def heatmap(n_range=5, n_az=4, seed=0) -> RangeAzimuth:
    rng = np.random.default_rng(seed)
    doppler = rng.normal(size=(n_range, n_az)).astype(np.float32)
    doppler[0, 0] = np.nan  # "not computed" cells travel as NaN
    return RangeAzimuth(rng.random((n_range, n_az), np.float32), rng.random((n_range, n_az), np.float32),
                        doppler, 0.05 * np.arange(n_range), np.linspace(-1.0, 1.0, n_az))


def points(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = np.zeros(n, POINT_DTYPE)
    for name in messages.POINTCLOUD_RECORD.names:
        out[name] = rng.normal(size=n)
    out["range_bin"] = rng.integers(0, 256, n)
    return out


# =========================================================================== odometry
@given(t=finite, frame=st.integers(0, 2**53), xyz=st.lists(finite, min_size=6, max_size=6),
       cov=st.lists(finite, min_size=18, max_size=18), flags=FLAGS, features=st.integers(0, 10_000),
       compute_s=st.floats(0.0, 10.0))
def test_odometry_round_trip(t, frame, xyz, cov, flags, features, compute_s):
    s = OdometryState(t=t, frame=frame, x=xyz[0], y=xyz[1], yaw=xyz[2], vx=xyz[3], vy=xyz[4], yaw_rate=xyz[5],
                      pose_covariance=np.reshape(cov[:9], (3, 3)), twist_covariance=np.reshape(cov[9:], (3, 3)),
                      flags=flags, features=features, compute_s=compute_s)
    m = messages.parse_odometry(messages.odometry_json(s))
    assert m["schema"] == "radarodom/odom" and m["version"] == 1
    assert (m["t"], m["frame"], m["x"], m["y"], m["yaw"], m["vx"], m["vy"], m["yaw_rate"]) == (t, frame, *xyz)
    assert m["pose_covariance"] == cov[:9] and m["twist_covariance"] == cov[9:]  # row-major, exact
    assert m["flags"] == list(flags) and m["ok"] == s.ok and m["features"] == features
    assert m["compute_ms"] == pytest.approx(1e3 * compute_s)
    assert (m["frame_id"], m["child_frame_id"]) == ("odom", "base_radar")


def test_odometry_json_is_plain_utf8_json_with_the_documented_keys():
    payload = messages.odometry_json(state())
    obj = json.loads(payload.decode("utf-8"))
    assert list(obj) == ["schema", "version", "t", "frame", "x", "y", "yaw", "vx", "vy", "yaw_rate",
                         "pose_covariance", "twist_covariance", "flags", "ok", "features", "compute_ms",
                         "frame_id", "child_frame_id"]
    assert obj["ok"] is False and obj["flags"] == ["velocity_held"]
    assert obj["pose_covariance"][4] == 2e-3


@pytest.mark.parametrize("bad", [dict(x=math.nan), dict(yaw=math.inf), dict(t=-math.inf),
                                 dict(pose_covariance=np.full((3, 3), np.nan)),
                                 dict(twist_covariance=np.eye(2))])
def test_odometry_refuses_what_it_cannot_encode(bad):
    with pytest.raises(MessageError):
        messages.odometry_json(state(**bad))


def _odom_obj(**changes) -> bytes:
    obj = json.loads(messages.odometry_json(state()))
    obj.update(changes)
    return json.dumps(obj).encode()


@pytest.mark.parametrize("payload, words", [
    (b"\xff\xfe", "not UTF-8"),
    (b"{not json", "not JSON"),
    (b"[1, 2]", "not an object"),
    (_odom_obj(schema="radarodom/status"), "schema 'radarodom/status'"),
    (_odom_obj(version=2), "version 2 is newer"),
    (_odom_obj(version="1"), "bad version"),
    (_odom_obj(version=True), "bad version"),
    (_odom_obj(frame=-1), "'frame'"),
    (_odom_obj(frame=1.5), "'frame'"),
    (_odom_obj(x="1.0"), "'x'"),
    (_odom_obj(ok="yes"), "'ok'"),
    (_odom_obj(yaw=True), "'yaw' must be a finite number, got true$"),  # the message's own word
    (_odom_obj(t=None), "'t' must be a finite number, got null$"),
    (_odom_obj(pose_covariance=[0.0] * 8), "'pose_covariance'"),
    (_odom_obj(flags=[1]), "'flags'"),
    (messages.odometry_json(state()).replace(b'"x":1.5', b'"x":1e400'), "1e400 is out of range"),
    (_odom_obj(x=10**400), "'x' must be a finite number"),  # an integer beyond every float
    (_odom_obj(frame=2**64), "'frame'"),
    (_odom_obj(t=None), "'t'"),
    (messages.odometry_json(state()).replace(b'"x":1.5', b'"x":NaN'), "NaN"),
])
def test_parse_odometry_refuses_bad_messages(payload, words):
    with pytest.raises(MessageError, match=words.replace("(", r"\(")):
        messages.parse_odometry(payload)


def test_parse_odometry_names_a_missing_field_and_ignores_unknown_ones():
    obj = json.loads(messages.odometry_json(state()))
    del obj["yaw_rate"]
    with pytest.raises(MessageError, match="'yaw_rate' is missing"):
        messages.parse_odometry(json.dumps(obj).encode())
    assert messages.parse_odometry(_odom_obj(extra={"added": "later"}))["extra"] == {"added": "later"}


def test_message_errors_are_radarodom_errors():
    assert issubclass(MessageError, RadarodomError)


# =========================================================================== status
def test_status_round_trip_and_refusals():
    info = {"rate_hz": 10.0, "dropped": 0, "latency_ms": {"p50": 3.2, "p99": 9.9}, "radar": "streaming"}
    m = messages.parse_status(messages.status_json(info))
    assert m == {"schema": "radarodom/status", "version": 1, **info}
    with pytest.raises(MessageError, match="non-finite"):
        messages.status_json({"latency_ms": math.nan})
    with pytest.raises(MessageError, match="version"):
        messages.status_json({"version": 3})
    with pytest.raises(MessageError, match="not a radarodom/status message"):
        messages.parse_status(messages.odometry_json(state()))
    with pytest.raises(MessageError):
        messages.status_json({"when": object()})


# =========================================================================== point cloud
@given(n=st.integers(0, 50), seed=st.integers(0, 2**32 - 1), frame=st.integers(0, 2**64 - 1), t=finite)
def test_pointcloud_round_trip(n, seed, frame, t):
    pts = points(n, seed)
    header, decoded = messages.decode_pointcloud(messages.encode_pointcloud(frame, t, pts))
    assert header == {"schema": "radarodom/pointcloud", "version": 1, "frame": frame, "t": t, "count": n}
    assert decoded.dtype == messages.POINTCLOUD_RECORD and decoded.flags.writeable
    for name in messages.POINTCLOUD_RECORD.names:
        np.testing.assert_array_equal(decoded[name], pts[name])


def test_pointcloud_layout_is_the_documented_one():
    pts = points(3)
    payload = messages.encode_pointcloud(42, 1000.5, pts)
    magic, version, header_bytes, frame, t, count, record_bytes, fields = struct.unpack_from("<4sHHQdIHH", payload)
    assert (magic, version, header_bytes, frame, t, count, record_bytes, fields) == \
        (b"RPC1", 1, 32, 42, 1000.5, 3, 36, 9)
    assert len(payload) == 32 + 3 * 36
    second = struct.unpack_from("<9f", payload, 32 + 36)
    assert second == tuple(np.float32(pts[1][f]) for f in
                           ("x", "y", "z", "range", "azimuth", "elevation", "velocity", "snr_db", "noise_db"))
    assert messages.POINTCLOUD_ENCODING == "application/octet-stream;radarodom/pointcloud/v1"


def _patched(payload: bytes, offset: int, fmt: str, value) -> bytes:
    out = bytearray(payload)
    struct.pack_into(fmt, out, offset, value)
    return bytes(out)


@pytest.mark.parametrize("change, words", [
    (lambda p: p[:20], "shorter than its 32-byte header"),
    (lambda p: p[:-1], "header says 2 points"),
    (lambda p: p + b"\0", "header says 2 points"),
    (lambda p: b"XPC1" + p[4:], "magic"),
    (lambda p: _patched(p, 4, "<H", 2), "version 2 is newer"),
    (lambda p: _patched(p, 6, "<H", 40), "header of 40 bytes"),
    (lambda p: _patched(p, 28, "<H", 40), "records of 40 bytes"),
    (lambda p: messages.encode_heatmap(1, 1.0, heatmap()), "magic"),
])
def test_decode_pointcloud_refuses_bad_messages(change, words):
    with pytest.raises(MessageError, match=words):
        messages.decode_pointcloud(change(messages.encode_pointcloud(1, 1.0, points(2))))


def test_encode_pointcloud_refusals():
    with pytest.raises(MessageError, match="lack field"):
        messages.encode_pointcloud(0, 0.0, np.zeros(2, [("x", "f4")]))
    with pytest.raises(MessageError, match="frame"):
        messages.encode_pointcloud(-1, 0.0, points(1))
    with pytest.raises(MessageError, match="t must be a finite number"):
        messages.encode_pointcloud(0, math.nan, points(1))


# =========================================================================== heatmap
@given(n_range=st.integers(1, 40), n_az=st.integers(1, 16), seed=st.integers(0, 1000),
       frame=st.integers(0, 2**40), t=finite)
def test_heatmap_round_trip(n_range, n_az, seed, frame, t):
    hm = heatmap(n_range, n_az, seed)
    header, arrays = messages.decode_heatmap(messages.encode_heatmap(frame, t, hm))
    assert header == {"schema": "radarodom/heatmap", "version": 1, "frame": frame, "t": t, "n_range": n_range,
                      "n_azimuth": n_az, "channels": ["intensity", "static", "doppler_mps"]}
    back = RangeAzimuth(**arrays)  # the arrays are RangeAzimuth's fields
    for name in ("intensity", "static", "doppler_mps", "range_m", "azimuth_rad"):
        expected = np.asarray(getattr(hm, name), np.float32)
        np.testing.assert_array_equal(getattr(back, name), expected)  # NaN == NaN here
        assert getattr(back, name).dtype == np.float32


def test_heatmap_layout_is_the_documented_one():
    hm = heatmap(5, 4)
    payload = messages.encode_heatmap(9, 12.5, hm)
    assert struct.unpack_from("<4sHHQdIII", payload) == (b"RHM1", 1, 36, 9, 12.5, 5, 4, 3)
    floats = np.frombuffer(payload, "<f4", offset=36)
    assert len(floats) == 5 + 4 + 3 * 5 * 4
    np.testing.assert_array_equal(floats[:5], np.float32(hm.range_m))
    np.testing.assert_array_equal(floats[5:9], np.float32(hm.azimuth_rad))
    cells = floats[9:].reshape(3, 5, 4)
    np.testing.assert_array_equal(cells[0], hm.intensity)
    np.testing.assert_array_equal(cells[1], hm.static)
    np.testing.assert_array_equal(cells[2], hm.doppler_mps)
    assert messages.HEATMAP_ENCODING == "application/octet-stream;radarodom/heatmap/v1"


def test_heatmap_encodes_non_contiguous_arrays():
    hm = heatmap(6, 8)
    sliced = RangeAzimuth(hm.intensity[::2], hm.static[::2], hm.doppler_mps[::2], hm.range_m[::2], hm.azimuth_rad)
    _, arrays = messages.decode_heatmap(messages.encode_heatmap(0, 0.0, sliced))
    np.testing.assert_array_equal(arrays["intensity"], hm.intensity[::2])


@pytest.mark.parametrize("change, words", [
    (lambda p: p[:30], "shorter than its 36-byte header"),
    (lambda p: p[:-4], "header says 5 x 4 x 3"),
    (lambda p: b"RPC1" + p[4:], "magic"),
    (lambda p: _patched(p, 4, "<H", 7), "version 7 is newer"),
    (lambda p: _patched(p, 32, "<I", 2), "2 channels"),
    (lambda p: _patched(p, 24, "<I", 6), "header says 6 x 4 x 3"),
])
def test_decode_heatmap_refuses_bad_messages(change, words):
    with pytest.raises(MessageError, match=words):
        messages.decode_heatmap(change(messages.encode_heatmap(1, 1.0, heatmap(5, 4))))


@pytest.mark.parametrize("n_range, n_az", [(0, 0), (0, 4), (5, 0)])
def test_an_empty_heatmap_round_trips(n_range, n_az):
    """Found by the fuzz suite: a heatmap with no cell (which readers take) failed to encode
    with a TypeError from memoryview.cast."""
    hm = heatmap(n_range, n_az) if n_range and n_az else RangeAzimuth(
        *(np.zeros((n_range, n_az), np.float32) for _ in range(3)), 0.05 * np.arange(n_range),
        np.linspace(-1.0, 1.0, n_az))
    header, arrays = messages.decode_heatmap(messages.encode_heatmap(3, 2.5, hm))
    assert (header["n_range"], header["n_azimuth"]) == (n_range, n_az)
    assert arrays["intensity"].shape == (n_range, n_az) and arrays["range_m"].shape == (n_range,)


def test_encode_heatmap_refuses_inconsistent_shapes():
    hm = heatmap(5, 4)
    with pytest.raises(MessageError, match="static has shape"):
        messages.encode_heatmap(0, 0.0, RangeAzimuth(hm.intensity, hm.static.T, hm.doppler_mps, hm.range_m,
                                                     hm.azimuth_rad))
    with pytest.raises(MessageError, match="1-D"):
        messages.encode_heatmap(0, 0.0, RangeAzimuth(hm.intensity, hm.static, hm.doppler_mps,
                                                     hm.range_m[:, None], hm.azimuth_rad))


# =========================================================================== ROS 2
@pytest.mark.parametrize("t, expected", [(0.0, (0, 0)), (1.5, (1, 500_000_000)), (1.9999999999, (2, 0)),
                                         (1700000000.123456789, (1700000000, 123456717))])
def test_ros2_stamp(t, expected):
    assert ros2.ros2_stamp(t) == expected


def test_a_ros2_stamp_before_0_is_refused():
    # int32 seconds hold it, but rclcpp::Time(stamp) throws "cannot store a negative time point".
    with pytest.raises(MessageError, match="time -0.25 s is before 0"):
        ros2.ros2_stamp(-0.25)


def test_ros2_odometry_through_rosbags_cdr():
    rosbags = pytest.importorskip("rosbags.typesys")
    store = rosbags.get_typestore(rosbags.Stores.ROS2_JAZZY)
    s = state(yaw=2.5, pose_covariance=np.arange(9.0).reshape(3, 3), twist_covariance=10 + np.arange(9.0).reshape(3, 3))
    cdr = bytes(store.serialize_cdr(ros2.ros2_odometry(s, store), "nav_msgs/msg/Odometry"))
    assert cdr[:4] == b"\x00\x01\x00\x00"  # CDR, little-endian
    msg = store.deserialize_cdr(cdr, "nav_msgs/msg/Odometry")
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1000, 250_000_000)
    assert (msg.header.frame_id, msg.child_frame_id) == ("odom", "base_link")  # no mount: the radar's motion
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    assert (p.x, p.y, p.z) == (1.5, -0.25, 0.0)
    assert 2 * math.atan2(q.z, q.w) == pytest.approx(2.5) and q.x == q.y == 0.0
    assert (msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.angular.z) == (0.8, 0.01, 0.1)
    pose_cov = msg.pose.covariance.reshape(6, 6)
    np.testing.assert_array_equal(pose_cov[np.ix_([0, 1, 5], [0, 1, 5])], np.arange(9.0).reshape(3, 3))
    assert pose_cov[2, 2] == pose_cov[3, 3] == pose_cov[4, 4] == 1e6 and pose_cov[0, 2] == 0.0
    twist_cov = msg.twist.covariance.reshape(6, 6)
    np.testing.assert_array_equal(twist_cov[np.ix_([0, 1, 5], [0, 1, 5])], 10 + np.arange(9.0).reshape(3, 3))
    with pytest.raises(MessageError):
        ros2.ros2_odometry(state(x=math.nan), store)


def test_ros2_attachment_is_zenoh_serialization_of_rmw_zenohs_fields():
    ext = pytest.importorskip("zenoh.ext")
    gid = bytes(range(16))
    attachment = ros2.ros2_attachment(7, 1_700_000_000_123_456_789, gid)
    assert len(attachment) == 33
    # rmw_zenoh_cpp: serializer.serialize(int64 seq); (int64 timestamp); (std::array<uint8_t, 16> gid)
    assert attachment == ext.z_serialize((ext.Int64(7), ext.Int64(1_700_000_000_123_456_789), gid)).to_bytes()
    with pytest.raises(MessageError):
        ros2.ros2_attachment(1, 0, b"short")


# =========================================================================== issue 18: hostile payloads
# Any peer on the network may put anything on these keys; each case below once ended a reader.
@pytest.mark.parametrize("parse", [messages.parse_odometry, messages.parse_status])
@pytest.mark.parametrize("payload", [b"[" * 1000, b'{"a":' * 1000, b"[" * 200_000])
def test_deeply_nested_json_is_a_message_error_not_a_recursion_error(parse, payload):
    with pytest.raises(MessageError, match="nested .* deep, more than the 32 allowed"):
        parse(payload)


@pytest.mark.parametrize("parse", [messages.parse_odometry, messages.parse_status])
def test_json_over_the_size_bound_is_refused_before_parsing(parse):
    payload = b'{"schema":"radarodom/status","version":1,"pad":"' + b"x" * messages.MAX_JSON_BYTES + b'"}'
    with pytest.raises(MessageError, match=f"more than the {messages.MAX_JSON_BYTES}"):
        parse(payload)


@pytest.mark.parametrize("number", [b"1e999", b"-1e999", b"NaN", b"Infinity", b"-Infinity"])
def test_a_status_with_a_non_finite_number_is_refused(number):
    payload = b'{"schema":"radarodom/status","version":1,"latency_ms":{"p50":' + number + b"}}"
    with pytest.raises(MessageError, match="not a radarodom/status message"):
        messages.parse_status(payload)


@pytest.mark.parametrize("t", [math.nan, math.inf, -math.inf])
def test_a_point_cloud_header_with_a_non_finite_t_is_refused(t):
    payload = _patched(messages.encode_pointcloud(1, 1.0, points(2)), 16, "<d", t)
    with pytest.raises(MessageError, match=f"radarodom/pointcloud: t is {t}, not a finite time"):
        messages.decode_pointcloud(payload)


@pytest.mark.parametrize("t", [math.nan, math.inf, -math.inf])
def test_a_heatmap_header_with_a_non_finite_t_is_refused(t):
    payload = _patched(messages.encode_heatmap(1, 1.0, heatmap(5, 4)), 16, "<d", t)
    with pytest.raises(MessageError, match=f"radarodom/heatmap: t is {t}, not a finite time"):
        messages.decode_heatmap(payload)


@pytest.mark.parametrize("decode, header_bytes, offset", [
    (messages.decode_pointcloud, 32, 24), (messages.decode_heatmap, 36, 24)])
def test_a_header_claiming_a_huge_size_is_checked_against_the_payload(decode, header_bytes, offset):
    payload = (messages.encode_pointcloud(1, 1.0, points(2)) if header_bytes == 32
               else messages.encode_heatmap(1, 1.0, heatmap(5, 4)))
    with pytest.raises(MessageError, match="but its header says"):
        decode(_patched(payload, offset, "<I", 2**32 - 1))


@pytest.mark.parametrize("decode", [messages.decode_pointcloud, messages.decode_heatmap])
def test_a_binary_payload_over_its_bound_is_refused_before_it_is_copied(decode):
    with pytest.raises(MessageError, match=f"more than the {messages.MAX_BINARY_BYTES}"):
        decode(memoryview(bytearray(messages.MAX_BINARY_BYTES + 1)))
    with pytest.raises(MessageError, match="a payload is bytes, not str"):
        decode("RPC1")


STATUS_HEAD = b'{"schema":"radarodom/status","version":1,'


@pytest.mark.parametrize("parse, payload", [
    (messages.parse_status, STATUS_HEAD + b'"frames":' + b"7" * 5000 + b"}"),
    (messages.parse_status, STATUS_HEAD + b'"frames":-' + b"7" * 5000 + b"}"),
    (messages.parse_odometry, b'{"schema":"radarodom/odom","version":' + b"1" * 5000 + b"}")])
def test_a_5000_digit_integer_gets_our_own_message(parse, payload):
    """Python's json refuses it with "use sys.set_int_max_str_digits()", advice for a programmer."""
    with pytest.raises(MessageError) as info:
        parse(payload)
    assert str(info.value).endswith("message: an integer of 5000 digits, more than the 4300 allowed")
    assert messages.parse_status(STATUS_HEAD + b'"n":' + b"9" * 4300 + b"}")["n"] == int("9" * 4300)


def test_a_huge_version_is_quoted_cut():
    with pytest.raises(MessageError) as info:
        messages.parse_status(b'{"schema":"radarodom/status","version":' + b"2" * 300 + b"}")
    message = str(info.value)
    assert len(message) < 200 and message.endswith("... (300 characters) is newer than this reader understands "
                                                   "(1); upgrade radarodom"), message


@pytest.mark.parametrize("decode, encoded", [
    (messages.decode_pointcloud, lambda: messages.encode_pointcloud(1, 1.0, points(2))),
    (messages.decode_heatmap, lambda: messages.encode_heatmap(1, 1.0, heatmap(5, 4)))])
def test_a_zeroed_magic_is_shown_as_its_bytes(decode, encoded):
    """numpy's S4 field drops trailing NULs: the message once said magic b''."""
    payload = encoded()
    expected = payload[:4]
    for magic, shown in ((b"\0" * 4, r"b'\x00\x00\x00\x00'"), (b"R\0\0\0", r"b'R\x00\x00\x00'")):
        with pytest.raises(MessageError) as info:
            decode(magic + payload[4:])
        assert str(info.value).endswith(f"message: magic {shown}, expected {expected!r}"), str(info.value)


@pytest.mark.parametrize("payload", [
    STATUS_HEAD + rb'"source":"\ud800"}',
    STATUS_HEAD + rb'"source":{"url":["ok","x\udfff"]}}',
    STATUS_HEAD + rb'"\udc00":1}',
    STATUS_HEAD + rb'"source":"\ude00\ud83d"}'])  # a pair in the wrong order is two lone halves
def test_a_lone_surrogate_in_a_status_string_is_refused(payload):
    """Strict JSON parsers refuse it (it is no Unicode text); radar-echo --json printed it."""
    with pytest.raises(MessageError, match=r"holds a lone surrogate, U\+D[89A-F][0-9A-F]{2} at character \d+: "
                                           r"not Unicode text"):
        messages.parse_status(payload)
    with pytest.raises(MessageError):
        radar_echo.format_message("status", "radar/awr1843/status", payload, as_json=True)


def test_a_lone_surrogate_in_odometry_flags_is_refused():
    obj = json.loads(messages.odometry_json(state()))
    obj["flags"] = ["\ud800"]
    with pytest.raises(MessageError, match="lone surrogate"):
        messages.parse_odometry(json.dumps(obj).encode())


def test_surrogate_pairs_and_escaped_backslashes_are_text():
    decoded = messages.parse_status(STATUS_HEAD + rb'"a":"\ud83d\ude00","b":"\\ud800"}')
    assert decoded["a"] == "\U0001F600" and decoded["b"] == "\\ud800"


def test_messages_import_neither_zenoh_nor_the_dsp():
    """radar-echo and other readers stay light: no zenoh, scipy or rosbags behind the schemas."""
    code = ("import sys, radarodom.messages; "
            "print(sorted(m for m in ('zenoh', 'scipy', 'rosbags', 'radarodom.dsp') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("call, words", [
    (lambda: messages.encode_pointcloud(0, 0.0, None), "point cloud: a structured array of points"),
    (lambda: messages.encode_pointcloud(0, 0.0, [[1.0, 2.0]]), "point cloud: a structured array of points"),
    (lambda: messages.encode_heatmap(0, 0.0, None), "heatmap: a range-azimuth heatmap"),
    (lambda: messages.odometry_json(None), "odometry: an OdometryState (radarodom.estimator.odometry), got NoneType"),
    (lambda: messages.odometry_dict({}), "odometry: an OdometryState"),
    (lambda: messages.status_json(None), "status: a mapping of the status' items, got NoneType"),
    # JSON writes the key 1 as "1": the message held "1" twice, which every reader refuses.
    (lambda: messages.status_json({1: 2, "1": 3}), "status: its keys must be strings, got 1"),
    (lambda: messages.encode_pointcloud(0, 0.0, np.zeros((2, 3), POINT_DTYPE)),
     "point cloud: a (n,) array of points, got the shape (2, 3)"),  # numpy's broadcast error
])
def test_the_encoders_name_what_they_take(call, words):
    with pytest.raises(MessageError) as info:
        call()
    assert words in str(info.value), str(info.value)
