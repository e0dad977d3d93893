"""The live view (radarodom.view, ``radar-capture --view``): what it draws, read back from its
.rrd with Rerun's own reader and compared with what the pipeline wrote elsewhere; that a slow or
failing view drops only its own frames; the option's checks.

Rerun's analytics are off for every test here: Rerun reads them from
``$XDG_CONFIG_HOME/rerun/analytics.json`` (no environment variable turns them off), so the tests
point XDG_CONFIG_HOME at a directory of their own where ``rerun analytics disable`` has run.
"""

from __future__ import annotations

import collections
import json
import logging
import math
import os
import signal
import socket
import re
import subprocess
import sys
import threading
import warnings

import numpy as np
import pytest

from conftest import make_capture

rr = pytest.importorskip("rerun", reason='the view needs rerun-sdk (pip install "radarodom[view]")')
from rerun.chunk import RrdReader  # noqa: E402

from radarodom.errors import CaptureError  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.pipeline import Pipeline, TumSink  # noqa: E402
from radarodom.tum import read_tum  # noqa: E402
from radarodom.view import ThreadDrawer, ViewSink, ViewTarget, open_view  # noqa: E402
from radarodom.view.scene import Scene  # noqa: E402
from radarodom.view.target import viewer_missing  # noqa: E402

RADAR = "/world/odom/base_link/radar"
#: Generous hang guard, s.
GUARD_S = 120.0


@pytest.fixture(scope="module", autouse=True)
def rerun_analytics_off(tmp_path_factory):
    """XDG_CONFIG_HOME of the tests' own, with Rerun's analytics disabled (by Rerun's CLI)."""
    config = tmp_path_factory.mktemp("xdg_config")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_CONFIG_HOME", str(config))
        # rerun_cli: the same CLI as `python -m rerun`, without importing the SDK first (Rerun's advice).
        subprocess.run([sys.executable, "-m", "rerun_cli", "analytics", "disable"], capture_output=True,
                       timeout=GUARD_S, check=True)
        assert json.loads((config / "rerun" / "analytics.json").read_text())["analytics_enabled"] is False
        yield config


def rows(path) -> dict[str, list[dict]]:
    """Every temporal row of the .rrd at *path*, by entity, in frame order (static rows under
    "static:ENTITY")."""
    out: dict[str, list[dict]] = collections.defaultdict(list)
    for chunk in RrdReader(str(path)).store().stream().to_chunks():
        key = ("static:" if chunk.is_static else "") + chunk.entity_path
        out[key] += chunk.to_record_batch().to_pylist()
    for key, found in out.items():
        if not key.startswith("static:"):
            found.sort(key=lambda row: row["frame"])
    return out


def saving(scene: Scene, path, **kwargs) -> ThreadDrawer:
    """*scene* drawn into the .rrd *path*, in a thread of this process."""
    scene.rec.save(str(path))
    return ThreadDrawer(scene, **kwargs)


