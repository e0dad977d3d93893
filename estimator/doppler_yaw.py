"""The yaw rate a wheeled base's radar sees in its own Doppler velocity (beyond the paper).

A base that cannot slide sideways moves at (v, 0) in its own frame while turning at w; a radar
mounted at (mx, my) on it, yawed by m_yaw, moves at (v - w my, w mx) in the base's axes (Kellner
et al., "Instantaneous ego-motion estimation using Doppler radar", 2014, cited by the paper).
The Doppler fit gives the radar's velocity in its own axes, so the base's sideways component,
divided by the lever arm mx, is the yaw rate: one measurement per step, free of what biases
heatmap registration (scene structure, the beam's shape), fused with the registration's
(inverse-variance weighted) before the yaw-rate filter.  It has a bias of its own (the Doppler
fit's direction), which a straight drive would integrate: it is used in turns, where it stands
well above that bias and registration is weakest, and wherever registration measured nothing.  Chosen once from the config.
"""

from __future__ import annotations

import math

import numpy as np

from .config import OdometryConfig


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


def doppler_yaw_part(config: OdometryConfig) -> DopplerYawRate | None:
    """The part when the base is wheeled and the radar far enough off its axis, else None."""
    if config.base == "wheeled" and abs(config.mount_x_m) >= config.min_lever_arm_m:
        return DopplerYawRate(config)
    return None
