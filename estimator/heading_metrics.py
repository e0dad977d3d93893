"""Heading metrics against a ground truth (issue 20's robustness matrix).

Per-frame RMSE hides systematic heading errors that a robot feels at once: a
small yaw bias on every straight frame, a turn measured a few percent too large
or too small.  These metrics measure them separately, by segmenting the truth:

- **yaw-increment RMSE** (deg): the frame-to-frame yaw change, estimate minus truth;
- **straight-drive heading bias**: the yaw-increment error (estimate minus truth) summed
  over the frames where the truth drives straight (|yaw rate| below ``straight_rate_dps``, speed above
  ``moving_speed_mps``), per metre driven and per minute of such driving (and per frame); and
  apart, the error summed over the straight frames within ``after_turn_frames`` after a turn
  (where the estimate takes back part of the turn's error: the same error then counts in the
  turn's ratio and again in the straight) and the bias of the other straight frames, the
  straights' own;
- **each straight's heading error** (deg/m): the same error summed over each run of straight
  frames at least ``min_straight_m`` long, over its length: their RMS and the largest.  The
  whole sequence's bias above is their weighted mean, in which a straight that turns left and
  one that turns right cancel; a robot on either feels it;
- **turn ratio**: estimated / true turned angle over the turns, a turn being a run of
  frames with |true yaw rate| above ``straight_rate_dps`` that turns at least
  ``min_turn_deg``; a turn whose median speed is below ``moving_speed_mps`` is a turn in
  place, else a moving turn; the two kinds are reported apart.  The ratio is the estimate's
  yaw change over the turn's frames (signed along the true turn) over the true angle, over all
  the turns of a kind together, and each turn's own: the one farthest from 1 (a left turn too
  long and a right one too short cancel in the first; a robot feels both);
- **drift** (% of the path): final position error, the estimate aligned at the first pose;
- **path ratio**: the estimate's path length over the truth's: a speed's scale error, which the
  drift of a closed loop hardly shows (a loop scaled still closes);
- **final heading error** (deg, signed, wrapped).

:func:`drift_parts` says what makes the drift: the drift each kind of frame's yaw errors make
alone, and the translation's.

Both trajectories are SE(2) arrays (n, 3) of x (m), y (m), yaw (rad) at the same times
(as :func:`radarodom.estimator.evaluation.associate` pairs them).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .evaluation import path_steps, se2_compose, se2_inverse, se2_relative

__all__ = ["AFTER_TURN_FRAMES", "DRIFT_PARTS", "HeadingMetrics", "drift_parts", "heading_metrics", "segment_turns",
           "straight_runs", "straight_steps"]

#: The parts :func:`drift_parts` reports, in order.
DRIFT_PARTS = ("all", "straight", "after turn", "moving turn", "turn in place", "other", "translation")
#: The defaults that tell the truth's motion apart: straight below this yaw rate (deg/s) while
#: moving faster than MOVING_MPS (m/s); a turn turns at least MIN_TURN_DEG; a straight measured
#: apart is at least MIN_STRAIGHT_M long.
STRAIGHT_RATE_DPS = 2.0
MOVING_MPS = 0.05
MIN_TURN_DEG = 10.0
MIN_STRAIGHT_M = 1.0
#: The straight frames after a turn whose error :func:`heading_metrics` sums apart (a second at
#: 10 frames a second: where the estimate settles a turn's error, docs/heading.md, "The straight
#: after a turn in place pays for the turn's error").
AFTER_TURN_FRAMES = 10


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True)
class HeadingMetrics:
    yaw_rmse_deg: float
    #: Straight driving: frames, metres and seconds it covers, and the estimate's heading change.
    straight_frames: int
    straight_m: float
    straight_s: float
    straight_bias_deg_per_m: float
    straight_bias_deg_per_min: float
    straight_bias_deg_per_frame: float
    #: Of those, the frames within ``after_turn_frames`` after a turn: how many, and their summed
    #: heading error, deg (in the bias above); and the bias of the other straight frames, deg a
    #: frame: the straights' own turning, a turn's error taken back after it apart.
    straight_after_turn_frames: int
    straight_after_turn_deg: float
    straight_own_bias_deg_per_frame: float
    #: Each straight drive of at least ``min_straight_m`` apart: how many, and their heading errors'
    #: RMS and largest magnitude, deg/m.
    straights: int
    straight_rms_deg_per_m: float
    straight_max_deg_per_m: float
    #: Turns while moving and in place: how many, true angle (deg, sum of magnitudes), ratio.
    moving_turns: int
    moving_turn_deg: float
    moving_turn_ratio: float
    inplace_turns: int
    inplace_turn_deg: float
    inplace_turn_ratio: float
    #: Each turn's own ratio, the one farthest from 1, of each kind.
    moving_turn_worst_ratio: float
    inplace_turn_worst_ratio: float
    path_m: float
    path_ratio: float
    drift_pct: float
    final_heading_error_deg: float

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in asdict(self).items()}


def _trajectories(times, ref, est) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """*times* (n,), *ref* and *est* (n, 3) as float arrays; ValueError unless they match."""
    times = np.asarray(times, float)
    ref = np.asarray(ref, float)
    est = np.asarray(est, float)
    if ref.shape != est.shape or ref.ndim != 2 or ref.shape[1] != 3 or len(ref) != len(times) or len(ref) < 2:
        raise ValueError("ref and est must be (n, 3) SE(2) arrays at the n >= 2 times")
    return times, ref, est


def _base(ref: np.ndarray, radar_on_base) -> np.ndarray:
    """The poses (n, 3) of the base that carries the radar at *ref* (n, 3), the radar sitting at
    *radar_on_base* (3,): x, y (m) and yaw (rad) in the base's frame."""
    mount = np.asarray(radar_on_base, dtype=float)
    if mount.shape != (3,) or not np.all(np.isfinite(mount)):
        raise ValueError(f"radar_on_base must be three finite numbers (x m, y m, yaw rad), got {radar_on_base!r}")
    if not mount.any():
        return ref
    return se2_compose(ref, se2_inverse(mount)[None, :])


