"""How well the odometry's reported covariance covers its errors against a ground truth: each
frame's heading and position error since the first compared frame over its reported standard
deviation, and each step's yaw rate's and velocity's (docs/estimator.md, "Pose covariance").  An RMS ratio below 1
says the covariance is wide, above 1 that it is narrow.  A normal heading or yaw-rate error lies
within one standard deviation in 68 % of the frames, within two in 95 %; a position error, its
distance over the root of the covariance's trace, in 63 % and 98 % (round, two dimensions)."""

from __future__ import annotations

import math

import numpy as np

from ..errors import EvaluationError
from ..plain_numbers import is_number, time_text
from ..tum import TumTrajectory
from .association import check_increasing, check_trajectory

#: The largest offset between a message's stamp and the time it describes: a frame's chirps last
#: tens of milliseconds.
MAX_MEASURED_AT_S = 1.0
#: A time this close to a truth pose's is that pose's (files round their times).
SAME_TIME_S = 1e-6
#: Truth poses farther apart than this many of the truth's median steps, and than
#: :data:`MIN_GAP_S`, are a gap, not interpolated across ...
MAX_GAP_STEPS = 2.0
#: ... s (a fast truth's dropout of a few poses is interpolated).
MIN_GAP_S = 0.05


def _normalised(errors: np.ndarray, variances: np.ndarray) -> np.ndarray:
    """Each error over its standard deviation, for the frames with a positive variance."""
    ok = variances > 0.0
    return errors[ok] / np.sqrt(variances[ok])


def _summary(z: np.ndarray) -> dict:
    if len(z) == 0:
        return {"z_rms": None, "within_1sigma": None, "within_2sigma": None}
    return {"z_rms": float(np.sqrt(np.mean(z * z))), "within_1sigma": float(np.mean(np.abs(z) <= 1.0)),
            "within_2sigma": float(np.mean(np.abs(z) <= 2.0))}


def _single_steps(estimate: np.ndarray, times: np.ndarray, yaw_rates: np.ndarray, frames: np.ndarray | None
                  ) -> np.ndarray:
    """Which of the n - 1 steps between consecutive frames are one estimator step each: its yaw rate
    times its time is its yaw change (a step measured across a bridged run carries the run's mean
    rate, and its twist is of the whole run), and, given *frames*, their numbers follow."""
    change = np.angle(np.exp(1j * np.diff(estimate[:, 2])))  # (a yaw read back from a quaternion wraps)
    single = np.abs(yaw_rates[1:] * np.diff(times) - change) <= 1e-9 + 1e-6 * np.abs(change)
    if frames is not None:
        single &= np.diff(np.asarray(frames).astype(np.uint64)) == 1  # (a number going down wraps)
    return single


def covariance_consistency(reference: np.ndarray, estimate: np.ndarray, pose_covariance: np.ndarray, *,
                           twist_covariance: np.ndarray | None = None, times: np.ndarray | None = None,
                           yaw_rates: np.ndarray | None = None, frames: np.ndarray | None = None) -> dict:
    """The heading's and the position's error over the reported standard deviation, frame by frame;
    with *twist_covariance*, *times* and *yaw_rates*, each step's yaw rate's too.

    *reference*, *estimate*: (n, 3) x, y m and yaw rad of the same frames (associated), each in its
    own world; the reference is put in the estimate's by their first poses, and the errors count
    from there, so the covariance the estimate had at its first frame is taken off (exact for the
    heading's random walk, near enough for the position's).  *pose_covariance*: (n, 3, 3) the
    estimate's, over (x, y, yaw).  *twist_covariance*: (n, 3, 3) over (vx, vy, yaw rate), each of
    its step from the frame before; *times* (n,) s; *yaw_rates* (n,) rad/s, the estimate's;
    *frames* (n,) its frame numbers (optional): only the steps that are one estimator step each are
    compared.  Returns ``yaw``, ``position``, and the twist's ``yaw_rate``, ``forward_speed`` and
    ``sideways_speed`` (each step's, its velocity from the poses; None without the twist's), each
    {"z_rms", "within_1sigma", "within_2sigma"} over the frames (steps) with a variance, and
    ``final_yaw_error_deg`` and ``final_yaw_sigma_deg`` (the last frame's, from the first)."""
    reference, estimate = _floats("reference", reference), _floats("estimate", estimate)
    cov = _floats("pose_covariance", pose_covariance)
    n = len(reference)
    twist = [None if a is None else _floats(name, a)
             for name, a in (("twist_covariance", twist_covariance), ("times", times), ("yaw_rates", yaw_rates))]
    given = [a is not None for a in twist]
    frames = None if frames is None else _frame_numbers(frames)
    if (reference.shape != (n, 3) or estimate.shape != (n, 3) or cov.shape != (n, 3, 3) or n < 2
            or any(given) != all(given) or (all(given) and [a.shape for a in twist] != [(n, 3, 3), (n,), (n,)])
            or (frames is not None and np.shape(frames) != (n,))):
        shapes = [np.shape(a) for a in (reference, estimate, cov, *twist, frames) if a is not None]
        raise EvaluationError(f"covariance_consistency: need n >= 2 poses (n, 3) and covariances (n, 3, 3) of the "
                              f"same frames (a twist's with their times and yaw rates (n,)), got shapes {shapes}")
    if all(given) and not np.all(np.diff(twist[1]) > 0):
        raise EvaluationError("covariance_consistency: the times must increase")
    with np.errstate(over="ignore", invalid="ignore"):  # (variances near the float limit: inf, not a warning)
        return _consistency(reference, estimate, cov - cov[0], twist, frames, all(given))


