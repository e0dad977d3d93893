"""The map of wall directions (``wall_map``, estimator/wall_map.py; docs/heading.md, "A map of wall
directions"): lines found in static points, and an odometry whose turns err corrected by the walls
seen again, in a synthetic room whose walls' returns are the points of each frame."""

from __future__ import annotations

import dataclasses
import math

import estimator_synth as synth
import numpy as np
import pytest

from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig, WallMapConfig
from radarodom.estimator.odometry import OdometryState, RadarOdometry
from radarodom.estimator.wall_map import WallMap, wall_lines

#: The room's walls, each from one end to the other (m, world): 10 by 6 m.
ROOM = [((-2.0, -3.0), (8.0, -3.0)), ((8.0, -3.0), (8.0, 3.0)), ((8.0, 3.0), (-2.0, 3.0)),
        ((-2.0, 3.0), (-2.0, -3.0))]
#: Drive 2 s, turn in place a whole turn, drive on 3 s: the side walls are seen again after it.
LOOP = synth.Trajectory([(2.0, 1.0, 0.0), (4.0, 0.0, math.radians(90.0)), (3.0, 1.0, 0.0)])
#: The same at 30 degrees a second: the window of frames spans 30 degrees of the turn.
SLOW_TURN = synth.Trajectory([(2.0, 1.0, 0.0), (12.0, 0.0, math.radians(30.0)), (3.0, 1.0, 0.0)])


def _wall_points(pose, rng, *, spacing=0.1, noise=0.02, reach=8.0):
    """The walls' points a radar at *pose* sees within *reach* and 60 degrees of its axis, (n, 2) m
    in its axes."""
    out = []
    for a, b in ROOM:
        a, b = np.array(a), np.array(b)
        n = int(np.linalg.norm(b - a) / spacing)
        out.append(a + (b - a) * (np.arange(n)[:, None] + 0.5) / n)
    body = synth.world_to_body(np.concatenate(out), pose)
    r, bearing = np.hypot(body[:, 0], body[:, 1]), np.arctan2(body[:, 1], body[:, 0])
    seen = body[(r < reach) & (r > 0.5) & (np.abs(bearing) < math.radians(60.0))]
    return seen + noise * rng.standard_normal(seen.shape)


def _odometry(turn_scale, *, seed=0, walls=True, jump=(None, 0.0), trajectory=LOOP):
    """The true poses and the odometry's states along *trajectory* at 10 Hz, whose turns are *turn_scale*
    times the true ones (and whose heading jumps by *jump* = (frame, rad)), and the clouds of each
    frame (the walls' points; none without *walls*)."""
    rng = np.random.default_rng(seed)
    truths, states, clouds = [], [], []
    yaw = 0.0
    position = np.zeros(2)
    previous = None
    for i in range(round(trajectory.duration * 10) + 1):
        t = i / 10
        pose = trajectory.pose(t)
        vx, vy, _ = trajectory.twist(t)
        if previous is not None:
            step = synth.rot(-previous[2]) @ (np.array(pose[:2]) - previous[:2])
            position = position + synth.rot(yaw) @ step
            yaw += turn_scale * (pose[2] - previous[2]) + (jump[1] if i == jump[0] else 0.0)
        previous = np.array(pose)
        truths.append(pose)
        states.append(OdometryState(t=t, frame=i, x=float(position[0]), y=float(position[1]), yaw=yaw, vx=vx, vy=vy))
        clouds.append(synth.points(_wall_points(pose, rng), (vx, vy)) if walls else synth.points(np.zeros((0, 2)),
                                                                                             (vx, vy)))
    return truths, states, clouds


def _run(config, states, clouds):
    walls = WallMap(config)
    out = []
    for state, cloud in zip(states, clouds):
        walls.add_points(cloud)
        out.append(walls(state))
    return walls, out


