"""radar-capture's live status line fitted to the terminal's width, and the yaw wrapped to
(-180, 180] with the total turned beside it (issue 19)."""

from __future__ import annotations

import io
import math
import time

import pytest

from radarodom.estimator.odometry import OdometryState
from radarodom.pipeline import PipelineStats
from radarodom.tools import capture_text
from radarodom.tools.status import Field, StatusLine, fit_fields, format_yaw, terminal_columns, wrap_degrees


class _Source:
    """What the status asks of a source: describe()."""

    def __init__(self, live: bool = False) -> None:
        self.live = live

    def describe(self) -> dict:
        if not self.live:
            return {"url": "sim://corridor"}
        return {"url": "dca1000://", "frames_dropped": 3, "packets_lost": 12, "truncated_packets": 1,
                "late_packets": 0}


def _stats(yaw_deg: float = -450.0, flags=()) -> PipelineStats:
    stats = PipelineStats(frames=1234, incomplete_frames=0, elapsed_s=123.4)
    stats.state = OdometryState(t=12.3, frame=1234, x=-12.345, y=104.5, yaw=math.radians(yaw_deg), vx=1.234,
                                flags=flags)
    stats.latency.add(0.012)
    stats.estimator_s.append(0.003)
    return stats


@pytest.mark.parametrize("live", [False, True])
@pytest.mark.parametrize("recording", [False, True])
def test_the_line_fits_80_and_40_columns_keeping_the_pose(live, recording):
    stats, source = _stats(), _Source(live)
    whole = capture_text.status_text(stats, recording, source, None)
    assert len(whole) > 80  # a log gets every field
    assert "elapsed 02:03.4" in whole and "latency 12/12 ms" in whole and "yaw -90.0 deg (turned -450)" in whole
    for width in (80, 40):
        line = capture_text.status_text(stats, recording, source, width)
        assert len(line) <= width - 1, (width, line)
        assert "x -12.35 y 104.50 m" in line and "yaw -90.0 deg" in line, line  # the pose stays
    line80 = capture_text.status_text(stats, recording, source, 80)
    assert "frames 1234" in line80 and ("[rec]" in line80) == recording
    if live:  # the live radar's losses matter more than the rate
        assert "dropped 3" in line80 and "lost 12" in line80
    assert "elapsed" not in line80 and "02:03.4" not in line80  # the least important goes first


def test_a_bad_step_flag_is_kept_before_the_speed():
    stats = _stats(yaw_deg=10.0, flags=("velocity_held",))
    line = capture_text.status_text(stats, False, _Source(), 60)
    assert "[velocity_held]" in line and len(line) <= 59


def test_a_long_flag_list_is_shortened_and_the_frame_count_stays():
    stats = _stats(yaw_deg=10.0, flags=("velocity_held", "yaw_held", "few_features"))
    line = capture_text.status_text(stats, False, _Source(), 80)
    assert line.startswith("frames 1234  ") and "[velocity_held,+2]" in line and len(line) <= 79


def test_fit_fields_drops_the_least_important_last_first_then_cuts():
    fields = [Field("aaaa", priority=1), Field("bbbb", "b", 3), Field("cccc", priority=3), Field("dddd", priority=2)]
    assert fit_fields(fields, None) == "aaaa  bbbb  cccc  dddd"
    assert fit_fields(fields, 23) == "aaaa  bbbb  cccc  dddd"  # 22 characters fit in 23 columns
    assert fit_fields(fields, 22) == "aaaa  b  cccc  dddd"  # short forms first
    assert fit_fields(fields, 15) == "aaaa  b  dddd"  # then priority 3, the last one first
    assert fit_fields(fields, 11) == "aaaa  dddd"
    assert fit_fields(fields, 10) == "aaaa  b"  # dddd no longer fits, the short b does
    assert fit_fields(fields, 5) == "aaaa"
    assert fit_fields(fields, 3) == "aa"  # one field left: cut
    # A field that does not fit leaves room for less important ones that do.
    assert fit_fields([Field("a" * 5), Field("b" * 30), Field("c" * 5, priority=2)], 14) == "aaaaa  ccccc"


