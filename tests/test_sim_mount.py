"""The simulator's radar mount: a radar ahead of a wheeled base's rotation axis moves sideways
at yaw rate x lever arm (issue 20); the trajectory's poses are the radar's, base_pose the base's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from radarodom.driver.sim.trajectory import from_segments, from_spec
from radarodom.errors import ConfigError

SEGMENTS = [{"pause": 0.5}, {"straight": 1.0, "speed": 0.5}, {"rotate": 90, "rate": 45},
            {"turn": -60, "radius": 1.0, "speed": 0.6}, {"pause": 0.5}]


def test_no_mount_is_the_same_trajectory_as_before():
    plain = from_segments(SEGMENTS, start=(1.0, 2.0, 30.0))
    zero = from_spec({"start": [1.0, 2.0, 30.0], "mount": [0, 0, 0], "segments": SEGMENTS})
    for a, b in ((plain.x, zero.x), (plain.y, zero.y), (plain.yaw, zero.yaw)):
        assert np.array_equal(a, b)
    assert plain.mount == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("mount", [(0.3, 0.0, 0.0), (-0.25, 0.1, 0.0), (0.2, -0.1, 15.0)])
def test_the_radar_moves_sideways_at_yaw_rate_times_lever_arm(mount):
    base = from_segments(SEGMENTS, start=(1.0, 2.0, 30.0))
    radar = from_segments(SEGMENTS, start=(1.0, 2.0, 30.0), mount=mount)
    t = np.linspace(0.0, radar.duration_s, 400)
    # The base is recovered exactly from the radar's poses.
    for a, b in zip(radar.base_pose(t), base.pose(t)):
        np.testing.assert_allclose(a, b, atol=1e-9)
    # The radar's velocity, in its own frame, is the base's forward speed plus omega x lever arm.
    vx, vy, w = radar.velocity(t)
    _, _, yaw = radar.pose(t)
    c, s = np.cos(yaw), np.sin(yaw)
    fwd, left = c * vx + s * vy, -s * vx + c * vy
    bvx, bvy, bw = base.velocity(t)
    _, _, byaw = base.pose(t)
    speed = np.cos(byaw) * bvx + np.sin(byaw) * bvy
    mx, my, myaw = mount[0], mount[1], math.radians(mount[2])
    # Base frame: v_radar = (speed - w my, w mx); the radar's frame is turned by the mount's yaw.
    ex, ey = speed - bw * my, bw * mx
    want_fwd = math.cos(myaw) * ex + math.sin(myaw) * ey
    want_left = -math.sin(myaw) * ex + math.cos(myaw) * ey
    np.testing.assert_allclose(fwd, want_fwd, atol=2e-3)
    np.testing.assert_allclose(left, want_left, atol=2e-3)
    np.testing.assert_allclose(w, bw, atol=1e-9)
    # A turn in place moves the radar on a circle of the lever arm's radius around the axis.
    in_place = (np.abs(bw) > 0.1) & (np.hypot(bvx, bvy) < 1e-6)
    assert in_place.sum() > 10
    np.testing.assert_allclose(np.hypot(fwd, left)[in_place], np.abs(bw[in_place]) * math.hypot(mx, my), atol=2e-3)


@pytest.mark.parametrize("mount", [[0.3, 0.0], "ahead", [0.3, float("nan"), 0.0], [True, 0, 0]])
def test_a_bad_mount_is_refused_naming_it(mount):
    with pytest.raises(ConfigError, match="mount must be"):
        from_spec({"mount": mount, "segments": SEGMENTS})
