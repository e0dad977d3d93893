"""The estimator's settings: one typed configuration that can be dumped and loaded.

``EstimatorConfig()`` is the best combination measured by the experiment
(``bench/paper_experiment.py``; docs/estimator.md has the tables, and its section "Why the
defaults" the measurements behind each default); ``EstimatorConfig.paper()``
is the method as the paper describes it, Top-k preprocessing and sampling + mwICP,
with none of the options that go beyond it.  Units: metres, seconds, radians.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial

from ..dsp.cfar import CfarParams
from ..errors import ConfigError
from ..settings import Settings, check_choice
from ..settings import check_field as _check
from .config_limits import CFAR, FEATURES, ICP, MAX_SMOOTHING_BINS, check_limits, check_search_size  # noqa: F401
from .config_odometry import (  # noqa: F401  (re-exported)
    KEYFRAME_STARTS, MIN_SEARCH_STEP_RAD, VELOCITY_FALLBACKS, OdometryConfig, PointYawConfig)
from .config_velocity import PROJECTIONS, VelocityConfig  # noqa: F401  (re-exported)
from .config_wall_map import WallMapConfig  # noqa: F401  (re-exported)

FEATURE_METHODS = ("topk", "raymax", "cfar")
DOPPLER_ELEVATIONS = ("off", "turns", "always")
INITIAL_GUESSES = ("zero", "constant_rate", "profile", "scan")
REFINEMENTS = ("none", "field")
FIELD_WINDOWS = ("icp", "icp_and_scan")


@dataclass
class FeatureConfig(Settings):
    """Heatmap features (paper III-B) and the options beyond the paper."""

    _what = "feature"

    #: "topk" (the k strongest cells), "raymax" (the strongest cell of each azimuth ray)
    #: or "cfar" (cells that CFAR detects along range and along azimuth).
    method: str = "topk"
    k: int = 200
    #: Region of interest: range and bearing limits of the features, m and rad; with the
    #: ``elevation`` used, features placed nearer than ``min_range_m`` (at r cos(el)) are dropped.
    min_range_m: float = 0.5
    max_range_m: float | None = None
    max_azimuth_rad: float = math.radians(65.0)
    #: CFAR of the "cfar" method, along range and along azimuth.  The azimuth guard spans the
    #: beam's main lobe (64 bins over 8 elements: 8 bins a side), so the training cells see the
    #: sidelobes, which a sidelobe alone does not stand out from.
    cfar: CfarParams = field(default_factory=partial(CfarParams, method="ca", guard=2, train=8, threshold_db=10.0))
    cfar_azimuth: CfarParams = field(default_factory=partial(CfarParams, method="ca", guard=7, train=4,
                                                             threshold_db=6.0))
    #: Weights from the intensity: "linear" power, or "db" (10 log10, less dominated by
    #: a few strong reflectors); normalised to sum to one.
    weighting: str = "linear"
    #: Beyond the paper: keep only cells that are local maxima over their 8 neighbours.
    peaks_only: bool = True
    #: Beyond the paper: sub-bin azimuth (and range) of each feature from a parabola through
    #: the log intensity of its neighbours, instead of the bin centre.
    subbin: bool = True
    #: Beyond the paper: drop cells whose dominant Doppler disagrees with the Doppler a
    #: static reflector would have at the estimated ego-velocity, by more than this, m/s
    #: (None: off); not without a velocity estimated within half a frame period of the frame.
    dynamic_rejection_mps: float | None = 0.15
    #: The DSP gives a dominant Doppler to this many times ``k`` of the heatmap's strongest
    #: cells (the rest get none): the features are chosen among the strongest cells, so a few
    #: times k covers them, local maxima and all, for the dynamic rejection, at a fraction of
    #: the full map's cost.
    doppler_cells_per_feature: int = 4
    #: Beyond the paper: "use" the heatmap's elevation of each cell (when the array has a raised
    #: row), placing a feature at its horizontal range r cos(el) and bearing, at its height;
    #: "ignore" takes every cell as level.  The array measures cos(el) sin(az): a reflector above
    #: or below the radar turns by cos(el) of a turn on the azimuth axis, so level geometry
    #: under-measures turns near tall walls, floors and ceilings (docs/heading.md, item 2).
    elevation: str = "use"
    #: ... and how a translation moves such a feature: "slant" as a reflector level with the radar
    #: at its slant range, keeping its elevation angle (a cell's elevation is noisy and mixes
    #: heights: docs/heading.md item 21), or "horizontal" as a fixed reflector at its height.
    parallax: str = "slant"
    #: Beyond the paper, for arrays without a raised row (2 TX): each cell's elevation from its
    #: dominant Doppler and the frame's own velocity, where the heatmap has none: "off", "turns"
    #: (only while the last measured yaw rate is above ``doppler_elevation_turn_radps``), or
    #: "always".  A static reflector's radial velocity is -(vx cos(el) cos(az) - vy u), u the
    #: azimuth axis, so cos(el)^2 = ((vy u - v_r) / vx)^2 + u^2 (estimator/doppler_elevation.py,
    #: docs/heading.md item 10).
    doppler_elevation: str = "turns"
    #: ... from a speed along the boresight (forward or back) of at least this, m/s; slower every
    #: way (at rest, turning in place), each range bin keeps its elevation from the frames that
    #: moved, ...
    doppler_elevation_min_mps: float = 0.2
    #: ... averaged over about this long of them, s (weights exp(-age / this) times the forward
    #: speed squared; one frame's cells are few, their Doppler a bin's centre; longer reaches back to
    #: where the range bins saw other things: heading.md item 24), ...
    doppler_elevation_memory_s: float = 0.5
    #: ... for at most this long, s; ...
    doppler_elevation_rest_s: float = 5.0
    #: ... and with "turns", a turn rate above this, rad/s.
    doppler_elevation_turn_radps: float = math.radians(10.0)

    @property
    def doppler_cells(self) -> int:
        """How many of the heatmap's strongest cells the DSP gives a dominant Doppler."""
        return self.doppler_cells_per_feature * self.k

    def __post_init__(self) -> None:
        self.check_types()
        check_limits(self, FEATURES)
        for name in ("cfar", "cfar_azimuth"):
            check_limits(vars(getattr(self, name)), CFAR, f"{name}.")
        check_choice(self.method, FEATURE_METHODS, "method")
        check_choice(self.weighting, ("linear", "db"), "weighting")
        check_choice(self.elevation, ("ignore", "use"), "elevation")
        check_choice(self.parallax, ("slant", "horizontal"), "parallax")
        check_choice(self.doppler_elevation, DOPPLER_ELEVATIONS, "doppler_elevation")
        _check(self.max_range_m is None or self.max_range_m > self.min_range_m,
               "must be above min_range_m", "max_range_m")

    def check_heatmap_range(self, range_bins: int) -> None:
        """Raise :class:`ConfigError` when the "cfar" method's range window does not fit a
        heatmap of *range_bins* range cells (a source's, or the DSP's for a cfg: checked before
        a run opens its outputs)."""
        if self.method == "cfar" and range_bins < self.cfar.window:
            raise ConfigError(f"a window of guard {self.cfar.guard} and train {self.cfar.train} spans "
                              f"{self.cfar.window} range cells, more than the heatmap's {range_bins}: choose "
                              "a smaller guard or train", field="features.cfar")


