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
(docs/heading.md, "2-TX arrays").  Chosen once from the config.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .config import OdometryConfig
from .velocity import VelocityEstimate


class DopplerYawRate:
    """The yaw rate (rad/s) and its variance from the radar's velocity (2,) m/s and its
    covariance (2, 2), for a radar mounted ``mount_x_m`` ahead of a wheeled base's axis."""

    def __init__(self, config: OdometryConfig) -> None:
        c, s = math.cos(config.mount_yaw_rad), math.sin(config.mount_yaw_rad)
        # The base's sideways axis in the radar's axes, over the lever arm: w = row . v_radar.
        self._row = np.array([s, c]) / config.mount_x_m
        self._min_var = config.doppler_yaw_rate_noise_radps ** 2
        self._min_rate = config.doppler_yaw_min_rate_radps

    def __call__(self, velocity: np.ndarray, covariance: np.ndarray, registered: bool) -> tuple[float, float] | None:
        """(rate rad/s, variance (rad/s)^2); None below ``doppler_yaw_min_rate_radps`` when the
        step's yaw was *registered* (else it is the only measurement there is)."""
        rate = float(self._row @ velocity)
        if registered and abs(rate) < self._min_rate:
            return None
        var = float(self._row @ covariance @ self._row) if np.all(np.isfinite(covariance)) else math.inf
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
    with its component along the base's sideways axis made yaw rate x ``mount_x_m``, and no
    variance there; the forward component and its variance kept."""

    def __init__(self, config: OdometryConfig) -> None:
        c, s = math.cos(config.mount_yaw_rad), math.sin(config.mount_yaw_rad)
        # The base's forward and sideways axes in the radar's axes.
        self._forward, self._side = np.array([c, -s]), np.array([s, c])
        self._lever_m = config.mount_x_m
        self._keep = np.outer(self._forward, self._forward)

    def __call__(self, est: VelocityEstimate, yaw_rate: float) -> VelocityEstimate:
        """*est* with no sideways slip at *yaw_rate* (rad/s; the last measured)."""
        if not est.ok:
            return est
        v = (self._forward @ est.velocity) * self._forward + yaw_rate * self._lever_m * self._side
        covariance = self._keep @ est.covariance @ self._keep
        return dataclasses.replace(est, vx=float(v[0]), vy=float(v[1]), covariance=covariance)


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
