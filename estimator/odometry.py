"""Radar odometry: Doppler velocity + heatmap yaw integrated into an SE(2) pose.

Two streams, as in the paper: point clouds give the velocity (any rate), heatmaps
give the yaw (any rate, possibly another sensor).  Feed them in time order:

    odom = RadarOdometry(EstimatorConfig())
    odom.add_points(t, points)        # -> VelocityEstimate
    state = odom.add_heatmap(t, hm)   # -> OdometryState (one per heatmap frame)

or ``odom.step(t, points, heatmap)`` when one radar gives both.  For each heatmap
frame the velocity is interpolated to the middle of it and the previous one
(paper eq. 2), the previous frame's features are shifted by -v dt (eq. 3) and
registered to the current ones by rotation-only weighted ICP; the pose moves by
the chord of that arc and turns by the ICP's rotation.  Poses are the body frame
(REP-103) in the world frame (the body frame at the first heatmap frame).

Nothing here returns NaN: a step that fails says so in ``flags`` and carries the
last good motion forward for ``odometry.hold_s``, then reports no motion.
"""

from __future__ import annotations

import bisect
import logging
import math
import time
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .config import EstimatorConfig
from .features import Features, LogHeatmap, PolarHeatmap, azimuth_profile, extract, heatmap_doppler_points
from .icp import (FEW_MATCHES, NOT_CONVERGED, Region, Registration, correlation_guess, field_rotation,
                  register_two_way, scan_guess)
from .velocity import VelocityEstimate, estimate_velocity

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

#: Quality flags of an odometry state.
FIRST_FRAME = "first_frame"
VELOCITY_FAILED = "velocity_failed"  # no good velocity near this frame
VELOCITY_HELD = "velocity_held"  # ... the last good one was used
VELOCITY_FROM_HEATMAP = "velocity_from_heatmap"  # ... the heatmap's Doppler gave it
FEW_FEATURES = "few_features"
NO_STRUCTURE = "no_structure"  # the heatmaps hold nothing to register (the scan guess's verdict)
ICP_FAILED = "icp_failed"  # registration found too few matches
ICP_NOT_CONVERGED = "icp_not_converged"
YAW_HELD = "yaw_held"  # the last good yaw rate was used
MOTION_LOST = "motion_lost"  # nothing good for longer than hold_s: no motion reported

#: Correlation guess: bearing grid step, rad.
_PROFILE_STEP = math.radians(0.25)
#: Two-model yaw-rate filter: per frame, the probability of staying in (diagonal) or switching
#: between the steady model and the manoeuvre model, rows "from", columns "to".  A turn's start
#: or end takes a few frames; straight drives and steady turns last tens.  The filter starts
#: with the steady row's probabilities.
_MODEL_SWITCH = ((0.9, 0.1), (0.3, 0.7))


@dataclass
class OdometryState:
    """The odometry after one heatmap frame."""

    t: float
    frame: int
    x: float = 0.0  # m, world frame
    y: float = 0.0
    yaw: float = 0.0  # rad, counter-clockwise, unwrapped
    vx: float = 0.0  # m/s, body frame (forward)
    vy: float = 0.0  # m/s, body frame (left)
    yaw_rate: float = 0.0  # rad/s
    #: Covariance of (x, y, yaw), propagated, and of (vx, vy, yaw_rate) of this step.
    pose_covariance: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    twist_covariance: np.ndarray = field(default_factory=lambda: np.eye(3))
    flags: tuple[str, ...] = ()
    features: int = 0
    #: The yaw increment of this step, rad, and what registration gave it.
    yaw_increment: float = 0.0
    registration: Registration | None = None
    velocity: VelocityEstimate | None = None
    #: Time spent in the estimator for this frame, s: the velocity estimates from the point
    #: clouds since the previous heatmap frame (:meth:`RadarOdometry.add_points`), then the
    #: features, the registrations and the integration.
    compute_s: float = 0.0

    @property
    def ok(self) -> bool:
        return not (set(self.flags) - {FIRST_FRAME})


