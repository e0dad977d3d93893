"""Movers followed across the radar's view (``icp.track_movers``, estimator/movers.py): a person
crossing square to the line of sight, whose Doppler then looks static, stays out of the scan's
points; static structure is never followed; and in the odometry the crossing no longer turns
the heading (synthetic heatmaps, tests/estimator_synth.py)."""

from __future__ import annotations

import dataclasses
import math

import estimator_synth as synth
import numpy as np
import pytest
from radarodom.estimator.features import Features, static_mask
from radarodom.estimator.movers import CONFIRM_HITS, GATE_M, MASK_M, MoverTracks, Track
from radarodom.estimator.odometry import RadarOdometry

DT = 0.1
WALK_MPS = 1.2


def crossing(i: int, strength: float = 4.0):
    """Frame *i* of a person 3 m ahead walking left at 1.2 m/s from 2 m to the right, among the
    twelve static reflectors, seen by a radar standing still: the heatmap and the person's place."""
    person = np.array([3.0, -2.0 + WALK_MPS * DT * i])
    world = np.vstack([synth.SCENE_WORLD, person])
    amplitude = np.r_[np.ones(len(synth.SCENE_WORLD)), strength]
    radial = np.r_[np.zeros(len(synth.SCENE_WORLD)), np.array([0.0, WALK_MPS]) @ person / np.hypot(*person)]
    return synth.heatmap(world, amplitude, radial_velocity=radial, noise=1e-4), person


def cells_near(heatmap, place, radius=0.3) -> np.ndarray:
    """The cells (n_range, n_azimuth) of *heatmap* within *radius* of *place*."""
    r = np.asarray(heatmap.range_m)[:, None]
    b = -np.asarray(heatmap.azimuth_rad)[None, :]
    return np.hypot(r * np.cos(b) - place[0], r * np.sin(b) - place[1]) < radius


def points_near(heatmap, place, radius=0.3) -> Features:
    """Every cell of *heatmap* within *radius* of *place* as a point (weights equal)."""
    near = cells_near(heatmap, place, radius)
    r = np.broadcast_to(np.asarray(heatmap.range_m)[:, None], near.shape)[near]
    b = np.broadcast_to(-np.asarray(heatmap.azimuth_rad)[None, :], near.shape)[near]
    return Features(r, b, np.full(len(r), 1.0 / len(r)), np.ones(len(r)))


def test_a_person_crossing_square_to_the_line_of_sight_stays_out_of_the_points():
    tracks = MoverTracks()
    unflagged_frames = 0
    for i in range(36):
        heatmap, person = crossing(i)
        flagged = ~static_mask(heatmap, np.zeros(2), 0.3)
        tracks.update(heatmap, flagged, np.zeros(2), 0.0, None if i == 0 else DT)
        near_person = points_near(heatmap, person)
        doppler_sees_it = bool((flagged & cells_near(heatmap, person)).any())
        # A track follows the person all the way, flagged or not (a sidelobe's blob may start
        # another for a frame, never followed).
        on_person = [t for t in tracks.tracks if np.hypot(*(t.position - person)) < 0.15]
        assert len(on_person) == 1, i
        assert all(t in on_person for t in tracks.tracks if t.unflagged), i
        track = on_person[0]
        kept = tracks.leave_out(near_person)
        if track.unflagged:
            unflagged_frames += 1
            assert track.hits >= CONFIRM_HITS
            assert len(kept) == len(near_person)  # fewer than three would be left: kept as they are
            far = Features(np.r_[near_person.range_m, 6.0, 7.0, 8.0], np.r_[near_person.bearing_rad, 0.5, 0.6, 0.7],
                           np.full(len(near_person) + 3, 1.0 / (len(near_person) + 3)), np.ones(len(near_person) + 3))
            out = tracks.leave_out(far)
            assert len(out) == 3 and out.weight.sum() == pytest.approx(1.0)
            assert np.all(np.hypot(*(out.xy - person).T) > MASK_M)
        else:
            assert kept is near_person  # flagged: the Doppler already leaves its cells out
        assert doppler_sees_it or track.unflagged
    # Within 14 degrees of square to the line of sight its radial speed is under 0.3 m/s: about
    # 1.5 m of the walk, over a dozen frames.
    assert unflagged_frames >= 10


def test_a_track_is_carried_by_the_radars_own_motion():
    # The radar drives at 0.6 m/s turning left at 10 deg/s while the person walks across 4 m ahead
    # (world frame): the track's prediction has to move and turn with the radar to stay on it.
    speed, rate = 0.6, math.radians(10.0)
    velocity = np.array([speed, 0.0])
    tracks = MoverTracks()
    pose = np.zeros(3)
    followed = 0
    for i in range(30):
        if i:
            pose = pose + [speed * DT * math.cos(pose[2] + 0.5 * rate * DT),
                           speed * DT * math.sin(pose[2] + 0.5 * rate * DT), rate * DT]
        person_world = np.array([4.0, -3.0 + WALK_MPS * DT * i])
        body = synth.world_to_body(np.vstack([synth.SCENE_WORLD, person_world]), tuple(pose))
        bearing = np.arctan2(body[:, 1], body[:, 0])
        unit = np.column_stack([np.cos(bearing), np.sin(bearing)])
        own = np.zeros((len(body), 2))
        own[-1] = synth.rot(-pose[2]) @ [0.0, WALK_MPS]  # the person's velocity in the radar's axes
        radial = ((own - velocity) * unit).sum(axis=1)
        heatmap = synth.heatmap(body, np.r_[np.ones(len(synth.SCENE_WORLD)), 4.0], radial_velocity=radial,
                                noise=1e-4)
        tracks.update(heatmap, ~static_mask(heatmap, velocity, 0.3), velocity, rate * DT, None if i == 0 else DT)
        for track in tracks.tracks:
            if track.unflagged:  # followed without flags: only ever near the person (its last
                # flagged cells, the blob's edge, can pull a track off by up to the mask's radius)
                assert np.hypot(*(track.position - body[-1])) < 0.6, i
                followed += 1
    assert followed >= 6  # it crossed unflagged for several frames and was followed there


