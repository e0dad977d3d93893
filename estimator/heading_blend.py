"""Beyond the paper: the heading of two registrations of the same frames, blended
(``point_yaw.blend``; docs/heading.md, item 30).

The heatmap field's registration (frame to frame, keyframes) and the point map's (each frame's
points against the last seconds' map, estimator/point_yaw.py) err by their own draws of the
scene's speckle: over the robustness matrix the two chains' turns in place, drift and straight
drives hardly correlate from cell to cell, so a share of each holds the heading better than
either alone.  The two run side by side, unaware of each other (each its own velocity fit, yaw-rate
filter and keyframes or map); what is published is the heatmap chain's state, each step's turn
moved *share* of the way to the points' chain's turn over the same step (but the heatmap chain's
alone where it did not measure the step or frames were lost), and its position integrated from
the heatmap chain's own steps along that heading; its covariances the heatmap chain's.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Protocol

import numpy as np


#: A step longer than this many frame periods has lost frames.
_LOST = 1.5


class _Odometry(Protocol):
    """What the blend needs of the points' estimator (a RadarOdometry with ``point_yaw.use``)."""

    def add_points(self, t: float, points: np.ndarray): ...

    def add_velocity(self, est) -> None: ...

    def add_heatmap(self, t: float, heatmap): ...


class HeadingBlend:
    """The published state of each frame from the heatmap chain's (:meth:`__call__`), the
    points' estimator fed the same points and heatmaps."""

    def __init__(self, points: _Odometry, share: float) -> None:
        self.points = points
        self.share = share
        self._period = math.inf  # the shortest step yet, s: the frame period
        self._last: tuple | None = None  # (the heatmap chain's state, the points', the published)

    def add_points(self, t: float, points: np.ndarray) -> None:
        self.points.add_points(t, points)

    def add_velocity(self, est) -> None:
        self.points.add_velocity(est)

    def __call__(self, own, t: float, heatmap):
        """The state to publish for the heatmap chain's *own* state at *t*, its heatmap given to
        the points' estimator too."""
        other = self.points.add_heatmap(t, heatmap)
        if self._last is None:
            state = replace(own)
        else:
            before, other_before, published = self._last
            dt = own.t - before.t
            self._period = min(self._period, dt)
            own_turn, other_turn = own.yaw - before.yaw, other.yaw - other_before.yaw
            # Where the heatmap chain held, bridged or lost its motion, or frames were lost (a step
            # half a period longer than the shortest), its turn stands, whose ways across such
            # steps are tested.  The points' chain's own such steps are blended: it makes up for
            # a turn it held in the steps after (point_yaw.correct_lag), which are blended too.
            w = self.share if own.ok and dt <= _LOST * self._period else 0.0
            increment = own_turn + w * (other_turn - own_turn)
            # The heatmap chain's step in its own axes at the step's start, turned onto the
            # published heading there.
            dx, dy = own.x - before.x, own.y - before.y
            turn = published.yaw - before.yaw
            c, s = math.cos(turn), math.sin(turn)
            state = replace(
                own, x=float(published.x + c * dx - s * dy), y=float(published.y + s * dx + c * dy),
                yaw=float(published.yaw + increment), yaw_increment=float(increment),
                yaw_rate=float(own.yaw_rate + w * (other.yaw_rate - own.yaw_rate)))
            # The covariances stay the heatmap chain's, which the blend's errors, smaller, stay
            # within (docs/heading.md item 30); the points' chain's grow by every step's variance
            # (estimator/point_map.py) and would widen them several times.
        state.compute_s = own.compute_s + other.compute_s
        self._last = (own, other, state)
        return state
