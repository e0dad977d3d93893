"""The local map of :mod:`.point_yaw`: the static points of the last frames placed in the world
along the map's own chain of poses (each step's displacement as the odometry integrated it, turned
by the turn the points measured), and the correction of the odometry's yaw by that chain
(``point_yaw.correct_lag``), in the keyframe correction's place.

The correction is a Kalman update of the odometry's yaw relative to a reference frame (``lag_frames``
back) by the chain's yaw since then, whose variance is the sum of its measured turns'.  Steps whose
turn went unmeasured do not move the reference: their turn is the held rate's on both sides, and
uncertain by ``gap_turn_std_rad`` each, so that what the chain measures against the map after a
braking gap (the turn the held rate missed) reaches the odometry's yaw, at most
``gap_correction_max_rad`` a step (the reference stays until the rest has come).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from .config import PointYawConfig
from .map_density import MapDensity
from .yaw_measurement import CurrentFrame, KeptFrame


def _world(xy: np.ndarray, pose: tuple[float, float, float]) -> np.ndarray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.stack([pose[0] + c * xy[:, 0] - s * xy[:, 1], pose[1] + s * xy[:, 0] + c * xy[:, 1]], 1)


def _gaussians(points: np.ndarray, origin: np.ndarray,
               cfg: PointYawConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The map's Gaussians of the *points* (k, 2) m seen from *origin* (2,) m: the points, their
    inverse covariances (k, 2, 2) 1/m^2 (``range_noise_m`` along the ray, ``bearing_noise_rad``
    times the range across, ``position_floor_m`` on both) and largest standard deviations (k,) m."""
    ray = points - origin
    r = np.maximum(np.hypot(ray[:, 0], ray[:, 1]), 1e-6)
    u = ray / r[:, None]
    n = np.stack([-u[:, 1], u[:, 0]], 1)
    across = (r * cfg.bearing_noise_rad) ** 2
    cov = (cfg.range_noise_m ** 2 * u[:, :, None] * u[:, None, :] + across[:, None, None] * n[:, :, None]
           * n[:, None, :] + cfg.position_floor_m ** 2 * np.eye(2))
    sigma = np.sqrt(np.maximum(across, cfg.range_noise_m ** 2) + cfg.position_floor_m ** 2)
    return points, np.linalg.inv(cov), sigma


@dataclass
class _Reference:
    """The frame ``correct_lag`` measures the yaw from (see :class:`LocalMap`)."""

    odometry_yaw: float
    chain_yaw: float
    odometry_var: float = 0.0
    chain_var: float = 0.0
    steps: int = 0
    #: Whether steps whose turn went unmeasured lie since it (their correction is capped) ...
    spans_gap: bool = False
    #: ... and whether the last correction was (the reference stays until it is not).
    capped: bool = False


