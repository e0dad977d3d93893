"""Property tests over the Zenoh boundary (issue 18): every decoder of radarodom.messages and
radar-echo's formatting, fed what any peer on the network could put on a key.

For arbitrary bytes, mutated valid messages and JSON trees full of hostile numbers:
only MessageError escapes; whatever decodes re-encodes to the same message; and what radar-echo
prints is one line, and with --json standard JSON (no NaN, no Infinity).
"""

from __future__ import annotations

import json
import math
import struct
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from radarodom import messages
from radarodom.errors import MessageError
from radarodom.estimator.odometry import OdometryState
from radarodom.tools import radar_echo

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])

DECODERS = {"odom": messages.parse_odometry, "status": messages.parse_status,
            "pointcloud": messages.decode_pointcloud, "heatmap": messages.decode_heatmap}


# ---------------------------------------------------------------------- what a reader must hold to
def _no_constant(name: str):
    raise AssertionError(f"{name} in output that claims to be JSON")


#: The longest message a refusal may have: bad values are quoted cut (errors.quoted).
MAX_MESSAGE_CHARS = 300


def _strings(obj):
    if isinstance(obj, str):
        yield obj
    elif isinstance(obj, dict):
        for key, value in obj.items():
            yield key
            yield from _strings(value)
    elif isinstance(obj, (list, tuple)):
        for value in obj:
            yield from _strings(value)


def check_one_payload(kind: str, payload: bytes) -> None:
    """Decode *payload* as *kind*: a MessageError of our own words, cut, or a message whose
    strings are Unicode text, that re-encodes to itself and that radar-echo prints as one line
    of UTF-8 (and, with --json, as standard JSON)."""
    try:
        decoded = DECODERS[kind](payload)
    except MessageError as exc:
        decoded = None
        assert len(str(exc)) <= MAX_MESSAGE_CHARS, str(exc)
        assert "sys." not in str(exc), str(exc)  # Python's advice to a programmer, not ours
    else:
        for text in _strings(decoded):
            text.encode("utf-8")  # no lone surrogate
        check_reencodes(kind, decoded, payload)
    for as_json in (False, True):
        try:
            line = radar_echo.format_message(kind, f"radar/awr1843/{kind}", payload, as_json=as_json)
        except MessageError:
            assert decoded is None, "radar-echo refused what the decoder took"
            continue
        assert decoded is not None, "radar-echo printed what the decoder refused"
        assert "\n" not in line and "\r" not in line
        line.encode("utf-8")  # printable to a UTF-8 terminal
        if as_json:
            obj = json.loads(line, parse_constant=_no_constant)
            assert obj["key"] == f"radar/awr1843/{kind}"


def check_reencodes(kind: str, decoded, payload: bytes) -> None:
    if kind == "odom":
        m = decoded
        state = OdometryState(
            t=m["t"], frame=m["frame"], x=m["x"], y=m["y"], yaw=m["yaw"], vx=m["vx"], vy=m["vy"],
            yaw_rate=m["yaw_rate"], pose_covariance=np.reshape(np.array(m["pose_covariance"], float), (3, 3)),
            twist_covariance=np.reshape(np.array(m["twist_covariance"], float), (3, 3)),
            flags=tuple(m["flags"]), features=m["features"], compute_s=m["compute_ms"] / 1e3)
        again = messages.parse_odometry(messages.odometry_json(state))
        for name in ("t", "x", "y", "yaw", "vx", "vy", "yaw_rate"):
            assert again[name] == float(m[name])
        for name in ("pose_covariance", "twist_covariance"):
            assert again[name] == [float(v) for v in m[name]]
        assert again["compute_ms"] == pytest.approx(float(m["compute_ms"]), rel=1e-12)
        assert (again["frame"], again["features"], again["flags"]) == (m["frame"], m["features"], m["flags"])
    elif kind == "status":
        body = {k: v for k, v in decoded.items() if k not in ("schema", "version")}
        assert messages.parse_status(messages.status_json(body)) == {**decoded, "version": 1}
    elif kind == "pointcloud":
        info, points = decoded
        assert messages.encode_pointcloud(info["frame"], info["t"], points) == bytes(payload)
    else:
        info, arrays = decoded
        assert messages.encode_heatmap(info["frame"], info["t"], SimpleNamespace(**arrays)) == bytes(payload)