def straight_steps(dt: np.ndarray, d_ref: np.ndarray, base: np.ndarray, straight_rate_dps: float,
                   moving_speed_mps: float) -> np.ndarray:
    """Which of the n-1 steps (durations *dt* s, true yaw increments *d_ref* rad, the *base*'s
    poses (n, 3)) drive straight: the truth turning at most *straight_rate_dps*, the base moving
    faster than *moving_speed_mps*."""
    speed = np.hypot(*np.diff(base[:, :2], axis=0).T) / dt
    return (np.degrees(np.abs(d_ref)) / dt <= straight_rate_dps) & (speed > moving_speed_mps)


def straight_runs(straight: np.ndarray, step_m: np.ndarray, err: np.ndarray,
                  min_m: float) -> list[tuple[int, int, float, float]]:
    """The runs of straight steps (*straight* (n-1,) bool) at least *min_m* long (*step_m*, m a
    step) as (first step, end step (exclusive), length m, heading error rad): *err*'s sum over
    the run (estimate minus truth, rad a step)."""
    out = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], straight.astype(np.int8), [0]])))
    for i, j in zip(edges[0::2], edges[1::2]):
        length = float(step_m[i:j].sum())
        if length >= min_m:
            out.append((int(i), int(j), length, float(err[i:j].sum())))
    return out


def segment_turns(times: np.ndarray, ref: np.ndarray, *, straight_rate_dps: float = STRAIGHT_RATE_DPS,
                  moving_speed_mps: float = MOVING_MPS, min_turn_deg: float = MIN_TURN_DEG
                  ) -> list[tuple[int, int, bool]]:
    """The truth's turns as (first interval, end interval (exclusive), in place) over the
    n-1 frame intervals: runs of |yaw rate| > *straight_rate_dps* turning >= *min_turn_deg*."""
    dt = np.diff(times)
    dyaw = _wrap(np.diff(ref[:, 2]))
    rate = np.degrees(np.abs(dyaw)) / dt
    speed = np.hypot(*np.diff(ref[:, :2], axis=0).T) / dt
    turning = rate > straight_rate_dps
    out = []
    i, n = 0, len(turning)
    while i < n:
        if not turning[i]:
            i += 1
            continue
        j = i
        while j < n and turning[j] and np.sign(dyaw[j]) == np.sign(dyaw[i]):
            j += 1
        if abs(math.degrees(dyaw[i:j].sum())) >= min_turn_deg:
            out.append((i, j, bool(np.median(speed[i:j]) < moving_speed_mps)))
        i = j
    return out