@pytest.fixture(scope="module")
def loop_run():
    """``_odometry(1.004)`` (the loop, its turns 0.4 % long) and the map's run over it with the
    default settings, made once for the tests that read them (never changed)."""
    truths, states, clouds = _odometry(1.004)
    walls, out = _run(WallMapConfig(), states, clouds)
    return truths, states, clouds, walls, out


def test_lines_are_the_walls_the_points_draw():
    rng = np.random.default_rng(1)
    along = np.column_stack([np.linspace(1.0, 5.0, 60), np.full(60, 2.0)])  # 4 m along x at y = 2
    across = np.column_stack([np.full(40, 6.0), np.linspace(-1.0, 1.5, 40)])  # 2.5 m along y at x = 6
    short = np.column_stack([np.linspace(2.0, 2.8, 30), np.full(30, -1.5)])  # 0.8 m: furniture
    clutter = rng.uniform(-4.0, 4.0, (20, 2))
    points = np.concatenate([along, across, short, clutter]) + 0.01 * rng.standard_normal((150, 2))
    lines = wall_lines(points, WallMapConfig())
    assert [round(math.degrees(line.direction)) % 180 for line in lines] == [0, 90]
    assert lines[0].middle == pytest.approx([3.0, 2.0], abs=0.05)
    assert lines[1].middle == pytest.approx([6.0, 0.25], abs=0.05)
    assert all(0 < line.std < math.radians(0.5) for line in lines)
    # Fewer points than a wall needs: none.
    assert wall_lines(along[:10], WallMapConfig()) == []
    assert wall_lines(np.zeros((0, 2)), WallMapConfig()) == []


def test_a_line_seen_again_and_again_at_the_same_places_states_their_precision():
    # A window's frames see the same reflectors again: 24 of them 0.2 m apart along a wall, seen in
    # five frames, are no more precise than seen once (docs/heading.md item 42).
    rng = np.random.default_rng(3)
    reflectors = np.column_stack([np.linspace(1.0, 5.6, 24), 2.0 + 0.03 * rng.standard_normal(24)])
    once = wall_lines(reflectors, WallMapConfig())
    again = np.repeat(reflectors, 5, axis=0) + 0.002 * rng.standard_normal((120, 2))
    five = wall_lines(again, WallMapConfig())
    assert len(once) == len(five) == 1
    assert five[0].direction == pytest.approx(once[0].direction, abs=math.radians(0.5))
    # (Counted by their points, five sightings would state sqrt(5) = 2.2 times less.)
    assert 0.75 * once[0].std < five[0].std < 1.25 * once[0].std
    # Points at more places state more: 120 points over the 4.6 m fill its 46 places of 0.1 m.
    dense = np.column_stack([np.linspace(1.0, 5.6, 120), 2.0 + 0.03 * rng.standard_normal(120)])
    assert wall_lines(dense, WallMapConfig())[0].std == pytest.approx(once[0].std * math.sqrt(24 / 46), rel=0.25)


@pytest.mark.parametrize("seed", range(20))
def test_a_lines_fit_is_the_total_least_squares_one(seed):
    # The closed form of the scatter's principal axis replaced an SVD per fit: the same axes.
    from radarodom.estimator.wall_map import _axes

    rng = np.random.default_rng(seed)
    points = rng.standard_normal((int(rng.integers(2, 200)), 2)) * rng.uniform(0.01, 5.0, 2)
    angle = rng.uniform(-math.pi, math.pi)
    points = points @ np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]).T
    centred = points - points.mean(axis=0)
    along, normal = _axes(centred)
    svd_along, svd_normal = np.linalg.svd(centred, full_matrices=False)[2]
    assert abs(along @ svd_along) == pytest.approx(1.0, abs=1e-9)
    assert abs(normal @ svd_normal) == pytest.approx(1.0, abs=1e-9)
    assert along @ normal == pytest.approx(0.0, abs=1e-12)


