"""The yaw from a radar's own detected points, registered to a local map of the last frames'
points, and from its zero-Doppler (static) heatmap where that holds the scene (``point_yaw.use``).

TI's demo firmware (``tidemo://``, docs/tidemo.md) sends a handful of points a frame and the
heatmap of the zero-Doppler bin only.  Driving at 0.5-1 m/s puts the static world 7-15 Doppler bins
from zero, so that heatmap holds little of it but window leakage: registered frame to frame it says
nothing of a moving turn.  The points carry the static world at every speed, too few a frame to
register frame to frame, but enough against the points of the last seconds:

- the map: the static points (Doppler consistent with the sensor's velocity) of the last
  ``map_frames`` frames (8 s at 10 frames/s: a long map anchors a frame's few points to what the
  frames before saw, and its errors do not add up from frame to frame as a short one's do), each
  placed in the world by the pose of its frame along the map's own chain of poses: each step's
  displacement as the odometry integrated it, turned by the yaw this part measured (so that the
  lag of the yaw-rate filter in a turn's first frames does not turn the map with it; where nothing
  was measured, the odometry's);
- each map point is a Gaussian whose spread is its measurement's: ``range_noise_m`` along its ray,
  ``bearing_noise_rad`` times its range across (the chip measures one azimuth a point with a small
  array), at least ``position_floor_m``;
- a step's turn: the frame's static points moved by the step's translation (the velocity's) and
  turned by each turn on a grid of ``step_rad`` within ``search_rad`` of the predicted turn (every
  ``coarse_step_rad`` first, then every ``step_rad`` about the best of those)
  (wider by ``gap_widen_rad`` for each of the steps just before whose turn went unmeasured, at
  most ``gap_widen_frames`` of them, the prior likewise: braking into a turn in place, the held
  rate misses what the map can still measure),
  scored by the log-likelihood of the points under the map (each point the log of its Gaussians'
  sum, at least that of ``outlier_sigmas``: a point the map has not seen costs the same at every
  turn); the best score plus a Gaussian prior of ``prior_rad`` about the prediction (which picks
  among peaks, not their place) is refined by a parabola, and its variance is the inverse
  curvature, between ``min_noise_rad`` and ``max_noise_rad`` squared;
- below ``slow_mps`` the static heatmap holds the scene (standing, turning in place, creeping;
  where the step has no velocity at all, the last one measured says, and before the first none
  does: a radar starting off with too few points for a velocity has a smeared zero-Doppler map):
  there the heatmap registration (:class:`~.yaw_measurement.YawMeasurement`, the raw path's)
  measures the turn too (a variance of at least ``heatmap_noise_rad`` squared); ``heatmap_use``
  says how the two are combined ("check", the default, takes the heatmap's where the points give
  none, where they disagree by more than ``check_sigmas`` (unless steadily), and where they
  agree but the points are fewer than ``check_min_points``: the settings' docstrings,
  :class:`~.config_odometry.PointYawConfig`, say why).  The demo's heatmap has no
  elevation, and facing a wall its few cells register to false turns: its turn is not believed
  further from the predicted one than ``heatmap_max_accel_radps2`` allows over the step.

After ``relocate_gap_frames`` unmeasured steps (a braking gap: 0-2 points a frame, the rate held)
and slow again, the static heatmap's ``relocate_cells`` strongest cells are registered on the map
like points, in a search widened further (``relocate_widen_rad``): the whole scene finds the turn
the gap missed where a frame's few points cannot.  That turn goes to the map's chain only; the
yaw-rate filter takes the step's own (the heatmap's, or the predicted one).

The measured turn goes on to the yaw-rate filter like a registration's.  This part takes the
keyframe correction's place (the map is its own) and its role (``correct_lag``, in
:mod:`.point_map`): the filter lags a turn's first frames, and the yaw it loses there is corrected
by the map's chain, whose turns are the measured ones, over the last frames: a Kalman update of
the filtered yaw relative to the chain's pose ``lag_frames`` back (kept over unmeasured steps, so
that what the chain finds after a gap reaches the yaw, ``gap_correction_max_rad`` a step), by the
chain's own yaw since then, whose variance is the sum of its measured turns' (their errors add up
along the chain).  Used by :class:`~.odometry.RadarOdometry` when ``point_yaw.use`` is set
(``EstimatorConfig.tidemo()``).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from .config import EstimatorConfig
from .current_frame import CurrentFrame
from .doppler_elevation import DopplerElevation
from .point_map import LocalMap
from .point_search import PairScore, climb, pairs_within_reach, search_grid
from .quality import Flag
from .velocity import OK, ZERO, VelocityEstimate
from .yaw_measurement import KeptFrame, YawMeasurement, YawStep

def static_points(points: np.ndarray, velocity: np.ndarray, threshold_mps: float,
                  cos_elevation: np.ndarray | None = None) -> np.ndarray:
    """The horizontal body-frame positions (m, 2) of the *points* (TI frame, products.POINT_DTYPE)
    whose radial velocity is within *threshold_mps* of a static reflector's at the sensor's
    body-frame *velocity* (2,) m/s: v_r = -(vx cos b + vy sin b) cos(el).  *cos_elevation* (n,):
    level points' elevation from elsewhere (their x is the slant range times the azimuth axis
    cos(el) sin(az), so only the forward coordinate moves)."""
    if len(points) == 0:
        return np.zeros((0, 2))
    x, y = points["x"].astype(float), points["y"].astype(float)
    bearing = np.arctan2(-x, y)
    expected = -(velocity[0] * np.cos(bearing) + velocity[1] * np.sin(bearing)) * np.cos(points["elevation"])
    static = np.abs(points["velocity"] - expected) <= threshold_mps
    if cos_elevation is not None:
        y = np.sqrt(np.maximum(cos_elevation ** 2 * (x * x + y * y) - x * x, 0.0))
    return np.stack([y[static], -x[static]], 1)


class PointYaw:
    """The yaw measurement of ``point_yaw.use``: :meth:`keep` and :meth:`measure` as
    :class:`~.yaw_measurement.YawMeasurement` (whose heatmap registration it runs when slow),
    :meth:`add_points` for each point cloud, and :attr:`map` in the keyframe correction's place."""

    def __init__(self, config: EstimatorConfig, heatmap: YawMeasurement,
                 elevation: DopplerElevation | None = None) -> None:
        self._config = config.point_yaw
        self._heatmap = heatmap
        #: The heatmap's elevation from its Doppler (features.doppler_elevation), which gives a
        #: cloud without elevation its points' too (the same frame's: it runs on the heatmap first).
        self._elevation = elevation
        #: The initial guess's part (the odometry predicts the turn from the yaw rate when it uses it).
        self.guess = heatmap.guess
        self.map = LocalMap(config.point_yaw)
        self._points: tuple[float, np.ndarray, np.ndarray | None] | None = None
        #: The speed of the last point cloud whose velocity was measured, m/s (None: none yet).
        self._last_speed: float | None = None
        cfg = self._config
        self._offsets = search_grid(cfg.search_rad, cfg.step_rad)
        #: How many steps in a row, up to the last, went unmeasured (``gap_widen_frames``).
        self._gap = 0
        #: The points' turn less the heatmap's (rad) in the steps running whose turn the heatmap's
        #: check took from the heatmap (``check_steady_frames``).
        self._overrides: deque[float] = deque(maxlen=max(cfg.check_steady_frames, 1))
        #: A point's likelihood under the map at the least: that of ``outlier_sigmas``.
        self._floor = math.exp(-0.5 * cfg.outlier_sigmas ** 2)
        self._fuse = cfg.heatmap_use == "fuse"
        #: Whether the heatmap is measured beside the points' turn (not only in its absence).
        self._beside = cfg.heatmap_use in ("check", "fuse")

    def add_points(self, t: float, points: np.ndarray, estimate: VelocityEstimate) -> None:
        """The point cloud taken at *t* and the velocity estimated from it."""
        velocity = estimate.velocity if estimate.status == OK else np.zeros(2) if estimate.status == ZERO else None
        self._points = (t, points, velocity)
        if velocity is not None:
            self._last_speed = float(np.hypot(*velocity))
        if self.map.pose is None and velocity is not None:  # the first frame's, for the map
            self.map.pending = (t, static_points(points, velocity, self._config.static_threshold_mps))

    def keep(self, frame: CurrentFrame, velocity: np.ndarray | None, *, turn_rad: float = 0.0,
             dt: float | None = None) -> KeptFrame:
        return self._heatmap.keep(frame, velocity, turn_rad=turn_rad, dt=dt)

    def measure(self, previous: KeptFrame, current: KeptFrame, frame: CurrentFrame, translation: np.ndarray,
                predicted: float, flags: list[Flag], *, translation_held: bool = False,
                widen_rad: float = 0.0) -> YawStep:
        """The rotation from *previous* to *current* (source -> target: minus the sensor's turn)
        from the points on the map and, when slow, the heatmap; see the module docstring.
        *translation_held*, *widen_rad*: as :meth:`YawMeasurement.measure`, for the heatmap's part."""
        cfg = self._config
        dt = current.t - previous.t
        velocity = translation / dt
        xy = np.zeros((0, 2))
        if self._points is not None and self._points[0] == current.t:
            own, cloud = self._points[2], self._points[1]
            cos_el = None if self._elevation is None else self._elevation.points_cos_elevation(cloud)
            xy = static_points(cloud, own if own is not None else velocity, cfg.static_threshold_mps, cos_el)
        self.map.pending = (current.t, xy)
        slow = self._slow(velocity, flags)
        # At rest every frame sees the same: no lopsided density to take out (docs/heading.md item 38).
        points = self._points_turn(xy, translation, -predicted, weighted=not slow)
        relocated = self._relocate(current, translation, -predicted) if slow else None
        heatmap = None
        if slow and (self._beside or points is None or relocated is not None):
            step = self._heatmap.measure(previous, current, frame, translation, predicted, [],
                                         translation_held=translation_held, widen_rad=widen_rad)
            if step.rotation is not None and ((self._fuse and points is not None)
                                              or self._plausible(-step.rotation, -predicted, dt)):
                heatmap = (-step.rotation, max(step.variance, cfg.heatmap_noise_rad ** 2))
        if relocated is not None:
            # The map's chain takes the turn the gap missed; the yaw rate the step's own.
            self._gap = 0
            self._overrides.clear()
            self.map.turn, self.map.turn_variance = relocated
            return YawStep(-heatmap[0], None, heatmap[1]) if heatmap else YawStep(predicted, None, relocated[1])
        found = self._choose(heatmap, points, len(xy))  # (turn rad, variance rad^2)
        if not found:
            flags.append(Flag.FEW_FEATURES if len(xy) < cfg.min_points else Flag.NO_STRUCTURE)
            self._gap += 1
            return YawStep(None, None, 0.0)
        if points is not None:  # only the map registers what the gap missed
            self._gap = 0
        weights = np.array([1.0 / var for _, var in found])
        turn = float(weights @ np.array([t for t, _ in found]) / weights.sum())
        self.map.turn, self.map.turn_variance = turn, float(1.0 / weights.sum())
        return YawStep(-turn, None, self.map.turn_variance)

    def _choose(self, heatmap: tuple[float, float] | None, points: tuple[float, float] | None,
                count: int) -> list[tuple[float, float]]:
        """The measurements (turn rad, variance rad^2) the step's turn is averaged from, by
        ``heatmap_use``: where both measured, "check" keeps the points' (*count* static points)
        unless the heatmap's differs by more than ``check_sigmas`` of their combined spread, or
        agrees but the points are fewer than ``check_min_points``; "fuse" both unless they differ
        by more than ``agreement_sigmas`` (then the points'); "check" takes the points' after
        ``check_steady_frames`` steps running of the heatmap's taken by a steady difference."""
        if heatmap is None or points is None:
            self._overrides.clear()
            return [m for m in (heatmap, points) if m is not None]
        cfg = self._config
        difference = abs(heatmap[0] - points[0]) / math.sqrt(heatmap[1] + points[1])
        if self._fuse:
            return [heatmap, points] if difference <= cfg.agreement_sigmas else [points]
        if difference <= cfg.check_sigmas:
            # A few points' turn within the check errs by what its spread lets pass (short, a
            # degree a step at times, facing a near wall); one off by more is the map's chain's
            # making up a turn it missed, as below, which the heatmap, frame to frame, cannot see.
            self._overrides.clear()
            return [points] if count >= cfg.check_min_points else [heatmap]
        run = self._overrides
        run.append(points[0] - heatmap[0])
        if (len(run) == cfg.check_steady_frames and (min(run) > 0 or max(run) < 0)
                and max(run) - min(run) <= cfg.check_steady_rad):
            run.clear()
            return [points]
        return [heatmap]

    def _slow(self, velocity: np.ndarray, flags: list[Flag]) -> bool:
        """Whether the step is slow enough for the static heatmap: its *velocity* (2,) m/s below
        ``slow_mps``; where the step has no velocity at all (none measured near it, none held:
        a zero that is no evidence: the velocity track flags it ``motion_lost``), the last one
        measured, and never before the first (a radar starting off from a stop has a smeared
        zero-Doppler map)."""
        speed = self._last_speed if Flag.MOTION_LOST in flags else float(np.hypot(*velocity))
        return speed is not None and speed < self._config.slow_mps

    def _plausible(self, turn: float, predicted_turn: float, dt: float) -> bool:
        """Whether the static heatmap's *turn* (rad), standing in for the points', lies within
        ``heatmap_max_accel_radps2`` over *dt* (s) and three of its noise of the *predicted_turn*
        (always, when nothing is predicted: ``icp.initial_guess`` "zero")."""
        cfg = self._config
        if cfg.heatmap_max_accel_radps2 is None or not self.guess.uses_rate:
            return True
        return abs(turn - predicted_turn) <= cfg.heatmap_max_accel_radps2 * dt * dt + 3.0 * cfg.heatmap_noise_rad

    @property
    def _gap_widen_rad(self) -> float:
        """How much wider the points' search and prior are after the unmeasured steps just before,
        rad: what the held rate may have missed (``gap_widen_rad`` each, ``gap_widen_frames`` at most)."""
        return min(self._gap, self._config.gap_widen_frames) * self._config.gap_widen_rad

    def _points_turn(self, xy: np.ndarray, translation: np.ndarray, predicted_turn: float,
                     weighted: bool = False) -> tuple[float, float] | None:
        """The static points' turn and variance (:meth:`_register`); where the search found no peak,
        with ``look_beyond`` a second search as far again beyond it, whose peak counts only outside
        the first (a rate held from a false turn puts the true one past the edge), unless the
        search is already wider by what steps the points did not measure may have missed: a look
        beyond that took a braking gap's few points to false turns (docs/heading.md item 32)."""
        found = self._register(xy, translation, predicted_turn, weighted=weighted)
        cfg = self._config
        if found is not None or not cfg.look_beyond or self._gap_widen_rad > 0:
            return found
        beyond = self._register(xy, translation, predicted_turn, cfg.search_rad, cfg.prior_rad, weighted=weighted)
        if beyond is None or abs(beyond[0] - predicted_turn) <= cfg.search_rad - cfg.step_rad:
            return None
        return beyond

    def _relocate(self, current: KeptFrame, translation: np.ndarray,
                  predicted_turn: float) -> tuple[float, float] | None:
        """After ``relocate_gap_frames`` unmeasured steps, the turn (rad) and variance that lay the
        static heatmap's ``relocate_cells`` strongest cells of *current* best on the map, searched
        wider than the points (see :meth:`_register`); None otherwise, or without a peak."""
        cfg = self._config
        if cfg.relocate_cells == 0 or self._gap < cfg.relocate_gap_frames or not len(current.features):
            return None
        features = current.features
        strongest = np.argsort(features.intensity)[::-1][:cfg.relocate_cells]
        widen = self._gap_widen_rad + self._gap * cfg.relocate_widen_rad
        return self._register(features.xy[strongest], translation, predicted_turn, widen, cfg.relocate_prior_rad,
                              cfg.relocate_step_rad)

    def _register(self, xy: np.ndarray, translation: np.ndarray, predicted_turn: float, widen: float | None = None,
                  prior_rad: float | None = None, step_rad: float | None = None,
                  weighted: bool = False) -> tuple[float, float] | None:
        """The turn (rad, counter-clockwise) that lays the static points *xy* (n, 2), moved by
        *translation* (2,) m in the previous frame's axes, best on the map, and its variance; None
        with too few points or map points, or no peak inside the search (widened by *widen* rad, by
        default after unmeasured steps; a prior of *prior_rad*, by default the widened one's; turns
        every *step_rad*, by default ``step_rad``; *weighted*: the map's weights, when
        ``density_weighted`` makes them)."""
        cfg = self._config
        if self.map.pose is None or len(xy) < cfg.min_points:
            return None
        centres, inverse, sigma = self.map.arrays()
        if len(centres) < cfg.min_map_points:
            return None
        x0, y0, yaw0 = self.map.pose
        c0, s0 = math.cos(yaw0), math.sin(yaw0)
        origin = np.array([x0 + c0 * translation[0] - s0 * translation[1],
                           y0 + s0 * translation[0] + c0 * translation[1]])
        if widen is None:
            widen = self._gap_widen_rad
        step = cfg.step_rad if step_rad is None else step_rad
        offsets = self._offsets if widen == 0 and step_rad is None else search_grid(cfg.search_rad + widen, step)
        if prior_rad is None:
            prior_rad = math.hypot(cfg.prior_rad, widen)
        point, near = pairs_within_reach(xy, origin, yaw0 + predicted_turn, centres, sigma, cfg.search_rad + widen)
        turns = predicted_turn + offsets
        pairs = PairScore(xy, origin, centres, inverse, point, near, self._floor,
                          self.map.log_weights() if weighted else None)
        score, best = climb(lambda i: pairs.at(yaw0 + turns[i]), -0.5 * (offsets / prior_rad) ** 2,
                            max(1, round(cfg.coarse_step_rad / step)) if cfg.coarse_step_rad else 1)
        if best == 0 or best == len(score) - 1:
            return None
        left, mid, right = score[best - 1:best + 2]
        curvature = left - 2.0 * mid + right
        if curvature >= 0:
            return None
        offset = min(max(0.5 * (left - right) / curvature, -0.5), 0.5)
        variance = -step ** 2 / curvature
        variance = min(max(variance, cfg.min_noise_rad ** 2), cfg.max_noise_rad ** 2)
        return float(turns[best] + offset * step), variance

def point_yaw_part(config: EstimatorConfig, heatmap: YawMeasurement,
                   elevation: DopplerElevation | None = None) -> PointYaw | None:
    """The part for ``point_yaw.use`` (None when off: the heatmap registration alone)."""
    return PointYaw(config, heatmap, elevation) if config.point_yaw.use else None
