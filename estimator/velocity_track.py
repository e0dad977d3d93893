"""The velocity of each odometry step: recent point-cloud velocities, interpolated to the
middle of a step (paper eq. 2), and what stands in when the point clouds give none (the
heatmap's Doppler, or the last good velocity held).  Chosen once from the config."""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import TimeOrderError
from .config import EstimatorConfig
from .features import PolarHeatmap, heatmap_doppler_points, strongest_points
from .level_speed import LevelSpeed, level_speed_part
from .quality import Flag, may_hold
from .velocity import ReachableVelocity, VelocityEstimate, estimate_velocity


class VelocityHistory:
    """The last *size* good velocity estimates, in time order, for interpolation to heatmap
    times."""

    def __init__(self, size: int) -> None:
        self.items: deque[VelocityEstimate] = deque(maxlen=size)
        self._times: deque[float] = deque(maxlen=size)  # the items' times, for bisection

    def add(self, est: VelocityEstimate) -> None:
        if self.items and est.t < self.items[-1].t:
            raise TimeOrderError(f"velocity at t={est.t} after one at t={self.items[-1].t}: "
                                 "feed measurements in time order")
        self.items.append(est)
        self._times.append(est.t)

    def nearest(self, t: float) -> VelocityEstimate | None:
        """The estimate nearest *t* (the first of equal times; the earlier of two as near);
        None when there is none."""
        times = self._times
        if not times:
            return None
        k = bisect.bisect_left(times, t)
        if k > 0 and (k == len(times) or t - times[k - 1] <= times[k] - t):
            k = bisect.bisect_left(times, times[k - 1])
        return self.items[k]

    def interpolated(self, t: float) -> VelocityEstimate | None:
        """The velocity at *t*, linear between the estimates around it (eq. 2); the nearest
        when *t* is not between two."""
        times = self._times
        k = bisect.bisect_left(times, t)
        if k == 0 or k == len(times):
            return self.nearest(t)
        a, b = self.items[k - 1], self.items[k]
        f = (t - a.t) / (b.t - a.t) if b.t > a.t else 0.0
        return VelocityEstimate(t=t, vx=a.vx + f * (b.vx - a.vx), vy=a.vy + f * (b.vy - a.vy),
                                covariance=(1 - f) * a.covariance + f * b.covariance,
                                n_points=b.n_points, inliers=b.inliers, status=b.status,
                                level_scale=a.level_scale + f * (b.level_scale - a.level_scale))


@dataclass
class StepVelocity:
    """The velocity of one step: the point clouds' estimate at its middle (None when there is
    none), and what the step uses, (2,) m/s body frame with its (2, 2) covariance."""

    estimate: VelocityEstimate | None
    velocity: np.ndarray
    covariance: np.ndarray


