"""What the odometry publishes after each heatmap frame (:class:`OdometryState`), apart from
:class:`~.odometry.RadarOdometry`, which makes it, since the sinks, messages and views read it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .icp import Registration
from .quality import Flag
from .velocity import VelocityEstimate

__all__ = ["OdometryState"]


@dataclass
class OdometryState:
    """The odometry after one heatmap frame."""

    t: float
    frame: int
    x: float = 0.0  # m, world frame
    y: float = 0.0
    yaw: float = 0.0  # rad, counter-clockwise, unwrapped
    vx: float = 0.0  # m/s, body frame (forward)
    vy: float = 0.0  # m/s, body frame (left)
    yaw_rate: float = 0.0  # rad/s
    #: Covariance of (x, y, yaw), propagated, and of (vx, vy, yaw_rate) of this step.
    pose_covariance: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    twist_covariance: np.ndarray = field(default_factory=lambda: np.eye(3))
    flags: tuple[Flag, ...] = ()
    features: int = 0
    #: The yaw increment since the previous state, rad, and what registration gave it (after a
    #: bridged run, ``odometry.bridge_s``: the registration across the run).
    yaw_increment: float = 0.0
    registration: Registration | None = None
    velocity: VelocityEstimate | None = None
    #: Time spent in the estimator for this frame, s: the velocity estimates from the point
    #: clouds since the previous heatmap frame (:meth:`~.odometry.RadarOdometry.add_points`), then the
    #: features, the registrations and the integration.
    compute_s: float = 0.0

    @property
    def ok(self) -> bool:
        return not (set(self.flags) - {Flag.FIRST_FRAME})

    @property
    def pose(self) -> tuple[float, float, float]:
        return self.x, self.y, self.yaw
