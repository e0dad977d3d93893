"""The yaw measurement of one step: what a frame keeps for the next (features, the initial
guess's view, the likelihood field), the initial guess, rotation-only ICP and the field
refinement.  The options (``icp.initial_guess``, ``icp.refinement``, ``icp.field_window``,
``icp.field_fallback``) are chosen once, into parts."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np

from .config import EstimatorConfig
from .current_frame import CurrentFrame, features_key, settings_key, velocity_key
from .features import Features, PolarHeatmap, azimuth_profile, static_mask
from .icp import (FEW_MATCHES, NOT_CONVERGED, Region, Registration, correlation_guess, field_rotation,
                  register_two_way, scan_guess, score_back)
from .log_heatmap import LogHeatmap
from .movers import MoverTracks
from .peak_shape import shape_weighted
from .quality import Flag


@dataclass
class LikelihoodField:
    """What the field refinement keeps of a frame: its strongest cells and its smoothed log
    heatmap."""

    points: Features
    smoothed: LogHeatmap


@dataclass
class KeptFrame:
    """What the estimator keeps of a frame, for the next frame and as a keyframe."""

    t: float
    features: Features
    #: The initial guess's view of the frame: its azimuth profile (n,), its strongest cells,
    #: or None (a guess from the yaw rate alone).
    guide: Any
    field: LikelihoodField | None
    #: The frame's log heatmap, for the scan's two-way verdict (None: not asked for).
    log: LogHeatmap | None = None


@dataclass
class YawStep:
    """A step's measured rotation (source -> target, rad; None: not measured), the
    registration that gave it (None: none was tried) and its variance, rad^2."""

    rotation: float | None
    registration: Registration | None
    variance: float


# ---------------------------------------------------------------------- initial guesses
class PredictedGuess:
    """The registration starts from the prediction: zero (the paper) or the last good yaw
    rate times the step ("constant_rate")."""

    def __init__(self, uses_rate: bool) -> None:
        self.uses_rate = uses_rate

    def view(self, frame: CurrentFrame, velocity: np.ndarray | None = None) -> None:
        return None

    def __call__(self, previous: KeptFrame, current: KeptFrame, frame: CurrentFrame, translation: np.ndarray,
                 predicted: float, record: bool = True, widen_rad: float = 0.0) -> float | None:
        return predicted


class ProfileGuess:
    """The shift that best correlates the two frames' azimuth power profiles, around the
    prediction."""

    uses_rate = True

    def __init__(self, config: EstimatorConfig, step_rad: float) -> None:
        self._features = config.features
        self._step_rad = step_rad
        self._max_rad = config.icp.max_rotation_rad
        grid_max = config.features.max_azimuth_rad
        self._grid = np.arange(-grid_max, grid_max + 1e-9, step_rad)

    def view(self, frame: CurrentFrame, velocity: np.ndarray | None = None) -> np.ndarray:
        return azimuth_profile(frame.heatmap, self._features, self._grid)

    def __call__(self, previous: KeptFrame, current: KeptFrame, frame: CurrentFrame, translation: np.ndarray,
                 predicted: float, record: bool = True, widen_rad: float = 0.0) -> float | None:
        guess = correlation_guess(previous.guide, current.guide, self._step_rad, self._max_rad + widen_rad, predicted)
        return predicted if guess is None else guess


#: How many of the last steps that held structure set the usual score (``icp.scan_score_fraction``):
#: 5 s at 10 frames/s.  Only steps that passed count: heatmaps that never hold structure (a covered
#: radome, the zero-Doppler map of a moving radar) must not lower the bar to their own level.
SCORE_HISTORY_FRAMES = 50


class ScanGuess:
    """The rotation that lays the previous frame's strongest cells, rectified, on the brightest
    cells of the current heatmap, around the prediction; None when the best score says the
    heatmaps hold no structure."""

    uses_rate = True

    def __init__(self, config: EstimatorConfig, scan_features) -> None:
        self._scan_features = scan_features
        self._step_rad = config.icp.scan_step_rad
        self._max_rad = config.icp.max_rotation_rad
        self._min_score = config.icp.min_scan_score
        self._fraction = config.icp.scan_score_fraction
        #: The best forward scores of the last steps that held structure (``scan_score_fraction``).
        self._scores: deque[float] = deque(maxlen=SCORE_HISTORY_FRAMES)
        self._common = config.icp.scan_score_support == "common"
        self._scan_key = settings_key(scan_features)

    def view(self, frame: CurrentFrame, velocity: np.ndarray | None = None) -> Features:
        """The frame's strongest cells (moving ones left out, given the *velocity*)."""
        return frame.features(self._scan_features, self._scan_key, velocity)

    def __call__(self, previous: KeptFrame, current: KeptFrame, frame: CurrentFrame, translation: np.ndarray,
                 predicted: float, record: bool = True, widen_rad: float = 0.0) -> float | None:
        """The scan's rotation, None when the step holds no structure; *record*: a step's first
        look, whose score joins the usual scores (a second look at the same step must not);
        *widen_rad*: the search reaches that much further either side of *predicted*."""
        found = scan_guess(previous.guide.shifted(translation), frame.log, self._step_rad, self._max_rad + widen_rad,
                           predicted, self._common)
        threshold = self.min_score
        if found is None or found[1] < threshold:
            return None
        if previous.log is not None and score_back(current.guide, previous.log, found[0], translation) < threshold:
            return None
        if record:
            self._scores.append(found[1])
        return found[0]

    @property
    def min_score(self) -> float:
        """The score below which a step holds no structure (``min_scan_score``, lowered to the
        frames' own structure by ``scan_score_fraction``)."""
        if self._fraction is None or len(self._scores) < 5:
            return self._min_score
        usual = self._fraction * float(np.median(self._scores))
        return min(self._min_score, max(usual, self._fraction * self._min_score))


