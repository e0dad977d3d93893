"""The range of every numeric estimator setting, one table per section, checked in one place
(:func:`check_limits`): each number a settings file gives has a lower and an upper bound in the
field's own units, generous (far outside anything useful: a noise of a radian, a speed of
100 m/s, a yaw acceleration of 1000 rad/s^2, counts of a million), so that a typo or a hostile
value is refused naming the field and its range ("odometry.yaw_noise_rad: must be in [1e-6, 1]
rad, got 1e+308") instead of overflowing in the estimator frames later.  Conditions between
fields (``max_range_m`` above ``min_range_m``) stay with their sections.  Units: metres,
seconds, radians."""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping
from typing import Any

from ..errors import ConfigError, quoted
from ..plain_numbers import beyond_text, is_number

#: The finest grid step a rotation search takes, rad (0.006 degrees): with searches of at most
#: half a turn, a grid of at most some 63 000 rotations (a finer step is a typo, and its grid
#: would not fit in memory).
MIN_SEARCH_STEP_RAD = 1e-4
#: The most (rotation, point) scores one rotation search holds at once: its grid's rotations
#: times the points it turns (the defaults: some 12 000; the limit keeps a search's arrays within
#: a few hundred MB, where a fine step over a wide window with many points ran out of memory).
MAX_SEARCH_SCORES = 2e7
#: The most rotations one pass of the points' search scores at once, each against every
#: (point, map point) pair (a few thousand): the defaults some 30.
MAX_POINT_SEARCH_ROTATIONS = 2000


def search_reach(span_rad: float, step_rad: float) -> int:
    """The steps each side of a search over +/- *span_rad* every *step_rad* (at least one): the
    grid the searches use (icp.py) and the size the checks here refuse."""
    return max(1, math.ceil(span_rad / step_rad))


def search_rotations(span_rad: float, step_rad: float) -> int:
    """The rotations of a search over +/- *span_rad* every *step_rad*."""
    return 2 * search_reach(span_rad, step_rad) + 1


def check_search_size(span: tuple[str, float], step: tuple[str, float], points: tuple[str, int] | None = None) -> None:
    """Refuse a rotation search too large to hold: over +/- *span* every *step* (each a field's
    name and value, rad), times *points* (its name and count; else the points' search's own
    limit on the rotations alone).  The message names the fields and what to change."""
    rotations = search_rotations(span[1], step[1])
    if points is None:
        if rotations > MAX_POINT_SEARCH_ROTATIONS:
            raise ConfigError(f"+/- {span[0]} {span[1]:g} every {step[1]:g} is {rotations} rotations, each "
                              f"scored against every point pair at once: at most {MAX_POINT_SEARCH_ROTATIONS}; "
                              f"a coarser {step[0]} or a narrower {span[0]}", field=step[0])
        return
    scores = rotations * points[1]
    if scores > MAX_SEARCH_SCORES:
        raise ConfigError(f"+/- {span[0]} {span[1]:g} every {step[1]:g} is {rotations} rotations of "
                          f"{points[1]} points ({points[0]}): {scores:.3g} scores at once, at most "
                          f"{MAX_SEARCH_SCORES:g}; a coarser {step[0]}, a narrower {span[0]} "
                          f"or fewer {points[0]}", field=step[0])


#: The widest smoothing of the likelihood field, bins (a sigma beyond it spreads a cell over
#: more of the heatmap than its 64 azimuth bins hold).
MAX_SMOOTHING_BINS = 64.0

_NAMED = {"pi": math.pi, "pi/2": math.pi / 2, "2pi": 2 * math.pi, "-2pi": -2 * math.pi}
_RANGE = re.compile(r"([\[(])([^,\s]+), ([^\])\s]+)([\])])")


class Limit:
    """A range as its message writes it: ``"(0, 1] rad"``, ``"[1, 1e6]"`` (ends: numbers, pi,
    pi/2, 2pi, -2pi; a bracket includes its end, a parenthesis excludes it), then the unit and
    any note."""

    __slots__ = ("low", "high", "low_open", "high_open", "text")

    def __init__(self, text: str) -> None:
        m = _RANGE.match(text)
        if m is None:
            raise ValueError(f"not a range: {text!r}")
        self.low, self.high = (_NAMED[end] if end in _NAMED else float(end) for end in m.group(2, 3))
        self.low_open, self.high_open = m.group(1) == "(", m.group(4) == ")"
        self.text = text

    def admits(self, value: float) -> bool:
        above = value > self.low if self.low_open else value >= self.low
        return above and (value < self.high if self.high_open else value <= self.high)


@functools.cache
def limit(text: str) -> Limit:
    """The range *text* spells (a table's entry), parsed once, when a section is first checked."""
    return Limit(text)