class LocalMap:
    """The static points of the last frames in the world (see the module docstring), along the map's
    chain of poses; in the keyframe correction's place in the odometry (:meth:`correct`,
    :meth:`update`)."""

    #: Whether its corrections keep each step's yaw noise out of the heading: not shown for the
    #: demo's points, so the steps' variances still add up (wide, the walk alone narrow at 15 dB:
    #: docs/tidemo.md, "The reported covariance").
    bounds_noise = False

    def __init__(self, config: PointYawConfig) -> None:
        self._config = config
        #: Each frame's points placed in the world, their inverse covariances and largest standard
        #: deviations (:meth:`arrays`): placed once, so worked out once.
        self._frames: deque[tuple[np.ndarray, np.ndarray, np.ndarray]] = deque(maxlen=config.map_frames)
        self._arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        #: The map's density at each of its points, kept as frames enter and leave
        #: (``density_weighted``), and the weights last made from it.
        self._density = MapDensity(config.map_frames) if config.density_weighted else None
        self._log_weights: np.ndarray | None = None
        #: The last frame's pose along the map's chain, and the odometry's.
        self.pose: tuple[float, float, float] | None = None
        self._odometry_pose: tuple[float, float, float] | None = None
        #: The current step's turn as this part measured it (rad, counter-clockwise) and its
        #: variance (rad^2); its static points.
        self.turn: float | None = None
        self.turn_variance = 0.0
        self.pending: tuple[float, np.ndarray] | None = None
        #: For ``correct_lag``: the odometry's and the chain's yaw at the reference frame (rad),
        #: the variances of the odometry's and the chain's yaw relative to it (rad^2), and the
        #: steps since it.
        self._reference: _Reference | None = None

    def correct(self, step, current: KeptFrame, frame: CurrentFrame, *, registered: bool = True) -> tuple[float, float]:
        """The step's yaw increment (rad) and variance (rad^2) as the filter gave it, corrected
        with ``correct_lag`` by the chain's yaw since the reference frame (module docstring).
        *registered* (whether the points' own turn was measured) is the keyframes' concern: the
        map's chain holds no turn then."""
        ref = self._reference
        if ref is None or self.turn is None or self.pose is None:
            return step.dyaw, step.var_yaw
        ref.odometry_var += step.var_yaw
        ref.chain_var += self.turn_variance
        predicted = step.pose[2] + step.dyaw - ref.odometry_yaw
        measured = self.pose[2] + self.turn - ref.chain_yaw
        gain = ref.odometry_var / (ref.odometry_var + ref.chain_var)
        correction = gain * (measured - predicted)
        limit = self._config.gap_correction_max_rad
        ref.capped = ref.spans_gap and abs(correction) > limit
        if ref.capped:
            correction = math.copysign(limit, correction)
            gain = correction / (measured - predicted)
        ref.odometry_var *= 1.0 - gain
        return step.dyaw + correction, (1.0 - gain) * step.var_yaw

    def update(self, pose: tuple[float, float, float], current: KeptFrame, *, measured: bool, rate: float,
               registered: bool = True) -> None:
        """The odometry's *pose* of *current*: the map's chain moves by the step (turned by the
        measured turn, when there was one) and takes in the frame's static points (*rate*, the
        step's yaw rate, and *registered* are the keyframes' concern)."""
        if self.pose is None or self._odometry_pose is None:
            chained = pose
        else:
            ox, oy, oyaw = self._odometry_pose
            c, s = math.cos(oyaw), math.sin(oyaw)
            dx, dy = c * (pose[0] - ox) + s * (pose[1] - oy), -s * (pose[0] - ox) + c * (pose[1] - oy)
            x, y, yaw = self.pose
            c, s = math.cos(yaw), math.sin(yaw)
            turn = self.turn if self.turn is not None else pose[2] - oyaw
            chained = (x + c * dx - s * dy, y + s * dx + c * dy, yaw + turn)
        if self._config.correct_lag:
            ref = self._reference
            if ref is not None and not measured:
                # What the map's chain finds after the gap is measured from before it.
                ref.odometry_var += self._config.gap_turn_std_rad ** 2
                ref.spans_gap = True
            elif ref is None or (ref.steps >= self._config.lag_frames and not ref.capped):
                self._reference = ref = _Reference(pose[2], chained[2])
            ref.steps += 1
        self._odometry_pose, self.pose, self.turn = pose, chained, None
        if self.pending is not None and self.pending[0] == current.t and len(self.pending[1]):
            self.add(_gaussians(_world(self.pending[1], chained), np.array(chained[:2]), self._config))
        self.pending = None

    def add(self, gaussians: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        """A frame's points placed in the world, with their Gaussians (:func:`_gaussians`), join the
        map; its oldest frame leaves when it holds ``map_frames``."""
        if self._density is not None:
            self._density.enter(gaussians)
        self._frames.append(gaussians)
        self._arrays = self._log_weights = None

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The map's points (m, 2) m, their Gaussians' inverse covariances (m, 2, 2), 1/m^2, and
        their largest standard deviations (m,), m."""
        if self._arrays is None:
            if not self._frames:
                return np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros(0)
            self._arrays = tuple(np.concatenate([f[i] for f in self._frames]) for i in range(3))
        return self._arrays

    def log_weights(self) -> np.ndarray | None:
        """Each map point's log weight (m,) (``density_weighted``: minus the log of the map's
        density there), None when unweighted."""
        if self._density is None:
            return None
        if self._log_weights is None:
            self._log_weights = -self._density.log_density()
        return self._log_weights