def _consistency(reference: np.ndarray, estimate: np.ndarray, cov: np.ndarray, twist: list, frames, with_twist: bool
                 ) -> dict:
    turn = estimate[0, 2] - reference[0, 2]
    c, s = math.cos(turn), math.sin(turn)
    d = reference[:, :2] - reference[0, :2]
    placed = np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], axis=1) + estimate[0, :2]
    yaw_error = np.angle(np.exp(1j * (estimate[:, 2] - reference[:, 2] - turn)))
    out = {"yaw": _summary(_normalised(yaw_error, cov[:, 2, 2])),
           "position": _summary(_normalised(np.hypot(*(estimate[:, :2] - placed).T), cov[:, 0, 0] + cov[:, 1, 1])),
           "yaw_rate": None, "forward_speed": None, "sideways_speed": None,
           "final_yaw_error_deg": math.degrees(float(yaw_error[-1])),
           "final_yaw_sigma_deg": math.degrees(math.sqrt(max(float(cov[-1, 2, 2]), 0.0)))}
    if with_twist:
        tw, stamps, rates = twist
        single = _single_steps(estimate, stamps, rates, frames)
        step_error = np.angle(np.exp(1j * (np.diff(estimate[:, 2]) - np.diff(reference[:, 2]))))[single]
        out["yaw_rate"] = _summary(_normalised(step_error, (tw[1:, 2, 2] * np.diff(stamps) ** 2)[single]))
        dt = np.diff(stamps)[single]
        error = (_body_step(estimate) - _body_step(reference))[single] / dt[:, None]
        out["forward_speed"] = _summary(_normalised(error[:, 0], tw[1:, 0, 0][single]))
        out["sideways_speed"] = _summary(_normalised(error[:, 1], tw[1:, 1, 1][single]))
    return out


def _floats(name: str, value) -> np.ndarray:
    """*value* as an array of finite floats, or :class:`EvaluationError` naming the argument."""
    try:
        array = np.asarray(value, float)
    except (TypeError, ValueError, OverflowError):
        raise EvaluationError(f"{name}: numbers are needed, got {type(value).__name__}") from None
    if not np.all(np.isfinite(array)):
        raise EvaluationError(f"{name}: every value must be a finite number")
    return array


def _frame_numbers(value) -> np.ndarray:
    """Frame numbers as unsigned integers, or :class:`EvaluationError`."""
    array = np.asarray(value)
    if array.dtype.kind == "f" and np.all(np.isfinite(array)) and np.all(array == np.round(array)) \
            and np.all(array >= 0) and np.all(array < 2.0 ** 64):
        array = array.astype(np.uint64)
    if array.dtype.kind not in "iu" or (array.dtype.kind == "i" and np.any(array < 0)):
        raise EvaluationError("frames: whole numbers from 0 are needed")
    return array


def _body_step(poses: np.ndarray) -> np.ndarray:
    """Each step's displacement (n - 1, 2), m, in the body's axes half-way through its turn: the
    odometry's chord of the step's velocity times its time, exactly (a truth's, near enough)."""
    turn = np.angle(np.exp(1j * np.diff(poses[:, 2])))
    mid = poses[:-1, 2] + 0.5 * turn
    d = np.diff(poses[:, :2], axis=0)
    c, s = np.cos(mid), np.sin(mid)
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)