COUNT = "[1, 1e6]"
SPEED = "(0, 100] m/s"
RATE = "(0, 100] rad/s"
#: Noises and standard deviations are squared into variances and divided by: a millionth is the
#: least (below 1e-162 a square is 0).
NOISE = "[1e-6, 1] rad"
RATE_NOISE = "[1e-6, 100] rad/s"
ANGLE = "(0, pi] rad"
WIDENING = "[0, pi] rad"
STEP = f"[{MIN_SEARCH_STEP_RAD:g}, pi] rad"
#: A prior about a predicted turn narrower than the finest search step weighs nothing but the
#: prediction (and squares of turns over it overflow).
PRIOR = STEP
SIGMAS = "(0, 100] standard deviations"

VELOCITY = {
    "min_points": "[2, 1e6]", "ransac_iterations": "[1, 1e4]", "inlier_threshold_mps": SPEED,
    "min_inlier_ratio": "(0, 1]", "zero_velocity_threshold_mps": "[0, 100] m/s", "zero_velocity_ratio": "(0, 1]",
    "max_elevation_rad": "(0, pi/2] rad", "max_condition": "(1, 1e12]",
    "max_accel_mps2": "(0, 1000] m/s^2 (or null: any)", "bearing_noise_rad": "[0, pi/2) rad",
    "doppler_noise_mps": "[1e-6, 100] m/s", "level_edge_quantile": "(0, 1) (or null: off)",
    "level_edge_window_s": "(0, 60] s", "level_edge_min_mps": SPEED, "seed": f"[0, {2 ** 64 - 1}]",
}

FEATURES = {
    "k": COUNT, "min_range_m": "[0, 1000] m", "max_range_m": "(0, 1000] m (or null: no limit)",
    "max_azimuth_rad": "(0, pi/2] rad", "dynamic_rejection_mps": "(0, 100] m/s (or null: off)",
    "doppler_cells_per_feature": "[1, 1000]", "doppler_elevation_min_mps": SPEED,
    "doppler_elevation_memory_s": "(0, 3600] s", "doppler_elevation_rest_s": "[0, 3600] s (0: not at rest)",
    "doppler_elevation_turn_radps": "[0, 100] rad/s",
}

#: The numbers of a CFAR section (``features.cfar``, ``features.cfar_azimuth``) the CFAR's own
#: checks leave unbounded (``CfarParams`` bounds threshold_db to [0, 200] dB, pfa and os_rank).
CFAR = {
    "guard": "[0, 10000] cells", "train": "[1, 10000] cells", "channels": COUNT,
}

ICP = {
    "alpha": "(0, 1e8] 1/m^2", "beta": "(0, 1e8] 1/rad^2", "eps_min": "[0, 1e8)", "eps_max": "(0, 1e8]",
    "iterations": "[1, 1000]", "tolerance_rad": ANGLE, "min_matches": COUNT, "max_rotation_rad": ANGLE,
    "scan_points": "[10, 1e5]", "scan_step_rad": STEP, "min_scan_score": "[-100, 100] (natural log units)",
    "scan_score_fraction": "(0, 1] (or null: off)", "field_search_rad": ANGLE,
    "field_smoothing_bins": f"[0, {MAX_SMOOTHING_BINS:g}] bins (0: not smoothed)", "field_upsampling": "[1, 16]",
    "field_step_rad": STEP, "field_shape_width": "[1e-3, 1000] (or null: off)", "field_shape_floor": "[0, 1]",
    "reject_moving_mps": "(0, 100] m/s (or null: off)", "moving_turn_min_range_m": "(0, 1000] m (or null: off)",
}