@dataclass
class IcpConfig(Settings):
    """Rotation-only weighted ICP with the paper's sampling (eqs. 4-6)."""

    _what = "ICP"

    #: Correspondence error e = alpha dr^2 + beta dtheta^2: alpha in 1/m^2, beta in 1/rad^2.
    #: The defaults make e the squared distance in units of 0.1 m and 2 degrees.
    alpha: float = 100.0
    beta: float = 1.0 / math.radians(2.0) ** 2
    #: Sampling (eq. 5): e_min > eps_max: remove; e_min < eps_min (or outside the region of
    #: interest): neglect for this iteration; else match.
    eps_min: float = 0.01
    eps_max: float = 25.0
    #: Without sampling every source point is matched to its nearest target ("wICP").
    sampling: bool = True
    #: The paper's reading of eq. 5: aligned points (e_min < eps_min) sit out each step.  It
    #: lets the iteration cycle between rotations; off, they stay in the fit as anchors.
    neglect_aligned: bool = False
    #: Register both ways and average (mwICP); else previous -> current only.
    two_way: bool = True
    #: Weight of a matched pair: "source" (the source point's normalised intensity) or
    #: "product" of the two points' weights.
    weight: str = "source"
    iterations: int = 10
    #: Converged when an iteration changes the rotation by less than this, rad.
    tolerance_rad: float = 1e-4
    #: Fewer matched pairs than this: the registration failed.
    min_matches: int = 5
    #: Beyond the paper, a starting rotation without an IMU: "zero" (the paper); the previous
    #: frame's yaw rate ("constant_rate"); the shift that best correlates the two frames'
    #: azimuth power profiles ("profile"); or the rotation that lays the previous frame's
    #: ``scan_points`` strongest cells, rectified, on the brightest cells of the current
    #: heatmap ("scan").  The last two search around the constant-rate prediction.
    initial_guess: str = "scan"
    #: Search range of the profile and scan guesses around their centre, rad.
    max_rotation_rad: float = math.radians(15.0)
    scan_points: int = 400
    #: Grid step of the scan guess, rad (the best refined by a parabola).  A second, finer
    #: search around the best changed nothing measurable (docs/estimator.md, "Why the defaults"): the guess
    #: only starts ICP and bounds the field search.
    scan_step_rad: float = math.radians(1.0)
    #: With the scan guess: a frame whose best scan score (mean log intensity of the matched
    #: cells over the heatmap's median, natural-log units) stays below this holds no structure
    #: to register (noise, a blocked radar): its yaw is not measured ("no_structure").
    min_scan_score: float = 1.0
    #: ... unless the frames' own structure is weaker (a weak radar, a low SNR: at -15 dB the
    #: simulated lab's frames score 1-2 where they score 3-5 at 0 dB): then the threshold is this
    #: fraction of the median score of the last 50 steps that held structure (once there are
    #: five; yaw_measurement.SCORE_HISTORY_FRAMES), never below this fraction of
    #: ``min_scan_score``; None: always ``min_scan_score``.  A noise-only frame scores about 0.1
    #: at any SNR.
    scan_score_fraction: float | None = 0.3
    #: Whose structure the scan's verdict asks for: "two_way" (the default), each frame's
    #: strongest cells on the other's bright cells at the rotation found (the previous frame's
    #: on the current heatmap, and the current's, taken back, on the previous one); "one_way",
    #: the previous frame's alone, which a noise-only previous frame passes whenever the
    #: current heatmap is bright: its noise cells land on bright cells somewhere in the window
    #: (docs/heading.md, item 7).
    scan_structure: str = "two_way"
    #: Beyond the paper: after ICP, "field" refines the rotation without correspondences:
    #: the rotation (within +/- ``field_search_rad`` of ICP's) that maximises the two-way
    #: likelihood field, the mean log intensity of each frame's ``scan_points`` strongest cells
    #: sampled in the other frame's heatmap smoothed by ``field_smoothing_bins`` (a Gaussian's
    #: sigma in range and azimuth bins).  ICP matches points to points and is pulled around by
    #: wrong pairs along walls; the field uses all the bright cells of both frames.  The keyframe
    #: registration is then the field search alone (where: ``odometry.keyframe_start``).
    #: "none": ICP's.
    #: The default: it lowers the experiment's yaw RMSE and drift at about the same time,
    #: though a straight drive's worst frame grows (docs/estimator.md, "Why the defaults").
    refinement: str = "field"
    field_search_rad: float = math.radians(3.0)
    field_smoothing_bins: float = 2.0
    #: The smoothed field is interpolated every 1/``field_upsampling`` azimuth bin (a cubic spline
    #: through its bins) and sampled bilinearly on that finer grid.  Sampled bilinearly on the
    #: heatmap's own bins, a field of points at bin centres scores rotations that move the points
    #: by whole bins highest (the interpolation is piecewise linear, kinked at the bins), which
    #: draws the rotation to multiples of the bin (docs/heading.md, item 11).
    #: 1: the heatmap's bins (so too with ``field_smoothing_bins`` 0: no field to evaluate).
    field_upsampling: int = 4
    #: Grid step of the field search, rad; the best rotation on the grid is refined by a
    #: parabola through it and its two neighbours.  The field's peak is some degrees wide
    #: (beams of about 15 degrees, smoothed): a parabola through points 1.5 degrees apart fits
    #: that peak.  With ``field_upsampling`` 0.5 degrees measures as well, with three times the
    #: samples; without it, a fine step finds the bilinear sampling's kinks (docs/estimator.md,
    #: "Why the defaults").
    field_step_rad: float = math.radians(1.5)
    #: Where the frame-to-frame field search looks: "icp", +/- ``field_search_rad`` around ICP's
    #: rotation; "icp_and_scan", from the smaller of ICP's rotation and the scan guess to the
    #: larger, widened by ``field_search_rad`` each side.  ICP drawn off by wrong pairs (near
    #: walls, few features) can leave the true rotation outside ICP's window, which the field
    #: then cannot reach (it ends on the window's edge); the scan guess is independent of ICP.
    #: The window grows only when the two disagree.
    field_window: str = "icp_and_scan"
    #: The field's points weighed by how like one reflector's their azimuth peak is, floor + (1 -
    #: floor) exp(-((q - 1) / width)^2), q its curvature over the frame's usual peak's: scatterers
    #: sharing a beam peak where their phases put them (docs/heading.md item 22).  None: off.
    field_shape_width: float | None = 0.3
    field_shape_floor: float = 0.3
    #: The scan guess and the field search leave out cells whose dominant Doppler differs by
    #: more than this (m/s) from what a static reflector shows at the frame's velocity: their
    #: strongest cells skip them and their log heatmaps set them to the background (None: off).
    #: A person walking past fills the strongest cells with a reflector that does not turn
    #: with the world; a static cell's Doppler is off by its bin's width and its elevation.
    #: The frame's velocity is its own (estimated within half a frame period of it): with none,
    #: no cell is left out (a velocity held from before a hard stop calls the world moving).
    reject_moving_mps: float | None = 0.3
    #: With ``reject_moving_mps`` and the scan guess (without either it does nothing), a blob it
    #: flags is followed from frame to frame, and while it crosses the line of sight (its Doppler
    #: then like the static world's) the scan's points around it (which the field search scores
    #: too; ICP's features keep them) are left out: a person walking across the radar's view
    #: turned the heading by its own bearing rate (estimator/movers.py; docs/heading.md, item 16).
    track_movers: bool = True
    #: With the scan guess: while the radar moves and turns (faster than yaw_measurement's
    #: MOVING_TURN_MPS and MOVING_TURN_DPS), the scan's points (which the field search scores too)
    #: nearer than this are left out, m (None: off), unless they hold most of the points' weight: in
    #: a moving turn near walls their cells do not move as the reflectors the registration takes them
    #: for, and turns came out short (docs/heading.md item 18).
    moving_turn_min_range_m: float | None = 1.0
    #: Which points the field search's score (and the keyframe's narrow scan's) averages over:
    #: "inside", those inside the heatmap at each rotation tried; "common", those inside at
    #: every rotation tried.  A mean over the points inside at each rotation rises where a
    #: rotation turns the weak points at the field of view's edge out of the heatmap, and so
    #: favours larger rotations (docs/heading.md, item 1).
    score_support: str = "common"
    #: The same for each step's scan guess.  Over its wide window (+/- max_rotation_rad) the points
    #: inside at every rotation are few, and a scan centred on a wrong prediction followed its
    #: own error from frame to frame (docs/heading.md, item 1): "inside" by default.
    scan_score_support: str = "inside"
    #: With the scan guess and the field refinement: when ICP fails (too few features or
    #: matches) but the scan found structure, measure the yaw by the field search around the
    #: scan guess instead of holding the last yaw rate (the frame keeps its icp_failed /
    #: few_features flag).
    field_fallback: bool = True

    def __post_init__(self) -> None:
        self.check_types()
        check_limits(self, ICP)
        _check(self.eps_min < self.eps_max, "need 0 <= eps_min < eps_max", "eps_min")
        points = ("scan_points", self.scan_points)
        check_search_size(("max_rotation_rad", self.max_rotation_rad), ("scan_step_rad", self.scan_step_rad), points)
        check_search_size(("field_search_rad", self.field_search_rad), ("field_step_rad", self.field_step_rad), points)
        check_choice(self.weight, ("source", "product"), "weight")
        check_choice(self.initial_guess, INITIAL_GUESSES, "initial_guess")
        check_choice(self.refinement, REFINEMENTS, "refinement")
        check_choice(self.field_window, FIELD_WINDOWS, "field_window")
        check_choice(self.score_support, ("inside", "common"), "score_support")
        check_choice(self.scan_score_support, ("inside", "common"), "scan_score_support")
        check_choice(self.scan_structure, ("one_way", "two_way"), "scan_structure")


