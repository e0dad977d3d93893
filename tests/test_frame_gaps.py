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


@pytest.mark.parametrize("loss", ["lose5", "dropx", "gap"])
def test_a_bad_loss_name_says_what_is_understood(loss):
    with pytest.raises(ValueError, match="none, dropP .* or gapS"):
        frame_gaps.delivered(TIMES, loss)
