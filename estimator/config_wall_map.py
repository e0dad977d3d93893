"""The estimator's settings of the map of wall directions that holds the heading on long runs (an
option beyond the paper; estimator/wall_map.py says how, docs/heading.md "A map of wall
directions" what it gives): a part of :class:`~.config.EstimatorConfig`, which re-exports it.
Units: metres, seconds, radians."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..settings import Settings
from .config_limits import WALL_MAP, check_limits


@dataclass
class WallMapConfig(Settings):
    """Walls as landmarks of direction: the straight lines the static points draw, each wall's
    direction kept in a small Kalman filter with the heading, which a wall seen again corrects."""

    _what = "wall-map"

    #: Correct the published heading by the walls seen again (off: the odometry alone; on since
    #: docs/heading.md item 35).
    use: bool = True
    #: Lines are fitted to the static points of this many last frames, ...
    window_frames: int = 10
    #: ... and matched to the walls seen before while the heading turned by at most this over
    #: them, rad (in a turn, so that a wall seen again corrects the turn's error within it), ...
    match_span_rad: float = math.radians(45.0)
    #: ... each line's direction the more uncertain for it by this share of that turn (the frames'
    #: points are placed by the odometry's turn, itself off by a percent or two).
    span_noise: float = 0.01
    #: A line no wall matches starts a new wall only while the heading held within this, rad, ...
    steady_rad: float = math.radians(3.0)
    #: ... over this many last frames (``window_frames`` if more): a wall's direction is kept as
    #: first seen, and after a turn the odometry's heading still moves by what its keyframes correct.
    settle_frames: int = 10
    #: A point counts when it is static, its radial velocity within this of a static reflector's,
    #: m/s, ...
    static_threshold_mps: float = 0.1
    #: ... and within this of the radar where the latest frame places it, m (the Hough vote's grid
    #: spans the points: a stray point kilometres off would make it gigabytes; at most 200 m, some
    #: 50 MB).
    max_range_m: float = 30.0
    #: A wall: at least this many points within ``band_m`` of a line, ...
    min_points: int = 20
    band_m: float = 0.08
    #: ... spanning at least this along it, m (a short run of points is a corner or a piece of
    #: furniture, whose direction changes with the side seen); ...
    min_length_m: float = 1.5
    #: ... with no gap wider than this along it, m (else its longest stretch is taken), ...
    max_gap_m: float = 1.0
    #: ... at most this many walls a frame, the strongest first.
    max_lines: int = 4
    #: The heading's own error grows each frame by this share of the frame's turn, ...
    turn_noise: float = 0.01
    #: ... by this much a metre driven, rad/m, ...
    distance_noise_rad_per_m: float = 0.007
    #: ... and by this much a frame, rad (standard deviations, independent).
    frame_noise_rad: float = math.radians(0.02)
    #: A wall's direction as one window's points give it is uncertain by at least this, rad: its
    #: returns are the points of a few beams, not of a surface.
    direction_floor_rad: float = math.radians(0.5)
    #: A line is a wall seen before when its direction is within this of the wall's, rad, ...
    gate_rad: float = math.radians(5.0)
    #: ... and within three standard deviations, and its middle within this of the wall's line, m.
    distance_gate_m: float = 0.25
    #: Both direction gates allow for the error the heading may have taken since a wall was last
    #: seen by the turn made since: ``turn_noise`` of that turn as one scale over it (the filter
    #: counts a turn's share frame by frame, as independent; docs/heading.md item 41).
    gate_turn_error: bool = True
    #: The walls kept: past this many the one seen longest ago is forgotten (the filter's cost grows
    #: with the square of their number: at most 1000, 8 MB and some milliseconds an update).
    max_walls: int = 200

    def __post_init__(self) -> None:
        self.check_types()
        check_limits(self, WALL_MAP)
