"""The whole tidemo path with radar-capture, no hardware: the fake AWR1843's CLI and demo data port
on ptys (this process), radar-capture in its own process giving odometry, points, heatmaps and
Zenoh messages (a private loopback port), with the line's noise, cut packets and lost bytes
counted; a recorded stream replayed through radar-capture gives the same odometry."""

from __future__ import annotations

import os

import numpy as np
import pytest
from test_cli_capture import run_capture_cli
from zenoh_helpers import Inbox, free_endpoint, peer, wait_for

from radarodom import messages
from radarodom.cfg import RadarConfig
from radarodom.driver import open_source
from radarodom.driver.emulators.fake_demo_uart import DemoUartRig, UartFaults
from radarodom.estimator.config import EstimatorConfig
from radarodom.pipeline import Pipeline, TumSink, source_estimator
from radarodom.tum import read_tum

from tidemo_helpers import TIDEMO_CFG

FRAMES = 20


@pytest.fixture
def cfg_file(tmp_path):
    path = tmp_path / "tidemo.cfg"
    path.write_text(TIDEMO_CFG)
    return path


def test_radar_capture_on_tidemo_gives_odometry_points_heatmaps_and_messages(tmp_path, cfg_file):
    faults = UartFaults(garbage=0.2, truncate=0.1, drop=0.1, seed=3)
    here = free_endpoint()
    with DemoUartRig("sim://corridor", faults=faults, boot_time_s=0.05) as rig, peer(listen=[here]) as session:
        inbox = Inbox()
        sub = session.declare_subscriber("test/tidemo/**", inbox)
        try:
            # max_points=0: the UART budget checked for no point a frame, which every frame with one exceeds.
            proc = run_capture_cli("--source", rig.url(max_points=0), "--cfg", cfg_file, "--frames", FRAMES,
                                   "--odom-out", tmp_path / "odom.tum", "--points-out", tmp_path / "points.csv",
                                   "--heatmap-out", tmp_path / "heatmaps", "--key-prefix", "test/tidemo",
                                   "--connect", here, "--listen", free_endpoint(), timeout=300)
            assert proc.returncode == 0, proc.stderr
            assert wait_for(lambda: sum(k.endswith("/odom") for k, _, _, _ in inbox.samples) >= FRAMES, 10.0)
        finally:
            sub.undeclare()
        truth = rig.data.stats
    assert f"radar-capture: {FRAMES} frames (0 incomplete, 0 bytes missing)" in proc.stdout
    assert "Traceback" not in proc.stderr
    damaged = len(truth.truncated) + len(truth.dropped)
    assert damaged, "the seed must damage packets"
    # The line's damage is counted where the user sees it (the source's closing line).
    assert "frames from the demo;" in proc.stderr and "packets rejected" in proc.stderr
    assert "packets with more points than max_points=0" in proc.stderr
    assert " over max_points=0 (the UART budget's; give a larger one)" in proc.stdout, proc.stdout
    odom = read_tum(str(tmp_path / "odom.tum"))
    assert len(odom.times) == FRAMES and np.all(np.diff(odom.times) > 0)
    intensity = sorted(n for n in os.listdir(tmp_path / "heatmaps") if n.endswith("_intensity.npy"))
    assert len(intensity) == FRAMES
    hm = np.load(tmp_path / "heatmaps" / intensity[0])
    assert hm.ndim == 2 and hm.shape[1] == 64 and hm.max() > 0
    assert (tmp_path / "points.csv").read_text().startswith("frame,")
    kinds = {key.rsplit("/", 1)[1] for key, _, _, _ in inbox.samples}
    assert {"odom", "pointcloud", "heatmap", "status"} <= kinds
    odom_msgs = [messages.parse_odometry(p) for k, _, p, _ in inbox.samples if k.endswith("/odom")]
    assert [m["t"] for m in odom_msgs] == pytest.approx(list(odom.times), abs=1e-6)