# ---------------------------------------------------------------------- field refinement
class FieldSearch:
    """The rotation refined without correspondences, on both frames' likelihood fields."""

    def __init__(self, config: EstimatorConfig, scan_features, views_are_scan_points: bool) -> None:
        self._scan_features = scan_features
        self._views_are_scan_points = views_are_scan_points
        self._smoothing_bins = config.icp.field_smoothing_bins
        self._upsampling = config.icp.field_upsampling
        self._search_rad = config.icp.field_search_rad
        self._step_rad = config.icp.field_step_rad
        self._common = config.icp.score_support == "common"
        width = config.icp.field_shape_width
        self._weigh = _as_they_are if width is None else partial(shape_weighted, width=width,
                                                                  floor=config.icp.field_shape_floor)
        self._scan_key = settings_key(scan_features)
        self._weigh_key = (width, config.icp.field_shape_floor)

    def field(self, frame: CurrentFrame, guide: Any) -> LikelihoodField:
        points = guide if self._views_are_scan_points else frame.features(self._scan_features, self._scan_key)
        weighed = frame.made(lambda: ("weighed", self._weigh_key) + features_key(points),
                             lambda: self._weigh(points, frame.heatmap))
        return LikelihoodField(weighed, frame.smoothed(self._smoothing_bins, self._upsampling))

    def refine(self, source: LikelihoodField | None, target: LikelihoodField | None, translation: np.ndarray,
               rotation: float, other: float | None = None, reach: float | None = None) -> float:
        """*rotation* refined within +/- *reach* (by default ``field_search_rad``) or, given
        *other* (another estimate of the same rotation), from the smaller of the two to the
        larger widened by *reach* each side; *rotation* when a frame has no field or the
        search finds no peak."""
        if source is None or target is None:
            return rotation
        centre, reach = rotation, self._search_rad if reach is None else reach
        if other is not None:
            centre, reach = 0.5 * (rotation + other), reach + 0.5 * abs(rotation - other)
        refined = field_rotation(source.points, target.points, source.smoothed, target.smoothed,
                                 translation, centre, reach, self._step_rad, self._common)
        return rotation if refined is None else refined


def _as_they_are(points: Features, heatmap: PolarHeatmap) -> Features:
    """``icp.field_shape_width`` None: the field's points weighed by their intensity alone."""
    return points


