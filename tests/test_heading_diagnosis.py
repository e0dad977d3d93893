"""bench/heading_diagnosis.py on a short recorded loop: the report by kind of step, and ``--trace``,
each step's truth, estimate and error, summed, one line a frame."""

from __future__ import annotations

import dataclasses
import os
import re
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
import heading_diagnosis as hd  # noqa: E402
import robustness_matrix as rm  # noqa: E402
import sequences  # noqa: E402
import turn_phases  # noqa: E402
import wall_lines  # noqa: E402
from bench_recordings import shared_recording  # noqa: E402
from radarodom.estimator.velocity import estimate_velocity  # noqa: E402

#: A short loop (turns at 90 deg/s, straights of 0.5 m): a few seconds to record.
CELL = rm.SimCell(scene="room", turn_rate_dps=90.0, straight_m=0.5)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return shared_recording(CELL, tmp_path_factory)


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


def test_each_straight_apart_splits_its_error_into_its_ends_and_middle(recording, capsys):
    """--straights: each straight of the loop long enough (its first and last, some 0.3 m of
    straight driving each between their ramps and turns) with the estimate's error over it, and
    that error again over its first 0.1 m, its middle and its last 0.1 m, which add up to it (to
    the printed rounding), in the loop's order."""
    assert hd.main([recording, "--straights", "1", "--min-straight-m", "0.3", "--straight-end-m", "0.1"]) == 0
    out = capsys.readouterr().out.splitlines()
    rows = [re.search(r"straight from frame (\d+), ([\d.]+) m: estimate [-+][\d.]+ deg/m \(([-+][\d.]+) deg\).*"
                      r"first 0\.1 m / middle / last 0\.1 m ([-+][\d.]+) / ([-+][\d.]+) / ([-+][\d.]+) deg$", line)
            for line in out if line.startswith("  straight from frame")]
    assert len(rows) == 2 and all(rows)
    frames = [int(r[1]) for r in rows]
    assert frames == sorted(frames)
    for r in rows:
        assert 0.2 <= float(r[2]) <= 0.5
        whole, parts = float(r[3]), [float(r[k]) for k in (4, 5, 6)]
        assert sum(parts) == pytest.approx(whole, abs=0.021)
    # The middle is what the ends leave: not empty on a 0.3 m straight with 0.1 m ends.
    assert any(float(r[5]) != 0.0 for r in rows)


