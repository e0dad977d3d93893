"""radar-capture --mcap, --odom-json and --mount as a user runs them: any recording converts (a
capture directory replayed at full speed, a ColoRadar run), a recording killed with SIGKILL stays
readable up to its last chunk, and the options' refusals (an existing file, --odom-json without
the estimator, a bad mount).  Runs whose subject is the program's answer call its main() in this
process (``capture_main``: conftest's run_main); the installed console script runs in a
subprocess where the process matters (SIGKILL, a file size limit) and once as the end-to-end check
of the script (a bad --ros2-topic)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import time
from collections import Counter

import pytest
from conftest import console_command

pytest.importorskip("rosbags.typesys")
mcap_reader = pytest.importorskip("mcap.reader")
mcap_ros2_decoder = pytest.importorskip("mcap_ros2.decoder")
from mcap.exceptions import EndOfFile  # noqa: E402
from mcap.records import Channel, Message, Schema  # noqa: E402
from mcap.stream_reader import StreamReader  # noqa: E402

from coloradar_synth import write_run  # noqa: E402

CAPTURE = console_command("radar-capture")


def capture(*args, timeout=300, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run(CAPTURE + [str(a) for a in args] + ["--no-publish", "-q"], stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=timeout, cwd=cwd)


def topics(path) -> dict[str, list]:
    """Decoded messages by topic (mcap-ros2-support), from a complete file."""
    out: dict[str, list] = {}
    with open(path, "rb") as fh:
        reader = mcap_reader.make_reader(fh, validate_crcs=True, decoder_factories=[mcap_ros2_decoder.DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages():
            out.setdefault(channel.topic, []).append(msg)
    return out


@pytest.fixture
def capture_main(run_main):
    """``capture_main(*args)``: capture()'s run (the same argv) made in this process, with
    radar-capture's main() (conftest's run_main); a CompletedProcess."""
    return lambda *args: run_main("radar-capture", *args, "--no-publish", "-q")


@pytest.fixture(scope="module")
def corridor(tmp_path_factory):
    """A capture directory of the simulated corridor (1 s, with its ground truth), at the
    simulator's fast fidelity (what the tests count and compare is the replay against itself)."""
    out = tmp_path_factory.mktemp("rec") / "corridor"
    subprocess.run(console_command("radar-sim") + ["corridor", "--duration", "1", "--fidelity", "fast", "--out",
                                                   str(out), "-q"],
                   check=True, timeout=300, stdin=subprocess.DEVNULL)
    return out


def test_a_recording_converts_at_full_speed_with_the_mount_and_the_odometry_lines(corridor, tmp_path, capture_main):
    out, lines = tmp_path / "run.mcap", tmp_path / "odom.jsonl"
    proc = capture_main("--source", f"replay://{corridor}?rate=max", "--mcap", out, "--odom-json", lines,
                        "--mount", "0.3,0,0.2,90")
    assert proc.returncode == 0, proc.stderr
    assert f"; ROS 2 bag {out}" in proc.stdout  # the summary names the bag it wrote
    assert f"; odometry messages in {lines}; " in proc.stdout, proc.stdout
    frames = len((corridor / "timestamps.txt").read_text().split())
    got = topics(out)
    assert {k: len(v) for k, v in got.items() if k != "/diagnostics"} == {
        "/tf_static": 1, "/radar/odom": frames, "/tf": frames, "/radar/points": frames, "/radar/heatmap": frames,
        "/radar/heatmap/axes": frames, "/radar/groundtruth": frames}
    mount = got["/tf_static"][0].transforms[0].transform
    assert (mount.translation.x, mount.translation.y, mount.translation.z) == (0.3, 0.0, 0.2)
    assert 2 * math.atan2(mount.rotation.z, mount.rotation.w) == pytest.approx(math.pi / 2)
    odometry = [json.loads(line) for line in lines.read_text().splitlines()]
    assert [o["frame"] for o in odometry] == list(range(frames))
    assert [o["t"] for o in odometry] == pytest.approx([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
                                                        for m in got["/radar/odom"]], abs=1e-9)

    # Outputs are never overwritten unasked; --overwrite replaces both.
    out.write_bytes(b"mine")
    proc = capture_main("--source", f"replay://{corridor}?rate=max", "--mcap", out, "--frames", "2")
    assert proc.returncode == 2 and "already exists" in proc.stderr and "Traceback" not in proc.stderr
    assert out.read_bytes() == b"mine"
    proc = capture_main("--source", f"replay://{corridor}?rate=max", "--mcap", out, "--odom-json", lines,
                        "--frames", "2", "--overwrite")
    assert proc.returncode == 0, proc.stderr
    assert len(topics(out)["/radar/odom"]) == 2 and len(lines.read_text().splitlines()) == 2