class NoFieldSearch:
    """``refinement`` "none": ICP's rotation as it is."""

    def field(self, frame: CurrentFrame, guide: Any) -> None:
        return None

    def refine(self, source, target, translation, rotation: float, other=None, reach=None) -> float:
        return rotation


# ---------------------------------------------------------------------- near points in a moving turn
#: A frame is in a moving turn (``icp.moving_turn_min_range_m``) above this speed, m/s, and turn
#: rate, deg/s: the radar drives through its turn (a robot braking into a turn in place passes
#: through it too, which NEAR_SHARE guards).
MOVING_TURN_MPS = 0.2
MOVING_TURN_DPS = 10.0
#: The near points are kept where they hold more than this share of the points' weight: a radar
#: facing a close obstacle has nothing else to turn by.
NEAR_SHARE = 0.5


def far_in_moving_turn(points: Features, min_range_m: float, velocity: np.ndarray | None, turn_rad: float,
                       dt: float | None) -> Features:
    """*points* without those nearer than *min_range_m* (horizontal range, m) while the radar
    moves (*velocity* (2,) m/s body axes, None: unknown) and turns (*turn_rad* in *dt* s); as they
    are otherwise, or when fewer than three would be left or the near ones hold more than
    NEAR_SHARE of the weight.  In a moving turn near walls, the near cells are mostly the walls',
    which do not move as the fixed reflectors the registration moves them as (docs/heading.md
    item 18)."""
    if velocity is None or dt is None or not dt > 0:
        return points
    speed, rate = math.hypot(velocity[0], velocity[1]), abs(turn_rad) / dt
    # Written so that a NaN or an infinite speed or rate (an outside velocity) changes nothing.
    if not (MOVING_TURN_MPS < speed < math.inf and math.radians(MOVING_TURN_DPS) < rate < math.inf):
        return points
    far = points.range_m >= min_range_m
    if points.weight[far].sum() < (1.0 - NEAR_SHARE) * points.weight.sum():
        return points
    return points.subset(far)