#: The sections of a settings file, in its order.
SECTIONS = ("velocity", "features", "icp", "odometry", "point_yaw", "wall_map")


@dataclass
class EstimatorConfig(Settings):
    _what = "estimator"

    velocity: VelocityConfig = field(default_factory=VelocityConfig)
    features: FeatureConfig = field(default_factory=FeatureConfig)
    icp: IcpConfig = field(default_factory=IcpConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)
    point_yaw: PointYawConfig = field(default_factory=PointYawConfig)
    wall_map: WallMapConfig = field(default_factory=WallMapConfig)

    def __post_init__(self) -> None:
        self.check_types()
        # The keyframe's scan search: the odometry's window at the ICP section's step.
        check_search_size(("odometry.keyframe_search_rad", self.odometry.keyframe_search_rad),
                          ("icp.scan_step_rad", self.icp.scan_step_rad), ("icp.scan_points", self.icp.scan_points))

    @classmethod
    def paper(cls, *, method: str = "topk", sampling: bool = True, two_way: bool = True) -> "EstimatorConfig":
        """The paper's method (one of its variants), without the options beyond it."""
        return cls(velocity=VelocityConfig(bearing_noise_rad=0.0, level_edge_quantile=None),
                   features=FeatureConfig(method=method, peaks_only=False, subbin=False, dynamic_rejection_mps=None,
                                          elevation="ignore", doppler_elevation="off"),
                   icp=IcpConfig(sampling=sampling, two_way=two_way, initial_guess="zero", neglect_aligned=True,
                                 refinement="none", score_support="inside", reject_moving_mps=None),
                   odometry=OdometryConfig(yaw_rate_filter=False, keyframe_distance_m=0.0,
                                           velocity_fallback="hold", rectification="velocity", bridge_s=0.0,
                                           yaw_walk_per_sqrt_m=0.0, yaw_walk_per_sqrt_rad=0.0),
                   point_yaw=PointYawConfig(blend=0.0), wall_map=WallMapConfig(use=False))

    @classmethod
    def tidemo(cls) -> "EstimatorConfig":
        """The settings for TI's demo firmware's output (``tidemo://`` and its replays): the yaw
        from its few points on a local map and its static heatmap when slow (``point_yaw``), a
        velocity from as few as 3 points, standing still when half of them say so (a person walking
        past a robot turning in place is a larger share of a handful of points), fitted unweighted
        (of 6-12 points on the chip's bins, those across the motion fix the sideways speed), its
        heatmap's cells not weighed by their peak's shape (docs/tidemo.md: the chip's static
        heatmap is not the raw one those weights were measured on), its speed not scaled to the
        level reflectors' edge (its Doppler on the chip's bins: not measured there), no map of
        wall directions (not measured on the chip's few points), its points' map unweighted by its
        density (on the demo's sequences, seed 0, it moved the yaw both ways) and no bound on the yaw-rate
        filter's lag (made the default with the keyframes' payments of the lag, which the points'
        yaw does not make: alone, on the demo's sequences, it raised the yaw RMSE and a lab run's
        drift to 5.0 %, docs/tidemo.md)."""
        return cls().preset("tidemo")

    def preset(self, name: str | None) -> "EstimatorConfig":
        """These settings with the preset *name* of :data:`PRESETS` applied (None: unchanged)."""
        if name is None:
            return self
        if not isinstance(name, str) or name not in PRESETS:
            raise ConfigError(f"unknown estimator preset {name!r} (known: {', '.join(sorted(PRESETS))})")
        return self.with_(**PRESETS[name])

    def with_(self, **sections) -> "EstimatorConfig":
        """A copy with fields of sections replaced: ``cfg.with_(icp={"two_way": False})``."""
        data = {name: getattr(self, name) for name in SECTIONS}
        for name, changes in sections.items():
            if name not in data:
                raise ConfigError(f"unknown estimator section {name!r}")
            if not isinstance(changes, Mapping):
                raise ConfigError(f"the changes to a section are a dict of its settings, got {type(changes).__name__}",
                                  field=name)
            current, section = data[name], data[name].to_dict()
            for key, value in changes.items():
                # A CFAR's changes go over this config's CFAR (its own rules: CfarParams.updated),
                # not over the default CFAR that a settings file's go over.
                here = getattr(current, key, None)
                if not (isinstance(here, CfarParams) and isinstance(value, Mapping)):
                    section[key] = value
                    continue
                try:
                    section[key] = here.updated(value).to_dict()
                except ConfigError as exc:
                    where = f"{name}.{key}"
                    raise exc.located(field=f"{where}.{exc.field}" if exc.field else where, command=None) from None
            data[name] = section
        return EstimatorConfig.from_dict(data)