def test_the_true_velocity_is_what_the_estimator_is_given_in_place_of_the_fit(recording, capsys):
    """--true-velocity: each frame's velocity by the truth's poses (the radar's), body frame, fed
    with the frame's points; every step's velocity is then the truth's at its middle, and the
    drift the estimate's translation makes alone is the truth's sampling's."""
    seq = sequences.load(recording)
    config = hd.EstimatorConfig()
    given = hd.true_velocities(seq, config)
    assert [v.t for v in given] == list(seq.times)
    speeds = np.hypot([v.vx for v in given], [v.vy for v in given])
    # The loop drives at 0.8 m/s, forward (the radar on the axis does not slide), and stands.
    moving = speeds > 0.75
    assert moving.sum() > 10 and all(abs(v.vy) < 0.02 and v.vx > 0 for v, m in zip(given, moving) if m)
    assert all(v.status == ("zero_velocity" if s < config.velocity.zero_velocity_threshold_mps else "ok")
               for v, s in zip(given, speeds))
    assert any(v.status == "zero_velocity" for v in given)
    # This cfg's clouds measure elevation: nothing to keep of a level fit.
    assert all(v.level_scale == 1.0 for v in given)
    # Without elevation (as a 2-TX array's), each moving frame keeps its level fit's forward speed.
    level = [p.copy() for p in seq.points]
    for p in level:
        p["elevation"] = 0.0
    flat = hd.true_velocities(dataclasses.replace(seq, points=level), config)
    fits = [estimate_velocity(p, v.t, config.velocity, np.random.default_rng(config.velocity.seed))
            for p, v in zip(level, flat)]
    kept = [(v, f) for v, f in zip(flat, fits) if v.level_scale != 1.0]
    assert len(kept) > 10 and all(v.level_velocity[0] == pytest.approx(f.vx, rel=0.05) for v, f in kept)
    assert [(v.vx, v.vy) for v in flat] == [(v.vx, v.vy) for v in given]
    steps = 0
    for i, state, _, _ in hd.run(seq, config, given):
        if i and state.velocity is not None:
            a, b = given[i - 1], given[i]
            assert (state.velocity.vx, state.velocity.vy) == (pytest.approx(0.5 * (a.vx + b.vx), abs=1e-9),
                                                              pytest.approx(0.5 * (a.vy + b.vy), abs=1e-9))
            steps += 1
    assert steps > 0.9 * len(seq)
    assert hd.main([recording, "--true-velocity"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == os.path.basename(recording) + " (the estimator given the true velocity)"
    parts = dict(item.rsplit(" ", 1) for item in out[-1].split(": ", 1)[1].split(", "))
    assert float(parts["translation"]) < 0.5, out[-1]


def test_the_baselines_give_each_turns_two_terms_apart(recording, capsys):
    # Each turn's field search given the true motion: its two-way ratio (the report's "field, true
    # translation" stage, for consecutive frames) and each of its terms' alone, which the straights'
    # forward and backward terms already had.
    assert hd.main([recording, "--baselines", "1"]) == 0
    out = capsys.readouterr().out.splitlines()
    line = next(line for line in out if line.strip().startswith("1 frame(s) apart"))
    seq = sequences.load(recording)
    config = hd.EstimatorConfig()
    _, kept, _, _, _ = hd.diagnose(seq, config)
    poses = hd.truth(seq)
    deltas = hd._offsets(np.radians(3.0), np.radians(0.25))
    icp = config.icp
    for kind in hd.KINDS[2:]:
        m = re.search(re.escape(kind) + r" ratio ([\d.]+) \(forward ([\d.]+), backward ([\d.]+); n=(\d+)\)", line)
        assert m, kind
        two_way, forward, backward, n = float(m[1]), float(m[2]), float(m[3]), int(m[4])
        stage = next(row for row in out if row.strip().startswith(kind))
        assert two_way == pytest.approx(float(re.search(r"field, true translation: ratio ([\d.]+)", stage)[1]),
                                        abs=0.0006)
        # The terms again from the kept frames: the two-way peak where the search itself finds
        # the turn, each term's turns summed as the line has them.
        terms = {"forward": [], "backward": []}
        for j in range(1, len(seq)):
            t, dyaw = hd.step_motion(poses, j - 1, j)
            if hd.kind(t, dyaw, seq.times[j] - seq.times[j - 1]) != kind:
                continue
            a, b = kept[j - 1].field, kept[j].field
            found = hd._terms(a, b, t, dyaw, deltas, True)
            r = hd.field_rotation(a.points, b.points, a.smoothed, b.smoothed, t, -dyaw, icp.field_search_rad,
                                  icp.field_step_rad, True)
            assert np.degrees(abs(-dyaw + found["two-way"] - r)) < 0.05
            for name in terms:
                terms[name].append((dyaw - found[name], dyaw))
        assert len(terms["forward"]) == n
        assert forward == pytest.approx(hd._ratio(np.array(terms["forward"])), abs=0.0006)
        assert backward == pytest.approx(hd._ratio(np.array(terms["backward"])), abs=0.0006)
        assert 0.8 < forward < 1.25 and 0.8 < backward < 1.25


def _driven(speed: np.ndarray, turn: np.ndarray, dt: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Frame times and true poses (n + 1, 3) of steps at *speed* (m/s) turning *turn* (rad) each."""
    yaw = np.concatenate([[0.0], np.cumsum(turn)])
    step = speed * dt
    xy = np.vstack([[0.0, 0.0], np.cumsum(np.column_stack([step * np.cos(yaw[:-1]), step * np.sin(yaw[:-1])]), 0)])
    return np.arange(len(yaw)) * dt, np.column_stack([xy, yaw])


def test_turn_phases_split_each_turn_in_place_by_the_truths_speed():
    # A turn in place of 10 steps: braking in (moving, turning), 6 at rest, starting off; a straight
    # step; then a moving turn, which is not one; at 10 Hz, turning right (negative) 0.1 rad a step.
    speed = np.array([0.0, 0.3, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1, 0.3, 0.5, 0.5, 0.5, 0.5, 0.5, 0.0])
    true = np.array([0.0, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, 0.0, -0.1, -0.1, -0.1, 0.0, 0.0])
    times, ref = _driven(speed, true)
    estimates = np.column_stack([true * 1.1, true, true * 0.9])  # too long, right, too short
    estimates[12, :] += 0.05  # the moving turn's error is no turn in place's
    table = turn_phases.phase_errors(times, ref, estimates)
    np.testing.assert_allclose(table[:, -1], [0.2, 0.6, 0.2])  # truth: braking in 2, at rest 6, starting off 2
    np.testing.assert_allclose(table[:, 0], 0.1 * table[:, -1])  # in the turn's direction: too long is positive
    np.testing.assert_allclose(table[:, 1], 0.0, atol=1e-15)
    np.testing.assert_allclose(table[:, 2], -0.1 * table[:, -1])
    # The step after the turn in place (the straight one), its error in the turn's direction: taking
    # back 0.02 rad of a right turn is turning left by it.
    estimates[11, :] += 0.02
    after = turn_phases.phase_errors(times, ref, estimates, after_steps=1)
    np.testing.assert_allclose(after[:3], table)
    np.testing.assert_allclose(after[3], [-0.02, -0.02, -0.02, 0.0], atol=1e-15)
    estimates[11, :] -= 0.02
    # Mostly moving (its median speed 0.1 m/s): a moving turn's slow passage, not a turn in place.
    slow = speed.copy()
    slow[4:9] = 0.1
    times, ref = _driven(slow, true)
    assert not turn_phases.phase_errors(times, ref, estimates).any()


def test_turn_phases_show_a_chain_the_estimator_lacks_as_a_dash():
    # Without the blend (point_yaw.blend off) the chains' columns are NaN: "-", as in the ratio line,
    # not "+nan".
    table = np.array([[0.01, np.nan, np.nan, 0.2], [0.0, np.nan, np.nan, 2.8], [-0.02, np.nan, np.nan, 0.1]])
    text = turn_phases.lines("run", table)
    assert "nan" not in "\n".join(text).lower()
    assert text[1] == "  braking in    +0.57 / - / -  of 11 turned"
    assert text[-1] == "  whole turn ratio 0.9968 / - / -"
    # A fourth row, the steps after the turn, stays out of the ratio.
    text = turn_phases.lines("run", np.vstack([table, [0.01, np.nan, np.nan, 0.0]]))
    assert text[-2] == "  whole turn ratio 0.9968 / - / -"
    assert text[-1] == f"  after it      +0.57 / - / -  over the {turn_phases.AFTER_STEPS} steps after each turn"


def test_turn_phases_of_a_recording_sum_to_its_turn_in_place(recording, tmp_path, capsys):
    settings = tmp_path / "no_wall_map.json"
    settings.write_text('{"wall_map": {"use": false}}')
    assert turn_phases.main([recording, "--estimator-config", str(settings)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(os.path.basename(recording) + ": turns in place")
    rows = [re.fullmatch(r"  (braking in|at rest|starting off) +([-+\d.]+) / ([-+\d.]+) / ([-+\d.]+)  of (\d+) "
                         r"turned", line) for line in out[1:4]]
    assert all(rows) and [r[1] for r in rows] == list(turn_phases.PHASES)
    turned = [int(r[5]) for r in rows]
    # The loop's one turn in place is 180 degrees, most of it standing.
    assert 178 <= sum(turned) <= 182 and turned[1] > 120
    for r in rows:  # without the wall map the published heading is the chains' mean
        assert float(r[2]) == pytest.approx(0.5 * (float(r[3]) + float(r[4])), abs=0.011)
    ratios = [float(v) for v in re.findall(r"\d\.\d{4}", out[4])]
    sums = [sum(float(r[k]) for r in rows) for k in (2, 3, 4)]
    assert ratios == pytest.approx([1 + s / sum(turned) for s in sums], abs=0.003)
    after = re.fullmatch(r"  after it +([-+\d.]+) / ([-+\d.]+) / ([-+\d.]+)  over the 10 steps after each turn", out[5])
    assert after and float(after[1]) == pytest.approx(0.5 * (float(after[2]) + float(after[3])), abs=0.011)


def test_a_lines_error_is_against_the_nearest_wall_direction_whichever_its_sense():
    walls = np.array([0.0, np.pi / 2])
    errors = wall_lines.direction_errors(np.array([0.1, np.pi - 0.05, np.pi / 2 + 0.2, 1.0, -np.pi / 2]), walls)
    assert errors == pytest.approx([0.1, -0.05, 0.2, 1.0 - np.pi / 2, 0.0])
    assert wall_lines.direction_errors(np.zeros(0), walls).shape == (0,)


def test_lines_grouped_by_what_they_state_count_each_near_line_once():
    # (error, stated) in degrees: two groups near a wall, one line far off any.
    lines = np.radians([[0.1, 0.1], [-0.3, 0.15], [2.0, 0.6], [-4.0, 0.7], [30.0, 0.1]])
    rows = wall_lines.by_stated(lines, 10.0)
    assert len(rows) == 2
    low = re.search(r"stating 0\.0-0\.2 degrees: +(\d+) lines, median \|error\| ([\d.]+), RMS ([\d.]+) "
                    r"\(([\d.]+) times the stated\), beyond 1 degree (\d+) %", rows[0])
    assert low and int(low[1]) == 2 and float(low[2]) == pytest.approx(0.2, abs=0.01)
    assert float(low[3]) == pytest.approx(np.sqrt((0.1 ** 2 + 0.3 ** 2) / 2), abs=0.01) and low[5] == "0"
    high = re.search(r"stating 0\.5-0\.8 degrees: +(\d+) lines.*RMS ([\d.]+) \(([\d.]+) times.*beyond 1 degree "
                     r"(\d+) %", rows[1])
    assert high and int(high[1]) == 2 and high[4] == "100"
    assert float(high[3]) == pytest.approx(np.sqrt(10.0) / 0.65, abs=0.05)


def test_the_wall_maps_lines_of_a_recording_lie_along_its_scenes_walls(recording, capsys):
    # The room is a rectangle: its walls run along x and y.
    assert wall_lines.scene_directions(recording) == pytest.approx([0.0, np.pi / 2])
    assert wall_lines.main([recording, "--by-stated"]) == 0
    out = capsys.readouterr().out.splitlines()
    heads = [i for i, line in enumerate(out) if line.endswith("by what each line states:")]
    assert [out[i] for i in heads] == ["true poses, by what each line states:", "own poses, by what each line states:"]
    grouped = out[heads[0] + 1:heads[1]]
    out = out[:heads[0]]
    assert [line.split()[1] for line in out] == ["true", "own"]
    truth = re.search(r"(\d+) lines, +(\d+) within 10 degrees: median \|error\| ([\d.]+), RMS ([\d.]+)", out[0])
    assert truth, out[0]
    # Placed by the true poses the lines err by their points' places alone: most of them lie on a
    # wall, within a degree or two of its direction.
    assert int(truth[2]) >= 0.6 * int(truth[1]) > 0
    assert float(truth[3]) < 2.0
    # Grouped by what they state, the same lines near a wall, each once.
    assert sum(int(re.search(r"degrees: +(\d+) lines", line)[1]) for line in grouped) == int(truth[2])
