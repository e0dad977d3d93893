"""What a heatmap frame gives made once for both of the blend's chains (estimator/current_frame.py):
each chain gets exactly what it would have made alone, the products are shared where their inputs
are the same, and not where the heatmap or the velocity differ."""

from __future__ import annotations

import math

import estimator_synth as synth
import numpy as np
import pytest

from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.current_frame import CurrentFrame, FrameProducts
from radarodom.estimator.odometry import RadarOdometry

DRIVE = synth.Trajectory([(1.0, 0.8, 0.0), (2.0, 0.8, math.radians(40.0)), (1.0, 0.8, 0.0),
                          (2.0, 0.0, math.radians(60.0)), (0.5, 0.0, 0.0)])


def _state(s):
    return (s.t, s.x, s.y, s.yaw, s.vx, s.vy, s.yaw_rate, s.yaw_increment, s.flags, s.features,
            s.pose_covariance.tobytes(), s.twist_covariance.tobytes())


@pytest.mark.parametrize("changes", [{"features": {"doppler_elevation": "off"}}, {},
                                     {"odometry": {"mount_x_m": 0.3, "base": "wheeled"}}],
                         ids=["no Doppler elevation", "default", "wheeled, radar ahead of the axis"])
def test_each_chain_of_the_blend_gets_to_the_bit_what_it_makes_alone(changes):
    config = EstimatorConfig().with_(**changes)
    frames = synth.frames(DRIVE)
    blend = RadarOdometry(config)
    # Each chain alone as the blend runs it: the map of wall directions corrects only what the
    # blend publishes.
    alone = {"heatmaps": RadarOdometry(config.with_(point_yaw={"blend": 0.0}, wall_map={"use": False})),
             "points": RadarOdometry(config.with_(point_yaw={"use": True, "blend": 0.0}, wall_map={"use": False}))}
    shared = 0
    for t, cloud, hm in frames:
        blend.step(t, cloud, hm)
        heatmaps, points = (alone[k].step(t, cloud, hm) for k in ("heatmaps", "points"))
        assert _state(blend.blend.points.state) == _state(points)
        # The heatmap chain's own state is what it publishes less the blend's turn: its steps are
        # its own (estimator/heading_blend.py), so its next frames equal the chain's alone.
        assert _state(blend._state) == _state(heatmaps)
        mine, theirs = blend._previous, blend.blend.points._previous
        shared += mine.field.smoothed is theirs.field.smoothed
        assert (mine.field.smoothed is theirs.field.smoothed) == (mine.features is theirs.features)
    # The test sees sharing: every frame's products where both chains see the same heatmap and
    # velocity; in the turns, by default each chain's heatmap has its own elevations from the
    # Doppler at its own yaw rate (the synthetic heatmaps have none), and a wheeled base's
    # chains fit their velocities at their own yaw rates: there each makes its own.
    if "features" in changes:
        assert shared == len(frames)
    else:
        assert 0 < shared < len(frames)


def test_a_product_is_made_once_per_heatmap_and_inputs():
    cfg = EstimatorConfig()
    hm, other = synth.scene_heatmap(), synth.scene_heatmap((0.1, 0.0, 0.0))
    products = FrameProducts()
    made = []

    def make(value):
        made.append(value)
        return value

    a, b = CurrentFrame(0.0, hm, cfg, products), CurrentFrame(0.0, hm, cfg, products)
    assert a.made(("x", (1.0, 0.0)), lambda: make(1)) == 1
    assert b.made(("x", (1.0, 0.0)), lambda: make(2)) == 1  # the same heatmap and inputs: shared
    assert b.made(("x", (1.0, 0.5)), lambda: make(3)) == 3  # another velocity
    assert CurrentFrame(0.0, other, cfg, products).made(("x", (1.0, 0.0)), lambda: make(4)) == 4  # another heatmap
    alone = CurrentFrame(0.0, hm, cfg)  # a chain alone: nothing to share
    assert alone.made(("x", (1.0, 0.0)), lambda: make(5)) == 5 and alone.products is None
    assert made == [1, 3, 4, 5]
    # The log heatmap and the field follow the moving cells they were made without.
    a.set_moving(lambda: np.zeros(hm.intensity.shape, bool), (0.3, (1.0, 0.0)))
    b.set_moving(lambda: np.ones(hm.intensity.shape, bool), (0.3, (0.0, 0.0)))
    assert a.log is not b.log and a.smoothed(2.0, 4) is not b.smoothed(2.0, 4)
    c = CurrentFrame(0.0, hm, cfg, products)
    c.set_moving(lambda: np.ones(hm.intensity.shape, bool), (0.3, (1.0, 0.0)))
    assert c.moving is a.moving and c.log is a.log and c.smoothed(2.0, 4) is a.smoothed(2.0, 4)