@pytest.mark.parametrize("user_settings", [False, True], ids=["the source's preset", "--estimator-config"])
def test_a_recorded_tidemo_stream_replays_through_radar_capture_to_the_same_odometry(tmp_path, cfg_file,
                                                                                       user_settings):
    """Recorded live (the source's recorder sink, odometry by the same pipeline), then played with
    radar-capture --source replay://DIR: the same trajectory, line for line; radar-capture takes the
    source's estimator preset (EstimatorConfig.tidemo()) unless --estimator-config says otherwise."""
    cfg = RadarConfig.from_file(cfg_file)
    rec, live_tum = tmp_path / "rec", tmp_path / "live.tum"
    with DemoUartRig("sim://corridor", boot_time_s=0.05) as rig:
        with open_source(rig.url(), cfg) as source:
            estimator = EstimatorConfig() if user_settings else source_estimator(source)
            assert estimator.point_yaw.use != user_settings
            sinks = [source.recorder(str(rec)), TumSink(str(live_tum))]
            with Pipeline(source, estimator=estimator, sinks=sinks, max_frames=FRAMES) as pipe:
                pipe.run()
    options = []
    if user_settings:
        EstimatorConfig().dump(tmp_path / "default.json")
        options = ["--estimator-config", tmp_path / "default.json"]
    proc = run_capture_cli("--source", f"replay://{rec}?rate=max", "--no-publish", "--odom-out",
                           tmp_path / "replay.tum", *options, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert f"radar-capture: {FRAMES} frames" in proc.stdout
    assert (tmp_path / "replay.tum").read_text() == live_tum.read_text()


def test_radar_capture_records_a_tidemo_stream_that_replays_to_the_same_odometry(tmp_path, cfg_file):
    """--record on tidemo:// keeps the UART packets (the source's recorder, not raw ADC frames), the
    line's damage is in the closing line, and the recording replays through radar-capture to the
    live run's trajectory; a replay records itself too (its first frames)."""
    faults = UartFaults(garbage=0.2, truncate=0.1, drop=0.1, seed=5)
    with DemoUartRig("sim://corridor", faults=faults, boot_time_s=0.05) as rig:
        proc = run_capture_cli("--source", rig.url(), "--cfg", cfg_file, "--frames", 8, "--no-publish",
                               "--record", tmp_path / "rec", "--odom-out", tmp_path / "live.tum", timeout=300)
        truth = rig.data.stats
    assert proc.returncode == 0, proc.stderr
    assert "; recorded to " in proc.stdout and "frame numbers skipped, " in proc.stdout
    assert len(truth.truncated) + len(truth.dropped), "the seed must damage packets"
    rec = tmp_path / "rec"
    assert sorted(os.listdir(rec)) == ["capture.json", "radar.cfg", "timestamps.txt", "uart.bin"]
    replay = run_capture_cli("--source", f"replay://{rec}?rate=max", "--no-publish", "--odom-out",
                             tmp_path / "replay.tum", "--record", tmp_path / "again", "--frames", 8, timeout=300)
    assert replay.returncode == 0, replay.stderr
    assert "radar-capture: 8 frames" in replay.stdout and "0 packets rejected, 0 bytes discarded" in replay.stdout
    assert (tmp_path / "replay.tum").read_text() == (tmp_path / "live.tum").read_text()
    assert (tmp_path / "again" / "uart.bin").read_bytes() == (rec / "uart.bin").read_bytes()
    # --overwrite replaces the recording, its uart.bin too, and leaves the directory's other files.
    (tmp_path / "again" / "notes.txt").write_text("mine")
    over = run_capture_cli("--source", f"replay://{rec}?rate=max", "--no-publish", "--record", tmp_path / "again",
                           "--frames", 4, "--overwrite", timeout=300)
    assert over.returncode == 0, over.stderr
    assert sorted(os.listdir(tmp_path / "again")) == ["capture.json", "notes.txt", "radar.cfg", "timestamps.txt",
                                                      "uart.bin"]
    shorter = (tmp_path / "again" / "uart.bin").read_bytes()
    assert 0 < len(shorter) < len((rec / "uart.bin").read_bytes())
    assert (rec / "uart.bin").read_bytes().startswith(shorter)
    assert (rec / "timestamps.txt").read_text().startswith((tmp_path / "again" / "timestamps.txt").read_text())
