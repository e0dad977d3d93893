"""The yaw-rate filter (beyond the paper): a robot's yaw rate changes smoothly, frame-to-frame
registration noise does not.  One Kalman model of the rate, or two mixed as an
interacting-multiple-model filter; or no filter.  Chosen once from the config."""

from __future__ import annotations

import math

import numpy as np

from .config import OdometryConfig


def _within(part: float, whole: float) -> float:
    """*part* kept of the same sign as *whole* and no larger (0 when their signs differ), rad."""
    return math.copysign(min(abs(part), abs(whole)), part) if part * whole > 0 else 0.0


class YawRateFilter:
    """Kalman filter(s) of the yaw rate, constant rate with white yaw acceleration: one model,
    or several of different acceleration mixed as an interacting-multiple-model filter (each
    model's estimate is blended with the others' by the switch probabilities before its step,
    and the models are weighted by the likelihood of the measurement under each).  With one
    model this is the plain scalar Kalman filter."""

    def __init__(self, accel_std: tuple[float, ...], switch: tuple[tuple[float, ...], ...] = ((1.0,),)) -> None:
        """*accel_std*: each model's yaw acceleration standard deviation, rad/s^2; *switch*:
        per frame, the probability of going from one model (row) to another (column); the
        filter starts with the first row's probabilities."""
        self.accel_std = np.asarray(accel_std, dtype=float)
        self.switch = np.array(switch, dtype=float)
        self.rate: np.ndarray | None = None  # per model, rad/s
        self.var = np.zeros(0)  # per model, (rad/s)^2
        self.prob = self.switch[0].copy()  # of each model

    def update(self, z: float, r: float, dt: float) -> tuple[float, float]:
        """Filter the rate measurement *z* (rad/s) of variance *r* taken *dt* after the last:
        the combined (rate, variance)."""
        if self.rate is None:
            self.rate, self.var = np.full(len(self.accel_std), z), np.full(len(self.accel_std), r)
            return z, r
        # Mix: each model starts from the others' estimates weighted by how likely it is
        # that the motion switched from them.
        predicted = self.switch.T @ self.prob
        w = self.switch * self.prob[:, None] / predicted[None, :]  # [from, to]
        rate = w.T @ self.rate
        var = w.T @ self.var + np.einsum("ij,ij->j", w, (self.rate[:, None] - rate[None, :]) ** 2)
        # Each model's Kalman step.
        var = var + (self.accel_std * dt) ** 2
        s = var + r
        innovation = z - rate
        gain = var / s
        self.rate, self.var = rate + gain * innovation, var * (1.0 - gain)
        # Model probabilities from the measurement's likelihood (in logs: a large innovation
        # must not underflow every model to zero).
        log_lik = -0.5 * (innovation * innovation / s + np.log(s))
        prob = predicted * np.exp(log_lik - log_lik.max())
        self.prob = prob / prob.sum()
        mean = float(self.prob @ self.rate)
        return mean, float(self.prob @ (self.var + (self.rate - mean) ** 2))


class FilteredYaw:
    """Each measured yaw increment through the yaw-rate filter; the filter restarts from the
    next measurement after a frame whose yaw was not measured."""

    def __init__(self, config: OdometryConfig) -> None:
        self._noise_rad = config.yaw_noise_rad
        self._accel = (config.yaw_accel_std_radps2,)
        self._switch: tuple[tuple[float, ...], ...] = ((1.0,),)
        if config.yaw_manoeuvre_accel_std_radps2 is not None:
            self._accel += (config.yaw_manoeuvre_accel_std_radps2,)
            start, end = config.yaw_manoeuvre_start_prob, config.yaw_manoeuvre_end_prob
            self._switch = ((1.0 - start, start), (end, 1.0 - end))
        self._filter: YawRateFilter | None = None
        self._max_lag = config.yaw_filter_max_lag_rad
        self._trusted_only = config.yaw_filter_max_lag_trusted_only
        #: The measured increments less those given since the restart, rad (within
        #: ``yaw_filter_max_lag_rad``, but for the part weak steps left, ``_weak``).
        self._debt = 0.0
        #: Of that, what the weak steps' measurements left, rad (``yaw_filter_max_lag_trusted_only``):
        #: of the same sign as the whole and no larger, given at the filter's own pace.
        self._weak = 0.0
        #: The measured increments less the filter's own since the restart (its lag), rad, and the
        #: part of that lag a keyframe's correction gave already (``keyframe_pays_lag``): of the same
        #: sign as the lag and no larger.
        self._lag = self._prepaid = 0.0
        #: The filter's own increment of the last call, rad (the increment given but for the bound).
        self.filtered = 0.0

    def __call__(self, dyaw: float, var_yaw: float, dt: float, floored: bool = False,
                 weak: bool = False) -> tuple[float, float]:
        """The filtered increment (rad) and its variance (rad^2) for the measured *dyaw* of
        variance *var_yaw* (taken as at least the configured per-frame noise unless *floored*:
        a fusion of measurements floored each) over *dt* s; *weak*: measured on a step whose
        velocity was not (``yaw_filter_max_lag_trusted_only``)."""
        r = (var_yaw if floored else max(var_yaw, self._noise_rad ** 2)) / (dt * dt)  # rate measurement variance
        if self._filter is None:
            self._filter = YawRateFilter(self._accel, self._switch)
        rate, p = self._filter.update(dyaw / dt, r, dt)
        delivered = self.filtered = rate * dt
        self._lag += dyaw - delivered
        if self._prepaid:
            # What the lag no longer holds of the part given already is not given again.
            kept = _within(self._prepaid, self._lag)
            delivered -= self._prepaid - kept
            self._prepaid = kept
        if self._max_lag is not None:
            # What the heading has yet to be given of the measured turn: held back while within
            # the bound (the filter's smoothing), the rest given at once; but a weak step's part,
            # which a braking frame's outlying turn may be, only as the filter gives it.
            debt = self._debt + dyaw - delivered
            if weak and self._trusted_only:
                self._weak += dyaw - delivered
            self._weak = _within(self._weak, debt)
            bounded = debt - self._weak
            held = min(max(bounded, -self._max_lag), self._max_lag)
            delivered += bounded - held
            self._debt = held + self._weak
        return delivered, p * dt * dt

    def pay(self, amount: float) -> None:
        """A keyframe's correction of the heading, *amount* rad: its part toward the filter's lag,
        up to what of the lag was not given yet, counts as given, and the filter does not give it
        again as it catches up."""
        self._prepaid += _within(amount, self._lag - self._prepaid)

    def restart(self) -> None:
        self._filter = None
        self._debt = self._lag = self._prepaid = self._weak = 0.0


class UnfilteredYaw:
    """The measured yaw increment as it is (``yaw_rate_filter`` off)."""

    #: The last increment given, rad.
    filtered = 0.0

    def pay(self, amount: float) -> None:
        """Nothing is held back, so nothing is given again."""

    def __call__(self, dyaw: float, var_yaw: float, dt: float, floored: bool = False,
                 weak: bool = False) -> tuple[float, float]:
        self.filtered = dyaw
        return dyaw, var_yaw

    def restart(self) -> None:
        pass


def yaw_rate_part(config: OdometryConfig) -> FilteredYaw | UnfilteredYaw:
    return FilteredYaw(config) if config.yaw_rate_filter else UnfilteredYaw()