class _Velocities:
    """Recent good velocity estimates, for interpolation to heatmap times."""

    def __init__(self, size: int = 32) -> None:
        self.items: deque[VelocityEstimate] = deque(maxlen=size)
        self._times: deque[float] = deque(maxlen=size)  # the items' times, for bisection

    def add(self, est: VelocityEstimate) -> None:
        if self.items and est.t < self.items[-1].t:
            raise ValueError(f"velocity at t={est.t} after one at t={self.items[-1].t}: feed in time order")
        self.items.append(est)
        self._times.append(est.t)

    def at(self, t: float, mode: str) -> VelocityEstimate | None:
        """The velocity at *t*: linear between the bracketing estimates (eq. 2), else the
        nearest (the first of equal times; the earlier of two as near); None when there is none."""
        times = self._times
        if not times:
            return None
        k = bisect.bisect_left(times, t)
        if mode == "nearest" or k == 0 or k == len(times):
            if k > 0 and (k == len(times) or t - times[k - 1] <= times[k] - t):
                k = bisect.bisect_left(times, times[k - 1])
            return self.items[k]
        a, b = self.items[k - 1], self.items[k]
        f = (t - a.t) / (b.t - a.t) if b.t > a.t else 0.0
        return VelocityEstimate(t=t, vx=a.vx + f * (b.vx - a.vx), vy=a.vy + f * (b.vy - a.vy),
                                covariance=(1 - f) * a.covariance + f * b.covariance,
                                n_points=b.n_points, inliers=b.inliers, status=b.status)