# ---------------------------------------------------------------------- valid messages to start from
def _state(seed: int) -> OdometryState:
    rng = np.random.default_rng(seed)
    return OdometryState(t=1000.0 + seed, frame=seed, x=rng.normal(), y=rng.normal(), yaw=rng.normal(),
                         vx=rng.normal(), vy=rng.normal(), yaw_rate=rng.normal(),
                         pose_covariance=np.diag(rng.random(3)), twist_covariance=np.diag(rng.random(3)),
                         flags=("velocity_held",) if seed % 2 else (), features=seed * 3, compute_s=0.004)


def _points(n: int) -> np.ndarray:
    out = np.zeros(n, messages.POINTCLOUD_RECORD)
    for i, name in enumerate(messages.POINTCLOUD_RECORD.names):
        out[name] = np.arange(n) + i
    return out


def _heatmap(n_range: int, n_az: int) -> SimpleNamespace:
    cells = np.arange(n_range * n_az, dtype=np.float32).reshape(n_range, n_az)
    doppler = cells.copy()
    if cells.size:
        doppler.flat[0] = np.nan  # a cell not computed: the arrays may hold NaN, the header may not
    return SimpleNamespace(range_m=np.arange(n_range), azimuth_rad=np.linspace(-1, 1, n_az),
                           intensity=cells, static=cells / 2, doppler_mps=doppler)


VALID = {
    "odom": [messages.odometry_json(_state(s)) for s in range(3)],
    "status": [messages.status_json({"rate_hz": 10.0, "frames": 4, "latency_ms": {"p50": None}, "source": {
        "url": "sim://", "packets": [1, 2, {"late": 0}]}}), messages.status_json({})],
    "pointcloud": [messages.encode_pointcloud(7, 1000.5, _points(n)) for n in (0, 1, 3)],
    "heatmap": [messages.encode_heatmap(7, 1000.5, _heatmap(nr, na)) for nr, na in ((0, 0), (2, 3), (4, 1))],
}
KINDS = st.sampled_from(sorted(DECODERS))


def test_the_valid_messages_decode():
    for kind, payloads in VALID.items():
        for payload in payloads:
            check_one_payload(kind, payload)
            DECODERS[kind](payload)


# ---------------------------------------------------------------------- arbitrary bytes
@FUZZ
@given(kind=KINDS, payload=st.binary(max_size=300))
def test_arbitrary_bytes(kind, payload):
    check_one_payload(kind, payload)


@FUZZ
@given(kind=KINDS, text=st.text(alphabet=st.sampled_from('[]{}",:0123456789.eE+-nulltrfaseNIiy \\u'), max_size=200))
def test_json_punctuation_soup(kind, text):
    check_one_payload(kind, text.encode())


# ---------------------------------------------------------------------- mutated valid messages
@st.composite
def mutated(draw):
    kind = draw(KINDS)
    payload = bytearray(draw(st.sampled_from(VALID[kind])))
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["flip", "set", "cut", "insert", "delete", "append"]))
        at = draw(st.integers(0, len(payload)))
        if op in ("flip", "set") and at < len(payload):
            payload[at] = payload[at] ^ (1 << draw(st.integers(0, 7))) if op == "flip" else draw(st.integers(0, 255))
        elif op == "cut":
            del payload[at:]
        elif op == "insert":
            payload[at:at] = draw(st.binary(min_size=1, max_size=8))
        elif op == "delete":
            del payload[at:at + draw(st.integers(1, 8))]
        else:
            payload += draw(st.binary(min_size=1, max_size=40))
    return kind, bytes(payload)


@FUZZ
@given(case=mutated())
def test_mutated_valid_messages(case):
    check_one_payload(*case)