def test_walls_seen_again_correct_a_turn_that_erred(loop_run):
    assert WallMapConfig().use  # the shared run's settings: the map in use
    truths, states, _, walls, out = loop_run
    final_truth = truths[-1][2]
    odometry_error = math.degrees(states[-1].yaw - final_truth)
    assert odometry_error == pytest.approx(1.44, abs=0.01)  # 0.4 % of a whole turn
    assert abs(math.degrees(out[-1].yaw - final_truth)) < 0.3
    assert 2 <= walls.walls <= 6  # the room's four walls, one seen from both sides at most twice
    # Before the turn the walls are only being learnt (each seen again from the straight moves the
    # heading by its points' noise alone): the odometry's heading, within a thousandth of a degree.
    before = round(2.0 * 10)
    assert [s.yaw for s in out[:before]] == pytest.approx([s.yaw for s in states[:before]], abs=math.radians(1e-3))
    # The published position follows the corrected heading: the last straight nearer the truth.
    assert np.hypot(out[-1].x - truths[-1][0], out[-1].y - truths[-1][1]) < \
        np.hypot(states[-1].x - truths[-1][0], states[-1].y - truths[-1][1])
    # Each state's increment is its change of heading.
    assert [s.yaw_increment for s in out[1:]] == pytest.approx(np.diff([s.yaw for s in out]), abs=1e-12)


def test_without_walls_the_odometry_passes_through():
    _, states, clouds = _odometry(1.004, walls=False)
    walls, out = _run(WallMapConfig(use=True), states, clouds)
    assert walls.walls == 0
    assert np.array([s.pose for s in out]) == pytest.approx(np.array([s.pose for s in states]), abs=1e-9)


def test_a_turn_that_erred_is_corrected_while_it_turns_and_no_wall_starts_in_it():
    """Lines fitted while the heading turns (up to ``match_span_rad``, 45 degrees, over the window:
    here 30) are matched to the walls seen before it: a turn 1.5 % off (5.4 degrees over a whole
    turn) is mostly corrected by its end, and no new wall is started while turning."""
    truths, states, clouds = _odometry(1.015, trajectory=SLOW_TURN)
    walls = WallMap(WallMapConfig())
    counts, out = [], []
    for state, cloud in zip(states, clouds):
        walls.add_points(cloud)
        out.append(walls(state))
        counts.append(walls.walls)
    turn = slice(round(2.0 * 10) + 1, round(14.0 * 10) + 1)
    assert counts[turn][-1] == counts[turn][0]
    end = turn.stop - 1
    assert math.degrees(states[end].yaw - truths[end][2]) == pytest.approx(5.4, abs=0.05)
    assert abs(math.degrees(out[end].yaw - truths[end][2])) < 3.0
    assert abs(math.degrees(out[-1].yaw - truths[-1][2])) < 1.5
    # Matched only while the heading holds, the walls seen after the turn lie 5.4 degrees off their
    # prediction: past the fixed gates (5 degrees, three standard deviations of the filter's own
    # spread), ...
    fixed = WallMapConfig(match_span_rad=math.radians(3.0), gate_turn_error=False)
    _, late = _run(fixed, states, clouds)
    assert math.degrees(late[-1].yaw - truths[-1][2]) == pytest.approx(5.4, abs=0.1)
    # ... within gates that allow for the turn's error since they were last seen (1 % of 360
    # degrees): matched, they take back half of it by the run's end.
    _, late = _run(dataclasses.replace(fixed, gate_turn_error=True), states, clouds)
    assert 0.5 < math.degrees(late[-1].yaw - truths[-1][2]) < 3.5


def test_a_heading_that_jumped_past_the_gate_starts_new_walls():
    """An odometry heading off by 8 degrees at once (a wrong registration) is past ``gate_rad``: the
    walls seen after it are new ones, and the heading stays the odometry's."""
    truths, states, clouds = _odometry(1.0, jump=(75, math.radians(8.0)))
    walls, out = _run(WallMapConfig(), states, clouds)
    assert out[-1].yaw == pytest.approx(states[-1].yaw, abs=math.radians(0.2))
    assert walls.walls >= 4