class RadarOdometry:
    """Streaming odometry; see the module docstring."""

    def __init__(self, config: EstimatorConfig | None = None) -> None:
        self.config = config or EstimatorConfig()
        self.rng = np.random.default_rng(self.config.velocity.seed)
        # Its own generator, so that the fallback leaves the point clouds' RANSAC draws as they were.
        self._fallback_rng = np.random.default_rng(self.config.velocity.seed + 1)
        self._fallback: VelocityEstimate | None = None  # the heatmap's velocity of the last frame that needed it
        self._velocities = _Velocities()
        self._last_velocity: VelocityEstimate | None = None  # latest, good or not
        self._previous: tuple[float, Features, Any, Any] | None = None  # (t, features, guide, field)
        self._state: OdometryState | None = None
        self._good_rate: tuple[float, float] | None = None  # (t, yaw rate) of the last good ICP
        self._good_velocity_t: float | None = None
        self._rate_filter: _YawRateFilter | None = None
        self._key: _Keyframe | None = None
        self._log: tuple | None = None  # (heatmap, its LogHeatmap)
        self._frames = 0
        self._velocity_s = 0.0  # time in add_points since the last heatmap frame
        grid_max = self.config.features.max_azimuth_rad
        self._scan_features = replace(self.config.features, method="topk", k=self.config.icp.scan_points,
                                      weighting="db", peaks_only=False, subbin=False)
        self._grid = np.arange(-grid_max, grid_max + 1e-9, _PROFILE_STEP)

    @property
    def state(self) -> OdometryState | None:
        return self._state

    # ------------------------------------------------------------------ velocity stream
    def add_points(self, t: float, points: np.ndarray) -> VelocityEstimate:
        """Estimate the velocity from one point cloud (TI frame fields azimuth, elevation,
        velocity) taken at *t* and keep it for the heatmap frames around it."""
        start = time.perf_counter()
        est = estimate_velocity(points, t, self.config.velocity, self.rng)
        self.add_velocity(est)
        self._velocity_s += time.perf_counter() - start
        return est

    def add_velocity(self, est: VelocityEstimate) -> None:
        """Use a velocity from elsewhere (or from :meth:`add_points`)."""
        self._last_velocity = est
        if est.ok:
            self._velocities.add(est)
            self._good_velocity_t = est.t

    # ------------------------------------------------------------------ heatmap stream
    def step(self, t: float, points: np.ndarray, heatmap: PolarHeatmap) -> OdometryState:
        """One radar giving both streams at *t*."""
        self.add_points(t, points)
        return self.add_heatmap(t, heatmap)

    def add_heatmap(self, t: float, heatmap: PolarHeatmap) -> OdometryState:
        start = time.perf_counter()
        cfg = self.config
        if self._previous is not None and t <= self._previous[0]:
            raise ValueError(f"heatmap at t={t} not after the previous one at t={self._previous[0]}: "
                             "feed in time order")
        flags: list[str] = []
        velocity_now = self._velocities.at(t, "nearest")
        v_now = None if velocity_now is None else velocity_now.velocity
        features = extract(heatmap, cfg.features, v_now)
        guide = self._guide(heatmap)
        field = self._field(heatmap, guide)
        frame = self._frames
        self._frames += 1

        if self._previous is None:
            state = OdometryState(t=t, frame=frame, flags=(FIRST_FRAME,), features=len(features))
            if velocity_now is not None:
                state.vx, state.vy, state.velocity = velocity_now.vx, velocity_now.vy, velocity_now
            self._update_keyframe(state, features, guide, field, ok=False)
            self._finish(state, t, features, guide, field, heatmap, start)
            return state

        t_prev, prev_features, prev_guide, prev_field = self._previous
        previous = self._state
        dt = t - t_prev

        # Velocity at the middle of the two frames (eq. 2), or the last good one held.
        velocity = self._velocities.at(0.5 * (t + t_prev), cfg.odometry.velocity_sync)
        v, v_cov = self._velocity_or_hold(velocity, t, t_prev, flags, heatmap)

        # Yaw: rectify (eq. 3), register both ways, average.
        initial = self._initial_rotation(prev_guide, heatmap, guide, v * dt, dt)
        scan = initial if cfg.icp.initial_guess == "scan" else None
        rotation, registration, var_yaw = self._register(prev_features, features, v * dt, initial, flags)
        if rotation is not None:
            span = scan if cfg.icp.field_window == "icp_and_scan" else None
            rotation = self._refined(prev_field, field, v * dt, rotation, span)
        elif cfg.icp.field_fallback and scan is not None and prev_field is not None and field is not None:
            rotation = self._refined(prev_field, field, v * dt, scan)
        if rotation is None:
            self._rate_filter = None  # restart from the next measurement
            rate = self._held_rate(t, flags)
            dyaw, var_yaw = rate * dt, (math.radians(10.0) * dt) ** 2 + var_yaw
        else:
            dyaw = -rotation  # the world turns the other way
            if cfg.odometry.yaw_rate_filter:
                dyaw, var_yaw = self._filtered(dyaw, var_yaw, dt)
            self._good_rate = (t, dyaw / dt)

        if rotation is not None and cfg.odometry.keyframe_distance_m > 0:
            dyaw, var_yaw = self._against_keyframe(previous, v, dt, dyaw, var_yaw, features, field, heatmap)
        state = self._integrate(previous, t, frame, v, v_cov, dyaw, var_yaw, dt)
        self._update_keyframe(state, features, guide, field, ok=rotation is not None)
        state.flags = tuple(flags)
        state.features = len(features)
        state.registration = registration
        state.velocity = velocity
        self._finish(state, t, features, guide, field, heatmap, start)
        return state

    # ------------------------------------------------------------------ helpers
    def _guide(self, heatmap: PolarHeatmap):
        """What the initial guess keeps of a frame: its azimuth profile, or its strongest cells."""
        guess = self.config.icp.initial_guess
        if guess == "profile":
            return azimuth_profile(heatmap, self.config.features, self._grid)
        if guess == "scan":
            return extract(heatmap, self._scan_features)
        return None

    def _field(self, heatmap: PolarHeatmap, guide):
        """What the field refinement keeps of a frame: (its strongest cells, its smoothed log
        heatmap), or None when the refinement is off."""
        icp = self.config.icp
        if icp.refinement != "field":
            return None
        points = guide if icp.initial_guess == "scan" else extract(heatmap, self._scan_features)
        return points, self._log_heatmap(heatmap).smoothed(icp.field_smoothing_bins)

    def _refined(self, source_field, target_field, translation: np.ndarray, rotation: float,
                 other: float | None = None, reach: float | None = None) -> float:
        """The registration's *rotation* refined on the likelihood fields of both frames (when
        the refinement is on and both frames have one): searched +/- *reach* (by default
        ``field_search_rad``) around it or, given *other* (another estimate of the same
        rotation), from the smaller of the two to the larger, widened by *reach* each side."""
        if source_field is None or target_field is None:
            return rotation
        centre, reach = rotation, self.config.icp.field_search_rad if reach is None else reach
        if other is not None:
            centre, reach = 0.5 * (rotation + other), reach + 0.5 * abs(rotation - other)
        refined = field_rotation(source_field[0], target_field[0], source_field[1], target_field[1],
                                 translation, centre, reach, self.config.icp.field_step_rad)
        return rotation if refined is None else refined

    def _finish(self, state: OdometryState, t: float, features: Features, guide, field, heatmap,
                start: float) -> None:
        self._previous = (t, features, guide, field)
        self._log = None  # the heatmap is the caller's: do not keep it
        self._state = state
        self._region = Region(self.config.features.min_range_m,
                              self.config.features.max_range_m or float(np.max(heatmap.range_m)),
                              self.config.features.max_azimuth_rad)
        state.compute_s = time.perf_counter() - start + self._velocity_s
        self._velocity_s = 0.0

    def _velocity_or_hold(self, velocity: VelocityEstimate | None, t: float, t_prev: float,
                          flags: list[str], heatmap: PolarHeatmap) -> tuple[np.ndarray, np.ndarray]:
        """The velocity (2,) m/s of the step from *t_prev* to *t* and its covariance (2, 2): the
        point clouds' when the latest was good, else the heatmap's Doppler
        (``velocity_fallback``), else the last good one held."""
        last = self._last_velocity
        fresh = last is not None and last.ok
        if velocity is not None and fresh:
            self._fallback = None
            return velocity.velocity, velocity.covariance
        flags.append(VELOCITY_FAILED)
        if self.config.odometry.velocity_fallback == "heatmap":
            est = self._heatmap_velocity(t, t_prev, heatmap)
            if est is not None:
                flags.append(VELOCITY_FROM_HEATMAP)
                return est
        if velocity is not None and self._held(self._good_velocity_t, t, VELOCITY_HELD, flags):
            return velocity.velocity, velocity.covariance * 4.0
        return np.zeros(2), np.eye(2)

    def _heatmap_velocity(self, t: float, t_prev: float,
                          heatmap: PolarHeatmap) -> tuple[np.ndarray, np.ndarray] | None:
        """The step's velocity (2,) m/s and covariance (2, 2) from the heatmap's Doppler at *t*,
        averaged with the velocity at *t_prev* (the step's mid-time, as eq. 2 for the point
        clouds: a robot slowing down is 0.05-0.1 m/s slower at the frame than at mid-step);
        None when the heatmap gives none."""
        points = heatmap_doppler_points(heatmap, self.config.features, self.config.odometry.fallback_cells)
        if points is None:
            return None
        est = estimate_velocity(points, t, self.config.velocity, self._fallback_rng)
        if not est.ok:
            self._fallback = None
            return None
        # Kept apart from the point clouds' estimates: those may come from another sensor, later.
        before = self._fallback if self._fallback is not None and self._fallback.t == t_prev else None
        if before is None:
            good = self._velocities.at(t_prev, "nearest")
            # Only an estimate of the previous frame's own time (within half a step) stands for it.
            if good is not None and abs(good.t - t_prev) <= 0.5 * (t - t_prev):
                before = good
        self._fallback = est
        if before is None:
            return est.velocity, est.covariance
        return 0.5 * (before.velocity + est.velocity), 0.25 * (before.covariance + est.covariance)

    def _log_heatmap(self, heatmap: PolarHeatmap) -> LogHeatmap:
        """The log heatmap of the frame being processed, made once for both registrations."""
        if self._log is None or self._log[0] is not heatmap:
            self._log = (heatmap, LogHeatmap(heatmap, self.config.features))
        return self._log[1]

    def _against_keyframe(self, previous: OdometryState, v: np.ndarray, dt: float, dyaw: float,
                          var_yaw: float, features: Features, field, heatmap: PolarHeatmap) -> tuple[float, float]:
        """Beyond the paper: correct the frame-to-frame yaw by registering the current frame to
        the keyframe (a frame up to ``keyframe_distance_m`` / ``keyframe_angle_rad`` back), so
        that registration noise does not add up frame by frame.  A Kalman update of the yaw
        relative to the keyframe.  Returns the corrected increment and its variance."""
        if self._key is None:
            return dyaw, var_yaw
        key = self._key
        key_pose = key.pose
        cfg = self.config
        start = cfg.odometry.keyframe_start
        # The current pose as predicted by this frame's step, relative to the keyframe.
        step, _ = _chord(previous.yaw, dyaw, v, dt)
        x, y = previous.x + step[0], previous.y + step[1]
        c, s = math.cos(key_pose[2]), math.sin(key_pose[2])
        t_rel = np.array([c * (x - key_pose[0]) + s * (y - key_pose[1]),
                          -s * (x - key_pose[0]) + c * (y - key_pose[1])])
        predicted = previous.yaw + dyaw - key_pose[2]  # yaw relative to the keyframe
        key.yaw_var += var_yaw
        initial, other = -predicted, None  # the search's start, and what its window spans
        if start in ("scan", "predicted_and_scan") and key.guide is not None and cfg.icp.initial_guess == "scan":
            found = scan_guess(key.guide.shifted(t_rel), self._log_heatmap(heatmap), cfg.icp.scan_step_rad,
                               cfg.odometry.keyframe_search_rad, initial)
            if found is not None and found[1] >= cfg.icp.min_scan_score:
                if start == "scan":
                    initial = found[0]
                else:
                    other = found[0]
        if key.field is not None and field is not None:
            # The field search alone, around the start (within a degree or so here): ICP
            # before it changed nothing measurable and cost 2 ms a frame.
            registration = Registration(initial, 0, "ok", variance=0.0)
        else:
            registration, _ = register_two_way(key.features.shifted(t_rel), features, cfg.icp, initial_rad=initial,
                                               region=self._region)
        measured = -registration.rotation_rad
        if registration.status != FEW_MATCHES:
            # Started from the prediction, the search reaches as far as the prediction may move.
            reach = cfg.odometry.keyframe_search_rad if start != "scan" else None
            measured = -self._refined(key.field, field, t_rel, registration.rotation_rad, other, reach)
        # The measurement may move the prediction by the search range (plus the span to the
        # other estimate, when the search spans one).
        allowed = cfg.odometry.keyframe_search_rad + (0.0 if other is None else abs(other - initial))
        if registration.status == FEW_MATCHES or abs(measured - predicted) > allowed:
            return dyaw, var_yaw
        noise = cfg.odometry.keyframe_noise_rad or cfg.odometry.yaw_noise_rad
        r = max(registration.variance, noise ** 2)
        gain = key.yaw_var / (key.yaw_var + r)
        corrected = predicted + gain * (measured - predicted)
        key.yaw_var *= 1.0 - gain
        return dyaw + (corrected - predicted), (1.0 - gain) * var_yaw

    def _update_keyframe(self, state: OdometryState, features: Features, guide, field, ok: bool) -> None:
        """Make this frame the keyframe when the last one is far enough behind (or unusable)."""
        odo = self.config.odometry
        if odo.keyframe_distance_m <= 0:
            return
        if self._key is not None and ok:
            kx, ky, kyaw = self._key.pose
            near = (math.hypot(state.x - kx, state.y - ky) < odo.keyframe_distance_m
                    and abs(state.yaw - kyaw) < odo.keyframe_angle_rad)
            if near:
                return
        self._key = _Keyframe((state.x, state.y, state.yaw), features, guide, field)

    def _filtered(self, dyaw: float, var_yaw: float, dt: float) -> tuple[float, float]:
        """The yaw-rate filter: the measured increment, of variance at least the configured
        per-frame noise, blended with the prediction.  Returns the filtered increment and its
        variance."""
        odo = self.config.odometry
        r = max(var_yaw, odo.yaw_noise_rad ** 2) / (dt * dt)  # rate measurement variance
        if self._rate_filter is None:
            accel = (odo.yaw_accel_std_radps2,)
            if odo.yaw_manoeuvre_accel_std_radps2 is not None:
                accel += (odo.yaw_manoeuvre_accel_std_radps2,)
            self._rate_filter = _YawRateFilter(accel)
        rate, p = self._rate_filter.update(dyaw / dt, r, dt)
        return rate * dt, p * dt * dt

    def _held_rate(self, t: float, flags: list[str]) -> float:
        good_t = None if self._good_rate is None else self._good_rate[0]
        return self._good_rate[1] if self._held(good_t, t, YAW_HELD, flags) else 0.0

    def _held(self, good_t: float | None, t: float, flag: str, flags: list[str]) -> bool:
        """Whether the last good value (at *good_t*) may still stand in at *t*: flagged
        *flag* if so, ``motion_lost`` (once) if not."""
        if good_t is not None and t - good_t <= self.config.odometry.hold_s:
            flags.append(flag)
            return True
        if MOTION_LOST not in flags:
            flags.append(MOTION_LOST)
        return False

    def _initial_rotation(self, prev_guide, heatmap: PolarHeatmap, guide, translation: np.ndarray,
                          dt: float) -> float | None:
        """Starting rotation of the registration (source -> target convention); None when
        the scan finds no structure to register."""
        icp = self.config.icp
        predicted = 0.0
        if icp.initial_guess != "zero" and self._good_rate is not None:
            predicted = -self._good_rate[1] * dt
        guess = None
        if prev_guide is not None and icp.initial_guess == "profile":
            guess = correlation_guess(prev_guide, guide, _PROFILE_STEP, icp.max_rotation_rad, predicted)
        elif prev_guide is not None and icp.initial_guess == "scan":
            found = scan_guess(prev_guide.shifted(translation), self._log_heatmap(heatmap),
                               icp.scan_step_rad, icp.max_rotation_rad, predicted)
            if found is None or found[1] < icp.min_scan_score:
                return None
            guess = found[0]
        return predicted if guess is None else guess

    def _register(self, prev_features: Features, features: Features, translation: np.ndarray,
                  initial: float | None, flags: list[str]):
        """(rotation or None, registration, variance) of previous -> current."""
        minimum = self.config.odometry.min_features
        if len(features) < minimum or len(prev_features) < minimum:
            flags.append(FEW_FEATURES)
            return None, None, 0.0
        if initial is None:
            flags.append(NO_STRUCTURE)
            return None, None, 0.0
        source = prev_features.shifted(translation)
        registration, _ = register_two_way(source, features, self.config.icp, initial_rad=initial,
                                           region=self._region)
        if registration.status == FEW_MATCHES:
            flags.append(ICP_FAILED)
            return None, registration, 0.0
        if registration.status == NOT_CONVERGED:
            flags.append(ICP_NOT_CONVERGED)  # its rotation is still the best there is
        variance = registration.variance if math.isfinite(registration.variance) else math.radians(5.0) ** 2
        return registration.rotation_rad, registration, variance

    def _integrate(self, previous: OdometryState, t: float, frame: int, v: np.ndarray, v_cov: np.ndarray,
                   dyaw: float, var_yaw: float, dt: float) -> OdometryState:
        step, turn = _chord(previous.yaw, dyaw, v, dt)
        x, y = previous.x + step[0], previous.y + step[1]
        # Covariance: pose (x, y, yaw) through the step's Jacobians.
        f = np.eye(3)
        f[0, 2], f[1, 2] = -step[1], step[0]
        g = np.zeros((3, 3))
        g[:2, :2] = turn * dt
        g[2, 2] = dt
        twist = np.zeros((3, 3))
        twist[:2, :2] = v_cov
        twist[2, 2] = var_yaw / (dt * dt)
        pose_cov = f @ previous.pose_covariance @ f.T + g @ twist @ g.T
        return OdometryState(t=t, frame=frame, x=float(x), y=float(y), yaw=float(previous.yaw + dyaw),
                             vx=float(v[0]), vy=float(v[1]), yaw_rate=float(dyaw / dt),
                             pose_covariance=pose_cov, twist_covariance=twist, yaw_increment=float(dyaw))


