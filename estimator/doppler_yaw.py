"""What a wheeled base's radar learns from its own Doppler velocity (beyond the paper): the yaw
rate off the base's rotation axis, and on it a velocity with no sideways slip.

A base that cannot slide sideways moves at (v, 0) in its own frame while turning at w; a radar
mounted at (mx, my) on it, yawed by m_yaw, moves at (v - w my, w mx) in the base's axes (Kellner
et al., "Instantaneous ego-motion estimation using Doppler radar", 2014, cited by the paper).
The Doppler fit gives the radar's velocity in its own axes, so the base's sideways component,
divided by the lever arm mx, is the yaw rate: one measurement per step, free of what biases
heatmap registration (scene structure, the beam's shape), fused with the registration's
(inverse-variance weighted) before the yaw-rate filter.  It has a bias of its own (the Doppler
fit's direction), which a straight drive would integrate: it is used in turns, where it stands
well above that bias and registration is weakest, and wherever registration measured nothing.

On the axis (a lever arm shorter than ``min_lever_arm_m``) the sideways velocity says nothing of
the yaw rate, but it is known: yaw rate times the lever arm, nothing on the axis.  The fit's
sideways component is then replaced by it (:class:`NoSideSlip`): an array without elevation
(2-TX) leans its fit sideways with elevated returns, which the translation would integrate
(docs/heading.md, item 27).

Either way, which way is sideways is learnt from the velocity's direction on straight drives
(:class:`BaseAxes`), not taken from the mount's yaw: a degree off would put more sideways speed
into every frame than the lean removed, and a false yaw rate into every turn.  Chosen once from
the config.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections import deque

import numpy as np

from .config import OdometryConfig
from .velocity import VelocityEstimate

log = logging.getLogger(__name__)


class DopplerYawRate:
    """The yaw rate (rad/s) and its variance from the radar's velocity (2,) m/s and its
    covariance (2, 2), for a radar mounted ``mount_x_m`` ahead of a wheeled base's axis, along
    the base's axes as learnt (:class:`BaseAxes`)."""

    def __init__(self, config: OdometryConfig) -> None:
        self.axes = BaseAxes(config)
        self._lever_m = config.mount_x_m
        self._min_var = config.doppler_yaw_rate_noise_radps ** 2
        self._min_rate = config.doppler_yaw_min_rate_radps

    def __call__(self, velocity: np.ndarray, covariance: np.ndarray, registered: bool,
                 last_rate: float = 0.0) -> tuple[float, float] | None:
        """(rate rad/s, variance (rad/s)^2); None below ``doppler_yaw_min_rate_radps`` when the
        step's yaw was *registered* (else it is the only measurement there is), and None until
        the base's axes are learnt (*last_rate*, rad/s: the last measured, which tells the
        straight drives they are learnt from)."""
        self.axes.learn(velocity, last_rate)
        axes = self.axes.axes
        if axes is None:
            return None
        row = axes[1] / self._lever_m  # w = the base's sideways speed over the lever arm
        rate = float(row @ velocity)
        if registered and abs(rate) < self._min_rate:
            return None
        var = float(row @ covariance @ row) if np.all(np.isfinite(covariance)) else math.inf
        return rate, max(var, self._min_var)


def fuse(dyaw: float | None, var_yaw: float, doppler: tuple[float, float] | None, dt: float) -> tuple[float | None, float]:
    """The step's yaw increment (rad) and variance (rad^2) from the registration's (*dyaw*,
    *var_yaw*; None: not measured) and the Doppler yaw rate's (*doppler*: rate rad/s and its
    variance, None: none), inverse-variance weighted; (None, *var_yaw*) when neither measured."""
    if doppler is None:
        return dyaw, var_yaw
    z, r = doppler[0] * dt, doppler[1] * dt * dt
    if dyaw is None:
        return z, r
    w1, w2 = 1.0 / var_yaw, 1.0 / r
    return (w1 * dyaw + w2 * z) / (w1 + w2), 1.0 / (w1 + w2)


class NoSideSlip:
    """A velocity estimate (radar axes, m/s) of a radar on or near a wheeled base's rotation axis
    with its component along the base's sideways axis made yaw rate x ``mount_x_m``; the forward
    component and its variance kept; an estimate passes as measured until the base's axes are
    learnt (:class:`BaseAxes`)."""

    def __init__(self, config: OdometryConfig) -> None:
        self.axes = BaseAxes(config)
        self._lever_m = config.mount_x_m
        self._angle_std = config.no_slip_angle_std_rad

    def __call__(self, est: VelocityEstimate, yaw_rate: float) -> VelocityEstimate:
        """*est* with no sideways slip at *yaw_rate* (rad/s; the last measured)."""
        if not est.ok:
            return est
        self.axes.learn(est.velocity, yaw_rate)
        axes = self.axes.axes
        if axes is None:
            return est
        forward, side = axes
        along = float(forward @ est.velocity)
        v = along * forward + yaw_rate * self._lever_m * side
        side_std = max(self._angle_std * abs(along), _MIN_SIDE_STD_MPS)
        keep = np.outer(forward, forward)
        covariance = keep @ est.covariance @ keep + side_std ** 2 * np.outer(side, side)
        return dataclasses.replace(est, vx=float(v[0]), vy=float(v[1]), covariance=covariance)


