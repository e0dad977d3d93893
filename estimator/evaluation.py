"""Trajectory evaluation in SE(2): an estimate against a reference (ground truth).

The metrics follow evo (``evo_rpe``, ``evo_ape``) so the numbers can be checked
against it, restricted to the plane: a pose is x, y (m) and yaw (rad, from the
quaternion); z, roll and pitch are ignored.

- Relative pose error (RPE) over pairs of poses (i, j):
  ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``, Q the reference and P the estimate; its
  translation norm (m) and rotation angle (deg).  Per frame: j = i + 1.  Per
  distance: evo's consecutive pairs (``--delta D --delta_unit m`` with
  ``--pairs_from_reference``): segments chained end to end, each ending at the
  first pose whose reference path length from the segment's start reaches D.
- Yaw-increment error per frame: ``wrap(wrap(dyaw_est) - wrap(dyaw_ref))`` in
  deg, signed (the per-frame RPE rotation is its absolute value), its RMSE and
  cumulative square.
- Absolute trajectory error (ATE): the estimate's positions aligned to the
  reference by Umeyama's rotation and translation (no scale, ``evo_ape -a``).
- Final drift: the estimate aligned by its first pose (``T_ref0 T_est0^-1``);
  the distance between the last positions, also as % of the reference path.

Pure numpy; imports nothing from the driver or the tools.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np

from .. import strict_json
from ..errors import EvaluationError
from ..plain_numbers import is_number
from ..tum import TumTrajectory, unit_quaternions
from .angles import wrap
from .association import associate

log = logging.getLogger(__name__)

#: Height changes (m) and roll/pitch (rad) above these are worth a warning: the evaluation ignores them.
_PLANAR_Z_TOL_M = 1e-3
_PLANAR_TILT_TOL_RAD = 1e-3


# ------------------------------------------------------------------------ statistics
@dataclass(frozen=True)
class Stats:
    """Summary of an error series, as evo reports it (std is the population
    std); in the series' unit.  NaN values (and n = 0) for an empty series."""

    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    n: int

    @classmethod
    def of(cls, errors) -> "Stats":
        e = np.asarray(errors, dtype=float).reshape(-1)
        if not len(e):
            nan = float("nan")
            return cls(nan, nan, nan, nan, nan, nan, 0)
        return cls(rmse=float(np.sqrt(np.mean(e * e))), mean=float(np.mean(e)),
                   median=float(np.median(e)), std=float(np.std(e)), min=float(np.min(e)),
                   max=float(np.max(e)), n=len(e))

    def to_dict(self) -> dict[str, Any]:
        # JSON has no NaN: an undefined number is null.
        return strict_json.finite({k: getattr(self, k) for k in ("rmse", "mean", "median", "std", "min", "max", "n")})


# ------------------------------------------------------------------------ SE(2)
def se2_relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 b`` for poses (..., 3) x, y (m), yaw (rad): b seen from a."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap(b[..., 2] - a[..., 2])], axis=-1)


def se2_compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a b`` for poses (..., 3) x, y (m), yaw (rad)."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([a[..., 0] + c * b[..., 0] - s * b[..., 1], a[..., 1] + s * b[..., 0] + c * b[..., 1],
                     wrap(a[..., 2] + b[..., 2])], axis=-1)


def se2_inverse(a: np.ndarray) -> np.ndarray:
    """``a^-1`` for poses (..., 3)."""
    return se2_relative(a, np.zeros_like(a))