def test_an_offline_conversion_names_the_odometry_topic(corridor, tmp_path, capture_main):
    # --ros2-topic names the bag's odometry topic with --no-publish too (it was refused as a
    # publishing option); a topic that is not a ROS name is refused before anything is written.
    out = tmp_path / "run.mcap"
    proc = capture_main("--source", f"replay://{corridor}?rate=max", "--mcap", out, "--ros2-topic", "/robot/radar_odom",
                        "--frames", "3")
    assert proc.returncode == 0, proc.stderr
    got = topics(out)
    assert len(got["/robot/radar_odom"]) == 3 and "/radar/odom" not in got
    bad = tmp_path / "bad.mcap"
    # A subprocess on purpose: the file's end-to-end check of the installed console script.
    proc = capture("--source", f"replay://{corridor}?rate=max", "--mcap", bad, "--ros2-topic", "radar odom")
    assert proc.returncode == 2 and "argument --ros2-topic: ROS 2 topic must be an absolute ROS name" in proc.stderr
    assert not bad.exists()
    proc = capture_main("--source", f"replay://{corridor}?rate=max", "--mcap", bad, "--ros2-topic", "/tf")
    assert proc.returncode == 2 and "/tf is one of radarodom's other topics" in proc.stderr and not bad.exists()
    proc = capture_main("--source", f"replay://{corridor}?rate=max", "--ros2-topic", "/robot/radar_odom")
    assert proc.returncode == 2 and "--ros2-topic is about publishing over Zenoh" in proc.stderr  # no bag: no use


def test_a_coloradar_run_converts(tmp_path, capture_main):
    run = write_run(tmp_path, "ec_hallways_run0", frames=6)
    out = tmp_path / "run.mcap"
    proc = capture_main("--source", f"coloradar://{run}?rate=max", "--mcap", out,
                        "--odom-json", tmp_path / "odom.jsonl")
    assert proc.returncode == 0, proc.stderr
    got = topics(out)
    states = len((tmp_path / "odom.jsonl").read_text().splitlines())
    assert states >= 2 and len(got["/radar/odom"]) == len(got["/tf"]) == states
    assert got["/radar/points"] and got["/radar/heatmap"] and got["/radar/groundtruth"]
    assert {m.header.frame_id for m in got["/radar/points"]} == {"radar"}


def test_a_recording_killed_with_sigkill_reads_back_up_to_its_last_chunk(corridor, tmp_path):
    out = tmp_path / "run.mcap"
    proc = subprocess.Popen(CAPTURE + ["--source", f"replay://{corridor}?rate=max&loop=0", "--mcap", str(out),
                                       "--no-publish", "-q"], stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 300  # a hang guard, not a speed limit
        while not (out.exists() and out.stat().st_size > (2 << 20)):  # two chunks or more on disk
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline, "no chunks written"
            time.sleep(0.2)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=60)
        proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    # No summary and no end magic: the indexed reader refuses, a reader that scans takes every
    # whole chunk, in order, and stops at the cut.
    with open(out, "rb") as fh, pytest.raises(Exception):
        mcap_reader.make_reader(fh).get_summary()
    schemas, channels, found = {}, {}, []
    with open(out, "rb") as fh:
        with pytest.raises(EndOfFile):
            for record in StreamReader(fh, validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    found.append(record)
    factory = mcap_ros2_decoder.DecoderFactory()
    by_topic = Counter()
    frames = []
    for message in found:
        channel = channels[message.channel_id]
        # Every message decodes with its own schema (the decoder raises otherwise).
        factory.decoder_for(channel.message_encoding, schemas[channel.schema_id])(message.data)
        by_topic[channel.topic] += 1
        if channel.topic == "/radar/odom":
            frames.append(message.log_time)
    assert by_topic["/tf_static"] == 1 and by_topic["/radar/odom"] >= 20
    assert by_topic["/radar/odom"] == by_topic["/radar/points"] == by_topic["/radar/heatmap"]
    assert frames == sorted(frames) and frames[0] == 0 and len(set(frames)) == len(frames)


@pytest.mark.parametrize("args, message", [
    (["--no-odom", "--odom-json", "x.jsonl"], "--no-odom turns the estimator off"),
    (["--mount", "0.3,0,0"], "a mount is x,y,z,yaw_deg"),
    (["--mount", "0.3,0,0,nan"], "mount yaw_deg"),
])
def test_refusals_name_the_option(tmp_path, args, message, capture_main, monkeypatch):
    monkeypatch.chdir(tmp_path)  # where the relative x.jsonl would go, as for a run started there
    proc = capture_main("--source", "sim://corridor?rate=max&duration=0.2", *args)
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "x.jsonl").exists()