def test_the_prediction_moves_with_the_radar_and_the_track():
    # A track 3 m ahead walking left at 3 m/s; the radar drives at 3 m/s and turns 0.1 rad in the
    # step: the blob where the track must be now is taken, one where a sign error would put it
    # (each beyond the 0.5 m gate) is not.
    turn, dt = 0.1, DT
    radar = np.array([3.0, 0.0])
    expected = synth.rot(-turn) @ (np.array([3.0, 0.0]) - radar * dt) + synth.rot(-turn) @ [0.0, 3.0] * dt
    wrong = [synth.rot(turn) @ (np.array([3.0, 0.0]) - radar * dt) + synth.rot(turn) @ [0.0, 3.0] * dt,
             synth.rot(-turn) @ (np.array([3.0, 0.0]) + radar * dt) + synth.rot(-turn) @ [0.0, 3.0] * dt,
             synth.rot(-turn) @ (np.array([3.0, 0.0]) - radar * dt) - synth.rot(-turn) @ [0.0, 3.0] * dt]
    grid = np.zeros((2, 2))
    for place, taken in [(expected, True)] + [(w, False) for w in wrong]:
        assert taken or np.hypot(*(place - expected)) > GATE_M
        track = Track(np.array([3.0, 0.0]), np.array([0.0, 3.0]), 1.0, hits=CONFIRM_HITS, moved=True)
        used = [False]
        alive = MoverTracks._update(track, [(place, 0.8)], used, grid > 0, grid, grid, grid, radar, turn, dt)
        assert used == [taken]
        if taken:
            assert alive and np.allclose(track.position, expected) and track.hits == CONFIRM_HITS + 1


def test_without_a_doppler_channel_a_live_track_ends():
    tracks = MoverTracks()
    for i in range(12):  # a followed track: flagged, then crossing
        heatmap, _ = crossing(i)
        tracks.update(heatmap, ~static_mask(heatmap, np.zeros(2), 0.3), np.zeros(2), 0.0, None if i == 0 else DT)
    assert tracks.tracks and tracks.tracks[0].unflagged > 0
    heatmap, person = crossing(12)
    tracks.update(dataclasses.replace(heatmap, doppler_mps=None), np.zeros(heatmap.intensity.shape, bool),
                  np.zeros(2), 0.0, DT)
    assert tracks.tracks == []
    points = points_near(heatmap, person)
    assert tracks.leave_out(points) is points


@pytest.mark.parametrize("pattern", ["flickering", "steady"])
def test_static_structure_is_never_followed(pattern):
    # A static reflector 3 m ahead whose Doppler reads 0.8 m/s every other frame (a ghost), or
    # in every frame until it stops (a fan): tracks start, but none is followed unflagged.
    tracks = MoverTracks()
    place = np.array([3.0, 0.5])
    for i in range(30):
        odd = pattern == "flickering" and i % 2 == 1
        radial = 0.0 if odd or (pattern == "steady" and i >= 15) else 0.8
        world = np.vstack([synth.SCENE_WORLD, place])
        heatmap = synth.heatmap(world, np.r_[np.ones(len(synth.SCENE_WORLD)), 4.0],
                                radial_velocity=np.r_[np.zeros(len(synth.SCENE_WORLD)), radial], noise=1e-4)
        flagged = ~static_mask(heatmap, np.zeros(2), 0.3)
        tracks.update(heatmap, flagged, np.zeros(2), 0.0, None if i == 0 else DT)
        assert not any(t.unflagged for t in tracks.tracks), i
        points = points_near(heatmap, place)
        assert tracks.leave_out(points) is points


def run(track: bool, strength: float) -> list[float]:
    odom = RadarOdometry(synth.heatmap_chain(icp={"track_movers": track}))
    return [odom.step(DT * i, synth.static_cloud((0.0, 0.0), seed=i), crossing(i, strength)[0]).yaw
            for i in range(36)]


@pytest.mark.parametrize("strength", [1.0, 4.0])
def test_in_the_odometry_the_crossing_turns_the_heading_less(strength):
    # The radar stands still: every degree of heading is the crossing's.
    followed, not_followed = run(True, strength), run(False, strength)
    worst_followed = max(abs(y) for y in followed)
    worst = max(abs(y) for y in not_followed)
    assert worst > math.radians(0.25)  # the crossing does turn the heading without it
    assert worst_followed < 0.6 * worst
    assert followed[:11] == not_followed[:11]  # the same until the track is first followed
