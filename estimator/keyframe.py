"""Keyframe correction (beyond the paper): each frame is also registered to a keyframe, a frame
up to ``keyframe_distance_m`` / ``keyframe_angle_rad`` back (one taken in a turn only until the
turn ends, ``keyframe_turn_renew_radps``), and the frame chain's yaw is corrected by it (a Kalman
update of the yaw relative to the keyframe), so that registration noise does not add up frame by
frame.  ``keyframe_start`` is chosen once."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import EstimatorConfig
from .current_frame import CurrentFrame
from .icp import FEW_MATCHES, OK, Registration, register_two_way, scan_guess
from .motion import chord
from .yaw_measurement import KeptFrame, YawMeasurement


@dataclass
class Keyframe:
    """The frame the current one is also registered to."""

    pose: tuple[float, float, float]  # x, y (m), yaw (rad) in the world
    frame: KeptFrame
    #: Variance of the yaw relative to it, rad^2: grows by each frame's, shrinks by each update.
    yaw_var: float = 0.0
    #: Whether it was taken in a turn (``keyframe_turn_renew_radps``): renewed when the turn ends.
    in_turn: bool = False


@dataclass
class ChainStep:
    """One step of the frame chain, as the keyframe correction sees it: the pose before it
    (x, y m, yaw rad), its velocity (2,) m/s and duration s, and its yaw increment (rad) and
    variance (rad^2)."""

    pose: tuple[float, float, float]
    velocity: np.ndarray
    dt: float
    dyaw: float
    var_yaw: float


class KeyframeCorrection:
    """Corrects each measured yaw increment against the keyframe (:meth:`correct`) and takes a
    new keyframe when the last is far enough behind or its turn has ended (:meth:`update`)."""

    #: A measured step's noise is corrected against the keyframe: it does not add up in the heading.
    bounds_noise = True

    def __init__(self, config: EstimatorConfig, yaw: YawMeasurement) -> None:
        odo = config.odometry
        self._config = config
        self._yaw = yaw
        self._distance_m, self._angle_rad = odo.keyframe_distance_m, odo.keyframe_angle_rad
        self._search_rad = odo.keyframe_search_rad
        self._noise_var = (odo.keyframe_noise_rad or odo.yaw_noise_rad) ** 2
        # A keyframe is in a turn above this rate (never without the option), and the turn has
        # ended where the step turns less than half as fast.
        renew = odo.keyframe_turn_renew_radps
        self._turn_radps = math.inf if renew is None else renew
        self._turn_end_radps = 0.5 * self._turn_radps
        start = odo.keyframe_start
        # Whether the scan guess of the keyframe on the current heatmap starts the search (and
        # whether it replaces the prediction, or the search spans both).
        self._scan_start = start in ("scan", "predicted_and_scan") and yaw.scans
        self._scan_replaces = start == "scan"
        # Started from the prediction, the field search reaches as far as the prediction may move.
        self._reach = None if start == "scan" else odo.keyframe_search_rad
        self.key: Keyframe | None = None

    def correct(self, step: ChainStep, current: KeptFrame, frame: CurrentFrame, *,
                registered: bool = True) -> tuple[float, float]:
        """The step's yaw increment corrected by the registration of the keyframe to *current*,
        and its variance: unchanged when there is no keyframe or the measurement fails or
        moves the prediction further than the search allows, or when the step's own registration
        measured nothing (not *registered*: the Doppler alone did, on a heatmap where the
        keyframe's registration would measure noise); the keyframe's yaw variance grows by the
        step's either way."""
        key = self.key
        if key is None:
            return step.dyaw, step.var_yaw
        key.yaw_var += step.var_yaw
        if not registered:
            return step.dyaw, step.var_yaw
        cfg = self._config
        kx, ky, kyaw = key.pose
        # The current pose as predicted by this step, relative to the keyframe.
        move, _ = chord(step.pose[2], step.dyaw, step.velocity, step.dt)
        x, y = step.pose[0] + move[0], step.pose[1] + move[1]
        c, s = math.cos(kyaw), math.sin(kyaw)
        t_rel = np.array([c * (x - kx) + s * (y - ky), -s * (x - kx) + c * (y - ky)])
        predicted = step.pose[2] + step.dyaw - kyaw
        initial, other = -predicted, None  # the search's start, and what its window spans
        if self._scan_start and key.frame.guide is not None:
            found = scan_guess(key.frame.guide.shifted(t_rel), frame.log, cfg.icp.scan_step_rad, self._search_rad,
                               initial, cfg.icp.score_support == "common")
            if found is not None and found[1] >= cfg.icp.min_scan_score:
                if self._scan_replaces:
                    initial = found[0]
                else:
                    other = found[0]
        if key.frame.field is not None and current.field is not None:
            # The field search alone, around the start: ICP before it changes nothing
            # measurable there (docs/estimator.md).
            registration = Registration(initial, 0, OK, variance=0.0)
        else:
            registration, _ = register_two_way(key.frame.features.shifted(t_rel), current.features, cfg.icp,
                                               initial_rad=initial, region=frame.region)
        measured = -registration.rotation_rad
        if registration.status != FEW_MATCHES:
            measured = -self._yaw.field.refine(key.frame.field, current.field, t_rel, registration.rotation_rad,
                                               other, self._reach)
        # The measurement may move the prediction by the search range (plus the span to the
        # other estimate, when the search spans one).
        allowed = self._search_rad + (0.0 if other is None else abs(other - initial))
        if registration.status == FEW_MATCHES or abs(measured - predicted) > allowed:
            return step.dyaw, step.var_yaw
        r = max(registration.variance, self._noise_var)
        gain = key.yaw_var / (key.yaw_var + r)
        corrected = predicted + gain * (measured - predicted)
        key.yaw_var *= 1.0 - gain
        return step.dyaw + (corrected - predicted), (1.0 - gain) * step.var_yaw

    def update(self, pose: tuple[float, float, float], current: KeptFrame, *, measured: bool, rate: float,
               registered: bool = True) -> None:
        """Make *current* (at *pose*, its step turning at *rate* rad/s) the keyframe when the last
        one is far enough behind, or was taken in a turn that has ended, or when this frame's yaw
        was not *measured* (the chain broke); not a frame whose yaw the Doppler alone measured
        (not *registered*): the last keyframe stays until a frame with structure takes over."""
        key = self.key
        if key is not None and measured:
            if not registered:
                return
            kx, ky, kyaw = key.pose
            near = math.hypot(pose[0] - kx, pose[1] - ky) < self._distance_m and abs(pose[2] - kyaw) < self._angle_rad
            turn_ended = key.in_turn and abs(rate) < self._turn_end_radps
            if near and not turn_ended:
                return
        # Only by the step's own rate: one taken by distance or angle while a turn slows down and
        # counted in the turn too did worse over the robustness matrix (docs/heading.md, item 14).
        self.key = Keyframe(pose, current, in_turn=abs(rate) > self._turn_radps)


class NoKeyframes:
    """``keyframe_distance_m`` 0: the frame chain alone."""

    #: Each frame's yaw noise stays in the chain's heading.
    bounds_noise = False

    def correct(self, step: ChainStep, current: KeptFrame, frame: CurrentFrame, *,
                registered: bool = True) -> tuple[float, float]:
        return step.dyaw, step.var_yaw

    def update(self, pose: tuple[float, float, float], current: KeptFrame, *, measured: bool, rate: float,
               registered: bool = True) -> None:
        pass