ODOMETRY = {
    "hold_s": "[0, 3600] s", "fallback_cells": "[2, 1e6]", "min_features": "[2, 1e6]", "yaw_noise_rad": NOISE,
    "yaw_accel_std_radps2": "(0, 1000] rad/s^2", "yaw_filter_max_lag_rad": "[0, 1] rad (or null: no bound)",
    "yaw_manoeuvre_accel_std_radps2": "(0, 1000] rad/s^2 (or null: one model)",
    "keyframe_distance_m": "[0, 1000] m (0: off)", "keyframe_angle_rad": "(0, 2pi] rad",
    "keyframe_search_rad": ANGLE, "keyframe_noise_rad": "[1e-6, 1] rad (or null: yaw_noise_rad)",
    "keyframe_turn_renew_radps": "(0, 100] rad/s (or null: off)", "yaw_walk_per_sqrt_m": "[0, 1] rad/sqrt(m)",
    "yaw_walk_per_sqrt_rad": "[0, 1] rad/sqrt(rad)", "mount_x_m": "[-100, 100] m",
    "mount_y_m": "[-100, 100] m", "mount_yaw_rad": "[-2pi, 2pi] rad", "min_lever_arm_m": "(0, 100] m",
    "doppler_yaw_rate_noise_radps": RATE_NOISE, "doppler_yaw_min_rate_radps": "[0, 100] rad/s",
    "axis_learn_frames": "[0, 1e6] (0: the mount's yaw as given)", "axis_straight_radps": RATE,
    "axis_min_speed_mps": SPEED, "no_slip_angle_std_rad": "(0, pi/2) rad", "yaw_manoeuvre_start_prob": "(0, 1)",
    "yaw_manoeuvre_end_prob": "(0, 1)", "velocity_history": "[2, 1e6]", "held_velocity_variance_factor": "[1, 1e6]",
    "held_velocity_yaw_check": "(0, 100] (or null: off)", "held_yaw_rate_std_radps": RATE_NOISE,
    "gap_yaw_rate_radps": "[0, 100] rad/s (0: search no wider after a gap)", "gap_search_rad": WIDENING,
    "bridge_s": "[0, 3600] s (0: off)", "max_step_s": "(0, 1e9] s", "unmeasured_yaw_std_rad": NOISE,
}

POINT_YAW = {
    "blend": "[0, 1)", "map_frames": "[1, 10000]", "bearing_noise_rad": NOISE, "range_noise_m": "[1e-6, 10] m",
    "position_floor_m": "[1e-6, 10] m", "static_threshold_mps": SPEED, "min_points": COUNT, "min_map_points": COUNT,
    # the step below the search (each at least the finest step), and below half a turn
    "search_rad": f"({MIN_SEARCH_STEP_RAD:g}, pi] rad", "step_rad": f"[{MIN_SEARCH_STEP_RAD:g}, pi) rad",
    "coarse_step_rad": f"[{MIN_SEARCH_STEP_RAD:g}, pi) rad (or null: every step_rad)", "prior_rad": PRIOR,
    "gap_widen_rad": WIDENING,
    "gap_widen_frames": "[0, 1000]", "relocate_cells": "[0, 1e6] (0: never)", "relocate_gap_frames": COUNT,
    "relocate_widen_rad": WIDENING, "relocate_prior_rad": PRIOR, "relocate_step_rad": STEP,
    "gap_turn_std_rad": NOISE, "gap_correction_max_rad": ANGLE,
    "outlier_sigmas": "(0, 30] standard deviations", "min_noise_rad": NOISE, "max_noise_rad": NOISE,
    "slow_mps": "[0, 100] m/s", "heatmap_noise_rad": NOISE, "agreement_sigmas": SIGMAS, "check_sigmas": SIGMAS,
    "check_steady_frames": "[0, 1e6] (0: always taken)", "check_steady_rad": ANGLE,
    "check_min_points": "[0, 1e6] (0: never)",
    "heatmap_max_accel_radps2": "(0, 1000] rad/s^2 (or null: always believed)", "lag_frames": COUNT,
}

WALL_MAP = {
    "window_frames": "[2, 100]", "settle_frames": "[1, 10000]", "steady_rad": ANGLE, "match_span_rad": ANGLE,
    "span_noise": "[0, 1]", "static_threshold_mps": SPEED, "max_range_m": "(0, 200] m", "min_points": "[3, 1e6]",
    "band_m": "(0, 10] m", "min_length_m": "(0, 1000] m", "max_gap_m": "(0, 1000] m", "max_lines": "[1, 100]",
    "turn_noise": "[0, 1]", "distance_noise_rad_per_m": "[0, 1] rad/m", "frame_noise_rad": "[0, 1] rad",
    "direction_floor_rad": NOISE, "gate_rad": "(0, pi/2] rad", "distance_gate_m": "(0, 1000] m",
    "max_walls": "[1, 1000]",
}


def _spelled(value: Any, bounds: Limit) -> str:
    return beyond_text(value, bounds.low, bounds.high) if isinstance(value, float) else quoted(value)


def check_limits(values: object, limits: Mapping[str, str], prefix: str = "") -> None:
    """:class:`ConfigError` naming the first field of *limits* (its name after *prefix*) whose
    number in *values* (settings, or a mapping of a section not yet made) is outside its range;
    None (a setting switched off) and what is no number (the types' own checks say so) pass."""
    for name, text in limits.items():
        value = values.get(name) if isinstance(values, Mapping) else getattr(values, name)
        if is_number(value) and not limit(text).admits(value):
            raise ConfigError(f"must be in {text}, got {_spelled(value, limit(text))}", field=prefix + name)