def umeyama_se2(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The rotation and translation (no scale) that best map points *src* (n, 2)
    onto *dst* (n, 2) in least squares (Umeyama 1991), as a pose (3,) x, y, yaw.

    All points at one place (a rotation on the spot) leave the rotation
    undetermined: then only the translation is fitted; so it is where the positions are too
    large for their spread to be computed (it overflows: the SVD of an infinite matrix fails).
    """
    with np.errstate(over="ignore", invalid="ignore"):
        mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
        cov = (dst - mu_d).T @ (src - mu_s) / len(src)
        if not np.isfinite(cov).all():
            log.info("the positions are too large to align by rotation (their spread overflows): ATE aligned by "
                     "translation only")
            return np.array([*(mu_d - mu_s), 0.0])
    u, d, vt = np.linalg.svd(cov)
    if d[0] <= 1e-12:
        log.info("the estimate's positions do not move: ATE aligned by translation only")
        rot = np.eye(2)
    else:
        sign = np.diag([1.0, 1.0 if np.linalg.det(u) * np.linalg.det(vt) >= 0 else -1.0])
        rot = u @ sign @ vt
    t = mu_d - rot @ mu_s
    return np.array([t[0], t[1], math.atan2(rot[1, 0], rot[0, 0])])


def path_steps(xy: np.ndarray) -> np.ndarray:
    """Distances (n-1,) m between consecutive positions *xy* (n, 2)."""
    return np.linalg.norm(np.diff(xy, axis=0), axis=1)


def distance_pairs(xy: np.ndarray, delta_m: float) -> np.ndarray:
    """Index pairs (k, 2) of consecutive segments of at least *delta_m* path length
    along positions *xy* (n, 2), chained end to end: evo's
    ``filter_pairs_by_path`` with ``all_pairs=False``, the same running sum."""
    ids = [0]
    current = 0.0
    for i, step in enumerate(path_steps(xy), start=1):
        current += float(step)
        if current >= delta_m:
            ids.append(i)
            current = 0.0
    return np.array(list(pairwise(ids)), dtype=int).reshape(-1, 2)


# ------------------------------------------------------------------------ results
@dataclass(frozen=True)
class RelativeError:
    """Relative pose errors over pairs of matched poses.

    ``pairs`` (k, 2) indices into the matched poses; ``translation_m`` (k,) m;
    ``rotation_deg`` (k,) deg, absolute; ``path_m`` (k,) the reference path
    length of each pair, m.
    """

    pairs: np.ndarray
    translation_m: np.ndarray
    rotation_deg: np.ndarray
    path_m: np.ndarray

    @property
    def translation_pct(self) -> np.ndarray:
        """Translation error (k,) as % of each pair's reference path length
        (pairs without motion left out)."""
        moved = self.path_m > 0
        return 100.0 * self.translation_m[moved] / self.path_m[moved]

    def to_dict(self, *, percent: bool) -> dict[str, Any]:
        out = {"translation_m": Stats.of(self.translation_m).to_dict()}
        if percent:
            out["translation_pct"] = Stats.of(self.translation_pct).to_dict()
        out["rotation_deg"] = Stats.of(self.rotation_deg).to_dict()
        return out


def relative_error(ref: np.ndarray, est: np.ndarray, pairs: np.ndarray) -> tuple[RelativeError, np.ndarray]:
    """RPE of SE(2) poses *est* (n, 3) against *ref* (n, 3) over index *pairs*
    (k, 2); also the signed rotation error (k,) rad."""
    i, j = pairs[:, 0], pairs[:, 1]
    err = se2_relative(se2_relative(ref[i], ref[j]), se2_relative(est[i], est[j]))
    cum = np.concatenate([[0.0], np.cumsum(path_steps(ref[:, :2]))])
    rel = RelativeError(pairs, np.hypot(err[:, 0], err[:, 1]), np.degrees(np.abs(err[:, 2])), cum[j] - cum[i])
    return rel, err[:, 2]


@dataclass(frozen=True)
class EvaluationResult:
    """What :func:`evaluate` finds.  Series for plots are over the m matched
    poses; times are seconds from the first matched reference pose."""

    est_source: str
    ref_source: str
    est_poses: int
    ref_poses: int
    max_diff_s: float
    delta_m: float
    #: (m,) s: reference times of the matched poses, from the first.
    times: np.ndarray
    #: (m, 3) x, y (m), yaw (rad): the reference.
    ref: np.ndarray
    #: (m, 3): the estimate as given (its own world frame).
    est: np.ndarray
    #: (m, 3): the estimate aligned to the reference by Umeyama (ATE).
    est_umeyama: np.ndarray
    #: (m, 3): the estimate aligned to the reference by the first pose (drift).
    est_first_pose: np.ndarray
    #: Umeyama's alignment as a pose (3,): x, y (m), rotation (rad).
    alignment: np.ndarray
    rpe_frame: RelativeError
    rpe_distance: RelativeError
    #: (m-1,) deg, signed: yaw-increment error of each frame (at times[1:]).
    yaw_error_deg: np.ndarray
    #: (m,) m: position error after Umeyama alignment.
    ate_m: np.ndarray

    @property
    def matched(self) -> int:
        return len(self.times)

    @property
    def duration_s(self) -> float:
        return float(self.times[-1] - self.times[0])

    @property
    def ref_path_m(self) -> float:
        return float(path_steps(self.ref[:, :2]).sum())

    @property
    def est_path_m(self) -> float:
        return float(path_steps(self.est[:, :2]).sum())

    @property
    def yaw_cumulative_sq_deg2(self) -> np.ndarray:
        """(m-1,) deg^2: running sum of the squared yaw-increment errors (the paper's figure)."""
        return np.cumsum(self.yaw_error_deg ** 2)

    @property
    def yaw_rmse_deg(self) -> float:
        return Stats.of(self.yaw_error_deg).rmse

    @property
    def drift_m(self) -> float:
        """Final position error (m) with the estimate aligned by its first pose."""
        return float(np.hypot(*(self.est_first_pose[-1, :2] - self.ref[-1, :2])))

    @property
    def drift_pct(self) -> float:
        """:attr:`drift_m` as % of the reference path length (NaN without motion)."""
        path = self.ref_path_m
        return 100.0 * self.drift_m / path if path > 0 else float("nan")

    @property
    def drift_yaw_deg(self) -> float:
        """Final yaw error (deg, signed) with the estimate aligned by its first pose."""
        return float(np.degrees(wrap(self.est_first_pose[-1, 2] - self.ref[-1, 2])))

    def to_dict(self) -> dict[str, Any]:
        """The numbers (no series), JSON-ready: undefined values (NaN, and infinity where
        coordinates so large that a length overflows) are None, numbers plain floats."""
        return strict_json.finite({
            "estimate": self.est_source,
            "reference": self.ref_source,
            "poses": {"estimate": self.est_poses, "reference": self.ref_poses, "matched": self.matched},
            "max_diff_s": self.max_diff_s,
            "duration_s": self.duration_s,
            "reference_path_length_m": self.ref_path_m,
            "estimate_path_length_m": self.est_path_m,
            "rpe_per_frame": self.rpe_frame.to_dict(percent=False),
            "rpe_per_distance": {"delta_m": self.delta_m, **self.rpe_distance.to_dict(percent=True)},
            "yaw_increment_error_deg": Stats.of(self.yaw_error_deg).to_dict(),
            "ate_m": Stats.of(self.ate_m).to_dict(),
            "ate_alignment": {"x_m": float(self.alignment[0]), "y_m": float(self.alignment[1]),
                              "rotation_deg": float(np.degrees(self.alignment[2]))},
            "final_drift": {"position_m": self.drift_m, "percent_of_path": self.drift_pct,
                            "yaw_deg": self.drift_yaw_deg},
        })


def _warn_if_not_planar(traj: TumTrajectory) -> None:
    z = traj.positions[:, 2]
    q = unit_quaternions(traj.quaternions)
    # For a unit quaternion, |(qx, qy)| = sin(tilt / 2) whatever the yaw.
    tilt = 2.0 * np.arcsin(np.clip(np.hypot(q[:, 0], q[:, 1]), 0.0, 1.0)) if len(q) else np.zeros(0)
    if not len(z):
        return
    found = ([f"z varies by {np.ptp(z):.3g} m"] if np.ptp(z) > _PLANAR_Z_TOL_M else []) \
        + ([f"roll/pitch reach {np.degrees(tilt.max()):.3g} deg"] if tilt.max() > _PLANAR_TILT_TOL_RAD else [])
    if found:
        log.warning("%s: %s; the evaluation is planar and ignores them", traj.source or "a trajectory",
                    " and ".join(found))


def evaluate(est: TumTrajectory, ref: TumTrajectory, *, delta_m: float = 1.0,
             max_diff: float = 0.01, warn_planar: bool = True) -> EvaluationResult:
    """Compare the estimate *est* with the reference *ref* (see the module text).

    *delta_m* is the path length (m) of the per-distance RPE; *max_diff* the
    largest time difference (s) of two associated poses.  *warn_planar*: warn when either
    trajectory leaves the plane (once is enough for several estimates of one ground truth).
    """
    if not (is_number(delta_m) and delta_m > 0 and math.isfinite(delta_m)):
        raise EvaluationError(f"delta_m must be a distance > 0 m, got {delta_m!r}")
    est_m, ref_m = associate(est, ref, max_diff)
    for traj in (est_m, ref_m) if warn_planar else ():
        _warn_if_not_planar(traj)
    p_ref, p_est = ref_m.se2(), est_m.se2()
    n = len(p_ref)

    frame_pairs = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    rpe_frame, yaw_err = relative_error(p_ref, p_est, frame_pairs)
    rpe_dist, _ = relative_error(p_ref, p_est, distance_pairs(p_ref[:, :2], delta_m))
    if not len(rpe_dist.pairs):
        log.warning("the reference path (%.3g m) is shorter than %g m: no RPE per distance",
                    path_steps(p_ref[:, :2]).sum(), delta_m)

    alignment = umeyama_se2(p_est[:, :2], p_ref[:, :2])
    est_umeyama = se2_compose(alignment, p_est)
    first = se2_compose(p_ref[0], se2_inverse(p_est[0]))
    return EvaluationResult(
        est_source=est.source, ref_source=ref.source, est_poses=len(est), ref_poses=len(ref),
        max_diff_s=float(max_diff), delta_m=float(delta_m),
        times=ref_m.times - ref_m.times[0], ref=p_ref, est=p_est,
        est_umeyama=est_umeyama, est_first_pose=se2_compose(first, p_est), alignment=alignment,
        rpe_frame=rpe_frame, rpe_distance=rpe_dist, yaw_error_deg=np.degrees(yaw_err),
        ate_m=np.hypot(*(est_umeyama[:, :2] - p_ref[:, :2]).T))
