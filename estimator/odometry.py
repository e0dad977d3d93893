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
last good motion forward for ``odometry.hold_s``, then reports no motion.  Frames lost
are measured across like any step (searched wider, ``odometry.gap_yaw_rate_radps``); a
run of frames that saw nothing is measured across when the radar sees again
(``odometry.bridge_s``).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import TimeOrderError, UsageError
from .config import EstimatorConfig
from .current_frame import CurrentFrame, FrameProducts
from .doppler_elevation import doppler_elevation_part
from .doppler_yaw import doppler_yaw_part, fuse, no_side_slip_part
from .features import PolarHeatmap
from .heading_blend import HeadingBlend
from .inputs import (MAX_CLOUD_POINTS, MAX_POINT_VALUE, POINT_FIELDS, POINT_YAW_FIELDS, check_heatmap, check_points,
                     check_time, check_velocity, distinct_points, finite_heatmap, finite_points, strongest_points)
from .icp import Registration
from .keyframe import ChainStep, KeyframeCorrection, NoKeyframes
from .motion import integrate
from .odometry_state import OdometryState
from .point_yaw import point_yaw_part
from .quality import HELD_OR_NO_VELOCITY, UNMEASURED_VELOCITY, Flag, may_hold
from .velocity import VelocityEstimate, estimate_velocity
from .velocity_track import StepVelocity, VelocityTrack
from .wall_map import WallMap
from .yaw_measurement import KeptFrame, YawMeasurement
from .yaw_rate import yaw_rate_part

logger = logging.getLogger(__name__)

# The flags by their former module-level names, which callers use.
FIRST_FRAME, VELOCITY_FAILED, VELOCITY_HELD = Flag.FIRST_FRAME, Flag.VELOCITY_FAILED, Flag.VELOCITY_HELD
VELOCITY_FROM_HEATMAP, FEW_FEATURES, NO_STRUCTURE = Flag.VELOCITY_FROM_HEATMAP, Flag.FEW_FEATURES, Flag.NO_STRUCTURE
ICP_FAILED, ICP_NOT_CONVERGED, YAW_HELD, MOTION_LOST = (Flag.ICP_FAILED, Flag.ICP_NOT_CONVERGED, Flag.YAW_HELD,
                                                        Flag.MOTION_LOST)

#: Correlation guess: bearing grid step, rad.
_PROFILE_STEP = math.radians(0.25)


@dataclass
class _Measured:
    """One step's measurement from *base* (the state at the frame registered against): its
    velocity, the registration, the yaw observed (None: not measured) and its variance,
    whether the Doppler's yaw rate was fused in, and whether the registration measured."""

    base: OdometryState
    velocity: StepVelocity
    registration: Registration | None
    observed: float | None
    variance: float
    fused_doppler: bool
    #: Whether the registration measured the yaw (not the Doppler alone): the keyframe's
    #: registration needs the structure this one found, and a new keyframe has it.
    registered: bool