class HeatmapVelocity:
    """The ``velocity_fallback`` "heatmap": the step's velocity from the heatmap's Doppler at its
    end, averaged with the velocity at its start (the step's mid-time, as eq. 2 for the point
    clouds: a robot slowing down is slower at the frame than at mid-step)."""

    def __init__(self, config: EstimatorConfig, history: VelocityHistory, level_speed: LevelSpeed | None,
                 constrain: Callable[[VelocityEstimate], VelocityEstimate] | None = None) -> None:
        self._config = config
        self._constrain = constrain or _as_measured
        self._history = history
        self._level_speed = level_speed
        # Its own generator, so that the fallback leaves the point clouds' RANSAC draws as they were.
        self._rng = np.random.default_rng(config.velocity.seed + 1)
        # The last frame's estimate, kept apart from the point clouds': those may come from
        # another sensor, later.
        self._last: VelocityEstimate | None = None
        # The strongest fallback_cells, then half and a quarter of them: in a weak scene most
        # maxima are noise, whose Doppler agrees with nothing, and the static world's share of
        # many cells falls below the fit's min_inlier_ratio where that of the strongest few does not
        # (never fewer than the fit's min_points; within the velocities the platform can reach).
        cells, fewest = config.odometry.fallback_cells, config.velocity.min_points
        self._cell_counts = tuple(dict.fromkeys(max(n, fewest) for n in (cells, cells // 2, cells // 4)))

    def reset(self) -> None:
        """The point clouds gave the last step's velocity: the next fallback starts afresh."""
        self._last = None

    def __call__(self, t_prev: float, t: float, heatmap: PolarHeatmap,
                 expected: ReachableVelocity | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """(velocity (2,) m/s, covariance (2, 2)) of the step from *t_prev* to *t*; None when
        the heatmap gives none (or none within the *expected* velocities)."""
        cfg = self._config
        candidates = heatmap_doppler_points(heatmap, cfg.features, self._cell_counts[0])
        if candidates is None:
            return None
        for cells in self._cell_counts:
            points = strongest_points(candidates, cells)
            est = estimate_velocity(points, t, cfg.velocity, self._rng, expected)
            if est.ok:
                if self._level_speed is not None:
                    est = self._level_speed.scaled(points, est)
                est = self._constrain(est)
                break
        if not est.ok:
            self._last = None
            return None
        before = self._last if self._last is not None and self._last.t == t_prev else None
        if before is None:
            good = self._history.nearest(t_prev)
            # Only an estimate of the previous frame's own time (within half a step) stands for it.
            if good is not None and abs(good.t - t_prev) <= 0.5 * (t - t_prev):
                before = good
        self._last = est
        if before is None:
            return est.velocity, est.covariance
        return 0.5 * (before.velocity + est.velocity), 0.25 * (before.covariance + est.covariance)


class VelocityTrack:
    """Velocity estimates as they come (:meth:`add`) and each step's velocity (:meth:`for_step`);
    *constrain* is what every estimate kept goes through first, the heatmap fallback's too (a
    wheeled base's on its axis: no sideways slip)."""

    def __init__(self, config: EstimatorConfig,
                 constrain: Callable[[VelocityEstimate], VelocityEstimate] | None = None) -> None:
        odo = config.odometry
        self._hold_s = odo.hold_s
        self._max_step_s = odo.max_step_s
        self._held_factor = odo.held_velocity_variance_factor
        self.history = VelocityHistory(odo.velocity_history)
        self._at_mid: Callable[[float], VelocityEstimate | None] = (
            self.history.nearest if odo.velocity_sync == "nearest" else self.history.interpolated)
        #: ``velocity.level_edge_quantile``: clouds without elevation, and the fallback's cells
        self.level_speed = level_speed_part(config.velocity)
        self._constrain = constrain or _as_measured
        self._fallback = (HeatmapVelocity(config, self.history, self.level_speed, self._constrain)
                          if odo.velocity_fallback == "heatmap" else None)
        self._last: VelocityEstimate | None = None  # the latest, good or not
        self._good_t: float | None = None  # the latest good one's time
        self._max_accel = config.velocity.max_accel_mps2

    def add(self, est: VelocityEstimate) -> VelocityEstimate:
        """Keep *est* (constrained); the estimate kept."""
        est = self._constrain(est)
        self._last = est
        if est.ok:
            self.history.add(est)
            self._good_t = est.t
        return est

    def reachable(self, t: float) -> ReachableVelocity | None:
        """The velocities the platform can have at *t* after the last good one (``max_accel_mps2``
        over the time since, plus three of its standard deviation); None without either."""
        if self._max_accel is None or not self.history.items:
            return None
        last = self.history.items[-1]
        spread = float(np.trace(last.covariance))  # a velocity from elsewhere may come without one
        noise = math.sqrt(spread) if math.isfinite(spread) and spread > 0.0 else 0.0
        return ReachableVelocity(last.velocity, self._max_accel * max(t - last.t, 0.0) + 3.0 * noise)

    def near(self, t: float) -> VelocityEstimate | None:
        """The good estimate nearest *t* (None when there is none)."""
        return self.history.nearest(t)

    def for_step(self, t_prev: float, t: float, heatmap: PolarHeatmap, flags: list[Flag]) -> StepVelocity:
        """The velocity of the step from *t_prev* to *t*: the point clouds' when the latest was
        good; else the fallback's (the heatmap's Doppler, when configured); else the last good
        one held for ``hold_s`` (covariance inflated); else zero, flagged ``motion_lost``, as for
        a step longer than ``odometry.max_step_s``."""
        if t - t_prev > self._max_step_s:
            if Flag.MOTION_LOST not in flags:
                flags.append(Flag.MOTION_LOST)
            return StepVelocity(None, np.zeros(2), np.eye(2))
        estimate = self._at_mid(0.5 * (t + t_prev))
        if estimate is not None and self._last is not None and self._last.ok:
            if self._fallback is not None:
                self._fallback.reset()
            return StepVelocity(estimate, estimate.velocity, estimate.covariance)
        flags.append(Flag.VELOCITY_FAILED)
        if self._fallback is not None:
            found = self._fallback(t_prev, t, heatmap, self.reachable(t))
            if found is not None:
                flags.append(Flag.VELOCITY_FROM_HEATMAP)
                return StepVelocity(estimate, *found)
        # Never measured (no estimate, no good time): not held, and flagged motion_lost like a
        # hold that ran out, since the zero below is no evidence of standing.
        if may_hold(self._good_t, t, self._hold_s, Flag.VELOCITY_HELD, flags) and estimate is not None:
            return StepVelocity(estimate, estimate.velocity, estimate.covariance * self._held_factor)
        return StepVelocity(estimate, np.zeros(2), np.eye(2))


def _as_measured(est: VelocityEstimate) -> VelocityEstimate:
    return est
