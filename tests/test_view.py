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
import math
import subprocess
import sys
import threading

import numpy as np
import pytest

from conftest import make_capture

rr = pytest.importorskip("rerun", reason='the view needs rerun-sdk (pip install "radarodom[view]")')
from rerun.chunk import RrdReader  # noqa: E402

from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.pipeline import Pipeline, TumSink  # noqa: E402
from radarodom.tum import read_tum  # noqa: E402
from radarodom.view import ThreadDrawer, ViewSink, ViewTarget, open_view  # noqa: E402
from radarodom.view.scene import Scene  # noqa: E402

RADAR = "/world/odom/base_link/radar"
#: Generous hang guard, s.
GUARD_S = 120.0


@pytest.fixture(scope="module", autouse=True)
def rerun_analytics_off(tmp_path_factory):
    """XDG_CONFIG_HOME of the tests' own, with Rerun's analytics disabled (by Rerun's CLI)."""
    config = tmp_path_factory.mktemp("xdg_config")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_CONFIG_HOME", str(config))
        subprocess.run([sys.executable, "-m", "rerun", "analytics", "disable"], capture_output=True,
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


def saving(scene: Scene, path) -> ThreadDrawer:
    """*scene* drawn into the .rrd *path*, in the sink's sender thread."""
    scene.rec.save(str(path))
    return ThreadDrawer(scene)


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
    view = ViewSink(saving(scene, tmp_path / "slow.rrd"), queue_frames=4, close_timeout_s=GUARD_S)
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


def test_a_failing_view_stops_drawing_not_the_radar(tmp_path, capture, warnings_log):
    estimator = EstimatorConfig()
    view = ViewSink(saving(FailingScene(rr.RecordingStream("radarodom-test"), estimator=estimator),
                           tmp_path / "failing.rrd"))
    with Pipeline.from_url(capture, estimator=estimator, sinks=[TumSink(tmp_path / "odom.tum"), view]) as pipe:
        stats = pipe.run()
    assert stats.frames == 30 and len(read_tum(tmp_path / "odom.tum")) == 30
    assert view.drawn == 3 and view.dropped == 27
    assert view.summary == "3 frames drawn, 27 dropped (the view failed: ValueError: a drawing bug)"
    assert any("the view stopped drawing: ValueError: a drawing bug" in r.getMessage() for r in warnings_log.records)
    assert len(rows(tmp_path / "failing.rrd")[RADAR + "/points"]) == 3  # what was drawn is kept


def test_the_view_draws_every_frame_in_the_body_and_odometry_frames(tmp_path, capture, small_cfg):
    """Drawn by the view's own process as radar-capture opens it: points in REP-103 (x = TI y,
    y = -TI x), the base's pose as the estimator's, the ground truth aligned at the first frame,
    a row per frame of every per-frame entity."""
    from radarodom.pipeline import PointsCsvSink

    estimator = EstimatorConfig()
    view = open_view(ViewTarget("save", path=str(tmp_path / "run.rrd")), estimator=estimator, queue_frames=64)
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
