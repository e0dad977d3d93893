"""How well the odometry's reported covariance covers its errors against a ground truth: each
frame's heading (and position) error since the start over its reported standard deviation
(docs/estimator.md, "Pose covariance").  An RMS ratio below 1 says the covariance is wide, above 1
that it is narrow.  A normal heading error lies within one standard deviation in 68 % of the
frames, within two in 95 %; a position error, its distance over the root of the covariance's
trace, in 63 % and 98 % (round, two dimensions)."""

from __future__ import annotations

import math

import numpy as np

from ..errors import EvaluationError


def _normalised(errors: np.ndarray, variances: np.ndarray) -> np.ndarray:
    """Each error over its standard deviation, for the frames with a positive variance."""
    ok = variances > 0.0
    return errors[ok] / np.sqrt(variances[ok])


def _summary(z: np.ndarray) -> dict:
    if len(z) == 0:
        return {"z_rms": None, "within_1sigma": None, "within_2sigma": None}
    return {"z_rms": float(np.sqrt(np.mean(z * z))), "within_1sigma": float(np.mean(np.abs(z) <= 1.0)),
            "within_2sigma": float(np.mean(np.abs(z) <= 2.0))}


def covariance_consistency(reference: np.ndarray, estimate: np.ndarray, pose_covariance: np.ndarray, *,
                           position: bool = True, twist_covariance: np.ndarray | None = None,
                           times: np.ndarray | None = None) -> dict:
    """The heading's (and, with *position*, the position's) error over the reported standard
    deviation, frame by frame; with *twist_covariance* and *times*, the yaw rate's too.

    *reference*, *estimate*: (n, 3) x, y m and yaw rad of the same frames (associated), each in its
    own world; the reference is put in the estimate's by their first poses.  *pose_covariance*:
    (n, 3, 3) the estimate's, over (x, y, yaw).  *twist_covariance*: (n, 3, 3) over (vx, vy, yaw
    rate), each frame's of its step from the frame before (consecutive states), *times* (n,) s.
    Returns ``yaw``, ``position`` (None without *position*) and ``yaw_rate`` (None without the
    twist's), each {"z_rms", "within_1sigma", "within_2sigma"} over the frames with a variance, and
    ``final_yaw_error_deg`` and ``final_yaw_sigma_deg`` (the last frame's)."""
    reference, estimate = np.asarray(reference, float), np.asarray(estimate, float)
    cov = np.asarray(pose_covariance, float)
    n = len(reference)
    twist = None if twist_covariance is None else np.asarray(twist_covariance, float)
    stamps = None if times is None else np.asarray(times, float)
    if (reference.shape != (n, 3) or estimate.shape != (n, 3) or cov.shape != (n, 3, 3) or n < 2
            or (twist is None) != (stamps is None)
            or (twist is not None and (twist.shape != (n, 3, 3) or stamps.shape != (n,)))):
        shapes = [a.shape for a in (reference, estimate, cov, twist, stamps) if a is not None]
        raise EvaluationError(f"covariance_consistency: need n >= 2 poses (n, 3) and covariances (n, 3, 3) of the "
                              f"same frames (a twist's with their times (n,)), got shapes {shapes}")
    turn = estimate[0, 2] - reference[0, 2]
    c, s = math.cos(turn), math.sin(turn)
    d = reference[:, :2] - reference[0, :2]
    placed = np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], axis=1) + estimate[0, :2]
    yaw_error = np.angle(np.exp(1j * (estimate[:, 2] - reference[:, 2] - turn)))
    out = {"yaw": _summary(_normalised(yaw_error, cov[:, 2, 2])), "position": None,
           "final_yaw_error_deg": math.degrees(float(yaw_error[-1])),
           "final_yaw_sigma_deg": math.degrees(math.sqrt(max(float(cov[-1, 2, 2]), 0.0)))}
    if position:
        out["position"] = _summary(_normalised(np.hypot(*(estimate[:, :2] - placed).T), cov[:, 0, 0] + cov[:, 1, 1]))
    out["yaw_rate"] = None
    if twist is not None:
        step_error = np.angle(np.exp(1j * (np.diff(estimate[:, 2]) - np.diff(reference[:, 2]))))
        out["yaw_rate"] = _summary(_normalised(step_error, twist[1:, 2, 2] * np.diff(stamps) ** 2))
    return out