class BaseAxes:
    """A wheeled base's forward and left axes in the radar's axes, learnt: once
    ``axis_learn_frames`` frames drove straight, the forward axis is the median direction of their
    velocities less the lever arm's sideways speed (relative to ``mount_yaw_rad``'s; a median,
    since a fit leans for a few seconds at a time, where the structure passing by is above or
    below the radar).  A mount's yaw is seldom known to a degree, and one degree is 14 mm/s
    sideways at 0.8 m/s: as much as the lean a radar on the axis removes, and 2.7 deg/s of yaw
    rate over a 0.3 m lever arm."""

    def __init__(self, config: OdometryConfig) -> None:
        self._given_yaw = config.mount_yaw_rad
        self._given = _base_axes(config.mount_yaw_rad)
        self._lever_m = config.mount_x_m
        self._learn_frames = config.axis_learn_frames
        self._straight_radps = config.axis_straight_radps
        self._min_speed = config.axis_min_speed_mps
        self._angles: deque[float] = deque(maxlen=_LEARN_MAX_FRAMES)
        self._offset: float | None = None if self._learn_frames else 0.0
        self.axes: tuple[np.ndarray, np.ndarray] | None = None if self._learn_frames else self._given

    @property
    def offset_rad(self) -> float | None:
        """How far the radar's velocity points from ``mount_yaw_rad``'s forward axis on the straight
        frames so far (rad, towards the base's left), once learnt (0 with ``axis_learn_frames``
        0: the mount's yaw as given); None before."""
        return self._offset

    def learn(self, velocity: np.ndarray, yaw_rate: float) -> None:
        """Learn from the radar's *velocity* (2,) m/s when *yaw_rate* (rad/s, the last measured)
        says the base drives straight."""
        if not self._learn_frames or abs(yaw_rate) >= self._straight_radps:
            return
        forward, side = self._given
        along = float(forward @ velocity)
        if not abs(along) > self._min_speed:
            return
        self._angles.append(math.atan((float(side @ velocity) - yaw_rate * self._lever_m) / along))
        if len(self._angles) < self._learn_frames:
            return
        first = self._offset is None
        self._offset = float(np.median(self._angles))
        self.axes = _base_axes(self._given_yaw - self._offset)
        if first and abs(self._offset) > _WARN_OFFSET_RAD:
            log.warning("on straight drives the radar's velocity points %.1f degrees %s of the base's forward axis "
                        "as a mount yaw of %.1f degrees places it: the radar is likely yawed %.1f degrees on the "
                        "base (--mount's YAW_DEG, odometry.mount_yaw_rad); the odometry follows the velocity",
                        math.degrees(abs(self._offset)), "left" if self._offset > 0 else "right",
                        math.degrees(self._given_yaw), round(math.degrees(self._given_yaw - self._offset), 1) + 0.0)


def _base_axes(mount_yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """The base's forward and sideways (left) axes, in the axes of a radar yawed *mount_yaw* on it."""
    c, s = math.cos(mount_yaw), math.sin(mount_yaw)
    return np.array([c, -s]), np.array([s, c])


#: A variance a consumer can invert, m/s.
_MIN_SIDE_STD_MPS = 0.001
#: The straight frames the axis is learnt from, at most: the last 5 minutes of them at 10 Hz.
_LEARN_MAX_FRAMES = 3000
#: A learnt axis further than this from the mount's (rad) is a mount the user should correct.
_WARN_OFFSET_RAD = math.radians(3.0)


def doppler_yaw_part(config: OdometryConfig) -> DopplerYawRate | None:
    """The part when the base is wheeled and the radar far enough off its axis, else None."""
    if config.base == "wheeled" and abs(config.mount_x_m) >= config.min_lever_arm_m:
        return DopplerYawRate(config)
    return None


def no_side_slip_part(config: OdometryConfig) -> NoSideSlip | None:
    """The part when the base is wheeled and the radar on or near its axis, else None."""
    if config.base == "wheeled" and abs(config.mount_x_m) < config.min_lever_arm_m:
        return NoSideSlip(config)
    return None
