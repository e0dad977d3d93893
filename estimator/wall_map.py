"""Beyond the paper: the heading held by the walls' directions (``wall_map``; docs/estimator.md, "A
map of wall directions"; docs/heading.md item 35).

A long straight wall's direction does not depend on which part of it the radar sees, nor from
where, so a wall seen again says how far the heading has drifted since.  Every frame, the static
points of the last ``window_frames`` frames, placed by the odometry's own poses in the latest
frame's axes, are searched for straight lines (a Hough vote, then a total-least-squares fit of each
line's points).  Each line is matched to a wall seen before by its direction and place, while the
heading turned by at most ``match_span_rad`` over those frames (the line the less certain the more
it turned: ``span_noise``; the gates the wider the more the heading turned since the wall was
last seen: ``gate_turn_error``), or, while it held (``steady_rad`` over ``settle_frames``), starts
a new wall.  A small Kalman filter holds the heading and every wall's direction in the world: the
odometry's turn over each frame moves the heading and grows its variance (``turn_noise``,
``distance_noise_rad_per_m``, ``frame_noise_rad``); a wall seen again measures their difference.
What is published is the odometry's state with the filter's heading and its position integrated
again from the odometry's own steps along it: the velocities, the yaw rate and the covariances stay
the odometry's.

A wall seen again corrects a turn's error during the turn where the window's frames still see it,
else in the frames after the turn (docs/heading.md says what that does to the straight drives'
figures); where no wall is seen the heading is the odometry's.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace
from typing import Iterable, Protocol, TypeVar

import numpy as np

from .angles import wrap_line
from .config_wall_map import WallMapConfig
from .point_yaw import static_points

#: The Hough vote's grid: directions every this, rad, ...
_HOUGH_STEP_RAD = math.radians(0.5)
#: ... offsets every this, m (a vote counts in its bin and the two beside it).
_HOUGH_BIN_M = 0.05
#: A line's points are taken again within ``band_m`` of its fit this many times.
_REFITS = 3
#: A line's spread across it is at least this, m (the points are placed to a range bin or so).
_MIN_SPREAD_M = 0.02
#: A line's places along it are counted in bins of this, m: the window's frames see the same
#: reflectors again, and a line's precision is that of the places it was seen at, not of its points
#: (docs/heading.md item 42).
_PLACE_BIN_M = 0.1
#: A line is a wall seen before only within this many standard deviations of its direction.
_GATE_SIGMAS = 3.0


class _State(Protocol):
    """What the map reads of an odometry state (estimator.odometry.OdometryState)."""

    t: float
    x: float
    y: float
    yaw: float
    vx: float
    vy: float
    yaw_increment: float


_S = TypeVar("_S", bound=_State)


@dataclass(frozen=True)
class WallLine:
    """A straight line through static points, in the axes they are given in."""

    #: Its direction, rad in [-pi/2, pi/2) (a line has no sense).
    direction: float
    #: The middle of its points, (2,) m.
    middle: np.ndarray
    #: The direction's standard deviation from the points' spread across it and the places along it
    #: they were seen at, rad.
    std: float


def _rot(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def placed_points(static: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Static points (n, 2) m in the radar's axes at *pose* (x m, y m, yaw rad), placed in the
    world: (n, 2) m."""
    return (_rot(pose[2]) @ static.T).T + pose[:2]


def window_points(placed: Iterable[np.ndarray], pose: np.ndarray, max_range_m: float) -> np.ndarray | None:
    """A window's points placed in the world (:func:`placed_points`, one (n, 2) m array a frame) in
    the axes of *pose*, within *max_range_m* of it: (n, 2) m; None if no frame has any."""
    placed = [points for points in placed if len(points)]
    if not placed:
        return None
    here = (np.concatenate(placed) - pose[:2]) @ _rot(pose[2])
    # The vote's grid spans the points: those of frames the odometry placed far off (a
    # velocity of kilometres a second) would make it gigabytes.
    return here[np.hypot(here[:, 0], here[:, 1]) <= max_range_m]