@pytest.mark.parametrize("turned, wrapped", [(0.0, 0.0), (179.9, 179.9), (180.0, 180.0), (-180.0, 180.0),
                                             (181.0, -179.0), (270.0, -90.0), (-270.0, 90.0), (-450.0, -90.0),
                                             (720.0, 0.0), (-0.0, 0.0)])
def test_yaw_wraps_to_minus_180_exclusive_180_inclusive(turned, wrapped):
    assert wrap_degrees(turned) == pytest.approx(wrapped, abs=1e-9)
    assert -180.0 < wrap_degrees(turned) <= 180.0


def test_yaw_text_shows_the_total_turned_only_when_it_differs():
    assert format_yaw(math.radians(270.0)) == "-90.0 deg (turned 270)"
    assert format_yaw(math.radians(-450.0)) == "-90.0 deg (turned -450)"
    assert format_yaw(math.radians(45.25)) == "45.2 deg"
    assert format_yaw(math.radians(-180.0)) == "180.0 deg (turned -180)"
    assert format_yaw(math.radians(180.0)) == "180.0 deg"
    assert format_yaw(-1e-9) == "-0.0 deg" or format_yaw(-1e-9) == "0.0 deg"


def test_the_summary_wraps_the_yaw_too():
    text = capture_text.odometry_summary(_stats(yaw_deg=270.0), None)
    assert "yaw -90.0 deg (turned 270)," in text


def test_a_status_line_on_a_terminal_is_cut_to_its_width(monkeypatch):
    class Tty(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setenv("COLUMNS", "40")
    stream = Tty()
    status = StatusLine(stream)
    assert status.columns == terminal_columns(stream) == 40
    status.update("x" * 100)
    assert stream.getvalue() == "\r" + "x" * 39 + "\x1b[K"
    status.update([Field("frames 1", priority=2), Field("y" * 35)], force=True)
    assert stream.getvalue().endswith("\r" + "y" * 35 + "\x1b[K")
    log = io.StringIO()
    status = StatusLine(log, log_period_s=0.0)
    assert status.columns is None
    status.update([Field("a" * 100), Field("b" * 100, priority=9)])
    assert log.getvalue() == "a" * 100 + "  " + "b" * 100 + "\n"  # a log gets the whole line


def test_a_log_gets_its_first_line_one_period_after_the_first_frame_not_after_start():
    """A view whose process started slowly on a busy machine made the first frame come more
    than a period after start: the log got 'frames 1  rate 0.0 Hz' at once."""
    log = io.StringIO()
    status = StatusLine(log, log_period_s=0.2)
    time.sleep(0.3)  # opening the source and the view
    status.update("frames 1")
    assert log.getvalue() == ""
    time.sleep(0.25)
    status.update("frames 2")
    assert log.getvalue() == "frames 2\n"
    status.update("frames 3", force=True)
    assert log.getvalue() == "frames 2\nframes 3\n"


def test_the_summarys_rate_counts_from_the_first_frame_not_from_the_start():
    """Frames over the run's whole time (opening the source included) said 5 Hz of a 20 Hz stream."""
    stats = PipelineStats(started_monotonic=time.monotonic() - 10.0)  # a source that took 10 s to open
    stats.count(0.0, 0, 0)
    time.sleep(0.01)
    stats.count(0.05, 0, 0)
    span = stats.last_frame_monotonic - stats.first_frame_monotonic
    assert stats.mean_rate_hz == 1 / span and stats.elapsed_s > 10.0 and stats.mean_rate_hz > 2 / stats.elapsed_s
    assert stats.stream_duration_s == 0.05


def test_the_summary_says_where_frames_were_recorded_and_when_nothing_was(tmp_path):
    """A run stopped before its first frame takes its empty recording with it: its summary said
    'recorded to DIR' of a directory that was not there."""
    stats = PipelineStats(frames=0, reason="stopped")
    assert capture_text.summary(stats, str(tmp_path / "rec")).endswith(
        f"stopped; nothing recorded ({tmp_path / 'rec'} not made)")
    (tmp_path / "rec").mkdir()
    stats.frames = 5
    assert capture_text.summary(stats, str(tmp_path / "rec"), 3).endswith(f"; recorded 3 of them to {tmp_path / 'rec'}")
    assert capture_text.summary(stats, str(tmp_path / "rec"), 5).endswith(f"; recorded to {tmp_path / 'rec'}")
