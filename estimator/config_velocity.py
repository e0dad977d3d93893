"""The estimator's settings of the linear velocity from a point cloud's Doppler (paper III-A) and
of the forward speed of clouds without elevation: a part of :class:`~.config.EstimatorConfig`,
which re-exports it.  Units: metres, seconds, radians."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..settings import Settings, check_choice
from .config_limits import VELOCITY, check_limits

PROJECTIONS = ("divide", "paper", "none")


@dataclass
class VelocityConfig(Settings):
    """Linear velocity from the point cloud's Doppler (paper III-A)."""

    _what = "velocity"

    #: Fewer points than this (after the elevation cut): no fit ("few_points").
    min_points: int = 5
    #: RANSAC hypotheses, each from two points; drawn all at once.
    ransac_iterations: int = 100
    #: |measured - predicted| radial velocity of an inlier, m/s (the Doppler bin is 0.07 m/s).
    inlier_threshold_mps: float = 0.1
    #: The fit is refused below this share of inliers (moving objects above 1 - this).
    min_inlier_ratio: float = 0.35
    #: Points within this of zero Doppler count as standing still, m/s ...
    zero_velocity_threshold_mps: float = 0.04
    #: ... and when at least this share does, the sensor stands still.
    zero_velocity_ratio: float = 0.7
    #: How a point's radial velocity relates to the planar velocity: "divide" by cos(elevation)
    #: (a static point's Doppler is -(v . u_xy) cos(el)); "paper" multiplies by it, as the
    #: paper's text under eq. 1 writes; "none" ignores elevation.
    elevation_projection: str = "divide"
    #: Points further above or below the horizon than this are not used, rad.
    max_elevation_rad: float = math.radians(40.0)
    #: Largest condition number of the inliers' normal matrix: above it the azimuths are too
    #: few or too clustered to tell vx from vy ("ill_conditioned").
    max_condition: float = 200.0
    #: The platform's largest acceleration, m/s^2 (None: any): a point cloud's velocity further
    #: from the last one measured than this allows over the time between them (plus the last
    #: one's noise) is refused for the consensus of the points a reachable velocity explains
    #: ("implausible" when they make none).
    max_accel_mps2: float | None = 5.0
    #: A detection's bearing error, rad (0: an unweighted fit): each inlier is weighted by its radial
    #: velocity's error, ``doppler_noise_mps`` and this times its slope with bearing at the
    #: unweighted fit's velocity, in quadrature: a bearing degrees off (two returns merged in a
    #: beam) misleads the fit less where it matters most (docs/heading.md item 20).
    bearing_noise_rad: float = math.radians(4.0)
    #: The radial velocity's own error in those weights, m/s (uniform over the shipped cfg's 0.07 m/s bin).
    doppler_noise_mps: float = 0.02
    #: A cloud without elevation (no raised antenna row: every point's elevation 0) has its forward
    #: velocity scaled by this quantile of its inliers' own forward speeds over the fit's, pooled
    #: over ``level_edge_window_s`` (s) of clouds moving forward or backward, more than sideways, at
    #: ``level_edge_min_mps`` (m/s) or more, where the Doppler's noise is a small share (the level
    #: reflectors' edge: estimator/level_speed.py; None: the fit as if all were level, 2-5 % slow).
    level_edge_quantile: float | None = 0.85
    level_edge_window_s: float = 2.0
    level_edge_min_mps: float = 0.5
    #: Seed of the random generator (results are reproducible).
    seed: int = 0

    def __post_init__(self) -> None:
        self.check_types()
        check_limits(self, VELOCITY)
        check_choice(self.elevation_projection, PROJECTIONS, "elevation_projection")