def test_points_beyond_the_range_are_left_out(loop_run):
    """Static points past ``max_range_m`` (30 m) are left out: a wall 45 m ahead is none (the
    vote's grid spans the points, and a stray point kilometres off would make it gigabytes)."""
    truths, states, clouds, walls, near_only = loop_run
    wall = np.column_stack([np.full(30, 45.0), np.linspace(-2.0, 2.0, 30)])
    far = [np.concatenate([cloud, synth.points(synth.world_to_body(wall, pose), (s.vx, s.vy))])
           for s, cloud, pose in zip(states, clouds, truths)]
    walls_far, with_far = _run(WallMapConfig(), states, far)
    assert walls_far.walls == walls.walls
    assert np.array([s.pose for s in with_far]) == pytest.approx(np.array([s.pose for s in near_only]), abs=1e-12)
    # Within the range, the same wall is one.
    more, _ = _run(WallMapConfig(max_range_m=60.0), states, far)
    assert more.walls > walls.walls


def test_a_window_the_odometry_spread_far_stays_small():
    """An odometry that jumps 500 m a frame (a garbled velocity) places the window's earlier points
    kilometres off: they are left out (``max_range_m`` in the latest frame's axes), and the vote's
    grid stays megabytes, not gigabytes."""
    import tracemalloc

    _, states, clouds = _odometry(1.0)
    jumped = [dataclasses.replace(s, x=s.x + 500.0 * i) for i, s in enumerate(states[:30])]
    tracemalloc.start()
    try:
        walls, out = _run(WallMapConfig(), jumped, clouds[:30])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(out) == 30 and all(math.isfinite(s.yaw) for s in out)
    assert peak < 50e6


def test_the_walls_kept_are_bounded(loop_run):
    _, states, clouds, _, _ = loop_run
    walls, out = _run(WallMapConfig(use=True, max_walls=1), states, clouds)
    assert walls.walls == 1
    assert len(out) == len(states)


def test_the_estimator_publishes_the_corrected_heading():
    """RadarOdometry with ``wall_map.use`` (the default): its states are the map's of its own
    odometry; the blend's points' estimator runs without one, and the paper's method too."""
    config = EstimatorConfig()
    assert config.wall_map.use and not EstimatorConfig.paper().wall_map.use
    odom = RadarOdometry(config)
    assert odom.walls is not None and odom.blend is not None and odom.blend.points.walls is None
    plain = RadarOdometry(EstimatorConfig().with_(wall_map={"use": False}))
    walls = WallMap(config.wall_map)
    _, states, clouds = _odometry(1.0, seed=3)
    corrected = 0.0
    # The loop's first 3.5 s: its straight and the turn's first half, where the map corrects.
    for state, cloud in list(zip(states, clouds))[:35]:
        heatmap = synth.scene_heatmap(LOOP.pose(state.t))
        got = odom.step(state.t, cloud, heatmap)
        walls.add_points(cloud)
        published = plain.step(state.t, cloud, heatmap)
        expected = walls(published)
        assert got.pose == pytest.approx(expected.pose, abs=1e-12)
        assert got.compute_s > 0
        corrected = max(corrected, abs(got.pose[2] - published.pose[2]))
    assert corrected > 1e-5  # the map did correct the heading


def test_settings_are_checked():
    assert EstimatorConfig.from_dict({"wall_map": {"use": True}}).wall_map.use
    with pytest.raises(ConfigError, match=r"wall_map\.window_frames: must be in \[2, 100\], got 1"):
        EstimatorConfig.from_dict({"wall_map": {"window_frames": 1}})
    with pytest.raises(ConfigError, match=r"wall_map\.gate_rad"):
        EstimatorConfig.from_dict({"wall_map": {"gate_rad": 2.0}})
