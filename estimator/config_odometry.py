"""The estimator's settings of integration (velocity and yaw into a pose, failed steps, the
keyframe, a wheeled base's Doppler yaw rate) and of the yaw from a radar's own points: parts of
:class:`~.config.EstimatorConfig`, which re-exports them.  Units: metres, seconds, radians."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..settings import Settings, check_choice
from ..settings import check_field as _check
from .config_limits import (  # noqa: F401  (re-exported)
    MIN_SEARCH_STEP_RAD, ODOMETRY, POINT_YAW, check_limits, check_search_size,
)

KEYFRAME_STARTS = ("scan", "predicted", "predicted_and_scan")
VELOCITY_FALLBACKS = ("hold", "heatmap")
HEATMAP_USES = ("check", "fallback", "fuse")


@dataclass
class OdometryConfig(Settings):
    """Integration of velocity and yaw into a pose, and what happens when a step fails."""

    _what = "odometry"

    #: A failed step carries the last good velocity / yaw rate forward this long, s; after
    #: that the motion it reports is zero (and flagged).
    hold_s: float = 0.5
    #: Beyond the paper: when the point cloud gives no velocity near a heatmap frame, "hold"
    #: the last good one (for ``hold_s``), or take it from the "heatmap": its strongest
    #: local-maximum cells' dominant Doppler, fitted like a point cloud (elevation unknown,
    #: so taken as 0) and averaged with the velocity at the previous frame (the step's
    #: mid-time), held only when that fails too.  A robot slowing down to stop or to turn in
    #: place leaves the point cloud a handful of detections for several frames; holding the
    #: speed from before adds drift, and the wrong rectification costs yaw
    #: (docs/estimator.md, "Why the defaults").
    velocity_fallback: str = "heatmap"
    #: With the "heatmap" fallback: the number of strongest local-maximum cells it fits.  Most
    #: weak maxima carry noise's Doppler: with too many, the static world's share falls below
    #: ``velocity.min_inlier_ratio`` and the fit fails; it is then tried on the strongest half,
    #: then a quarter (docs/estimator.md, "Why the defaults"; docs/heading.md, item 23).
    fallback_cells: int = 50
    #: Fewer heatmap features than this: no registration ("few_features").
    min_features: int = 10
    #: Velocity at the middle of two heatmap frames (paper eq. 2): "interpolate" linearly
    #: between the bracketing velocity estimates, or take the "nearest".
    velocity_sync: str = "interpolate"
    #: How the previous frame's features are moved to the current sensor position (paper eq.
    #: 3): "velocity", by the step's mid velocity times its duration, in the previous frame's
    #: axes (the paper); "chord", that displacement turned by half the step's predicted turn,
    #: the chord of the arc the sensor drove (the mid velocity is in the mid-step body's axes,
    #: half a turn from the previous frame's).  Uncorrected, a moving turn's features are moved
    #: sideways by v dt sin(turn / 2), which the registration reads as extra rotation.
    rectification: str = "chord"
    #: Beyond the paper: smooth the measured yaw rate with a Kalman filter (a robot's yaw rate
    #: changes smoothly; frame-to-frame registration noise does not) ...
    yaw_rate_filter: bool = True
    #: ... whose measurements have at least this noise per frame, rad ...
    yaw_noise_rad: float = math.radians(1.0)
    #: ... and whose yaw rate changes with this standard deviation of yaw acceleration, rad/s^2.
    yaw_accel_std_radps2: float = math.radians(50.0)
    #: ... and, when set, a second model of the yaw rate whose acceleration has this (larger)
    #: standard deviation, rad/s^2: the filter then mixes the two by how well each predicts
    #: the measurements (an interacting-multiple-model filter).  A robot turns on and off
    #: within a few frames; one model smooth enough for straight drives and steady turns lags
    #: those by degrees a frame, one loose enough to follow them lets registration noise
    #: through (docs/estimator.md, "Why the defaults").  None: the one model.
    yaw_manoeuvre_accel_std_radps2: float | None = math.radians(300.0)
    #: When set, the filter holds back at most this much of the measured turn, rad, and gives the
    #: rest at once (its lag at a turn's start, which it made up at the turn's end after the keyframes
    #: had).  None: no bound.  With ``keyframe_pays_lag`` and ``yaw_filter_max_lag_trusted_only``,
    #: 1 degree lowered the robustness matrix's drift by a third (docs/heading.md, item 36).
    yaw_filter_max_lag_rad: float | None = math.radians(1.0)
    #: With ``yaw_filter_max_lag_rad``: what a step whose velocity was not measured (the point
    #: cloud's fit failed, held or lost: a weak frame, braking hard) leaves of its measured turn is
    #: not given at once beyond the bound but at the filter's own pace, so that such a frame's
    #: outlying turn stays smoothed (docs/heading.md, item 36).
    yaw_filter_max_lag_trusted_only: bool = True
    #: Beyond the paper: also register each frame to a keyframe and correct the yaw with it,
    #: so that registration noise does not accumulate frame by frame.  A new keyframe is taken
    #: when the sensor is this far (m) or has turned this much (rad) from the last (0: off,
    #: which saves time but lets the room's drift grow; docs/estimator.md, "Why the defaults") ...
    keyframe_distance_m: float = 0.5
    keyframe_angle_rad: float = math.radians(10.0)
    #: ... and the keyframe registration may move the predicted yaw by at most this, rad (with
    #: ``keyframe_start`` "predicted_and_scan", plus the scan guess's disagreement with it).
    keyframe_search_rad: float = math.radians(3.0)
    #: Where the keyframe registration's field search looks: "scan", +/- ``field_search_rad``
    #: around the scan guess of the keyframe's strongest cells on the current heatmap (itself
    #: searched within ``keyframe_search_rad`` of the frame chain's prediction); "predicted",
    #: +/- ``keyframe_search_rad`` around the frame chain's predicted yaw relative to the
    #: keyframe (no scan guess); "predicted_and_scan", from the smaller of the prediction and
    #: the scan guess to the larger, widened by ``keyframe_search_rad`` each side, the
    #: measurement then allowed to move the prediction by that much plus the two's
    #: disagreement.  The scan guess against a keyframe is biased on straight drives and,
    #: started from it, a keyframe cannot repair a chain that drifted more than a few degrees
    #: (a filter lagging a turn's start); the prediction alone misses the turns the chain
    #: under-measures.  Spanning both halves the room's drift (docs/estimator.md, "Why the defaults").
    keyframe_start: str = "predicted_and_scan"
    #: The keyframe measurement's yaw noise (at least), rad; None: ``yaw_noise_rad``.  It is the
    #: noise measured against ground truth (docs/estimator.md, "Why the defaults"); weighted as less,
    #: every keyframe's error goes into one frame's increment.
    keyframe_noise_rad: float | None = math.radians(1.3)
    #: Whether the part of a keyframe's correction toward the yaw-rate filter's lag counts as that
    #: lag given, so that the filter does not give it again as it catches up (its increments sum to
    #: the measured turn): given twice, the lag a turn's start held back overshoots its end, and the
    #: straight after takes it back.  The heatmaps' keyframes only, not the points' map
    #: (``point_yaw``): its raw moving turns come out about 1 % short, which the lag given twice
    #: makes up on average (docs/heading.md, item 36).  With ``yaw_filter_max_lag_rad`` 1 degree it
    #: lowered the robustness matrix's drift by a third.
    keyframe_pays_lag: bool = True
    #: A keyframe taken while the step turned faster than this, rad/s, is renewed at the first
    #: measured frame whose step turns less than half as fast: the chain lags a turn by the
    #: filter's delay, so that keyframe's pose carries the lag, and the drive after the turn
    #: would be corrected towards it (docs/heading.md, item 14).  None: only distance and angle renew.
    keyframe_turn_renew_radps: float | None = math.radians(25.0)
    #: Beyond the paper: what the pose's yaw variance grows by.  Where the keyframes bound the
    #: frames' own noise, a step adds this squared for every metre the radar moves,
    #: rad per sqrt(m), and ``yaw_walk_per_sqrt_rad`` squared for every radian it turns, rad per
    #: sqrt(rad): a random walk in distance and angle, as a wheel odometry's error model, since what
    #: stays in the heading is each straight's and each turn's error, not each frame's; a step they
    #: do not bound (its yaw unmeasured, bridged, no keyframes, the point map's) adds its own variance
    #: too (0 and 0 with no keyframes: each step's own alone, the paper's).  The two are
    #: the robustness matrix's straights' and turns' errors (docs/heading.md, item 28) ...
    yaw_walk_per_sqrt_m: float = 0.017
    #: ... and its turns', rad per sqrt(rad).
    yaw_walk_per_sqrt_rad: float = 0.022

    #: Where the radar sits on the robot's base: x ahead, y left of the base's rotation axis
    #: (m), and its yaw on the base (rad).  The odometry stays the radar's; with ``base``
    #: "wheeled" the mounting lets the Doppler velocity measure the yaw rate.
    mount_x_m: float = 0.0
    mount_y_m: float = 0.0
    mount_yaw_rad: float = 0.0
    #: Beyond the paper (Kellner et al. 2014): "wheeled", the base cannot slide sideways, so a
    #: radar mounted ahead of or behind its rotation axis moves sideways at yaw rate times
    #: ``mount_x_m``: each step's Doppler velocity then measures the yaw rate, fused with the
    #: heatmap registration (inverse-variance weighted) before the yaw-rate filter, and stands
    #: in for it when the registration fails.  On the axis the velocity's sideways part is set
    #: to that product instead of the fit's (nothing on the axis).  "any": the base may slide
    #: (mecanum, legged, hand-held), and the velocity is the fit's.
    base: str = "any"
    #: With ``base`` "wheeled": a lever arm shorter than this (m) makes the yaw rate too noisy
    #: to use (its noise is the sideways velocity's over the lever arm): the radar counts as on
    #: the axis ...
    min_lever_arm_m: float = 0.05
    #: ... and the Doppler yaw rate counts as at least this noise, rad/s (the velocity fit's
    #: covariance comes from its residuals, which do not see a bias of the fit: in moving turns
    #: its direction leans towards the turn, and the registration, short there, weighs as much
    #: at this floor; docs/heading.md item 34).
    doppler_yaw_rate_noise_radps: float = math.radians(6.0)
    #: ... and is used only where it is at least this large, rad/s: in turns, where heatmap
    #: registration is weakest.  On straight drives a bias of the Doppler fit's direction (a
    #: tenth of a degree is 2 mm/s sideways at 1 m/s: 0.4 deg/s over a 0.3 m lever arm) would
    #: turn the heading steadily; there the registration and the keyframes keep it.
    doppler_yaw_min_rate_radps: float = math.radians(10.0)
    #: With ``base`` "wheeled": the base's forward axis is where the radar's Doppler velocity points
    #: over the frames driving straight (their median, less the lever arm's sideways speed), not
    #: where ``mount_yaw_rad`` says (a mount's yaw is seldom known to a degree, and one degree is
    #: 14 mm/s sideways at 0.8 m/s: more than the lean the radar on the axis removes, 2.7 deg/s of
    #: Doppler yaw rate over a 0.3 m lever arm); until this many such frames the velocity is the
    #: fit's and the Doppler measures no yaw rate.  0: the mount's yaw as given, from the first frame.
    axis_learn_frames: int = 20
    #: ... frames driving straight: the last yaw rate below this, rad/s ...
    axis_straight_radps: float = math.radians(3.0)
    #: ... and the forward speed above this, m/s (slower, the Doppler's noise is a large share).
    axis_min_speed_mps: float = 0.3
    #: With the radar on the axis, the velocity's sideways part is given this standard deviation
    #: times the forward speed, rad (what is left of the axis's error, a little skid), 1 mm/s at
    #: least: a consumer of the twist's covariance (robot_localization, a factor graph) can invert it.
    no_slip_angle_std_rad: float = math.radians(1.0)

    #: The two models' switch probabilities per frame: from the steady model to the manoeuvre
    #: model, and back.  A turn's start or end takes a few frames, straight drives and steady
    #: turns last tens; the filter starts in the steady model.
    yaw_manoeuvre_start_prob: float = 0.1
    yaw_manoeuvre_end_prob: float = 0.3
    #: Good velocity estimates kept for the interpolation to heatmap times: a second or more
    #: of point clouds at any radar rate, so a heatmap stream that lags behind still finds
    #: its velocities.
    velocity_history: int = 32
    #: A velocity held over a failed step is trusted less: its covariance times this.
    held_velocity_variance_factor: float = 4.0
    #: On a step whose velocity is held, the rotation is measured again without the
    #: translation, and this times the two rotations' difference is added to the measurement's
    #: standard deviation (in quadrature); None: off.  A robot braking while its velocity
    #: goes unmeasured moves less than the held velocity says, and the registration turns the
    #: heading to make up for features moved too far (docs/heading.md, item 15).
    held_velocity_yaw_check: float | None = 1.0
    #: A yaw rate held over a step whose yaw was not measured (or the zero one reported after
    #: ``hold_s``) has this standard deviation, rad/s: a robot's turn rate may change by
    #: about this much over a few frames.
    held_yaw_rate_std_radps: float = math.radians(10.0)
    #: A platform's fastest turn, rad/s.  A long step (frames lost on a stalled link, or a run of
    #: blind frames bridged, ``bridge_s``) is searched for its turn (by the scan guess or the
    #: profiles' correlation) around the last measured rate's turn, out to every turn this much
    #: faster or slower than that rate would make over the step: the radar may have started,
    #: stopped or kept turning.  Within a short step the usual window (``icp.max_rotation_rad``)
    #: spans that already.
    gap_yaw_rate_radps: float = math.radians(90.0)
    #: ... but at most this much beyond the usual window, rad: a longer search finds more false
    #: peaks than turns (docs/estimator.md, "Frames lost").
    gap_search_rad: float = math.radians(45.0)
    #: A run of frames that see nothing (no heatmap structure to register and no point cloud to
    #: fit a velocity to: the radar covered, a person right in front of it) is bridged for up to
    #: this long, s (0: off): the first frame that sees the world again is registered against the
    #: last one whose step was measured, across the run, like frames lost on the link, and the
    #: pose moves on from there (the run's own states hold the last motion, as before).  Not with
    #: ``point_yaw.use``, which relocates on its map instead.
    bridge_s: float = 2.0
    #: A step longer than this, s (frames lost for longer, a clock that jumped), moves the pose by
    #: no translation: the velocities at its ends say nothing of where the platform went between
    #: (integrated, a clock that jumped by years moved it by billions of metres).  It is flagged
    #: ``motion_lost`` and turns it by nothing either (the yaw rate held or measured at its ends
    #: says nothing of the turn between); its yaw's variance grows with it.
    max_step_s: float = 10.0
    #: A registration whose angular residuals give no variance (too few to say) is taken to
    #: have this standard deviation, rad: wide enough that the filter and the keyframe lean on
    #: their prediction.
    unmeasured_yaw_std_rad: float = math.radians(5.0)

    def __post_init__(self) -> None:
        self.check_types()
        check_limits(self, ODOMETRY)
        check_choice(self.base, ("any", "wheeled"), "base")
        _check(self.yaw_manoeuvre_accel_std_radps2 is None
               or self.yaw_manoeuvre_accel_std_radps2 > self.yaw_accel_std_radps2,
               "must be above yaw_accel_std_radps2 (or null: one model)", "yaw_manoeuvre_accel_std_radps2")
        check_choice(self.velocity_sync, ("interpolate", "nearest"), "velocity_sync")
        check_choice(self.rectification, ("velocity", "chord"), "rectification")
        check_choice(self.velocity_fallback, VELOCITY_FALLBACKS, "velocity_fallback")
        check_choice(self.keyframe_start, KEYFRAME_STARTS, "keyframe_start")


@dataclass
class PointYawConfig(Settings):
    """Beyond the paper: the yaw from a radar's own few detected points on a short local map, and
    from its zero-Doppler heatmap when slow (TI's demo firmware, ``tidemo://``; estimator/point_yaw.py
    says how, docs/tidemo.md what it gives)."""

    _what = "point-yaw"

    #: Measure the yaw this way instead of registering heatmaps (and their keyframes).
    use: bool = False
    #: Without ``use``: run this way beside the heatmaps' registration and publish each step's
    #: turn moved this share of the way from the heatmaps' chain's to the points' (0: not run;
    #: estimator/heading_blend.py, docs/heading.md item 30).  With ``use``: no effect.
    blend: float = 0.5
    #: With ``blend``: where the heatmaps' chain measured no turn in a step (it held its yaw rate
    #: or lost its motion: a weak view) and the points' chain measured one, publish the points'
    #: turn whole for that step rather than a share of it: a rate held through a turn's end runs
    #: the turn on (docs/heading.md item 39; on since 2026-12-06).
    blend_points_where_held: bool = True
    #: The map holds the static points of this many last frames: a long map anchors each frame's
    #: few points to what the frames before saw (docs/tidemo.md, "How it compares").
    map_frames: int = 80
    #: A point's spread across its ray is its range times this, rad (one azimuth a point from a
    #: small array), ...
    bearing_noise_rad: float = math.radians(2.0)
    #: ... along it this, m, ...
    range_noise_m: float = 0.05
    #: ... and at least this every way, m.
    position_floor_m: float = 0.05
    #: Each map point weighed by the inverse of the map's density about it (the map's Gaussians
    #: summed at its centre), so that a point is scored by whether the map has seen structure
    #: where it lies, not by how often: a sum of Gaussians draws a point on a wall toward where the
    #: map's frames saw it most often, on the matrix's scenes toward boresight on either side, a
    #: turn a lopsided scene does not cancel (docs/heading.md item 38; off in TI's demo preset,
    #: whose few points a frame make a sparse map).
    density_weighted: bool = True
    #: A point is static when its radial velocity is within this of a static reflector's, m/s.
    static_threshold_mps: float = 0.1
    #: Fewer static points than this in a frame, or map points than ``min_map_points``: no turn
    #: from the points.
    min_points: int = 2
    min_map_points: int = 10
    #: The turns tried: within this of the predicted turn, rad, ...
    search_rad: float = math.radians(8.0)
    #: ... every this, rad.
    step_rad: float = math.radians(0.1)
    #: ... first every this, rad, then every ``step_rad`` about the best of those (null: every
    #: ``step_rad`` at once; a point's likelihood spans degrees of turn, ``bearing_noise_rad``, so a
    #: coarse grid well finer than that finds the peak the fine one would at a fraction of the
    #: cost).  Taken as the nearest whole number of ``step_rad`` (of ``relocate_step_rad`` for
    #: the heatmap cells' search); under one and a half of them, every step is searched.
    coarse_step_rad: float | None = math.radians(0.5)
    #: The prior about the predicted turn that picks among peaks, rad (standard deviation).
    prior_rad: float = math.radians(3.0)
    #: After frames whose turn went unmeasured (the held rate stood in), the search and the prior
    #: widen by this much for each of them, rad, ...
    gap_widen_rad: float = math.radians(2.0)
    #: ... for at most this many: the turn the gap held back is uncertain by what the robot may
    #: have turned meanwhile (braking into a turn in place), and the map, placed before the gap,
    #: can measure it (docs/tidemo.md, "The turn after a gap").
    gap_widen_frames: int = 4
    #: Where the points' score still rises at the search's edge (no peak inside), search as far
    #: again beyond it and take a peak there: after a false turn the held rate is off, and the
    #: true turn lies past the edge, which else leaves the false rate held (docs/tidemo.md; not
    #: where the search is already widened after steps the points did not measure: heading.md
    #: item 32).
    look_beyond: bool = True
    #: After at least ``relocate_gap_frames`` unmeasured steps, when slow (the static heatmap then
    #: holds the scene), this many of the heatmap's strongest cells are registered on the map as
    #: the points are (0: never): where the chip's 0-2 points a frame cannot find the turn a braking
    #: gap missed, the whole static scene can.  Its search is wider by ``relocate_widen_rad`` for
    #: each unmeasured step, on top of the points' widening, and its prior ``relocate_prior_rad``.
    #: The turn found goes to the map's chain; the yaw-rate filter takes the step's own (the
    #: heatmap's, frame to frame), and the odometry's yaw follows the chain (``correct_lag``).
    relocate_cells: int = 40
    relocate_gap_frames: int = 4
    relocate_widen_rad: float = math.radians(5.0)
    relocate_prior_rad: float = math.radians(20.0)
    #: ... on a grid of this step, rad (a search seven times the points' on their grid would cost
    #: a frame period).
    relocate_step_rad: float = math.radians(0.5)
    #: A step whose turn went unmeasured may have missed this much of it, rad (standard
    #: deviation): ``correct_lag`` keeps its reference from before such steps, its yaw uncertain
    #: by this much more for each, so that what the map's chain finds afterwards reaches the
    #: odometry's yaw, ...
    gap_turn_std_rad: float = 0.2
    #: ... at most this much a step, rad (a turn found after a gap lands over a few frames, not
    #: all in one).
    gap_correction_max_rad: float = math.radians(3.0)
    #: A point's log-likelihood is at least that of this many standard deviations.
    outlier_sigmas: float = 3.0
    #: The points' turn has at least this noise, rad, and at most ``max_noise_rad``.
    min_noise_rad: float = math.radians(1.5)
    max_noise_rad: float = math.radians(4.0)
    #: Below this speed (the step's, or with none the last measured; none before the first) the
    #: static heatmap's registration may measure the turn, m/s ...
    slow_mps: float = 0.1
    #: ... "check": measured beside the points' and taken instead of it where the two disagree
    #: by more than ``check_sigmas`` of their combined standard deviations, and where the points
    #: give none; "fallback": only where the points give none; "fuse": averaged with the points'
    #: by their variances.  The demo's heatmap has no elevation, so the registration reads a cell
    #: at elevation el at cos(el) of its bearing's sine: near floors, ceilings and walls it measures
    #: turns in place short (docs/tidemo.md, "Odometry from what the chip sends"), but it does not
    #: jump as a turn from 3-5 points does.
    heatmap_use: str = "check"
    #: ... with at least this noise, rad; ...
    heatmap_noise_rad: float = math.radians(1.5)
    #: ... and, fused, when it disagrees with the points' by more than this many of their combined
    #: standard deviations, the points' is taken.
    agreement_sigmas: float = 2.0
    #: With "check", the heatmap's turn is taken where it differs from the points' by more than
    #: this many of their combined standard deviations.
    check_sigmas: float = 1.0
    #: ... unless it has been taken instead of the points' this many steps running (0: always
    #: taken) by differences of one sign within ``check_steady_rad`` of each other: a steady
    #: difference is the map's chain off by a turn the steps before missed (a braking gap whose
    #: turn the points found only once the heatmap measured it), which the points see against the
    #: map and the heatmap, frame to frame, cannot: then the points' turn is taken.
    check_steady_frames: int = 3
    check_steady_rad: float = math.radians(3.0)
    #: With "check", where the two agree within ``check_sigmas`` but the step has fewer static
    #: points than this, the heatmap's turn is taken (0: the points' always): turning in place
    #: facing a near wall, 2-20 points a frame measure the turn short, by a degree a step at
    #: times, within what the check lets pass; where they disagree, as above (docs/heading.md
    #: item 40; measured on the raw path's points, so 0 in TI's demo preset).
    check_min_points: int = 20
    #: Standing in for the points' or checking them ("check", "fallback"; not fused), its turn is
    #: not believed further from the predicted one (the last measured rate's;
    #: ``icp.initial_guess`` "zero" predicts none, and then it is not checked) than this yaw
    #: acceleration allows over the step (times its duration squared) plus three of
    #: ``heatmap_noise_rad``, rad/s^2 (None: always believed): facing a wall, the few cells in
    #: view register to false turns (docs/tidemo.md).
    heatmap_max_accel_radps2: float | None = math.radians(300.0)
    #: Correct the yaw-rate filter's yaw by the map's chain of measured turns over the last
    #: ``lag_frames`` frames, as the keyframes correct the raw path's: the filter lags a turn's
    #: first frames and what it loses there is otherwise lost for good.
    correct_lag: bool = True
    lag_frames: int = 10

    def __post_init__(self) -> None:
        self.check_types()
        check_limits(self, POINT_YAW)
        _check(self.step_rad < self.search_rad, "must be below search_rad", "step_rad")
        step = ("step_rad", self.step_rad)
        coarse = ("coarse_step_rad", self.coarse_step_rad) if self.coarse_step_rad else step
        check_search_size(("search_rad", self.search_rad), coarse)  # the first pass
        if coarse is not step:
            check_search_size(("coarse_step_rad", self.coarse_step_rad), step)  # about its best
        check_search_size(("search_rad", self.search_rad), ("relocate_step_rad", self.relocate_step_rad))
        _check(self.max_noise_rad >= self.min_noise_rad, "must be at least min_noise_rad", "max_noise_rad")
        check_choice(self.heatmap_use, HEATMAP_USES, "heatmap_use")
