"""sim://...&loop=N (issue 19): the trajectory played N times (0: until stopped), as replay's
loop does: timestamps and frame numbers keep increasing, the frames repeat, the ground-truth pose
restarts with the scene.  And the default simulator stream says when it ends."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from radarodom.driver.sources import open_source
from radarodom.errors import SourceError
from radarodom.tools import radar_capture

URL = "sim://calibration?rate=max&duration=0.3"
MOVING = "sim://room?rate=max&duration=0.3&fidelity=fast"


def test_loop_plays_the_trajectory_again_with_the_clock_and_frame_numbers_going_on():
    with open_source(MOVING) as once:
        first = list(once)
        period = once.config.frame_period_s
    with open_source(MOVING + "&loop=3") as looped:
        assert looped.describe()["loop"] == 3
        frames = list(looped)
    n = len(first)
    assert n == 3 and len(frames) == 3 * n
    assert [f.index for f in frames] == list(range(3 * n))
    stamps = np.array([f.timestamp for f in frames])
    assert np.all(np.diff(stamps) > 0)
    assert np.allclose(np.diff(stamps), period)  # one period from a pass's last frame to the next's first
    for k, frame in enumerate(frames):
        again = first[k % n]
        assert np.array_equal(frame.raw, again.raw)  # the same frames...
        assert frame.pose == again.pose  # ...and the ground truth restarts with the scene
    assert frames[n].pose == first[0].pose and frames[n - 1].pose != first[0].pose


def test_loop_0_runs_until_stopped():
    with open_source(URL + "&loop=0") as source:
        frames = []
        for frame in source:
            frames.append(frame)
            if len(frames) == 10:
                source.stop()
        assert len(frames) == 10 and [f.index for f in frames] == list(range(10))


def test_the_default_is_one_pass():
    with open_source(URL) as source:
        assert source.describe()["loop"] == 1 and len(list(source)) == 3


@pytest.mark.parametrize("loop", ["-1", "1.5", "x", "1_0", ""])
def test_a_bad_loop_is_refused_naming_it(loop):
    with pytest.raises(SourceError, match="loop="):
        open_source(URL + f"&loop={loop}")


def test_a_looped_recording_replays_with_increasing_timestamps(tmp_path, capsys):
    out = tmp_path / "rec"
    assert radar_capture.main(["--source", URL + "&loop=2", "--no-publish", "-q", "--no-odom",
                               "--record", str(out)]) == 0
    with open_source(f"replay://{out}?rate=max") as replay:
        stamps = [f.timestamp for f in replay]
    assert len(stamps) == 6 and all(b > a for a, b in itertools.pairwise(stamps))


def test_the_default_simulator_stream_says_when_it_ends(monkeypatch, capsys):
    monkeypatch.setattr(radar_capture, "_default_source", lambda: radar_capture.DEFAULT_SIM_URL)
    assert radar_capture.main(["--no-publish", "--frames", "2", "--no-odom"]) == 0
    err = capsys.readouterr().err
    with open_source(radar_capture.DEFAULT_SIM_URL) as sim:
        frames = sim.describe()["frames"]
        seconds = frames * sim.config.frame_period_s
    assert (f"radar-capture: warning: the simulated corridor runs {seconds:.1f} s ({frames} frames); "
            "Ctrl-C stops; --source 'sim://corridor?loop=0' runs forever") in err
    # A source the user chose gets no such note.
    assert radar_capture.main(["--source", URL, "--no-publish", "--frames", "1", "--no-odom"]) == 0
    assert "runs forever" not in capsys.readouterr().err