# ---------------------------------------------------------------------- the measurement
class YawMeasurement:
    """Keeps what each frame needs (:meth:`keep`) and measures the rotation between two
    (:meth:`measure`)."""

    def __init__(self, config: EstimatorConfig, profile_step_rad: float) -> None:
        icp = config.icp
        self._config = config
        self._features_key = settings_key(config.features)
        scan_features = replace(config.features, method="topk", k=icp.scan_points, weighting="db",
                                peaks_only=False, subbin=False)
        scan = icp.initial_guess == "scan"
        if scan:
            self.guess: PredictedGuess | ProfileGuess | ScanGuess = ScanGuess(config, scan_features)
        elif icp.initial_guess == "profile":
            self.guess = ProfileGuess(config, profile_step_rad)
        else:
            self.guess = PredictedGuess(uses_rate=icp.initial_guess == "constant_rate")
        #: Whether the guess searches the heatmap itself (and so may find no structure).
        self.scans = scan
        # The scan's two-way verdict samples the previous frame's log heatmap: kept only for it.
        self._keeps_log = scan and icp.scan_structure == "two_way"
        self.field: FieldSearch | NoFieldSearch = (FieldSearch(config, scan_features, scan)
                                                   if icp.refinement == "field" else NoFieldSearch())
        self._window_spans_scan = scan and icp.field_window == "icp_and_scan"
        self._field_fallback = scan and icp.field_fallback
        self._min_features = config.odometry.min_features
        self._unknown_variance = config.odometry.unmeasured_yaw_std_rad ** 2
        self._held_check = config.odometry.held_velocity_yaw_check or 0.0
        self._moving_mps = icp.reject_moving_mps
        # Movers are followed to leave them out of the scan's points (which the field scores too).
        self._movers = MoverTracks() if scan and icp.track_movers and icp.reject_moving_mps is not None else None
        self._moving_turn_min_range_m = icp.moving_turn_min_range_m if scan else None

    def keep(self, frame: CurrentFrame, velocity: np.ndarray | None, *, turn_rad: float = 0.0,
             dt: float | None = None) -> KeptFrame:
        """What the next frame needs of *frame*: its features (moving reflectors rejected by
        *velocity*, (2,) m/s body axes, when known), the guess's view and the field.  *turn_rad*
        (counter-clockwise) and *dt* (s; None: none before) are the radar's predicted turn and
        the time since the previous frame, for the movers followed across the view
        (``icp.track_movers``) and the near points left out in a moving turn
        (``icp.moving_turn_min_range_m``)."""
        features = frame.features(self._config.features, self._features_key, velocity)
        scan_velocity = None
        if self._moving_mps is not None and velocity is not None:
            frame.set_moving(lambda: ~static_mask(frame.heatmap, velocity, self._moving_mps),
                             (self._moving_mps, velocity_key(velocity)))
            scan_velocity = velocity
        if self._movers is not None:
            self._movers.update(frame.heatmap, frame.moving, scan_velocity, turn_rad, dt)
        guide = self.guess.view(frame, scan_velocity)
        if self._moving_turn_min_range_m is not None:
            guide = far_in_moving_turn(guide, self._moving_turn_min_range_m, velocity, turn_rad, dt)
        if self._movers is not None:
            guide = self._movers.leave_out(guide)
        return KeptFrame(frame.t, features, guide, self.field.field(frame, guide),
                         frame.log if self._keeps_log else None)

    def measure(self, previous: KeptFrame, current: KeptFrame, frame: CurrentFrame, translation: np.ndarray,
                predicted: float, flags: list[Flag], *, translation_held: bool = False,
                widen_rad: float = 0.0) -> YawStep:
        """The rotation from *previous* (moved by *translation*, (2,) m) to *current*, starting
        from *predicted* (rad), flagged in *flags* when it fails.  *translation_held*: the
        translation comes from a held velocity, not a measured one; with
        ``held_velocity_yaw_check`` the rotation measured without it widens the variance.
        *widen_rad*: how much further either side of *predicted* the step's guess searches
        (the prediction's own doubt, e.g. after a gap in the frames)."""
        step = self._measure(previous, current, frame, translation, predicted, flags, widen_rad=widen_rad)
        if translation_held and self._held_check and step.rotation is not None:
            # A second look at the same step: its flags and its scan score are not the step's.
            unmoved = self._measure(previous, current, frame, np.zeros(2), predicted, [], record=False,
                                    widen_rad=widen_rad)
            if unmoved.rotation is not None:  # else the variance stays as measured
                step.variance += (self._held_check * (unmoved.rotation - step.rotation)) ** 2
        return step

    def _measure(self, previous: KeptFrame, current: KeptFrame, frame: CurrentFrame, translation: np.ndarray,
                 predicted: float, flags: list[Flag], record: bool = True, widen_rad: float = 0.0) -> YawStep:
        initial = self.guess(previous, current, frame, translation, predicted, record, widen_rad)
        step = self._register(previous.features, current.features, frame.region, translation, initial, flags)
        scan = initial if self.scans else None
        if step.rotation is not None:
            span = scan if self._window_spans_scan else None
            step.rotation = self.field.refine(previous.field, current.field, translation, step.rotation, span)
        elif self._field_fallback and scan is not None and previous.field is not None and current.field is not None:
            step.rotation = self.field.refine(previous.field, current.field, translation, scan)
        return step

    def _register(self, previous: Features, current: Features, region: Region, translation: np.ndarray,
                  initial: float | None, flags: list[Flag]) -> YawStep:
        if len(current) < self._min_features or len(previous) < self._min_features:
            flags.append(Flag.FEW_FEATURES)
            return YawStep(None, None, 0.0)
        if initial is None:
            flags.append(Flag.NO_STRUCTURE)
            return YawStep(None, None, 0.0)
        registration, _ = register_two_way(previous.shifted(translation), current, self._config.icp,
                                           initial_rad=initial, region=region)
        if registration.status == FEW_MATCHES:
            flags.append(Flag.ICP_FAILED)
            return YawStep(None, registration, 0.0)
        if registration.status == NOT_CONVERGED:
            flags.append(Flag.ICP_NOT_CONVERGED)  # its rotation is still the best there is
        variance = registration.variance if math.isfinite(registration.variance) else self._unknown_variance
        return YawStep(registration.rotation_rad, registration, variance)