def _after_turns(straight: np.ndarray, turns: list[tuple[int, int, bool]], frames: int) -> np.ndarray:
    """Which steps (n-1,) are among the first *frames* straight steps (*straight* (n-1,) bool) that
    follow each of *turns* (:func:`segment_turns`') without a break."""
    out = np.zeros_like(straight)
    for _, j, _ in turns:
        k = j
        while k < len(straight) and k < j + frames and straight[k]:
            out[k] = True
            k += 1
    return out


def heading_metrics(times, ref, est, *, straight_rate_dps: float = STRAIGHT_RATE_DPS,
                    moving_speed_mps: float = MOVING_MPS, min_turn_deg: float = MIN_TURN_DEG,
                    min_straight_m: float = MIN_STRAIGHT_M, after_turn_frames: int = AFTER_TURN_FRAMES,
                    radar_on_base=(0.0, 0.0, 0.0)) -> HeadingMetrics:
    """The metrics of the module text for *est* against *ref* ((n, 3) SE(2) at *times*);
    *min_straight_m*: the shortest straight measured apart; *after_turn_frames*: the straight
    frames after a turn summed apart.
    *radar_on_base*: where the radar sits on the base that carries it, (3,) x, y (m) and yaw (rad)
    in the base's frame (e.g. 0.3 m ahead of a wheeled base's rotation axis): straight drives and
    turns in place are told by the base's motion (a radar ahead of the axis moves in a turn in
    place); the path and drift stay the radar's."""
    times, ref, est = _trajectories(times, ref, est)
    dt = np.diff(times)
    d_ref = _wrap(np.diff(ref[:, 2]))
    d_est = _wrap(np.diff(est[:, 2]))
    err = _wrap(d_est - d_ref)
    step_m = np.hypot(*np.diff(ref[:, :2], axis=0).T)
    base = _base(ref, radar_on_base)
    straight = straight_steps(dt, d_ref, base, straight_rate_dps, moving_speed_mps)
    s_m, s_s = float(step_m[straight].sum()), float(dt[straight].sum())
    s_yaw = math.degrees(float(err[straight].sum()))  # the truth turns ~0 there; its ramps' rest removed
    nan = float("nan")
    runs = np.array([math.degrees(e) / m for _, _, m, e in straight_runs(straight, step_m, err, min_straight_m)])

    turns = segment_turns(times, base, straight_rate_dps=straight_rate_dps, moving_speed_mps=moving_speed_mps,
                          min_turn_deg=min_turn_deg)
    kinds = {}
    for in_place in (False, True):
        true_sum, est_sum, ratios = 0.0, 0.0, []
        for i, j, ip in turns:
            if ip != in_place:
                continue
            true_angle = float(d_ref[i:j].sum())
            along = math.copysign(1.0, true_angle) * float(d_est[i:j].sum())
            true_sum += abs(true_angle)
            est_sum += along
            ratios.append(along / abs(true_angle))
        # (undefined when one is, as the kind's ratio is)
        worst = nan if not ratios or any(map(math.isnan, ratios)) else max(ratios, key=lambda r: abs(r - 1.0))
        kinds[in_place] = (len(ratios), math.degrees(true_sum), est_sum / true_sum if true_sum > 0 else nan, worst)
    after = _after_turns(straight, turns, after_turn_frames)
    own = straight & ~after

    path = float(step_m.sum())
    est_path = float(path_steps(est[:, :2]).sum())
    aligned = se2_compose(se2_compose(ref[0], se2_inverse(est[0]))[None, :], est)
    drift = float(np.hypot(*(aligned[-1, :2] - ref[-1, :2])))
    final = math.degrees(float(_wrap(aligned[-1, 2] - ref[-1, 2])))
    return HeadingMetrics(
        yaw_rmse_deg=math.degrees(float(np.sqrt(np.mean(err ** 2)))),
        straight_frames=int(straight.sum()), straight_m=s_m, straight_s=s_s,
        straight_bias_deg_per_m=s_yaw / s_m if s_m > 0 else nan,
        straight_bias_deg_per_min=60.0 * s_yaw / s_s if s_s > 0 else nan,
        straight_bias_deg_per_frame=s_yaw / int(straight.sum()) if straight.any() else nan,
        straight_after_turn_frames=int(after.sum()), straight_after_turn_deg=math.degrees(float(err[after].sum())),
        straight_own_bias_deg_per_frame=math.degrees(float(err[own].sum())) / int(own.sum()) if own.any() else nan,
        straights=len(runs), straight_rms_deg_per_m=float(np.sqrt(np.mean(runs ** 2))) if len(runs) else nan,
        straight_max_deg_per_m=float(np.abs(runs).max()) if len(runs) else nan,
        moving_turns=kinds[False][0], moving_turn_deg=kinds[False][1], moving_turn_ratio=kinds[False][2],
        inplace_turns=kinds[True][0], inplace_turn_deg=kinds[True][1], inplace_turn_ratio=kinds[True][2],
        moving_turn_worst_ratio=kinds[False][3], inplace_turn_worst_ratio=kinds[True][3],
        path_m=path, path_ratio=est_path / path if path > 0 else nan,
        drift_pct=100.0 * drift / path if path > 0 else nan, final_heading_error_deg=final)