@pytest.mark.skipif(not hasattr(signal, "SIGXFSZ"), reason="needs a POSIX file-size limit to make the write fail")
def test_a_bag_that_cannot_be_written_on_says_what_it_keeps(tmp_path):
    # A full disk (here the process's file-size limit): the error said "cannot write" and no more.
    import resource

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (900_000, 900_000))  # past the first chunks

    out = tmp_path / "full.mcap"
    proc = subprocess.run(CAPTURE + ["--source", "sim://corridor?rate=max&duration=6&fidelity=fast", "--mcap", str(out),
                                     "--no-publish", "-q"], capture_output=True, text=True, timeout=300,
                          preexec_fn=small_files)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert f"cannot write {out}: File too large; the chunks written before it are kept" in proc.stderr, proc.stderr
    assert proc.stderr.count("cannot write") == 1, proc.stderr  # not again at the close
    messages = 0
    with open(out, "rb") as fh:
        with pytest.raises(EndOfFile):
            for record in StreamReader(fh, validate_crcs=True).records:
                messages += isinstance(record, Message)
    assert messages > 0


def test_a_recording_past_2038_is_one_error_line_and_the_summary_has_no_empty_latency(tmp_path, capture_main):
    """ROS 2 counts a stamp's seconds in 32 bits: a recording whose clock is past 2038 was an
    internal error (rosbags' "'i' format requires ..."), and the summary of a run whose first
    frame's outputs failed said "latency p50 nan ms".  Such a recording is now refused before any
    output opens, naming its times; a loop's later pass that crosses 2038 mid-run is one line."""
    from conftest import SMALL_CFG, make_capture
    from radarodom.cfg import RadarConfig

    rec = tmp_path / "rec"
    make_capture(rec, RadarConfig.from_text(SMALL_CFG, "small.cfg"), 3, t0=3e9)
    proc = capture_main("--source", f"replay://{rec}?rate=max", "--mcap", tmp_path / "run.mcap")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    assert proc.stderr.strip().splitlines() == [
        f"radar-capture: error: {rec / 'timestamps.txt'}: the frames' times run from 3000000000.000 s to "
        "3000000000.100 s, and a ROS 2 stamp holds 0 to 2147483647 s (a node's time is never negative; its seconds are 32-bit): shift the "
        "times into that range, or leave out --mcap"], proc.stderr
    assert not (tmp_path / "run.mcap").exists()
    late = tmp_path / "late"
    make_capture(late, RadarConfig.from_text(SMALL_CFG, "small.cfg"), 3, t0=2**31 - 0.12)
    proc = capture_main("--source", f"replay://{late}?rate=max&loop=2", "--mcap", tmp_path / "late.mcap")
    assert proc.returncode == 1 and "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    assert [line for line in proc.stderr.strip().splitlines() if "error" in line] == [
        "radar-capture: error: ROS 2 stamp: time 2147483648.03 s is beyond what ROS 2's time holds (its seconds "
        "are a 32-bit integer: up to 2147483647 s, 2038-01-19)"], proc.stderr
    assert "stopped by an error" in proc.stdout and "nan" not in proc.stdout, proc.stdout
    assert f"; ROS 2 bag {tmp_path / 'late.mcap'}" in proc.stdout, proc.stdout  # (hunt 4: left out after an error)