#: What :meth:`EstimatorConfig.tidemo` changes, by section.
TIDEMO_PRESET = {"velocity": {"min_points": 3, "zero_velocity_ratio": 0.5, "bearing_noise_rad": 0.0,
                              "level_edge_quantile": None},
                 "icp": {"field_shape_width": None},
                 "odometry": {"yaw_filter_max_lag_rad": None},
                 "point_yaw": {"use": True, "density_weighted": False, "check_min_points": 0},
                 "wall_map": {"use": False}}
#: The presets a source may call for by name (``Source.estimator_preset``), each the changes it
#: makes to other settings, by section (:meth:`EstimatorConfig.preset`).
PRESETS = {"tidemo": TIDEMO_PRESET}


def paper_variants() -> dict[str, tuple[str, EstimatorConfig]]:
    """The variants of the paper's two tables, name -> (table, config): "preprocessing"
    (Table III: CFAR, Ray-max, Top-k with sampling + mwICP) and "icp" (Table IV: wICP,
    sampling + wICP, sampling + mwICP with Top-k)."""
    paper = EstimatorConfig.paper()
    return {
        "CFAR": ("preprocessing", EstimatorConfig.paper(method="cfar")),
        "Ray-max": ("preprocessing", EstimatorConfig.paper(method="raymax")),
        "Top-k": ("preprocessing", paper),
        "wICP": ("icp", EstimatorConfig.paper(sampling=False, two_way=False)),
        "Sampling + wICP": ("icp", EstimatorConfig.paper(two_way=False)),
        "Sampling + mwICP": ("icp", paper),
    }