class RadarOdometry:
    """Streaming odometry; see the module docstring.  Its parts are chosen once from the
    config: the velocity track (with its fallback), the yaw measurement (guess, ICP, field),
    the yaw-rate filter and the keyframe correction."""

    def __init__(self, config: EstimatorConfig | None = None) -> None:
        if config is not None and not isinstance(config, EstimatorConfig):
            raise UsageError(f"the estimator's settings must be an EstimatorConfig (EstimatorConfig.from_dict makes "
                             f"one from a dict) or None, got {type(config).__name__}")
        self.config = config or EstimatorConfig()
        odo = self.config.odometry
        self.rng = np.random.default_rng(self.config.velocity.seed)
        self.no_side_slip = no_side_slip_part(odo)
        self.velocities = VelocityTrack(self.config, None if self.no_side_slip is None else self._without_slip)
        self.yaw = YawMeasurement(self.config, _PROFILE_STEP)
        self.rate = yaw_rate_part(odo)
        self.doppler_yaw = doppler_yaw_part(odo)
        self.doppler_elevation = doppler_elevation_part(self.config.features)
        self._yaw_noise_var = odo.yaw_noise_rad ** 2
        self.keyframes = KeyframeCorrection(self.config, self.yaw) if odo.keyframe_distance_m > 0 else NoKeyframes()
        # point_yaw.use: the yaw from the point clouds on a local map (the heatmap's when slow),
        # which also stands in for the keyframes.
        self.point_yaw = point_yaw_part(self.config, self.yaw, self.doppler_elevation)
        if self.point_yaw is not None:
            self.yaw, self.keyframes = self.point_yaw, self.point_yaw.map
        self._walk_var_m, self._walk_var_rad = odo.yaw_walk_per_sqrt_m ** 2, odo.yaw_walk_per_sqrt_rad ** 2
        #: point_yaw.blend: the points' own estimator beside this one, its heading blended into
        #: what this one publishes (None: not run).
        self.blend = None
        if self.point_yaw is None and self.config.point_yaw.blend:
            points = RadarOdometry(self.config.with_(point_yaw={"use": True, "blend": 0.0}, wall_map={"use": False}))
            self.blend = HeadingBlend(points, self.config.point_yaw.blend, self._walk_var_rad,
                                      self.config.point_yaw.lag_frames,
                                      points_where_held=self.config.point_yaw.blend_points_where_held)
        #: wall_map.use: the published heading corrected by the walls seen again (None: not).
        self.walls = WallMap(self.config.wall_map) if self.config.wall_map.use else None
        self._held_rate_std = odo.held_yaw_rate_std_radps
        self._pays_lag = odo.keyframe_pays_lag and self.point_yaw is None
        # The points' yaw has its own way across unmeasured steps (point_yaw.relocate_*); a guess
        # without the rate's prediction would start the step across a run from no turn.
        self._bridge_s = odo.bridge_s if self.point_yaw is None and self.yaw.guess.uses_rate else 0.0
        # The last frame whose step was measured, and the state there (``bridge_s``); and whether
        # every frame since saw nothing, not even a point cloud to fit a velocity to.
        self._anchor: tuple[KeptFrame, OdometryState] | None = None
        self._blind_since = False
        self._chord = odo.rectification == "chord"
        self._previous: KeptFrame | None = None
        self._state: OdometryState | None = None  # this chain's, which its steps start from
        #: What add_points checks each point has: the points' yaw reads their place too.
        self._point_fields = POINT_FIELDS if self.point_yaw is None and self.blend is None and self.walls is None \
            else POINT_YAW_FIELDS
        self._told: set[str] = set()  # the kinds of inputs left out that were logged as a warning
        self._published: OdometryState | None = None  # with point_yaw.blend, the blend's
        self._good_rate: tuple[float, float] | None = None  # (t, yaw rate rad/s) of the last measured yaw
        self._frames = 0
        self._velocity_s = 0.0  # time in add_points since the last heatmap frame

    @property
    def state(self) -> OdometryState | None:
        return self._published

    # ------------------------------------------------------------------ velocity stream
    def add_points(self, t: float, points: np.ndarray, *, velocity: VelocityEstimate | None = None
                   ) -> VelocityEstimate:
        """Estimate the velocity from one point cloud (TI frame fields azimuth, elevation,
        velocity) taken at *t* and keep it for the heatmap frames around it; the estimate kept
        (a wheeled base's on its axis without sideways slip: ``odometry.base``).  *velocity*: one
        measured otherwise at *t* (the ground truth's, in a diagnosis) kept instead of the fit; the
        points still serve the points' yaw and the map of walls."""
        start = time.perf_counter()
        check_time(t, "point cloud")
        check_points(points, self._point_fields)
        n_given = len(points)
        points = finite_points(points, self._point_fields)
        if len(points) < n_given:
            self._input_note(t, "not finite", f"{n_given - len(points)} of {n_given} points hold NaN, inf or values "
                             f"past {MAX_POINT_VALUE:g} in {'/'.join(self._point_fields)}: left out")
        n_given = len(points)
        points = distinct_points(points, self._point_fields)
        if len(points) < n_given:
            self._input_note(t, "repeated", f"{n_given - len(points)} of {n_given} points repeat another in "
                             f"{'/'.join(self._point_fields)}: left out")
        if len(points) > MAX_CLOUD_POINTS:
            self._input_note(t, "too many", f"{len(points)} points: the {MAX_CLOUD_POINTS} strongest taken")
            points = strongest_points(points)
        if velocity is not None:
            check_velocity(velocity)
            if velocity.t != t:
                raise UsageError(f"velocity at t={velocity.t} given with the point cloud at t={t}")
            est = velocity
        else:
            est = estimate_velocity(points, t, self.config.velocity, self.rng, self.velocities.reachable(t))
            if self.velocities.level_speed is not None:
                est = self.velocities.level_speed(t, points, est)
        est = self.velocities.add(est)
        if self.point_yaw is not None:
            self.point_yaw.add_points(t, points, est)
        self._velocity_s += time.perf_counter() - start
        if self.blend is not None:
            self.blend.add_points(t, points, velocity=velocity)
        if self.walls is not None:
            self.walls.add_points(points)
        return est

    def add_velocity(self, est: VelocityEstimate) -> None:
        """Use a velocity from elsewhere (or from :meth:`add_points`); a wheeled base's on its
        axis loses its sideways part as the point clouds' do."""
        check_velocity(est)
        check_time(est.t, "velocity")
        self.velocities.add(est)
        if self.blend is not None:
            self.blend.add_velocity(est)

    def _input_note(self, t: float, kind: str, what: str) -> None:
        """Log *what* was left out of the inputs at *t*: a warning the first time for each *kind*,
        then at debug level (a source that pads its clouds with NaN does so every frame)."""
        level = logging.DEBUG if kind in self._told else logging.WARNING
        self._told.add(kind)
        logger.log(level, "estimator at t=%.3f s: %s%s", t, what,
                   "" if level == logging.DEBUG else " (said once; the rest at debug level)")

    def _without_slip(self, est: VelocityEstimate) -> VelocityEstimate:
        """*est* without sideways slip at the last measured yaw rate (``no_side_slip``)."""
        return self.no_side_slip(est, self._last_rate)

    # ------------------------------------------------------------------ heatmap stream
    def step(self, t: float, points: np.ndarray, heatmap: PolarHeatmap) -> OdometryState:
        """One radar giving both streams at *t*."""
        self.add_points(t, points)
        return self.add_heatmap(t, heatmap)

    def add_heatmap(self, t: float, heatmap: PolarHeatmap, *, products: FrameProducts | None = None) -> OdometryState:
        """The odometry after the heatmap frame taken at *t* (s, after the previous frame's).
        *products*: what another estimator made of the same heatmap in the same call, to share
        (:mod:`.current_frame`; the blend's points' estimator gets this one's)."""
        start = time.perf_counter()
        check_time(t, "heatmap")
        check_heatmap(heatmap)
        given = finite_heatmap(heatmap)  # what the blend's points' estimator is fed too
        if given is not heatmap:
            self._input_note(t, "not finite", "heatmap cells whose power is NaN or inf: taken as none")
        heatmap, previous = given, self._previous
        if previous is not None and not t > previous.t:
            raise TimeOrderError(f"heatmap at t={t} not after the previous one at t={previous.t}: "
                                 "feed frames in time order")
        near = self.velocities.near(t)
        # Moving cells are told from static ones by this frame's own velocity: one held from
        # before a hard stop calls the whole static world moving, and leaves a blank heatmap.
        own = near is not None and (previous is None or abs(near.t - t) <= 0.5 * (t - previous.t))
        own_velocity = near.velocity if own else None
        if self.doppler_elevation is not None:
            # Against the level fit's velocity a cell at the static points' mean elevation reads
            # level: the cells' Doppler is too coarse for their own (docs/heading.md, item 26).
            heatmap = self.doppler_elevation(heatmap, t, near.level_velocity if own else None, self._last_rate)
        if products is None and self.blend is not None:
            products = FrameProducts()  # for the points' estimator too
        frame = CurrentFrame(t, heatmap, self.config, products)
        dt = None if previous is None else t - previous.t
        current = self.yaw.keep(frame, own_velocity, turn_rad=0.0 if dt is None else self._last_rate * dt, dt=dt)
        index, self._frames = self._frames, self._frames + 1
        if previous is None:
            state = OdometryState(t=t, frame=index, flags=(Flag.FIRST_FRAME,), features=len(current.features))
            if near is not None:
                state.vx, state.vy, state.velocity = near.vx, near.vy, near
            self.keyframes.update(state.pose, current, measured=False, rate=0.0)
        else:
            state = self._step(previous, current, frame, index)
        self._previous, self._state = current, state
        state.compute_s = time.perf_counter() - start + self._velocity_s
        self._velocity_s = 0.0
        self._published = state if self.blend is None else self.blend(state, t, given, frame.products)
        if self.walls is not None:
            start = time.perf_counter()
            self._published = self.walls(self._published)
            self._published.compute_s += time.perf_counter() - start
        return self._published

    def _step(self, previous: KeptFrame, current: KeptFrame, frame: CurrentFrame, index: int) -> OdometryState:
        """The odometry of the step from *previous* to *current*: velocity at its middle (eq. 2),
        yaw from the registration of the rectified previous frame (eq. 3) filtered and
        corrected against the keyframe, then the pose integrated along the arc.  When the yaw
        cannot be measured from *previous*, the frames since the last measured step saw nothing
        (no heatmap structure, no point cloud's velocity) and this one's point cloud fits a
        velocity, within ``bridge_s`` of that step's frame, it is measured across from there and
        the pose moves on from the state there: the state then carries that measurement's
        flags, its yaw increment is the change since the latest state, its yaw rate the mean
        over the run."""
        t = current.t
        flags: list[Flag] = []
        step = self._measure(previous, self._state, current, frame, flags)
        bridged = False
        # Only a frame that sees again, its point cloud too: its velocity is then the clouds', and
        # a look that fails leaves nothing changed.
        if step.observed is None and self._blind_since and Flag.VELOCITY_FAILED not in flags \
                and self._anchor is not None and self._anchor[0] is not previous \
                and t - self._anchor[0].t <= self._bridge_s:
            across_flags: list[Flag] = []
            across = self._measure(*self._anchor, current, frame, across_flags)
            if across.observed is not None:
                step, flags, bridged = across, across_flags, True
        last, velocity = step.base, step.velocity
        dt = t - last.t
        v = velocity.velocity
        if step.observed is None:
            self.rate.restart()  # from the next measurement
            # A step past max_step_s turns by nothing, as it moves by nothing: a rate held (hold_s
            # up to an hour) times a gap of minutes is no turn measured.
            dyaw = 0.0 if dt > self.config.odometry.max_step_s else self._held_rate(t, flags) * dt
            var_yaw = (self._held_rate_std * dt) ** 2 + step.variance
        else:
            dyaw, var_yaw = self.rate(step.observed, step.variance, dt, floored=step.fused_doppler,
                                      weak=not UNMEASURED_VELOCITY.isdisjoint(flags))
            # The next search's prediction follows the filter's rate, not the increment given: with
            # yaw_filter_max_lag_rad that carries the measurements' noise (docs/heading.md).
            self._good_rate = (t, self.rate.filtered / dt)
            if not bridged:  # (the keyframe is a frame of the run: a new one starts here)
                given = dyaw
                dyaw, var_yaw = self.keyframes.correct(ChainStep(last.pose, v, dt, dyaw, var_yaw), current, frame,
                                                       registered=step.registered)
                if self._pays_lag:
                    self.rate.pay(dyaw - given)
        # Where the keyframes bound each frame's noise, what stays in the heading is each straight's
        # and each turn's error (docs/heading.md, item 28).  A measured step the keyframe measurement
        # failed on is bounded too: the next one corrects the chain against the same keyframe.
        added_yaw_var = self._walk_var_m * float(np.hypot(v[0], v[1])) * dt + self._walk_var_rad * abs(dyaw)
        if step.observed is None or bridged or not self.keyframes.bounds_noise:
            added_yaw_var += var_yaw
        pose, pose_cov, twist = integrate(last.pose, last.pose_covariance, v, velocity.covariance, dyaw, var_yaw, dt,
                                          pose_var_yaw=added_yaw_var)
        # Across a bridged run, the increment since the latest state (the run's held motion).
        increment = dyaw if last is self._state else pose[2] - self._state.yaw
        state = OdometryState(t=t, frame=index, x=pose[0], y=pose[1], yaw=pose[2], vx=float(v[0]), vy=float(v[1]),
                              yaw_rate=float(dyaw / dt), pose_covariance=pose_cov, twist_covariance=twist,
                              flags=tuple(flags), features=len(current.features), yaw_increment=float(increment),
                              registration=step.registration, velocity=velocity.estimate)
        self.keyframes.update(state.pose, current, measured=step.observed is not None and not bridged,
                              rate=state.yaw_rate, registered=step.registered)
        if step.observed is not None:
            self._anchor, self._blind_since = (current, state), True
        else:
            self._blind_since &= Flag.VELOCITY_FAILED in flags
        return state

    def _measure(self, previous: KeptFrame, base: OdometryState, current: KeptFrame, frame: CurrentFrame,
                 flags: list[Flag]) -> _Measured:
        """The velocity and the yaw measured from *previous* (whose state is *base*) to
        *current*, flagged in *flags*."""
        t, dt = current.t, current.t - previous.t
        velocity = self.velocities.for_step(previous.t, t, frame.heatmap, flags)
        if dt > self.config.odometry.max_step_s:  # the motion is unknown (motion_lost), its turn too: the
            # search's prediction and the rate filter take the turn over the step as a rate (times dt)
            return _Measured(base, velocity, None, None, self.config.odometry.unmeasured_yaw_std_rad ** 2,
                             False, False)
        v = velocity.velocity
        rate = self._last_rate
        predicted = -rate * dt if self.yaw.guess.uses_rate else 0.0
        measured = self.yaw.measure(previous, current, frame, self._translation(v, dt, rate * dt), predicted, flags,
                                    translation_held=Flag.VELOCITY_HELD in flags,
                                    widen_rad=self._gap_doubt(dt) if self.yaw.guess.uses_rate else 0.0)
        registered = None if measured.rotation is None else -measured.rotation  # the world turns the other way
        var_registered = measured.variance
        doppler = None
        if self.doppler_yaw is not None and HELD_OR_NO_VELOCITY.isdisjoint(flags):
            doppler = self.doppler_yaw(v, velocity.covariance, registered is not None, rate)
            if doppler is not None:
                var_registered = max(var_registered, self._yaw_noise_var)  # the filter's floor, before fusing
        observed, var_observed = fuse(registered, var_registered, doppler, dt)
        return _Measured(base, velocity, measured.registration, observed,
                         var_observed if observed is not None else measured.variance, doppler is not None,
                         registered is not None)

    @property
    def _last_rate(self) -> float:
        """The last measured yaw rate, rad/s (0 before any)."""
        return self._good_rate[1] if self._good_rate is not None else 0.0

    def _gap_doubt(self, dt: float) -> float:
        """How much further either side of the last rate's turn the search of a step of *dt* s
        reaches, rad: every turn the radar could have made at up to ``gap_yaw_rate_radps`` more
        or less than that rate (it may have started, stopped or kept turning), beyond what the
        usual window (``icp.max_rotation_rad``) spans already; ``gap_search_rad`` at most.  Only
        a long step (frames lost, a bridged run) needs it."""
        odo = self.config.odometry
        reach = odo.gap_yaw_rate_radps * dt - self.config.icp.max_rotation_rad
        return min(max(0.0, reach), odo.gap_search_rad)

    def _translation(self, v: np.ndarray, dt: float, turn: float) -> np.ndarray:
        """The sensor's displacement over the step in the previous frame's axes, (2,) m: v dt,
        turned by half the predicted *turn* (rad) with ``rectification`` "chord"."""
        if not self._chord:
            return v * dt
        half = 0.5 * turn
        c, s = math.cos(half), math.sin(half)
        return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]]) * dt

    def _held_rate(self, t: float, flags: list[Flag]) -> float:
        """The last measured yaw rate while it may stand in (``hold_s``), else 0."""
        good_t = None if self._good_rate is None else self._good_rate[0]
        held = may_hold(good_t, t, self.config.odometry.hold_s, Flag.YAW_HELD, flags)
        return self._good_rate[1] if held else 0.0


__all__ = ["RadarOdometry", "OdometryState", "Flag"]
