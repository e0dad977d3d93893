"""bench/frame_gaps.py: which frames each kind of loss delivers (the estimator's side of it is
tests/test_estimator_odometry.py's gap tests)."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
import frame_gaps  # noqa: E402

TIMES = np.arange(400) * 0.1  # 40 s at 10 Hz


def test_every_frame_arrives_without_loss():
    assert frame_gaps.delivered(TIMES, "none").all()


def test_a_random_drop_loses_about_its_share_the_same_frames_each_run_never_the_first():
    kept = frame_gaps.delivered(TIMES, "drop20")
    assert kept[0] and 0.70 < kept.mean() < 0.90
    assert np.array_equal(kept, frame_gaps.delivered(TIMES, "drop20"))
    assert frame_gaps.delivered(TIMES, "drop0").all()


def test_a_gap_loses_the_frames_within_its_length_after_each_mark():
    kept = frame_gaps.delivered(TIMES, "gap1")
    lost = TIMES[~kept]
    marks = np.arange(5.0, TIMES[-1] - 5.0, 7.0)  # 5, 12, 19, 26, 33 s
    assert len(marks) == 5
    for start in marks:
        inside = (TIMES > start) & (TIMES < start + 1.0)
        assert not kept[inside].any() and inside.sum() >= 9
    assert all(any(start < t < start + 1.0 for start in marks) for t in lost)


def test_a_blind_run_delivers_every_frame_and_blanks_those_a_gap_would_lose():
    assert frame_gaps.delivered(TIMES, "blind1").all()
    assert np.array_equal(frame_gaps.blinded(TIMES, "blind1"), ~frame_gaps.delivered(TIMES, "gap1"))
    assert not frame_gaps.blinded(TIMES, "gap1").any()


def test_a_blind_frame_is_noise_at_the_frames_level_without_doppler():
    import estimator_synth as synth
    hm = synth.scene_heatmap()
    blind = frame_gaps.blind_frame(hm, np.random.default_rng(0))
    assert blind.intensity.shape == hm.intensity.shape and blind.intensity.dtype == hm.intensity.dtype
    assert np.median(blind.intensity) == pytest.approx(np.median(hm.intensity) * np.log(2), rel=0.1)
    assert blind.intensity.max() < hm.intensity.max() and not blind.doppler_mps.any()


@pytest.mark.parametrize("loss", ["lose5", "dropx", "gap", "blind", "drop150", "drop-5", "dropnan", "gap-1", "gap7"])
def test_a_bad_loss_name_says_what_is_understood(loss):
    with pytest.raises(ValueError, match="none, dropP .*, gapS or blindS"):
        frame_gaps.delivered(TIMES, loss)


def test_the_command_line_says_what_is_wrong(capsys):
    with pytest.raises(SystemExit) as exit_info:
        frame_gaps.main(["--losses", "drop150"])
    assert exit_info.value.code == 2 and "--losses: loss 'drop150'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        frame_gaps.main(["--workers", "0"])
