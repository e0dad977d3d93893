"""bench/heading_diagnosis.py on a short recorded loop: the report by kind of step, and ``--trace``,
each step's truth, estimate and error, summed, one line a frame."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
import heading_diagnosis as hd  # noqa: E402
import robustness_matrix as rm  # noqa: E402
import sequences  # noqa: E402

#: A short loop (turns at 90 deg/s, straights of 0.5 m): a few seconds to record.
CELL = rm.SimCell(scene="room", turn_rate_dps=90.0, straight_m=0.5)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return rm.record(CELL, str(tmp_path_factory.mktemp("diagnosis")))


def test_the_trace_gives_each_step_its_truth_estimate_and_summed_error(recording, capsys):
    assert hd.main([recording, "--trace", "5", "40"]) == 0
    out = capsys.readouterr().out.splitlines()
    # The report by kind of step comes first: this loop has every kind.
    assert out[0] == os.path.basename(recording)
    for kind in hd.KINDS[1:]:
        assert any(line.strip().startswith(kind) for line in out), kind
    header = next(i for i, line in enumerate(out) if line.split()[:2] == ["frame", "t"])
    rows = [line.split() for line in out[header + 1:header + 37]]
    assert [int(r[0]) for r in rows] == list(range(5, 41))
    seq = sequences.load(recording)
    truth = hd.truth(seq)
    true_deg = np.degrees(np.diff(truth[:, 2]))
    errors = np.array([float(r[5]) for r in rows])
    for r, error in zip(rows, errors):
        frame = int(r[0])
        assert float(r[1]) == pytest.approx(seq.times[frame] - seq.times[0], abs=0.006)
        assert float(r[3]) == pytest.approx(true_deg[frame - 1], abs=0.006)
        assert error == pytest.approx(float(r[4]) - float(r[3]), abs=0.011)
    # Summed from the first traced step (each printed error rounded to 0.005).
    summed = np.array([float(r[6]) for r in rows])
    assert np.all(np.abs(summed - np.cumsum(errors)) <= 0.005 * np.arange(2, 38))
    # The loop turns in place at 90 deg/s: some of the traced steps turn 9 degrees standing.
    assert any(abs(float(r[3])) > 8.5 and float(r[2]) < 0.05 for r in rows)
    assert out[-1].startswith("  drift parts")


def test_the_trace_of_frames_outside_the_run_is_only_its_header(recording, capsys):
    assert hd.main([recording, "--trace", "100000", "100010"]) == 0
    out = capsys.readouterr().out.splitlines()
    header = next(i for i, line in enumerate(out) if line.split()[:2] == ["frame", "t"])
    assert out[header + 1].startswith("  drift parts")