U16, U32, U64 = st.integers(0, 2**16 - 1), st.integers(0, 2**32 - 1), st.integers(0, 2**64 - 1)
#: Header fields near the values that matter (0, 1, the right one, the largest) and anywhere.
SIZES = st.one_of(st.integers(0, 6), st.just(2**32 - 1), U32)
ANY_T = st.one_of(st.floats(), st.sampled_from([math.nan, math.inf, -math.inf, -0.0, 5e-324, 1.7976931348623157e308]))


def _mostly(draw, plausible, anything):
    """Usually *plausible*, one time in four *anything*: enough messages get past each check to
    reach the next."""
    return draw(anything if draw(st.integers(0, 3)) == 0 else plausible)


@st.composite
def binary_headers(draw):
    """A point cloud or heatmap whose header fields are drawn (mostly plausible, sometimes
    anything), followed by a body of about the size the header claims."""
    kind = draw(st.sampled_from(["pointcloud", "heatmap"]))
    right = b"RPC1" if kind == "pointcloud" else b"RHM1"
    magic = _mostly(draw, st.just(right), st.sampled_from([b"RPC1", b"RHM1", right[:3] + b"\0", b"\0\0\0\0"]))
    version = _mostly(draw, st.just(1), st.one_of(st.integers(0, 2), U16))
    frame, t = draw(U64), _mostly(draw, st.floats(allow_nan=False, allow_infinity=False), ANY_T)
    small = st.integers(0, 6)
    if kind == "pointcloud":
        header_bytes = _mostly(draw, st.just(32), U16)
        count = _mostly(draw, small, SIZES)
        record_bytes, fields = _mostly(draw, st.just(36), U16), _mostly(draw, st.just(9), U16)
        header = struct.pack("<4sHHQdIHH", magic, version, header_bytes, frame, t, count, record_bytes, fields)
        claimed = count * 36
    else:
        header_bytes = _mostly(draw, st.just(36), U16)
        nr, na = _mostly(draw, small, SIZES), _mostly(draw, small, SIZES)
        channels = _mostly(draw, st.just(3), st.one_of(st.integers(0, 4), U32))
        header = struct.pack("<4sHHQdIII", magic, version, header_bytes, frame, t, nr, na, channels)
        claimed = 4 * (nr + na + 3 * nr * na)
    body_size = max(0, min(claimed, 4096) + _mostly(draw, st.just(0), st.integers(-5, 5)))
    body = draw(st.one_of(st.just(bytes(body_size)), st.binary(min_size=body_size, max_size=body_size)))
    return kind, header + body


@FUZZ
@given(case=binary_headers())
def test_binary_headers_with_drawn_fields(case):
    check_one_payload(*case)


def test_binary_headers_with_nan_t_never_decode():
    for kind, make in (("pointcloud", lambda t: messages.encode_pointcloud(1, 1.0, _points(2))),
                       ("heatmap", lambda t: messages.encode_heatmap(1, 1.0, _heatmap(2, 2)))):
        payload = bytearray(make(0.0))
        struct.pack_into("<d", payload, 16, math.nan)
        with pytest.raises(MessageError, match="not a finite time"):
            DECODERS[kind](bytes(payload))


# ---------------------------------------------------------------------- JSON trees with hostile numbers
class Raw(str):
    """Number text written as is: what a Python json.dumps would never write."""


HOSTILE_NUMBERS = st.sampled_from(["NaN", "-NaN", "Infinity", "-Infinity", "1e999", "-1e400", "1E+309", "2e308",
                                   "1.7976931348623157e308", "5e-324", "1e-400", "-0", "-0.0", "0e0",
                                   "1" * 400, "9" * 4400, "1" * 5000, "18446744073709551616", "01", "1.", ".5",
                                   "+1", "0x10", "1_0", "\u0661"])
LEAVES = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(-(10**400), 10**400),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8),
    st.sampled_from(["\ud800", "\x00", "\n\x1b[2J", "é"]), HOSTILE_NUMBERS.map(Raw))
TREES = st.recursive(LEAVES, lambda children: st.one_of(
    st.lists(children, max_size=4), st.dictionaries(st.text(max_size=6), children, max_size=4)), max_leaves=12)