def _axes(centred: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unit vectors (2,) along and across the line through *centred* points (n, 2) m, their
    mean at 0: the total-least-squares fit, the principal axis of their 2 x 2 scatter in closed
    form (an SVD of the (n, 2) points per fit was much of the map's time: docs/benchmarks.md)."""
    sxx, syy = np.einsum("ij,ij->j", centred, centred)
    sxy = float(centred[:, 0] @ centred[:, 1])
    angle = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    along = np.array([math.cos(angle), math.sin(angle)])
    return along, np.array([-along[1], along[0]])


def wall_lines(points: np.ndarray, config: WallMapConfig) -> list[WallLine]:
    """The straight lines the points (n, 2) m draw, the most points first: each with at least
    ``min_points`` within ``band_m`` of it over at least ``min_length_m``, ``max_lines`` at most."""
    found: list[WallLine] = []
    points = np.asarray(points, float).reshape(-1, 2)
    if len(points) < config.min_points:
        return found
    thetas = np.arange(0.0, math.pi, _HOUGH_STEP_RAD)
    normals = np.stack([np.cos(thetas), np.sin(thetas)])  # (2, T)
    # Every point's vote (direction, offset bin) once, as one index into the (T, width) grid; a
    # line's points take theirs back.
    offsets = np.round(points @ normals / _HOUGH_BIN_M).astype(np.int64)  # (n, T) bins
    low = int(offsets.min())
    width = int(offsets.max()) - low + 3
    votes_at = offsets - low + 1 + np.arange(len(thetas)) * width  # (n, T) into the flat grid
    counts = np.bincount(votes_at.ravel(), minlength=len(thetas) * width)
    # Each bin with its two neighbours along the offset (the first and last columns are never
    # voted in, so no row reaches into the next).
    votes = counts.copy()
    votes[1:] += counts[:-1]
    votes[:-1] += counts[1:]
    voting = np.ones(len(points), bool)
    for _ in range(config.max_lines):
        if voting.sum() < config.min_points:
            break
        best = int(np.argmax(votes))
        if votes[best] < config.min_points:
            break
        best_theta, best_bin = divmod(best, width)
        left = points[voting]
        normal = normals[:, best_theta]
        near = np.abs(left @ normal - (best_bin - 1 + low) * _HOUGH_BIN_M) < config.band_m
        for _ in range(_REFITS):
            if near.sum() < config.min_points:
                break
            middle = left[near].mean(axis=0)
            normal = _axes(left[near] - middle)[1]
            near = np.abs((left - middle) @ normal) < config.band_m
        on = left[near]
        gone = np.flatnonzero(voting)[near]
        voting[gone] = False
        taken = np.bincount(votes_at[gone].ravel(), minlength=len(votes))
        votes -= taken  # the smoothed votes they gave
        votes[1:] -= taken[:-1]
        votes[:-1] -= taken[1:]
        if len(on) < config.min_points:
            break
        on = _longest_run(on, config.max_gap_m)
        if len(on) < config.min_points:
            continue
        middle = on.mean(axis=0)
        along, normal = _axes(on - middle)
        spread = (on - middle) @ along
        length = float(spread.max() - spread.min())
        if length < config.min_length_m:
            continue
        across = max(float(((on - middle) @ normal).std()), _MIN_SPREAD_M)
        places = len(np.unique(np.floor(spread / _PLACE_BIN_M)))
        found.append(WallLine(wrap_line(math.atan2(along[1], along[0])), middle,
                              across * math.sqrt(12.0 / places) / length))
    return found


def _longest_run(points: np.ndarray, max_gap_m: float) -> np.ndarray:
    """Of *points* (n, 2) m near a line, those of its longest stretch without a gap wider than
    *max_gap_m* along it: a piece of furniture and a stray point in line with it are no wall."""
    middle = points.mean(axis=0)
    along = _axes(points - middle)[0]
    order = np.argsort((points - middle) @ along)
    position = (points[order] - middle) @ along
    breaks = np.flatnonzero(np.diff(position) > max_gap_m) + 1
    runs = np.split(order, breaks)
    return points[max(runs, key=len)]


class WallMap:
    """The odometry's states with the heading the walls correct (:meth:`__call__`), fed each
    frame's point clouds first (:meth:`add_points`)."""

    def __init__(self, config: WallMapConfig) -> None:
        self.config = config
        self._clouds: list[np.ndarray] = []  # the point clouds since the last frame
        #: The last frames' static points (n, 2) m, placed in the world by the odometry's poses.
        self._window: deque[np.ndarray] = deque(maxlen=config.window_frames)
        #: The odometry's heading over the last ``settle_frames`` frames, rad.
        self._headings: deque[float] = deque(maxlen=max(config.settle_frames, config.window_frames))
        self._last: np.ndarray | None = None  # the odometry's last pose
        self._position = np.zeros(2)  # m, the published position
        #: The filter: the heading, then each wall's direction (rad, world), and their covariance.
        self._x = np.zeros(1)
        self._p = np.zeros((1, 1))
        self._wall_points = np.zeros((0, 2))  # a point on each wall, m (world), ...
        self._wall_seen = np.zeros(0)  # ... when it was last seen, s, ...
        self._wall_heading = np.zeros(0)  # ... and the heading then, rad

    @property
    def walls(self) -> int:
        """The walls held."""
        return len(self._wall_seen)

    def add_points(self, points: np.ndarray) -> None:
        """A point cloud (TI frame fields x, y, elevation, velocity) taken since the last frame."""
        self._clouds.append(points)

    def __call__(self, state: _S) -> _S:
        """*state* with its heading corrected by the walls and its position integrated along it."""
        clouds, self._clouds = self._clouds, []
        cloud = np.concatenate(clouds) if clouds else None
        static = np.zeros((0, 2)) if cloud is None or not len(cloud) else \
            static_points(cloud, np.array([state.vx, state.vy]), self.config.static_threshold_mps)
        pose = np.array([state.x, state.y, state.yaw])
        previous_yaw, first = float(self._x[0]), self._last is None
        if first:
            self._position, self._x[0] = pose[:2].copy(), pose[2]
        else:
            self._predict(self._last, pose)
        self._last = pose
        self._window.append(placed_points(static, pose))
        self._headings.append(pose[2])
        span = self._span(self.config.window_frames)
        if span <= self.config.match_span_rad:
            settled = self._span(self._headings.maxlen) <= self.config.steady_rad
            self._observe(state.t, pose, span, may_start=settled)
        heading = float(self._x[0])
        return replace(state, x=float(self._position[0]), y=float(self._position[1]), yaw=heading,
                       yaw_increment=state.yaw_increment if first else heading - previous_yaw)

    def _predict(self, last: np.ndarray, pose: np.ndarray) -> None:
        """Move the heading and the position by the odometry's step from *last* to *pose*."""
        turn = pose[2] - last[2]
        step = _rot(-last[2]) @ (pose[:2] - last[:2])
        self._position = self._position + _rot(self._x[0]) @ step
        self._x[0] += turn
        c = self.config
        self._p[0, 0] += ((c.turn_noise * turn) ** 2 + (c.distance_noise_rad_per_m * float(np.hypot(*step))) ** 2
                          + c.frame_noise_rad ** 2)

    def _span(self, frames: int) -> float:
        """How far the heading turned over the last *frames* frames, rad (inf: fewer frames yet)."""
        if len(self._headings) < frames:
            return math.inf
        last = list(self._headings)[-frames:]
        return max(last) - min(last)

    def _observe(self, t: float, pose: np.ndarray, span: float, may_start: bool) -> None:
        """Fit lines to the window's static points, over which the heading turned by *span* (rad),
        and match each to a wall or, if *may_start*, start one."""
        here = window_points(self._window, pose, self.config.max_range_m)
        if here is None:
            return
        used = np.zeros(self.walls, bool)
        # Consecutive windows share all their frames but one: each fit's information is counted
        # once over the window.
        shared = self.config.window_frames
        for line in wall_lines(here, self.config):
            variance = (max(line.std, self.config.direction_floor_rad) ** 2
                        + (self.config.span_noise * span) ** 2) * shared
            middle = self._position + _rot(self._x[0]) @ line.middle
            wall = self._match(line.direction, middle, variance, used)
            if wall is None:
                if may_start:
                    self._add_wall(line.direction, middle, variance / shared, t)
                    used = np.append(used, True)
            else:
                self._wall_heading[wall] = self._x[0]
                self._update(wall, line.direction, variance)
                self._wall_seen[wall], used[wall] = t, True
        while self.walls > self.config.max_walls:
            self._forget(int(np.argmin(self._wall_seen)))

    def _match(self, direction: float, middle: np.ndarray, variance: float, used: np.ndarray) -> int | None:
        """The wall (index) a line of *direction* (rad, this frame's axes) through *middle* (world)
        is, the nearest in standard deviations among those within the gates; None: a new one."""
        if not self.walls:
            return None
        heading, walls = self._x[0], self._x[1:]
        innovation = wrap_line(direction - (walls - heading))
        p = self._p
        spread = np.diagonal(p)[1:] + p[0, 0] - 2.0 * p[0, 1:] + variance
        normals = np.stack([-np.sin(walls), np.cos(walls)], 1)
        off = np.abs(np.sum(normals * (middle - self._wall_points), axis=1))
        # A turn's error is one scale over the whole turn, which the filter's per-frame noise
        # understates: after a turn in place a wall seen again lies degrees off its prediction.
        # The gates allow for it by the turn since the wall was last seen (none: as fixed).
        turned = np.abs(heading - self._wall_heading) if self.config.gate_turn_error else 0.0
        allowance = self.config.turn_noise * turned
        gated = spread + allowance ** 2
        gate = self.config.gate_rad
        gate = np.maximum(gate, np.minimum(_GATE_SIGMAS * np.sqrt(gated), gate + _GATE_SIGMAS * allowance))
        squared = innovation ** 2
        fits = ~used & (np.abs(innovation) < gate) & (squared / gated < _GATE_SIGMAS ** 2) \
            & (off < self.config.distance_gate_m)
        return int(np.argmin(np.where(fits, squared / spread, np.inf))) if fits.any() else None

    def _update(self, wall: int, direction: float, variance: float) -> None:
        """The filter given that wall *wall* lies at *direction* from the heading (rad)."""
        j = wall + 1
        innovation = wrap_line(direction - (self._x[j] - self._x[0]))
        h_p = self._p[j] - self._p[0]  # H P with H = e_j - e_0
        gain = h_p / (h_p[j] - h_p[0] + variance)
        self._x = self._x + gain * innovation
        self._p = self._p - np.outer(gain, h_p)

    def _add_wall(self, direction: float, middle: np.ndarray, variance: float, t: float) -> None:
        """A wall first seen at *direction* from the heading (rad), through *middle* (world)."""
        n = len(self._x)
        p = np.zeros((n + 1, n + 1))
        p[:n, :n] = self._p
        p[n, :n] = p[:n, n] = self._p[0]
        p[n, n] = self._p[0, 0] + variance
        self._x, self._p = np.append(self._x, self._x[0] + direction), p
        self._wall_points = np.vstack([self._wall_points, middle])
        self._wall_seen = np.append(self._wall_seen, t)
        self._wall_heading = np.append(self._wall_heading, self._x[0])

    def _forget(self, wall: int) -> None:
        """Drop wall *wall* from the filter (its direction's information about the heading goes)."""
        keep = np.arange(len(self._x)) != wall + 1
        self._x, self._p = self._x[keep], self._p[np.ix_(keep, keep)]
        self._wall_points = np.delete(self._wall_points, wall, axis=0)
        self._wall_seen = np.delete(self._wall_seen, wall)
        self._wall_heading = np.delete(self._wall_heading, wall)