def drift_parts(times, ref, est, *, straight_rate_dps: float = STRAIGHT_RATE_DPS,
                moving_speed_mps: float = MOVING_MPS, min_turn_deg: float = MIN_TURN_DEG,
                after_turn_frames: int = 3, radar_on_base=(0.0, 0.0, 0.0)
                ) -> dict[str, float]:
    """Drift (% of the path, as :func:`heading_metrics`) that each kind of frame makes alone: the
    true path integrated again from its own steps, with the estimate's yaw increments on that
    kind's frames only: "straight" (as the straight-drive bias counts them, less the first
    *after_turn_frames* after a turn, which are "after turn"), "moving turn", "turn in place"
    (as :func:`segment_turns` finds them) and "other" (standing, a turn's ramps); "translation":
    the estimate's own steps (body frame) with the true yaw increments; "all": the estimate's
    drift.  The parts do not add up (a heading error moves everything after it), but the largest
    is what to mend first.  *ref*, *est*: (n, 3) SE(2) at *times*; keywords as heading_metrics."""
    times, ref, est = _trajectories(times, ref, est)
    dt = np.diff(times)
    d_ref = _wrap(np.diff(ref[:, 2]))
    err = _wrap(_wrap(np.diff(est[:, 2])) - d_ref)
    base = _base(ref, radar_on_base)
    straight = straight_steps(dt, d_ref, base, straight_rate_dps, moving_speed_mps)
    kind = np.where(straight, "straight", "other").astype(object)
    turns = segment_turns(times, base, straight_rate_dps=straight_rate_dps, moving_speed_mps=moving_speed_mps,
                          min_turn_deg=min_turn_deg)
    for i, j, in_place in turns:
        kind[i:j] = "turn in place" if in_place else "moving turn"
    kind[_after_turns(straight, turns, after_turn_frames)] = "after turn"
    ref_steps, est_steps = se2_relative(ref[:-1], ref[1:])[:, :2], se2_relative(est[:-1], est[1:])[:, :2]
    path = float(np.hypot(*ref_steps.T).sum())

    def drift(poses_xy: np.ndarray) -> float:
        return 100.0 * float(np.hypot(*(poses_xy - ref[-1, :2]))) / path if path > 0 else float("nan")

    parts = {"all": drift(_end(ref[0], d_ref + err, est_steps))}
    for name in DRIFT_PARTS[1:-1]:
        parts[name] = drift(_end(ref[0], d_ref + np.where(kind == name, err, 0.0), ref_steps))
    parts["translation"] = drift(_end(ref[0], d_ref, est_steps))
    return parts


def _end(start: np.ndarray, dyaw: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """The last position (2,), m, of a path from pose *start* (3,) by yaw increments *dyaw* (n-1,)
    rad and body-frame *steps* (n-1, 2) m, each step taken in the heading before its turn."""
    yaw = start[2] + np.concatenate([[0.0], np.cumsum(dyaw)[:-1]])
    c, s = np.cos(yaw), np.sin(yaw)
    return start[:2] + np.array([(c * steps[:, 0] - s * steps[:, 1]).sum(), (s * steps[:, 0] + c * steps[:, 1]).sum()])
