"""Beyond the paper: the heading of two registrations of the same frames, blended
(``point_yaw.blend``; docs/heading.md, item 30).

The heatmap field's registration (frame to frame, keyframes) and the point map's (each frame's
points against the last seconds' map, estimator/point_yaw.py) err by their own draws of the
scene's speckle: over the robustness matrix the two chains' turns in place, drift and straight
drives hardly correlate from cell to cell, so a share of each holds the heading better than
either alone.  The two run side by side, unaware of each other (each its own velocity fit, yaw-rate
filter and keyframes or map); what is published is the heatmap chain's state, each step's turn
moved *share* of the way to the points' chain's turn over the same step (the heatmap chain's
alone over frames lost and where the points' chain has long measured nothing; the points' whole
where the heatmap chain held its rate and the points' chain measured the step, item 39), and its position
integrated from the heatmap chain's own steps along that heading; its covariances the heatmap
chain's, the heading's walked further by the turn the blend adds.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Protocol

import numpy as np

from .quality import UNMEASURED_TURN


#: A step longer than this many frame periods has lost frames.
_LOST = 1.5


class _Odometry(Protocol):
    """What the blend needs of the points' estimator (a RadarOdometry with ``point_yaw.use``)."""

    def add_points(self, t: float, points: np.ndarray, *, velocity=None): ...

    def add_velocity(self, est) -> None: ...

    def add_heatmap(self, t: float, heatmap, *, products=None): ...


class HeadingBlend:
    """The published state of each frame from the heatmap chain's (:meth:`__call__`), the
    points' estimator fed the same points and heatmaps."""

    def __init__(self, points: _Odometry, share: float, walk_var_rad: float, catch_up_steps: int, *,
                 points_where_held: bool) -> None:
        self.points = points
        self.share = share
        #: Where the heatmap chain's step measured no turn (its rate held, or its motion lost) and
        #: the points' chain's did, the points' turn whole (``point_yaw.blend_points_where_held``).
        self.points_where_held = points_where_held
        #: The points' chain makes up for a turn it held within this many steps (its map's
        #: ``point_yaw.lag_frames``): a held step of its is blended only so soon after a measured one.
        self.catch_up_steps = catch_up_steps
        self._unmeasured = math.inf  # the points' chain's steps since its last measured one
        #: The heading's variance a radian turned adds, rad^2/rad (odometry.yaw_walk_per_sqrt_rad
        #: squared): the turn the blend adds to the heatmap chain's walks it too.
        self.walk_var_rad = walk_var_rad
        self._added_var = 0.0
        self._period = math.inf  # the shortest step yet, s: the frame period
        self._last: tuple | None = None  # (the heatmap chain's state, the points', the published)

    @property
    def chains(self) -> tuple | None:
        """The heatmap chain's and the points' chain's states of the last frame blended (None before
        the first): what a diagnosis holds the published heading against."""
        return None if self._last is None else self._last[:2]

    def add_points(self, t: float, points: np.ndarray, *, velocity=None) -> None:
        self.points.add_points(t, points, velocity=velocity)

    def add_velocity(self, est) -> None:
        self.points.add_velocity(est)

    def __call__(self, own, t: float, heatmap, products=None):
        """The state to publish for the heatmap chain's *own* state at *t*, its heatmap given to
        the points' estimator too, with what the heatmap chain made of it (*products*,
        estimator/current_frame.py): the same heatmap and velocity give both the same."""
        other = self.points.add_heatmap(t, heatmap, products=products)
        if self._last is None:
            state = replace(own)
        else:
            before, other_before, published = self._last
            dt = own.t - before.t
            self._period = min(self._period, dt)
            own_turn, other_turn = own.yaw - before.yaw, other.yaw - other_before.yaw
            # The heatmap chain's turn stands over frames lost (a step half a period longer than
            # the shortest: it searches such a step wider, and the points' chain misses a turn
            # made there for good) and where the points' chain has measured nothing for longer
            # than it catches up in (none of its own points: ColoRadar's point clouds come at
            # other times than its heatmaps).  Steps either chain held otherwise are blended: each
            # makes up for a held turn in its steps after (the keyframes, the bridge, the map's
            # lag correction), and a share of that without the held step would keep the held
            # step's error whole (docs/heading.md item 30).
            self._unmeasured = 0 if other.ok else self._unmeasured + 1
            alive = self._unmeasured <= self.catch_up_steps
            w = self.share if alive and dt <= _LOST * self._period else 0.0
            if w and self.points_where_held and other.ok and not UNMEASURED_TURN.isdisjoint(own.flags):
                w = 1.0
            increment = own_turn + w * (other_turn - own_turn)
            self._added_var += self.walk_var_rad * abs(increment - own_turn)
            # The heatmap chain's step in its own axes at the step's start, turned onto the
            # published heading there.
            dx, dy = own.x - before.x, own.y - before.y
            turn = published.yaw - before.yaw
            c, s = math.cos(turn), math.sin(turn)
            # The covariances are the heatmap chain's, the heading's walked by the turn the blend
            # adds (standing, the points' few-hundredths-of-a-degree turns: the chain's heading
            # variance does not grow while it reads none); the points' chain's own grow by every
            # step's variance (estimator/point_map.py) and would widen them several times.
            pose_covariance = own.pose_covariance.copy()
            pose_covariance[2, 2] += self._added_var
            state = replace(
                own, x=float(published.x + c * dx - s * dy), y=float(published.y + s * dx + c * dy),
                yaw=float(published.yaw + increment), yaw_increment=float(increment),
                yaw_rate=float(own.yaw_rate + w * (other.yaw_rate - own.yaw_rate)), pose_covariance=pose_covariance)
        state.compute_s = own.compute_s + other.compute_s
        self._last = (own, other, state)
        return state
