"""radar-echo, the command-line subscriber: run as a subprocess (the installed
console script) against a publisher in the test, on loopback endpoints."""

from __future__ import annotations

import argparse
import json
import math
import re
import signal
import struct
import subprocess
import threading
import time

import pytest
import zenoh
from conftest import console_command
from zenoh_helpers import estimator_run, free_endpoint, peer, wait_for

from radarodom import messages, strict_json
from radarodom.errors import MessageError
from radarodom.publish import Publisher, ZenohOptions
from radarodom.tools import radar_echo
from radarodom.tools.zenoh_args import add_zenoh_arguments, options_from_args

ECHO = console_command("radar-echo")
ODOM_LINE = re.compile(r"odom frame (\d+) t (\d+\.\d{3}) x (-?\d+\.\d{3}) y (-?\d+\.\d{3}) m "
                       r"yaw (-?\d+\.\d{2}) deg v (\d+\.\d{3}) m/s( \[[a-z_,]+\])?")


@pytest.fixture(scope="module")
def run():
    return estimator_run(frames=12)


class Publishing:
    """Publishes the run's odometry (and a status, point cloud, heatmap per frame)
    every 20 ms on a thread until stopped, looping over the run."""

    def __init__(self, pub: Publisher, run) -> None:
        self.pub, self.run = pub, run
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def _loop(self) -> None:
        i = 0
        while not self._stop.is_set():
            state, points, heatmap = self.run[i % len(self.run)]
            self.pub.odometry(state)
            self.pub.status({"frame": state.frame})
            self.pub.pointcloud(state.frame, state.t, points)
            self.pub.heatmap(state.frame, state.t, heatmap)
            i += 1
            time.sleep(0.02)

    def __enter__(self) -> Publishing:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(5)


def echo(*args, timeout=30) -> subprocess.CompletedProcess:
    return subprocess.run(ECHO + [str(a) for a in args], stdin=subprocess.DEVNULL, capture_output=True,
                          text=True, timeout=timeout)


def test_radar_echo_prints_odometry_lines_and_exits_after_count(run):
    endpoint = free_endpoint()
    with Publisher(ZenohOptions(listen=[endpoint])) as pub, Publishing(pub, run):
        proc = echo("--connect", endpoint, "--count", 5, "odom")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 5
    matches = [ODOM_LINE.fullmatch(line) for line in lines]
    assert all(matches), lines
    by_frame = {s.frame: s for s, _, _ in run}
    for m in matches:
        state = by_frame[int(m.group(1))]
        assert float(m.group(3)) == pytest.approx(state.x, abs=6e-4)
        assert float(m.group(5)) == pytest.approx(57.29577951 * state.yaw, abs=6e-3)
    assert f"connect {endpoint}" in proc.stderr and "Ctrl-C stops" in proc.stderr


def test_radar_echo_json_and_every_kind(run):
    endpoint = free_endpoint()
    with Publisher(ZenohOptions(listen=[endpoint], key_prefix="robot/radar")) as pub, Publishing(pub, run):
        proc = echo("--connect", endpoint, "--key-prefix", "robot/radar", "--count", 40, "--json", "-q",
                    "odom", "status", "pointcloud", "heatmap")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    objects = [json.loads(line) for line in proc.stdout.splitlines()]
    assert len(objects) == 40
    kinds = {o["key"]: o for o in objects}
    assert set(kinds) == {"robot/radar/odom", "robot/radar/status", "robot/radar/pointcloud",
                          "robot/radar/heatmap"}
    assert kinds["robot/radar/odom"]["schema"] == "radarodom/odom"
    assert kinds["robot/radar/heatmap"]["n_azimuth"] == 64
    assert kinds["robot/radar/pointcloud"]["schema"] == "radarodom/pointcloud"