def dump(obj) -> str:
    """JSON-like text of *obj*: Raw numbers verbatim, floats as Python writes them (NaN and
    Infinity included), strings escaped (lone surrogates too)."""
    if isinstance(obj, Raw):
        return str(obj)
    if isinstance(obj, dict):
        return "{" + ",".join(f"{json.dumps(k)}:{dump(v)}" for k, v in obj.items()) + "}"
    if isinstance(obj, list):
        return "[" + ",".join(dump(v) for v in obj) + "]"
    return json.dumps(obj)


def _nested(depth: int) -> Raw:
    return Raw("[" * depth + "]" * depth)


ODOM_FIELDS = list(json.loads(VALID["odom"][0]))


FINITE = st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.integers(-(10**300), 10**300))
#: Values a reader must take for each field: the edges of what is valid.
EDGE_VALID = {
    **{name: FINITE for name in ("t", "x", "y", "yaw", "vx", "vy", "yaw_rate", "compute_ms")},
    "frame": U64, "features": U64,
    "pose_covariance": st.lists(FINITE, min_size=9, max_size=9),
    "twist_covariance": st.lists(FINITE, min_size=9, max_size=9),
    "flags": st.lists(st.one_of(st.text(max_size=8), st.sampled_from(["\n\x1b[2J", ",", "x" * 300]))),
    "ok": st.booleans(), "frame_id": st.text(max_size=8), "child_frame_id": st.text(max_size=8),
}


@st.composite
def odometry_objects(draw):
    obj = dict(json.loads(draw(st.sampled_from(VALID["odom"]))))
    for name in ODOM_FIELDS[2:]:
        choice = draw(st.integers(0, 24))
        if choice < 3:
            obj[name] = draw(EDGE_VALID[name])
        elif choice == 3:
            obj[name] = draw(st.one_of(TREES, st.integers(30, 40).map(_nested),
                                       st.lists(LEAVES, min_size=9, max_size=9)))
    if draw(st.integers(0, 4)) == 0:
        obj.pop(draw(st.sampled_from(ODOM_FIELDS)), None)
    if draw(st.integers(0, 4)) == 0:
        obj[draw(st.text(max_size=4))] = draw(TREES)
    return dump(obj)


@st.composite
def status_objects(draw):
    body = draw(st.dictionaries(st.text(max_size=6), st.one_of(TREES, st.integers(28, 40).map(_nested)),
                                max_size=5))
    head = draw(st.sampled_from([{"schema": "radarodom/status", "version": 1},
                                 {"schema": "radarodom/status", "version": Raw("1.0")},
                                 {"schema": "radarodom/status", "version": 2}, {"version": 1}]))
    return dump({**head, **body})


@FUZZ
@given(text=odometry_objects(), encoding=st.sampled_from(["utf-8"] * 4 + ["utf-8-sig", "utf-16", "surrogatepass"]))
def test_odometry_with_hostile_values(text, encoding):
    payload = text.encode("utf-8", "surrogatepass") if encoding == "surrogatepass" else \
        text.encode(encoding, "replace")
    check_one_payload("odom", payload)


@FUZZ
@given(text=status_objects())
def test_status_with_hostile_values(text):
    check_one_payload("status", text.encode("utf-8", "surrogatepass"))


@FUZZ
@given(tree=TREES)
def test_any_json_tree_as_any_message(tree):
    for kind in ("odom", "status"):
        check_one_payload(kind, dump(tree).encode("utf-8", "surrogatepass"))


@settings(max_examples=40, deadline=None)
@given(number=HOSTILE_NUMBERS, where=st.sampled_from(["t", "x", "frame", "features", "pose_covariance"]))
def test_a_hostile_number_in_odometry_is_refused_or_finite(number, where):
    obj = json.loads(VALID["odom"][0])
    obj[where] = Raw(number) if where != "pose_covariance" else [Raw(number)] + [0.0] * 8
    payload = dump(obj).encode()
    try:
        m = messages.parse_odometry(payload)
    except MessageError:
        return
    values = m[where] if where == "pose_covariance" else [m[where]]
    assert all(math.isfinite(v) for v in values)
    check_one_payload("odom", payload)