def odometry_consistency(times: np.ndarray, poses: np.ndarray, pose_covariance: np.ndarray,
                         twist_covariance: np.ndarray, yaw_rates: np.ndarray, frames: np.ndarray | None,
                         reference: TumTrajectory, *, source: str = "odometry",
                         measured_at_s: float = 0.0) -> tuple[dict, int]:
    """:func:`covariance_consistency` of an odometry run's states (their *times* (n,) s, *poses*
    (n, 3), covariances (n, 3, 3), *yaw_rates* (n,) and *frames* (n,) or None) against the ground
    truth *reference*; and how many states were compared.  Each state is compared with the truth
    *measured_at_s* s after its time (the odometry describes the radar at the middle of the frame's
    chirps, ``RadarConfig.measured_at_s`` after its stamp), interpolated between the truth's poses
    (a pose within :data:`SAME_TIME_S` taken as it is), over the states whose time then lies within
    the truth's span and not in a gap of it (two truth poses farther apart than :data:`MAX_GAP_STEPS`
    of its median steps and :data:`MIN_GAP_S`).  Without *frames* the states' own order stands in
    for their numbers, so a step across a state left out is no single step.  The result has
    ``measured_at_s`` too.  Raises :class:`EvaluationError` (naming *source*) when fewer than two
    are compared, or an argument is not what it must be."""
    at = _offset(measured_at_s)
    check_trajectory("reference", reference)
    check_increasing(reference)
    times = _floats("times", times)
    n = len(times) if times.ndim == 1 else -1
    arrays = {name: _floats(name, value) for name, value in (
        ("poses", poses), ("pose_covariance", pose_covariance), ("twist_covariance", twist_covariance),
        ("yaw_rates", yaw_rates))}
    arrays["frames"] = np.arange(max(n, 0), dtype=np.uint64) if frames is None else _frame_numbers(frames)
    shapes = {"poses": (n, 3), "pose_covariance": (n, 3, 3), "twist_covariance": (n, 3, 3), "yaw_rates": (n,),
              "frames": (n,)}
    wrong = [f"{name} {np.shape(arrays[name])}" for name, shape in shapes.items() if np.shape(arrays[name]) != shape]
    if n < 0 or wrong:
        raise EvaluationError(f"odometry_consistency: times (n,) and each state's pose (n, 3), covariances (n, 3, 3), "
                              f"yaw rate and frame (n,) are needed; got times {times.shape}"
                              + "".join(f", {w}" for w in wrong))
    if n and not np.all(np.diff(times) > 0):
        raise EvaluationError(f"{source}: the times must increase")
    shifted = times + at
    if n and np.max(np.abs(shifted - times - at)) > SAME_TIME_S:
        raise EvaluationError(f"{source}: its times (t {time_text(times[-1])} s) are too large to be moved by "
                              f"{at:g} s in floating point: count them from the run's start")
    k = np.flatnonzero(_within_truth(reference, shifted))
    if len(k) < 2:
        span = f" (t {time_text(times[0])} .. {time_text(times[-1])} s)" if n else ""
        raise EvaluationError(f"{source}: fewer than two of its {n} messages{span} have a ground truth "
                              f"{offset_text(at, 'their')} (the truth: t {time_text(reference.times[0])} .. "
                              f"{time_text(reference.times[-1])} s, {len(reference)} poses)")
    result = covariance_consistency(_poses_at(reference, shifted[k]), arrays["poses"][k],
                                    arrays["pose_covariance"][k], twist_covariance=arrays["twist_covariance"][k],
                                    times=times[k], yaw_rates=arrays["yaw_rates"][k], frames=arrays["frames"][k])
    return {**result, "measured_at_s": at}, len(k)


def _offset(value) -> float:
    try:
        at = float(value) if is_number(value) else math.nan
    except OverflowError:
        at = math.nan
    if not (math.isfinite(at) and abs(at) <= MAX_MEASURED_AT_S):
        raise EvaluationError(f"measured_at_s must be a time within +/-{MAX_MEASURED_AT_S:g} s, got {value!r}")
    return at


def offset_text(at: float, whose: str = "its") -> str:
    """Where *at* s from a stamp is, as a message says it: "13.44 ms after its t"."""
    if at == 0.0:
        return f"at {whose} t"
    return f"{abs(at) * 1e3:.4g} ms {'after' if at > 0 else 'before'} {whose} t"


def _within_truth(reference: TumTrajectory, times: np.ndarray) -> np.ndarray:
    """Which *times* the truth's poses bracket closely enough to interpolate, or hit."""
    t = reference.times
    if len(t) < 2:
        return np.abs(times - t[0]) <= SAME_TIME_S if len(t) else np.zeros(len(times), bool)
    after = np.searchsorted(t, times, side="left")
    at_or_after, before = t[np.minimum(after, len(t) - 1)], t[np.maximum(after - 1, 0)]
    hit = (np.abs(at_or_after - times) <= SAME_TIME_S) | (np.abs(before - times) <= SAME_TIME_S)
    bracketed = (after > 0) & (after < len(t))
    gap = max(MAX_GAP_STEPS * float(np.median(np.diff(t))), MIN_GAP_S)
    return hit | (bracketed & (at_or_after - before <= gap))


def _poses_at(reference: TumTrajectory, times: np.ndarray) -> np.ndarray:
    """The reference's poses (k, 3) at *times* (k,) s within its span: x, y and the unwrapped yaw
    each linear between its own poses (a step's velocity from two such poses is then its chords'
    blend, the velocity at the shifted step to first order)."""
    se2 = reference.se2()
    columns = (se2[:, 0], se2[:, 1], np.unwrap(se2[:, 2]))
    return np.stack([np.interp(times, reference.times, c) for c in columns], axis=1)