def test_radar_echo_skips_malformed_messages_with_a_warning(run):
    endpoint = free_endpoint()
    with peer(listen=[endpoint]) as session:
        proc = subprocess.Popen(ECHO + ["--connect", endpoint, "--count", "1", "odom"], stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            publisher = session.declare_publisher("radar/awr1843/odom")
            deadline = time.monotonic() + 20
            while proc.poll() is None and time.monotonic() < deadline:
                publisher.put(b'{"schema": "radarodom/odom", "version": 1}')
                session.delete("radar/awr1843/odom")  # no message: was "malformed: not JSON: Expecting value"
                publisher.put(messages.odometry_json(run[3][0]))
                time.sleep(0.05)
            out, err = proc.communicate(timeout=30)
        finally:
            proc.kill()
    assert proc.returncode == 0, err
    assert ODOM_LINE.fullmatch(out.strip()) and out.startswith("odom frame 3 ")
    assert "ignored a malformed message" in err and "'t' is missing" in err
    assert "radar/awr1843/odom: ignored a DELETE (no message: a program deleted the key)" in err, err
    assert "Expecting value" not in err, err


def test_radar_echo_stops_on_ctrl_c_with_status_0():
    # Nothing publishes: it waits (retrying its connect) until interrupted.
    proc = subprocess.Popen(ECHO + ["--connect", free_endpoint()], stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert "Ctrl-C stops" in proc.stderr.readline()
        proc.send_signal(signal.SIGINT)
        started = time.monotonic()
        out, _ = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0 and out == ""
    assert time.monotonic() - started < 20.0  # a hang guard (under the communicate timeout), not a speed figure


def test_radar_echo_finds_a_default_publisher_without_options(run, default_endpoint, capsys):
    # In this process, with the default endpoint moved to a free port: never the real 7448,
    # which a radar-capture the user runs may hold.
    with Publisher() as pub, Publishing(pub, run):
        code = radar_echo.main(["--count", "2", "status"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert [json.loads(line.split(" ", 1)[1])["schema"] for line in out.splitlines()] == ["radarodom/status"] * 2


@pytest.mark.parametrize("args, words", [
    (["bogus"], "argument KIND: expected one of odom, pointcloud, heatmap, status, got 'bogus'"),
    # Its value was taken as a KIND and reported as a bad one.
    (["--duration", "2"], "unrecognized arguments: --duration"),
    (["odom", "--duration", "2"], "unrecognized arguments: --duration"),
    (["--count", "0"], "expected a whole number >= 1"),
    (["--connect", "tcp/192.168.1.5"], "needs HOST:PORT"),
    (["--mode", "client"], "needs --connect"),
    (["--listen", "tcp/0.0.0.0:17452", "--listen", "tcp/127.0.0.1:17452"], "are the same socket"),
    (["--key-prefix", "radar/*"], "wildcards"),
    # A newline in it split the status line in two; a space went through as well.
    (["--key-prefix", "a\nb"], "spaces and control characters are not allowed"),
    (["--key-prefix", "a b"], "spaces and control characters are not allowed"),
])
def test_radar_echo_bad_options_exit_2(capsys, args, words):
    assert radar_echo.main(args) == 2
    assert words in capsys.readouterr().err


def test_radar_echo_bad_config_file_exits_2(capsys, tmp_path):
    path = tmp_path / "bad.json5"
    path.write_text("{ mode: 'peer', listen: [ }")
    assert radar_echo.main(["--zenoh-config", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"radar-echo: error: zenoh config {path}:") and len(err.splitlines()) >= 1
    # An endpoint Zenoh cannot parse: it waited for ever on it, without a word.
    path.write_text('{ mode: "peer", connect: { endpoints: ["tcp/127.0.0.1:99999"] } }')
    assert radar_echo.main(["--zenoh-config", str(path), "--count", "1"]) == 2
    assert capsys.readouterr().err == (f"radar-echo: error: zenoh config {path}:1: connect/endpoints: "
                                       "'tcp/127.0.0.1:99999': port 99999 is above 65535\n")


def test_format_message_lines():
    state = estimator_run(frames=2)[1][0]
    line = radar_echo.format_message("odom", "radar/awr1843/odom", messages.odometry_json(state))
    assert ODOM_LINE.fullmatch(line) and line.startswith("odom frame 1 t 1000.100 ")
    # A peer's numbers are finite, of any size: not 300 digits, nor "yaw inf deg".
    huge = {**json.loads(messages.odometry_json(state)), "t": -1e300, "yaw": 1e308}
    line = radar_echo.format_message("odom", "k", json.dumps(huge).encode())
    assert line.startswith("odom frame 1 t -1e+300 x ") and " yaw 1e+308 rad v " in line, line
    obj = json.loads(radar_echo.format_message("status", "k", messages.status_json({"a": 1}), as_json=True))
    assert obj == {"key": "k", "schema": "radarodom/status", "version": 1, "a": 1}


def test_the_shared_session_arguments_make_zenoh_options():
    """What radar-capture and radar-echo share (tools/zenoh_args.py), with the ROS 2 ones."""
    parser = argparse.ArgumentParser()
    add_zenoh_arguments(parser, ros2=True)
    args = parser.parse_args(["--connect", "tcp/10.0.0.2:7447", "--connect", "tcp/10.0.0.3:7447",
                              "--listen", "tcp/0.0.0.0:7448", "--mode", "peer", "--key-prefix", "robot/radar",
                              "--ros2", "--ros2-domain", "7", "--ros2-topic", "/robot/odom"])
    assert options_from_args(args) == ZenohOptions(
        mode="peer", connect=("tcp/10.0.0.2:7447", "tcp/10.0.0.3:7447"), listen=("tcp/0.0.0.0:7448",),
        key_prefix="robot/radar", ros2=True, ros2_domain=7, ros2_topic="/robot/odom")
    assert options_from_args(parser.parse_args([])) == ZenohOptions()
    without = argparse.ArgumentParser()
    add_zenoh_arguments(without)
    assert options_from_args(without.parse_args(["--zenoh-config", "z.json5"])) == \
        ZenohOptions(config_file="z.json5")
    with pytest.raises(SystemExit):
        without.parse_args(["--ros2"])


# =========================================================================== issue 18: hostile peers
def _patched(payload: bytes, offset: int, fmt: str, value) -> bytes:
    out = bytearray(payload)
    struct.pack_into(fmt, out, offset, value)
    return bytes(out)


def _hostile_payloads(run) -> dict[str, list[bytes]]:
    """Per kind, payloads a peer may put that no reader can take: deep nesting, NaN and
    overflowing numbers, wrong magic, truncation, headers claiming huge sizes, non-UTF-8 and
    oversized payloads."""
    state, cloud, heatmap = run[3]
    odom = messages.odometry_json(state)
    pc = messages.encode_pointcloud(state.frame, state.t, cloud)
    hm = messages.encode_heatmap(state.frame, state.t, heatmap)
    status = messages.status_json({"rate_hz": 10.0})
    return {
        "odom": [b"[" * 1000, b'{"a":' * 1000, odom.replace(b'"x":', b'"x":NaN,"_":'),
                 odom.replace(b'"t":', b'"t":1e999,"_":'), b"\xff\xfe" + odom, odom[:-5], b"",
                 b'{"pad":"' + b"x" * messages.MAX_JSON_BYTES + b'"}'],
        "status": [b"[" * 1000, status.replace(b"10.0", b"1e999"), status.replace(b"10.0", b"Infinity"),
                   status.replace(b"10.0", b"NaN"), b"\xc3\x28" + status, b"[1, 2]", status[:-1]],
        "pointcloud": [_patched(pc, 16, "<d", math.nan), b"XPC1" + pc[4:], pc[:20], pc[:-1],
                       _patched(pc, 24, "<I", 2**32 - 1), b""],
        "heatmap": [_patched(hm, 16, "<d", math.inf), b"RPC1" + hm[4:], hm[:30], hm[:-4],
                    _patched(hm, 24, "<I", 2**32 - 1), bytes(messages.MAX_BINARY_BYTES + 1)],
    }


def test_radar_echo_never_formats_nan_or_infinity_as_json(run):
    """Regression (issue 18): a NaN t in a point cloud or heatmap header and 1e999 in a status
    were printed by --json as "t":NaN / "x":Infinity; now each is a MessageError."""
    for kind, payloads in _hostile_payloads(run).items():
        for payload in payloads:
            with pytest.raises(MessageError):
                radar_echo.format_message(kind, f"radar/awr1843/{kind}", payload, as_json=True)
    state = run[3][0]
    line = radar_echo.format_message("status", "k", messages.status_json({"lat": 10.0**308, "n": 10**400}), True)
    assert strict_json.loads(line, max_bytes=1 << 20)["lat"] == 1e308
    assert "NaN" not in radar_echo.format_message("odom", "k", messages.odometry_json(state), True)


def test_radar_echo_survives_a_burst_of_malformed_payloads(run):
    """Regression (issue 18): `[` x 1000 on odom or status ended every radar-echo with an internal
    error.  A peer now puts every kind of bad payload on all four keys: radar-echo prints one
    warning line per message ignored, then the next good message of each key, and exits 0 at
    --count."""
    endpoint = free_endpoint()
    hostile = _hostile_payloads(run)
    state, cloud, heatmap = run[5]
    good = {"odom": messages.odometry_json(state), "status": messages.status_json({"frame": state.frame}),
            "pointcloud": messages.encode_pointcloud(state.frame, state.t, cloud),
            "heatmap": messages.encode_heatmap(state.frame, state.t, heatmap)}
    with peer(listen=[endpoint]) as session:
        # Blocking puts: every payload reaches radar-echo, in order on each key.
        publishers = {kind: session.declare_publisher(f"radar/awr1843/{kind}",
                                                      congestion_control=zenoh.CongestionControl.BLOCK)
                      for kind in good}
        proc = subprocess.Popen(ECHO + ["--connect", endpoint, "--count", "4", "--json", *good],
                                stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            assert wait_for(lambda: all(p.matching_status.matching for p in publishers.values()), timeout=30)
            for kind, payloads in hostile.items():
                for payload in payloads:
                    publishers[kind].put(payload)
            for kind, payload in good.items():
                publishers[kind].put(payload)
            out, err = proc.communicate(timeout=60)
        finally:
            proc.kill()
    assert proc.returncode == 0, err
    warnings = [line for line in err.splitlines() if "ignored a malformed message" in line]
    assert len(warnings) == sum(len(p) for p in hostile.values()), err
    for kind, payloads in hostile.items():
        assert sum(line.startswith(f"radar/awr1843/{kind}: ") or f" radar/awr1843/{kind}: " in line
                   for line in warnings) == len(payloads), err
    others = [line for line in err.splitlines() if line not in warnings]
    assert len(others) == 1 and "Ctrl-C stops" in others[0], err  # the banner, nothing else
    assert "Traceback" not in err and "internal error" not in err
    objects = [strict_json.loads(line, max_bytes=1 << 20) for line in out.splitlines()]
    assert sorted(o["key"] for o in objects) == sorted(f"radar/awr1843/{kind}" for kind in good)
    by_key = {o["key"].rsplit("/", 1)[1]: o for o in objects}
    assert by_key["odom"]["frame"] == by_key["pointcloud"]["frame"] == by_key["heatmap"]["frame"] == state.frame
    assert by_key["status"]["frame"] == state.frame


class _Payload(bytes):
    def to_bytes(self) -> bytes:
        return bytes(self)


def _sample(key: str, payload: bytes, kind=zenoh.SampleKind.PUT) -> argparse.Namespace:
    """What the inbox reads of a zenoh.Sample."""
    return argparse.Namespace(key_expr=key, payload=_Payload(payload), kind=kind)


def test_the_inbox_keeps_a_bounded_backlog_and_counts_what_it_drops():
    """A flood faster than radar-echo prints is dropped beyond the backlog and counted per key
    (one warning per key and batch), and a payload over its kind's bound is never copied."""
    inbox = radar_echo._Inbox(backlog=3)
    receive = inbox.receiver("odom")
    for i in range(5):
        receive(_sample("radar/awr1843/odom", b"%d" % i))
    big = bytes(messages.MAX_JSON_BYTES + 1)
    inbox.receiver("status")(_sample("radar/awr1843/status", big))
    assert [inbox.get(0.1)[2] for _ in range(3)] == [b"0", b"1", b"2"]
    assert inbox.take_dropped() == {"radar/awr1843/odom": 2, "radar/awr1843/status": 1}
    assert inbox.take_dropped() == {}
    inbox.receiver("status")(_sample("radar/awr1843/status", big))
    assert inbox.get(0.1) == ("status", "radar/awr1843/status", None, messages.MAX_JSON_BYTES + 1)
    inbox.receiver("odom")(_sample("radar/awr1843/odom", b"", zenoh.SampleKind.DELETE))
    assert inbox.get(0.1) == ("odom", "radar/awr1843/odom", radar_echo.DELETED, 0)


def test_the_no_peer_hint_is_given_only_when_nothing_came():
    # Two listeners at once: one no peer ever reaches, one a peer reaches with malformed messages
    # and leaves before the hint's time (5 s): only the first is told that no peer was reached.
    alone, visited = free_endpoint(), free_endpoint()
    procs = [subprocess.Popen(ECHO + ["--listen", endpoint, "odom"], stdin=subprocess.DEVNULL,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for endpoint in (alone, visited)]
    try:
        with peer(connect=[visited]) as session:
            publisher = session.declare_publisher("radar/awr1843/odom")
            deadline = time.monotonic() + 4
            while time.monotonic() < deadline:
                publisher.put(b'{"schema": "radarodom/odom", "version": 1}')
                time.sleep(0.2)
        time.sleep(radar_echo._QUIET_HINT_S + 2 - 4)
        for proc in procs:
            proc.send_signal(signal.SIGINT)
        errs = [proc.communicate(timeout=30)[1] for proc in procs]
    finally:
        for proc in procs:
            proc.kill()
    assert [proc.returncode for proc in procs] == [0, 0], errs
    # It said 'is radar-capture publishing on this machine? (otherwise give --connect ...)', which
    # a listener need not do: it is told what its publisher needs.
    assert f"no Zenoh peer has connected yet to {alone}: give the publisher --connect {alone}" in errs[0], errs[0]
    assert "ignored a malformed message" in errs[1], errs[1]
    assert "no Zenoh peer" not in errs[1], errs[1]


@pytest.mark.parametrize("options, hint", [
    (ZenohOptions(), "is radar-capture publishing on this machine? (otherwise give --connect with its endpoint)"),
    (ZenohOptions(connect=["tcp/10.0.0.5:7447"]),
     "no Zenoh peer reached yet at tcp/10.0.0.5:7447: is a publisher listening there "
     "(radar-capture --listen tcp/10.0.0.5:7447)?"),
    (ZenohOptions(listen=["tcp/0.0.0.0:7447"]),
     "no Zenoh peer has connected yet to tcp/0.0.0.0:7447: give the publisher --connect tcp/THIS_MACHINE:7447"),
    # (hunt 4: it said "give the publisher --connect tcp/127.0.0.1:0", which --connect refuses)
    (ZenohOptions(listen=["tcp/127.0.0.1:0"]),
     "no Zenoh peer has connected yet to tcp/127.0.0.1:0: port 0 takes a free port the publisher cannot know; "
     "listen on a port of your own (e.g. tcp/127.0.0.1:7450) and give the publisher --connect to it"),
])
def test_the_no_peer_hint_says_where_this_session_looks(options, hint):
    # With --connect given it still said 'otherwise give --connect with its endpoint'.
    assert hint in radar_echo._no_peer_hint(options.for_subscriber())