@dataclass
class _Keyframe:
    """The frame the current one is also registered to (``_against_keyframe``)."""

    pose: tuple[float, float, float]  # x, y (m), yaw (rad) in the world
    features: Features
    guide: Any  # its scan points (None without the scan guess)
    field: Any  # its likelihood field (None without the field refinement)
    #: Variance of the yaw relative to it, rad^2: grows by each frame's, shrinks by each update.
    yaw_var: float = 0.0


class _YawRateFilter:
    """Kalman filter(s) of the yaw rate, constant rate with white yaw acceleration: one model,
    or several of different acceleration mixed as an interacting-multiple-model filter (each
    model's estimate is blended with the others' by the switch probabilities before its step,
    and the models are weighted by the likelihood of the measurement under each).  With one
    model this is the plain scalar Kalman filter."""

    def __init__(self, accel_std: tuple[float, ...]) -> None:
        self.accel_std = np.asarray(accel_std, dtype=float)
        self.switch = np.array(_MODEL_SWITCH if len(accel_std) == 2 else ((1.0,),))
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


def _chord(yaw: float, dyaw: float, v: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """World displacement (2,) m of a body at heading *yaw* moving at body velocity *v* (2,)
    m/s for *dt* s while turning by *dyaw*: along an arc, the chord points half the turn off
    the mid velocity.  Also the rotation (2, 2) from the body to the chord's heading."""
    half = yaw + 0.5 * dyaw
    c, s = math.cos(half), math.sin(half)
    turn = np.array([[c, -s], [s, c]])
    return turn @ v * dt, turn


__all__ = ["RadarOdometry", "OdometryState"]
