"""Beyond the paper: the heading of two registrations of the same frames, blended
(``point_yaw.blend``; docs/heading.md, item 30).

The heatmap field's registration (frame to frame, keyframes) and the point map's (each frame's
points against the last seconds' map, estimator/point_yaw.py) err by their own draws of the
scene's speckle: over the robustness matrix the two chains' turns in place, drift and straight
drives hardly correlate from cell to cell, so a share of each holds the heading better than
either alone.  The two run side by side, unaware of each other (each its own velocity fit, yaw-rate
filter and keyframes or map); what is published is the heatmap chain's state with its heading
moved *share* of the way to the points' chain, and its position integrated from the heatmap
chain's own steps along that heading.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Protocol

import numpy as np


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
        self._last: tuple | None = None  # (the heatmap chain's state, the published state)

    def add_points(self, t: float, points: np.ndarray) -> None:
        self.points.add_points(t, points)

    def add_velocity(self, est) -> None:
        self.points.add_velocity(est)

    def __call__(self, own, t: float, heatmap):
        """The state to publish for the heatmap chain's *own* state at *t*, its heatmap given to
        the points' estimator too."""
        other = self.points.add_heatmap(t, heatmap)
        w = self.share
        yaw = own.yaw + w * (other.yaw - own.yaw)
        if self._last is None:
            x, y, increment = own.x, own.y, yaw
        else:
            before, published = self._last
            # The heatmap chain's step in its own axes at the step's start, turned onto the
            # published heading there.
            dx, dy = own.x - before.x, own.y - before.y
            turn = published.yaw - before.yaw
            c, s = math.cos(turn), math.sin(turn)
            x, y = published.x + c * dx - s * dy, published.y + s * dx + c * dy
            increment = yaw - published.yaw
        state = replace(
            own, x=float(x), y=float(y), yaw=float(yaw), yaw_increment=float(increment),
            yaw_rate=float(own.yaw_rate + w * (other.yaw_rate - own.yaw_rate)),
            # A convex sum of the two covariances bounds the blend's whatever the chains'
            # correlation (they hardly correlate: it overstates the heading's by up to sqrt 2).
            pose_covariance=(1.0 - w) * own.pose_covariance + w * other.pose_covariance,
            twist_covariance=_twist_covariance(own.twist_covariance, other.twist_covariance, w),
            flags=own.flags + tuple(f for f in other.flags if f not in own.flags),
            compute_s=own.compute_s + other.compute_s)
        self._last = (own, state)
        return state


def _twist_covariance(own: np.ndarray, other: np.ndarray, w: float) -> np.ndarray:
    """(3, 3): the speeds' the heatmap chain's (both fit the same points), the yaw rate's the
    convex sum of the two."""
    out = np.array(own, dtype=float, copy=True)
    out[2, 2] = (1.0 - w) * own[2, 2] + w * other[2, 2]
    return out