class HeldScene(Scene):
    """A view whose drawing of frames waits until *release* is set: a viewer that stopped taking
    data while the radar goes on."""

    def __init__(self, *args, release: threading.Event, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.release = release

    def frame(self, track, points, heatmap) -> None:
        assert self.release.wait(GUARD_S), "hang guard"
        super().frame(track, points, heatmap)


class FailingScene(Scene):
    def frame(self, track, points, heatmap) -> None:
        if track.frame == 3:
            raise ValueError("a drawing bug")
        super().frame(track, points, heatmap)


@pytest.fixture
def capture(tmp_path, small_cfg) -> str:
    """30 frames of the small cfg with true poses, as a replay URL at full speed."""
    make_capture(tmp_path / "src", small_cfg, 30, poses=True, seed=5)
    return f"replay://{tmp_path / 'src'}?rate=max"


def test_a_slow_view_drops_only_its_own_frames(tmp_path, capture):
    """The view stops taking frames after the first; the pipeline runs all 30 frames to every
    output, the view's queue (4) fills and the rest of its frames are dropped and counted; the
    view's trajectory and time series still hold every frame."""
    release = threading.Event()
    estimator = EstimatorConfig()
    scene = HeldScene(rr.RecordingStream("radarodom-test"), estimator=estimator, release=release)
    view = ViewSink(saving(scene, tmp_path / "slow.rrd", queue_frames=4), close_timeout_s=GUARD_S)
    seen = []

    def on_frame(result, stats):
        seen.append(result.frame.index)
        if stats.frames == 30:
            release.set()  # the viewer wakes up once the radar is done

    with Pipeline.from_url(capture, estimator=estimator, sinks=[TumSink(tmp_path / "odom.tum"), view]) as pipe:
        stats = pipe.run(on_frame)
    assert stats.frames == 30 and seen == list(range(30))
    assert len(read_tum(tmp_path / "odom.tum")) == 30
    assert view.offered == 30
    assert view.drawn in (4, 5)  # the frame being drawn, and the queue's
    assert view.drawn + view.dropped == 30
    assert f"{view.drawn} frames drawn, {view.dropped} dropped (the view fell behind the radar)" == view.summary
    found = rows(tmp_path / "slow.rrd")
    assert [r["frame"] for r in found["/plots/time_ms"]] == list(range(30))
    assert [r["frame"] for r in found["/world/odom/base_link"]] == list(range(30))
    assert len(found[RADAR + "/points"]) == view.drawn
    assert len(found["/heatmap/polar"]) == view.drawn
    notes = [r["TextLog:text"][0] for r in found["/log/view"]]
    assert notes and notes[-1].endswith("frames not drawn so far: the view fell behind")


def test_a_view_that_takes_nothing_keeps_a_bounded_number_of_tracks(tmp_path, capture, monkeypatch):
    """Tracks wait for the view at most MAX_TRACKS frames (here 10): the oldest go, counted."""
    from radarodom.view import sink as view_sink

    monkeypatch.setattr(view_sink, "MAX_TRACKS", 10)
    release = threading.Event()
    estimator = EstimatorConfig()
    scene = HeldScene(rr.RecordingStream("radarodom-test"), estimator=estimator, release=release)
    view = ViewSink(saving(scene, tmp_path / "bounded.rrd", queue_frames=1), close_timeout_s=GUARD_S)

    def on_frame(result, stats):
        if stats.frames == 30:
            release.set()

    with Pipeline.from_url(capture, estimator=estimator, sinks=[view]) as pipe:
        assert pipe.run(on_frame).frames == 30
    assert view.drawn in (1, 2) and view.drawn + view.dropped == 30
    found = [r["frame"] for r in rows(tmp_path / "bounded.rrd")["/plots/time_ms"]]
    assert len(found) == 30 - view.tracks_dropped and found[-10:] == list(range(20, 30))
    assert view.summary.startswith(f"{view.drawn} frame") and \
        f", {view.tracks_dropped} missing from its trajectory and time series" in view.summary


def test_a_failing_view_stops_drawing_not_the_radar(tmp_path, capture, warnings_log):
    estimator = EstimatorConfig()
    view = ViewSink(saving(FailingScene(rr.RecordingStream("radarodom-test"), estimator=estimator),
                           tmp_path / "failing.rrd"))
    with Pipeline.from_url(capture, estimator=estimator, sinks=[TumSink(tmp_path / "odom.tum"), view]) as pipe:
        stats = pipe.run()
    assert stats.frames == 30 and len(read_tum(tmp_path / "odom.tum")) == 30
    assert view.drawn == 3 and view.dropped == 27
    assert view.summary == "3 frames drawn, 27 dropped (the view failed: ValueError: a drawing bug)"
    assert any(r.getMessage() == "the view failed: ValueError: a drawing bug; it stopped drawing"
               for r in warnings_log.records)
    assert len(rows(tmp_path / "failing.rrd")[RADAR + "/points"]) == 3  # what was drawn is kept


def test_a_viewer_that_stops_reading_holds_up_neither_the_radar_nor_its_end(tmp_path, capture):
    """``connect:`` to a host that accepts the connection and never reads: Rerun's last flush
    waits for it for good; the view's process is stopped after the close timeout, the pipeline
    and its other outputs have every frame, and the summary says what happened."""
    import socket
    import time

    with socket.socket() as deaf:
        deaf.bind(("127.0.0.1", 0))
        deaf.listen()
        held = []
        threading.Thread(target=lambda: held.append(deaf.accept()), daemon=True).start()
        estimator = EstimatorConfig()
        view = open_view(ViewTarget("connect", address=f"127.0.0.1:{deaf.getsockname()[1]}"), estimator=estimator,
                         close_timeout_s=2.0)
        assert view.where == f"the Rerun viewer at rerun+http://127.0.0.1:{deaf.getsockname()[1]}/proxy"
        started = time.monotonic()
        with Pipeline.from_url(capture, estimator=estimator, sinks=[TumSink(tmp_path / "odom.tum"), view]) as pipe:
            stats = pipe.run()
        assert time.monotonic() - started < GUARD_S
    assert stats.frames == 30 and len(read_tum(tmp_path / "odom.tum")) == 30
    assert view.drawn + view.dropped == 30
    assert view.problem == "the viewer did not take the view's last data within 2 s"
    assert view.summary.endswith("(the viewer did not take the view's last data within 2 s)")


def test_the_view_draws_every_frame_in_the_body_and_odometry_frames(tmp_path, capture, small_cfg):
    """Drawn by a process of its own (as radar-capture's spawn and connect: views draw): points in
    REP-103 (x = TI y, y = -TI x), the base's pose as the estimator's, the ground truth aligned at
    the first frame, a row per frame of every per-frame entity."""
    from radarodom.pipeline import PointsCsvSink

    estimator = EstimatorConfig()
    view = open_view(ViewTarget("save", path=str(tmp_path / "run.rrd")), estimator=estimator, process=True)
    assert view.where == f"{tmp_path / 'run.rrd'} (open it with: rerun {tmp_path / 'run.rrd'})"
    sinks = [PointsCsvSink(tmp_path / "points.csv"), TumSink(tmp_path / "odom.tum"), view]
    with Pipeline.from_url(capture, estimator=estimator, sinks=sinks) as pipe:
        pipe.run()
    assert view.finished and view.drawn + view.dropped == 30
    found = rows(tmp_path / "run.rrd")
    _check_points_against_csv(found, tmp_path / "points.csv")
    _check_poses_against_tum(found, tmp_path / "odom.tum")
    truth = found["/world/odom/groundtruth/pose"]
    assert len(truth) == 30
    # The capture's true poses move 0.1 m ahead per frame from x = 0: aligned at the first one.
    np.testing.assert_allclose([r["Transform3D:translation"][0] for r in truth],
                               [(0.1 * i, 0.0, 0.0) for i in range(30)], atol=1e-9)
    speeds = [r["Scalars:scalars"] for r in found["/plots/speed"]]
    assert math.isnan(speeds[0][1])
    np.testing.assert_allclose([s[1] for s in speeds[1:]], 0.1 / small_cfg.frame_period_s, rtol=1e-6)
    for entity in ("/plots/speed", "/plots/yaw_rate", "/plots/counts", "/plots/time_ms", RADAR + "/features"):
        assert len(found[entity]) == (30 if entity.startswith("/plots") else view.drawn), entity
    assert "static:" + RADAR + "/fov" in found and "static:/world" in found


def _check_points_against_csv(found, csv_path) -> None:
    table = np.genfromtxt(csv_path, delimiter=",", names=True)
    drawn = found[RADAR + "/points"]
    assert drawn
    for row in drawn:
        mine = table[table["frame"] == row["frame"]]
        got = np.array(row["Points3D:positions"], float).reshape(-1, 3)
        assert len(got) == len(mine)
        np.testing.assert_allclose(got, np.column_stack([mine["y"], -mine["x"], mine["z"]]), atol=1e-4)


def _check_poses_against_tum(found, tum_path) -> None:
    tum = read_tum(tum_path)
    base = found["/world/odom/base_link"]
    assert len(base) == len(tum)
    np.testing.assert_allclose([r["Transform3D:translation"][0][:2] for r in base], tum.positions[:, :2], atol=1e-9)


# ---------------------------------------------------------------------------- radar-capture --view
def capture_main(argv, capsys) -> tuple[int, str, str]:
    from radarodom.tools import radar_capture

    rc = radar_capture.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def test_quiet_keeps_the_view_to_the_summary(tmp_path, capsys):
    """-q: only errors and the summary (docs/cli.md); the summary still names the view's frames."""
    rrd = tmp_path / "run.rrd"
    rc, out, err = capture_main(["--source", "sim://corridor?rate=max&fidelity=fast&duration=0.3", "--no-publish",
                                 "-q", "--view", f"save:{rrd}"], capsys)
    assert rc == 0, err
    assert "view:" not in err, err
    assert re.search(r"; view: \d+ frames drawn", out), out


def test_radar_capture_saves_a_simulated_run_that_reads_back(tmp_path, capsys):
    """``--view save:FILE.rrd`` on the simulator: every frame's points (as --points-out writes
    them, in REP-103), the odometry (as --odom-out), the ground truth and the time series."""
    rrd = tmp_path / "run.rrd"
    rc, out, err = capture_main(["--source", "sim://corridor?rate=max&fidelity=fast&duration=0.5", "--no-publish",
                                 "--view", f"save:{rrd}", "--points-out", tmp_path / "points.csv",
                                 "--odom-out", tmp_path / "odom.tum"], capsys)
    assert rc == 0, err
    assert f"radar-capture: view: {rrd} (open it with: rerun {rrd})" in err
    drawn, dropped = map(int, re.search(r"; view: (\d+) frames drawn, (\d+) dropped", out).groups())
    assert "5 frames" in out and drawn + dropped == 5
    found = rows(rrd)
    _check_points_against_csv(found, tmp_path / "points.csv")
    _check_poses_against_tum(found, tmp_path / "odom.tum")
    assert len(found[RADAR + "/points"]) == len(found["/heatmap/polar"]) == drawn
    for entity in ("/plots/time_ms", "/plots/counts", "/world/odom/base_link", "/world/odom/groundtruth/pose"):
        assert [r["frame"] for r in found[entity]] == list(range(5)), entity
    image = found["/heatmap/polar"][0]
    width, height = image["Image:format"][0]["width"], image["Image:format"][0]["height"]
    assert len(image["Image:buffer"][0]) == width * height * 3
    opened = found["static:/log/opened"][0]["TextLog:text"][0]
    assert opened == f"radarodom's view, sent to {rrd} (open it with: rerun {rrd})"


@pytest.mark.parametrize("value, message", [
    ("web:abc", "argument --view: web:PORT takes a port number, got 'abc'"),
    ("web:65535", "the web viewer's port must be 1..65534 (its data uses the next), got 65535"),
    ("connect:", "connect: needs the viewer's HOST:PORT (or a rerun+http:// URL)"),
    ("connect:viewer", "a viewer's address is HOST:PORT or a rerun+http://HOST:PORT/proxy URL, got 'viewer'"),
    # (hunt 5: Rerun refused these in a thread of its own, a traceback, and the frames counted as drawn, exit 0)
    ("connect:http://127.0.0.1:9876", "got 'http://127.0.0.1:9876' (a viewer's gRPC address is no web page: give "
     "127.0.0.1:9876)"),
    ("connect:rerun://127.0.0.1:9876", "a rerun+http://HOST:PORT/proxy URL, got 'rerun://127.0.0.1:9876'"),
    ("connect:rerun+http://127.0.0.1:9876/bogus", "URL, got 'rerun+http://127.0.0.1:9876/bogus'"),
    ("connect:a b:9876", "a viewer's address 'a b:9876': 'a b' is not a host name or an IP address"),
    ("connect:256.1.1.1:9876", "a viewer's address '256.1.1.1:9876': 256.1.1.1 is not an IPv4 address"),
    ("connect:::1:9876", "a viewer's address '::1:9876': an IPv6 address goes in brackets, e.g. [::1]:9876"),
    ("save:", "save: needs a file name (FILE.rrd)"),
    ("spawn:now", "spawn:PORT takes a port number, got 'now'"),
    ("teleport", "expected spawn[:PORT], web[:PORT], connect:HOST:PORT or save:FILE.rrd, got 'teleport'"),
])
def test_bad_view_values_are_usage_errors(capture, capsys, value, message):
    rc, out, err = capture_main(["--source", capture, "--no-publish", "--view", value], capsys)
    assert rc == 2 and message in err and out == ""


def test_spawn_without_a_display_says_what_to_do_instead(capture, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    rc, out, err = capture_main(["--source", capture, "--no-publish", "--odom-out", tmp_path / "odom.tum",
                                 "--view"], capsys)
    assert rc == 2 and "no display" in err and "--view web[:PORT]" in err and "--view save:FILE.rrd" in err
    assert not (tmp_path / "odom.tum").exists()  # refused before anything opened


def test_spawn_reuses_the_viewer_listening_at_its_port_and_draws_every_frame(capture, tmp_path):
    """spawn[:PORT] with a display: Rerun's spawn reuses a viewer already listening at the port (here
    one that saves what it gets, the `rerun` command without a window) rather than start one.  Hunt
    5: every spawn failed with "the view could not open: TypeError: RecordingStream.spawn() got an
    unexpected keyword argument 'executable_path'" (the viewer's path goes to rerun.spawn)."""
    port = _free_port()
    received = tmp_path / "received.rrd"
    env = {**os.environ, "RERUN_ANALYTICS": "0", "DISPLAY": os.environ.get("DISPLAY") or ":99"}
    viewer = subprocess.Popen([sys.executable, "-m", "rerun_cli", "--port", str(port), "--save", str(received)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    try:
        assert viewer_missing(ViewTarget("connect", address=f"127.0.0.1:{port}"), wait_s=GUARD_S) is None
        proc = subprocess.run([sys.executable, "-m", "radarodom.tools.radar_capture", "--source", capture,
                               "--no-publish", "--view", f"spawn:{port}"], capture_output=True, text=True,
                              timeout=GUARD_S, env=env)
    finally:
        viewer.send_signal(signal.SIGINT)
        viewer.wait(GUARD_S)
    assert proc.returncode == 0, proc.stderr
    assert f"view: a Rerun viewer on this machine (port {port})" in proc.stderr, proc.stderr
    assert "view: 30 frames drawn, 0 dropped" in proc.stdout, proc.stdout
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Rerun's: an .rrd streamed to, without its footer, is read whole
        chunks = RrdReader(str(received)).stream().collect().stream().to_chunks()
        frames = {row["frame"] for chunk in chunks if chunk.entity_path == RADAR + "/points" and not chunk.is_static
                  for row in chunk.to_record_batch().to_pylist()}
    assert len(frames) == 30, sorted(frames)


@pytest.mark.parametrize("switch", ["off", "0", "False"])
def test_rerun_turned_off_by_the_environment_is_said_before_anything_opens(capture, tmp_path, capsys, monkeypatch,
                                                                          switch):
    # RERUN=off made Rerun drop everything: --view save: left an empty file and the run exited 0.
    monkeypatch.setenv("RERUN", switch)
    view = tmp_path / "view.rrd"
    rc, out, err = capture_main(["--source", capture, "--no-publish", "--view", f"save:{view}"], capsys)
    assert rc == 2 and f"the environment turns Rerun off (RERUN={switch})" in err and "unset RERUN" in err
    assert not view.exists()


def _taken_port_after_a_free_one():
    """A listening socket on a port whose port below is free (on a busy machine the one below an
    ephemeral port may be someone else's: then another pair is drawn)."""
    import socket

    for _ in range(50):
        taken = socket.socket()
        taken.bind(("0.0.0.0", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with socket.socket() as probe:
            try:
                probe.bind(("0.0.0.0", port - 1))
            except OSError:
                taken.close()
                continue
        return taken, port
    pytest.skip("no free port below a free ephemeral port in 50 draws")


def test_web_refuses_a_port_in_use(capture, capsys):
    taken, port = _taken_port_after_a_free_one()
    with taken:
        rc, _, err = capture_main(["--source", capture, "--no-publish", "--view", f"web:{port - 1}"], capsys)
    assert rc == 2 and f"port {port} is taken" in err


def test_an_existing_rrd_is_kept_unless_overwrite(capture, tmp_path, capsys):
    rrd = tmp_path / "run.rrd"
    rrd.write_bytes(b"mine")
    rc, _, err = capture_main(["--source", capture, "--no-publish", "--view", f"save:{rrd}"], capsys)
    assert rc == 2 and "already exists" in err and rrd.read_bytes() == b"mine"
    rc, out, err = capture_main(["--source", capture, "--no-publish", "--view", f"save:{rrd}", "--overwrite"],
                                capsys)
    assert rc == 0, err
    assert len(rows(rrd)["/plots/time_ms"]) == 30


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc, where no file can be made")
def test_an_rrd_that_cannot_be_made_is_one_error_line(capture):
    proc = subprocess.run([sys.executable, "-m", "radarodom.tools.radar_capture", "--source", capture, "--no-publish",
                           "-q", "--view", "save:/proc/radarodom-view.rrd"], capture_output=True, text=True,
                          timeout=GUARD_S, env={**os.environ, "RERUN_ANALYTICS": "0"})
    assert proc.returncode == 1
    # Rerun's own warning at exit, for a save it had failed, is not printed after it; the kernel's
    # words alone ('No such file or directory') named neither the directory nor the fix.
    assert proc.stderr == ("radar-capture: error: cannot write the view to /proc/radarodom-view.rrd: the directory "
                           "/proc takes no new files (the system says: No such file or directory); choose a writable "
                           "destination\n")


def test_an_rrd_where_no_file_can_be_made_is_refused_before_any_frame(capture, tmp_path, capsys, monkeypatch):
    """What, where, why and the fix, once, before the first frame; each said only 'cannot create
    PATH: ...' without the view (or, for /sys, only the kernel's 'Permission denied')."""
    afile, locked = tmp_path / "afile", tmp_path / "locked"
    afile.write_text("mine\n")
    locked.mkdir()
    cases = [(tmp_path / "nodir" / "v.rrd", 2, f"no directory {tmp_path / 'nodir'}; make it first (mkdir -p "
              f"{tmp_path / 'nodir'}) or choose a writable destination"),
             (afile / "v.rrd", 2, f"{afile} is a file, not a directory; choose a writable destination"),
             (afile / "sub" / "v.rrd", 2, f"{afile} is a file, not a directory; choose a writable destination"),
             (locked / "v.rrd", 2, f"the directory {locked} is not writable; choose a writable destination")]
    if os.path.isdir("/sys/kernel"):  # a directory that refuses new files with EACCES, for root too
        cases.append(("/sys/radarodom-view.rrd", 1, "no permission to make a file in the directory /sys "
                      "(Permission denied); choose a writable destination"))
    # Root writes anywhere, so the directory is read-only as os.access tells it (the check asks it).
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: os.fspath(path) != str(locked)
                        and real_access(path, mode, **kw))
    for rrd, code, why in cases:
        rc, out, err = capture_main(["--source", capture, "--no-publish", "--view", f"save:{rrd}"], capsys)
        assert (rc, out, err) == (code, "", f"radar-capture: error: cannot write the view to {rrd}: {why}\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "locked", "src"] and not any(locked.iterdir())
    # The library's view, not checked before, says the same when it opens, in its own process too.
    for (rrd, _, why), process in ((cases[0], False), (cases[2], True)):
        with pytest.raises(CaptureError) as info:
            open_view(ViewTarget("save", path=str(rrd)), process=process)
        assert str(info.value) == f"cannot write the view to {rrd}: {why}"


def test_without_rerun_the_view_says_which_extra_to_install(capture, tmp_path):
    script = ("import sys; sys.modules['rerun'] = None\n"  # as if rerun-sdk were not installed
              "from radarodom.tools.radar_capture import main\n"
              f"sys.exit(main(['--source', {capture!r}, '--no-publish', '--view', 'save:{tmp_path / 'x.rrd'}']))")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=GUARD_S)
    assert proc.returncode == 2, proc.stderr
    assert 'the view needs rerun-sdk: pip install "radarodom[view]"' in proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "x.rrd").exists()


def test_the_radar_sits_on_its_mount_and_the_base_moves_as_ros2_gets_it(tmp_path, capture):
    """With a mount, base_link carries the radar at the mount (static) and moves as the ROS 2
    outputs' base_link does (radarodom.ros2_frames: M R M^-1 of the estimator's radar poses)."""
    import types

    from radarodom.mount import Mount
    from radarodom.ros2_frames import base_pose
    from radarodom.tum import quaternion_yaw

    mount = Mount(0.3, 0.1, 0.2, math.radians(10.0))
    estimator = EstimatorConfig()
    view = open_view(ViewTarget("save", path=str(tmp_path / "mounted.rrd")), estimator=estimator, mount=mount)
    with Pipeline.from_url(capture, estimator=estimator, sinks=[TumSink(tmp_path / "odom.tum"), view]) as pipe:
        pipe.run()
    found = rows(tmp_path / "mounted.rrd")
    (radar,) = found["static:" + RADAR]
    np.testing.assert_allclose(radar["Transform3D:translation"][0], (0.3, 0.1, 0.2))
    tum = read_tum(tmp_path / "odom.tum")
    expected = [base_pose(types.SimpleNamespace(x=x, y=y, yaw=yaw, vx=0.0, vy=0.0, yaw_rate=0.0,
                                                pose_covariance=np.zeros((3, 3)), twist_covariance=np.eye(3)), mount)
                for (x, y, _), yaw in zip(tum.positions, quaternion_yaw(tum.quaternions))]
    got = [r["Transform3D:translation"][0][:2] for r in found["/world/odom/base_link"]]
    np.testing.assert_allclose(got, [(b.x, b.y) for b in expected], atol=1e-6)
    # The truth goes the same way: 0.1 m a frame straight ahead of the radar, from the mount.
    truth = [r["Transform3D:translation"][0][:2] for r in found["/world/odom/groundtruth/pose"]]
    c, s = math.cos(mount.yaw), math.sin(mount.yaw)
    np.testing.assert_allclose(truth, [(0.1 * i * c, 0.1 * i * s) for i in range(30)], atol=1e-9)


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc, where no file can be made")
def test_a_run_that_sees_no_frame_takes_back_its_bag_and_rrd(tmp_path, capsys):
    """The view's file cannot be made after the bag was: the bag, empty, is taken back, so the
    same command with the view elsewhere runs; and a view saved by a run that saw no frame goes
    too (both would block the next run: 'already exists')."""
    pytest.importorskip("rosbags.typesys")
    pytest.importorskip("mcap.writer")
    from radarodom.pipeline.stats import PipelineStats

    bag, rrd = tmp_path / "run.mcap", tmp_path / "run.rrd"
    argv = ["--source", "sim://corridor?rate=max&fidelity=fast&duration=0.3", "--no-publish", "-q", "--mcap", bag]
    rc, _, err = capture_main(argv + ["--view", "save:/proc/radarodom-view.rrd"], capsys)
    assert rc == 1 and "cannot write the view to /proc/radarodom-view.rrd" in err
    assert list(tmp_path.iterdir()) == []
    rc, _, err = capture_main(argv + ["--view", f"save:{rrd}"], capsys)
    assert rc == 0, err
    assert bag.stat().st_size > 0 and len(rows(rrd)["/plots/time_ms"]) == 3
    empty = tmp_path / "empty.rrd"
    sink = open_view(ViewTarget("save", path=str(empty)))
    assert empty.exists()
    sink.close(PipelineStats())
    assert sink.finished and not empty.exists()


@pytest.mark.skipif(not hasattr(signal, "SIGXFSZ"), reason="needs a POSIX file-size limit to make the write fail")
def test_a_saved_view_that_could_not_be_written_fails_the_run(tmp_path):
    """A .rrd whose writes fail (a full disk; here the process's file-size limit) is an output
    lost: the run prints its summary, then one error line, and exits 1 (it exited 0, '20 frames
    drawn')."""
    import resource

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails instead of killing
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))

    rrd = tmp_path / "v.rrd"
    # Not -q: the failure was also warned of as the view closed, a line before the same error.
    # 10 frames at fast fidelity make a .rrd of about 0.7 MB, well past the limit (as the exact
    # fidelity's do: the view draws the same heatmaps and point clouds either way).
    proc = subprocess.run([sys.executable, "-m", "radarodom.tools.radar_capture", "--source",
                           "sim://corridor?rate=max&fidelity=fast&duration=1", "--no-publish", "--view", f"save:{rrd}"],
                          capture_output=True, text=True, timeout=GUARD_S, preexec_fn=small_files,
                          env={**{k: v for k, v in os.environ.items() if k != "RUST_LOG"}, "RERUN_ANALYTICS": "0"})
    assert proc.returncode == 1, proc.stderr
    summary = [ln for ln in proc.stdout.splitlines() if ln.startswith("radar-capture: 10 frames")]
    assert len(summary) == 1 and "view: 10 frames drawn" in summary[0], proc.stdout
    # One line: not Rerun's own ANSI-coloured ERROR lines from its file writer (and at exit) too.
    lines = proc.stderr.splitlines()
    assert lines[-1].startswith(f"radar-capture: error: --view save:{rrd}: the file is incomplete"), lines
    # Rerun's words as Rerun's, without a Python exception's name ("the view did not close cleanly:
    # RuntimeError: File-writer thread shut down prematurely").
    assert "(Rerun failed as the view closed: " in summary[0] and "Error:" not in proc.stdout + proc.stderr, summary
    # (A slow run's status lines, "frames 9 ... incomplete 0 ...", are not messages.)
    said = [ln for ln in lines[:-1] if not ln.startswith("frames ")]
    assert "\x1b" not in proc.stderr and not any("incomplete" in ln or "close" in ln for ln in said), lines


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]  # closed again: nothing listens there


@pytest.mark.parametrize("source, close_timeout_s",
                         [("capture", 8.0), ("sim://corridor?rate=max&fidelity=fast&duration=2", 2.0)])
def test_connect_to_where_no_viewer_ever_listens_says_no_frame_reached_one(capture, caplog, source, close_timeout_s):
    """Nothing listens when the view opens, nor later: the summary said '30 frames drawn, 0 dropped'
    (Rerun had them, and waited for a viewer in vain, or gave up); now no frame counts as drawn.
    Rerun's last flush either gives up (more often with little data: the small capture) or waits
    until the close's timeout (more often with much: the simulator's heatmaps fill its queue).
    It is also said when the view opens: Rerun waited for a viewer in silence (30 s at the end, a
    live radar's frames dropped meanwhile); a viewer may come later (Rerun keeps the data), so it
    is said, not refused."""
    port = _free_port()
    url = f"rerun+http://127.0.0.1:{port}/proxy"
    caplog.set_level(logging.WARNING, logger="radarodom")
    view = open_view(ViewTarget("connect", address=f"127.0.0.1:{port}"), close_timeout_s=close_timeout_s)
    said = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert any(f"no Rerun viewer answers at {url}" in m and f"waits up to {close_timeout_s:.0f} s" in m
               for m in said), said
    with Pipeline.from_url(capture if source == "capture" else source, sinks=[view]) as pipe:
        stats = pipe.run()
    gave_up = r": Rerun never connected to it \(gRPC has been unable to connect for \d+s\)"
    waited = r" when the view opened nor when it closed \(Connection refused\)"
    said = rf"no Rerun viewer answered at {re.escape(url)}({gave_up}|{waited}); the frames were sent to no viewer"
    assert re.fullmatch(rf"0 frames drawn, {stats.frames} dropped \({said}\)", view.summary), view.summary
    assert view.drawn == 0 and view.finished
    if re.search(waited, view.summary):  # this process stopped the view's (which logs Rerun's error in its own)
        warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
        assert warned[-1] == f"{view.problem}; the view's process was stopped", warned


def test_a_viewer_started_after_the_view_opened_is_not_said_to_be_none(tmp_path, capture):
    """A viewer that starts listening just after the view found none: Rerun (0.41), which keeps
    trying to connect, either hands it every frame drawn (the summary counts them, and the viewer's
    saved file has them) or drops the connection as it is made, and its last flush fails (the
    summary says that the data did not all reach it; the only outcome seen in this test, while
    viewers started from a shell 3 to 7 s after radar-capture took every frame).  Either way a
    viewer came, and the summary does not say that no viewer got the frames."""
    port = _free_port()
    received = tmp_path / "received.rrd"
    view = open_view(ViewTarget("connect", address=f"127.0.0.1:{port}"), close_timeout_s=GUARD_S / 2)
    # A viewer that saves what it gets (`rerun --save`: no window; rerun_cli, the `rerun` command).
    viewer = subprocess.Popen([sys.executable, "-m", "rerun_cli", "--port", str(port), "--save", str(received)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              env={**os.environ, "RERUN_ANALYTICS": "0"})
    try:
        # Listening before the run (not only by its end: Rerun, never connected by then, would give up).
        assert viewer_missing(ViewTarget("connect", address=f"127.0.0.1:{port}"), wait_s=GUARD_S) is None
        with Pipeline.from_url(capture, sinks=[view]) as pipe:
            pipe.run()
    finally:
        viewer.send_signal(signal.SIGINT)
        viewer.wait(GUARD_S)
    assert view.drawn > 0 and view.drawn + view.dropped == 30 and "no viewer" not in view.summary, view.summary
    if view.problem is not None:
        assert view.problem.startswith(f"the view's data did not all reach rerun+http://127.0.0.1:{port}/proxy ("), \
            view.problem
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Rerun's: an .rrd streamed to, without its footer, is read whole
        chunks = RrdReader(str(received)).stream().collect().stream().to_chunks()
        frames = {row["frame"] for chunk in chunks if chunk.entity_path == RADAR + "/points" and not chunk.is_static
                  for row in chunk.to_record_batch().to_pylist()}
    assert len(frames) == view.drawn, sorted(frames)


# ------------------------------------------------------------------ connect: to what is no viewer
class _Closer:
    """A plain TCP listener on a free loopback port that accepts each connection and closes it."""

    def __init__(self) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen()
        self.port = self.sock.getsockname()[1]
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:  # closed: the test is over
                return
            conn.close()


def test_connect_to_a_listener_that_is_no_viewer_says_so_in_one_line_and_draws_nothing(capture):
    """Rerun printed its own ANSI-coloured ERROR lines (its gRPC client's: 'Write messages call
    failed', 'Failed to flush sink') and the summary said '30 frames drawn'."""
    closer = _Closer()
    url = f"rerun+http://127.0.0.1:{closer.port}/proxy"
    try:
        env = {key: value for key, value in os.environ.items() if key != "RUST_LOG"}
        proc = subprocess.run([sys.executable, "-m", "radarodom.tools.radar_capture", "--source", capture,
                               "--no-publish", "--view", f"connect:127.0.0.1:{closer.port}"], capture_output=True,
                              text=True, timeout=GUARD_S, env={**env, "RERUN_ANALYTICS": "0"})
    finally:
        closer.sock.close()
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert "\x1b" not in proc.stderr and "ERROR" not in proc.stderr, proc.stderr
    assert lines[0] == (f"radar-capture: warning: what answers at {url} is not a Rerun viewer: it closed the "
                        "connection when greeted in HTTP/2, which a viewer's gRPC speaks; the view is not drawn: "
                        f"start a Rerun viewer there (rerun --port {closer.port}) or give a viewer's address"), lines
    assert lines[1:] == [f"radar-capture: view: nothing ({url} is not a Rerun viewer)"], lines
    summary = proc.stdout.strip().splitlines()[-1]
    assert f"view: 0 frames drawn, 30 dropped (what answers at {url} is not a Rerun viewer: " in summary, summary


def test_connect_to_a_web_server_is_no_viewer_either(capture, caplog):
    import http.server

    class Quiet(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Quiet)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    port = server.server_address[1]
    caplog.set_level(logging.WARNING, logger="radarodom")
    try:
        view = open_view(ViewTarget("connect", address=f"127.0.0.1:{port}"), close_timeout_s=10.0)
        with Pipeline.from_url(capture, sinks=[view]) as pipe:
            pipe.run()
    finally:
        server.shutdown()
        server.server_close()
    assert view.where == f"nothing (rerun+http://127.0.0.1:{port}/proxy is not a Rerun viewer)"
    assert view.drawn == 0 and view.dropped == 30 and view.finished
    # Its answer is an HTTP/1 error page, whenever Rerun's gRPC client hears of it (a CI run once saw
    # that client report the view's first data flushed before the server's answer broke it).
    assert view.problem.startswith(f"what answers at rerun+http://127.0.0.1:{port}/proxy is not a Rerun viewer: "
                                   "it does not speak HTTP/2, which a viewer's gRPC does (its answer began ")
    said = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(said) == 1 and said[0].startswith(view.problem) and "the view is not drawn" in said[0], said


@pytest.fixture
def rerun_server():
    """A Rerun gRPC server in a process of its own (what a viewer listens with): its port and process."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    script = (f"import sys, time, rerun as rr; rec = rr.RecordingStream('server'); rec.serve_grpc(grpc_port={port}); "
              "print('serving', flush=True); time.sleep(600)")
    server = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "RERUN_ANALYTICS": "0"})
    try:
        assert server.stdout.readline() == "serving\n"
        yield port, server
    finally:
        server.kill()
        server.wait(GUARD_S)


def test_connect_to_a_rerun_server_draws_every_frame(capture, rerun_server, caplog):
    """What the check of a connect: target takes for a viewer: a Rerun gRPC server is one."""
    port, _ = rerun_server
    caplog.set_level(logging.WARNING, logger="radarodom")
    view = open_view(ViewTarget("connect", address=f"127.0.0.1:{port}"), close_timeout_s=30.0)
    with Pipeline.from_url(capture, sinks=[view]) as pipe:
        pipe.run()
    assert view.where == f"the Rerun viewer at rerun+http://127.0.0.1:{port}/proxy"
    assert view.drawn + view.dropped == 30 and view.drawn > 0 and view.problem is None
    assert not [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


def test_a_viewer_lost_during_the_run_is_said_in_the_summary(capture, rerun_server):
    """A viewer that goes away (closed) while the run draws: the view's last flush fails, and the
    summary says so (the close's error was not passed on from the view's process: '30 frames
    drawn, 0 dropped' and nothing else)."""
    port, server = rerun_server
    view = open_view(ViewTarget("connect", address=f"127.0.0.1:{port}"), close_timeout_s=10.0)

    def on_frame(result, stats):
        if result.frame.index == 10:
            server.kill()
            server.wait(GUARD_S)

    with Pipeline.from_url(capture, sinks=[view]) as pipe:
        pipe.run(on_frame)
    assert view.problem is not None, view.summary
    # Rerun says no more than that the last flush failed: which frames reached the viewer is unknown.
    assert view.problem.startswith(f"the view's data did not all reach rerun+http://127.0.0.1:{port}/proxy ("), \
        view.problem
    assert view.problem.endswith("): the frames drawn after the viewer went away, or all if none came, were not seen")
    assert view.summary.endswith(f"({view.problem})")
