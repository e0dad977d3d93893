"""Planar ego-velocity from the Doppler of one point cloud (paper III-A).

A static reflector seen from a sensor moving with velocity v has radial
velocity v_r = -v . u (u the unit vector to it; docs/conventions.md).  In the body
frame (x forward, y left) with bearing b = -azimuth_TI and elevation el,

    -v_r / cos(el) = cos(b) vx + sin(b) vy,

a line in (vx, vy) per point.  RANSAC over pairs of points finds the largest
set that agrees (the static world), least squares on it refines the answer
(each point weighted by its radial velocity's error, its bearing's included),
and its residuals give the covariance.  Moving objects are the outliers.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from .config_velocity import VelocityConfig
from .quality import TextEnum

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

class VelocityStatus(TextEnum):
    """Why a velocity is what it is."""

    OK = "ok"
    #: Most points stand still: the sensor does.
    ZERO = "zero_velocity"
    FEW_POINTS = "few_points"
    #: The inliers' azimuths are too few or too clustered to tell vx from vy.
    ILL_CONDITIONED = "ill_conditioned"
    #: No hypothesis gathered ``min_inlier_ratio`` of the points.
    NO_CONSENSUS = "no_consensus"
    #: The largest consensus moves faster than ``max_accel_mps2`` allows since the last
    #: velocity, and none of the points it leaves makes one that does not.
    IMPLAUSIBLE = "implausible"


OK, ZERO, FEW_POINTS = VelocityStatus.OK, VelocityStatus.ZERO, VelocityStatus.FEW_POINTS
ILL_CONDITIONED, NO_CONSENSUS = VelocityStatus.ILL_CONDITIONED, VelocityStatus.NO_CONSENSUS
IMPLAUSIBLE = VelocityStatus.IMPLAUSIBLE


@dataclass
class VelocityEstimate:
    """The sensor's planar velocity in its body frame (REP-103) at time ``t``."""

    t: float
    vx: float = 0.0  # m/s forward
    vy: float = 0.0  # m/s left
    #: 2x2 covariance of (vx, vy), m^2/s^2.
    covariance: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))
    n_points: int = 0
    inliers: int = 0
    status: VelocityStatus = FEW_POINTS
    #: Per input point: True for the inliers (the static world), (n,).
    inlier_mask: np.ndarray | None = field(default=None, repr=False)
    #: What vx was scaled by for points whose elevation is not measured (:mod:`.level_speed`;
    #: 1: as fitted).
    level_scale: float = 1.0

    @property
    def ok(self) -> bool:
        return self.status in (OK, ZERO)

    @property
    def inlier_ratio(self) -> float:
        return self.inliers / self.n_points if self.n_points else 0.0

    @property
    def velocity(self) -> np.ndarray:
        return np.array([self.vx, self.vy])

    @property
    def level_velocity(self) -> np.ndarray:
        """The fit as if every point were level, (2,) m/s: :attr:`velocity` before ``level_scale``."""
        return np.array([self.vx / self.level_scale, self.vy])


def design(azimuth_rad: np.ndarray, elevation_rad: np.ndarray, velocity_mps: np.ndarray,
           projection: str = "divide") -> tuple[np.ndarray, np.ndarray]:
    """The linear model of the module docstring: rows (n, 2) and right-hand sides (n,).

    *azimuth_rad* is in the TI sensor frame (positive to the right), as the DSP gives it.
    """
    bearing = -np.asarray(azimuth_rad, dtype=float)
    rows = np.stack([np.cos(bearing), np.sin(bearing)], axis=1)
    rhs = -np.asarray(velocity_mps, dtype=float)
    cos_el = np.cos(np.asarray(elevation_rad, dtype=float))
    if projection == "divide":
        rhs = rhs / cos_el
    elif projection == "paper":
        rhs = rhs * cos_el
    return rows, rhs


def _least_squares(rows: np.ndarray, rhs: np.ndarray, normal: np.ndarray,
                   weight: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Solution, inverse normal matrix and residual variance of rows @ v = rhs, given the
    (well-conditioned) normal matrix rows^T rows; with *weight* (n,), weighted least squares,
    *normal* then rows^T W rows and the variance the weighted residuals'."""
    inverse = _inverse(normal)
    v = inverse @ ((rows if weight is None else rows * weight[:, None]).T @ rhs)
    residual = rhs - rows @ v
    squares = float(residual @ residual if weight is None else weight @ (residual * residual))
    return v, inverse, squares / max(len(rhs) - 2, 1)


def _condition(normal: np.ndarray) -> float:
    """2-norm condition number of a symmetric positive semi-definite 2x2 matrix, inf when
    singular: its eigenvalues written out (np.linalg.cond's SVD cost more than the fit)."""
    a, b, c = float(normal[0, 0]), float(normal[0, 1]), float(normal[1, 1])
    mean, radius = 0.5 * (a + c), math.hypot(0.5 * (a - c), b)
    low = mean - radius
    return (mean + radius) / low if low > 0.0 else math.inf


def _inverse(normal: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric non-singular 2x2 matrix, written out."""
    a, b, c = float(normal[0, 0]), float(normal[0, 1]), float(normal[1, 1])
    return np.array([[c, -b], [-b, a]]) / (a * c - b * b)


@dataclass(frozen=True)
class ReachableVelocity:
    """The velocities the platform can have now: within *reach_mps* of *velocity* (2,) m/s (the
    last one measured), ``max_accel_mps2`` times the time since it plus its noise."""

    velocity: np.ndarray
    reach_mps: float

    def reaches(self, velocity: np.ndarray) -> bool:
        return math.hypot(*(velocity - self.velocity)) <= self.reach_mps

    def explains(self, rows: np.ndarray, rhs: np.ndarray, threshold_mps: float) -> np.ndarray:
        """Which points of the model (rows (n, 2), rhs (n,)) some reachable velocity explains
        to *threshold_mps*: a unit row moves a point's value by at most the reach."""
        return np.abs(rows @ self.velocity - rhs) <= self.reach_mps + threshold_mps


def estimate_velocity(points: np.ndarray, t: float, config: VelocityConfig, rng: np.random.Generator,
                      expected: ReachableVelocity | None = None) -> VelocityEstimate:
    """RANSAC + least squares on a point cloud with fields azimuth, elevation (rad) and
    velocity (m/s, positive receding), like :data:`radarodom.dsp.processor.POINT_DTYPE`.
    Given the *expected* velocities, a consensus outside them is refused for the largest
    inside them (status ``implausible`` when there is none).

    Never raises for bad data: an ill-posed cloud gives an estimate whose ``status`` says
    why and whose ``ok`` is False.
    """
    n_all = len(points)
    keep = np.abs(points["elevation"]) <= config.max_elevation_rad if n_all else np.zeros(0, bool)
    rows, rhs = design(points["azimuth"][keep], points["elevation"][keep], points["velocity"][keep],
                       config.elevation_projection)
    n = len(rhs)
    out = VelocityEstimate(t=t, n_points=n, inlier_mask=np.zeros(n_all, bool))
    if n < 2:
        return out

    # Standing still: most of the world has zero Doppler, whatever the azimuths.  A still
    # sensor sees few detections (the whole static world falls in one Doppler bin), so a
    # handful of points all at zero Doppler is enough to say so.
    still = np.abs(rhs) < config.zero_velocity_threshold_mps
    if still.mean() >= (config.zero_velocity_ratio if n >= config.min_points else 1.0):
        if not _well_conditioned(rows[still], config):
            # Zero Doppler from one direction only: sideways motion would look the same.
            out.status, out.inliers = ILL_CONDITIONED, int(still.sum())
            return out
        out.status, out.inliers = ZERO, int(still.sum())
        out.covariance = _zero_covariance(rows[still], config)
        out.inlier_mask[np.flatnonzero(keep)[still]] = True
        return out

    if n < config.min_points:
        return out
    needed = max(config.min_points, config.min_inlier_ratio * n)
    found = _consensus_fit(rows, rhs, np.ones(n, bool), needed, config, rng)
    if expected is not None and found.status == OK and not expected.reaches(found.fit[0]):
        # The largest consensus is one the platform cannot have reached since the last velocity
        # (people walking past a robot that sees a handful of points): the static world is among
        # the points a reachable velocity explains.
        among = expected.explains(rows, rhs, config.inlier_threshold_mps)
        found = _consensus_fit(rows, rhs, among, needed, config, rng)
        if found.status != OK or not expected.reaches(found.fit[0]):
            found.status = IMPLAUSIBLE
    out.inliers = int(found.inliers.sum())
    if found.status != OK:
        out.status = found.status
        return out
    v, inverse, sigma2 = found.fit
    # The Doppler grid quantises every measurement: the residual variance never drops
    # below the bin's uniform-quantisation variance, whatever few points agree.
    sigma2 = max(sigma2, config.inlier_threshold_mps ** 2 / 12.0)
    out.vx, out.vy = float(v[0]), float(v[1])
    out.covariance = sigma2 * inverse
    out.inlier_mask[np.flatnonzero(keep)[found.inliers]] = True
    out.status = OK
    return out


@dataclass
class _Consensus:
    """What :func:`_consensus_fit` found: its status, the inliers (n,) bool, and for OK the
    least-squares fit (velocity (2,) m/s, inverse normal matrix, residual variance)."""

    status: VelocityStatus
    inliers: np.ndarray
    fit: tuple[np.ndarray, np.ndarray, float] | None = None


def _consensus_fit(rows: np.ndarray, rhs: np.ndarray, among: np.ndarray, needed: float, config: VelocityConfig,
                   rng: np.random.Generator) -> _Consensus:
    """RANSAC on the points *among* (n,) bool, then least squares on the consensus and up to
    twice more on the points each fit explains (while they are at least *needed*)."""
    subset = np.flatnonzero(among)
    inliers = np.zeros(len(rhs), bool)
    if len(subset) < needed:
        return _Consensus(NO_CONSENSUS, inliers)
    chosen = _ransac(rows[subset], rhs[subset], config, rng)
    if chosen is not None:
        inliers[subset[chosen]] = True
    if chosen is None or inliers.sum() < needed:
        return _Consensus(NO_CONSENSUS, inliers)
    fit = _fit(rows, rhs, inliers, config)
    for _ in range(2):
        if fit is None:
            break
        refined = np.abs(rows @ fit[0] - rhs) < config.inlier_threshold_mps
        if refined.sum() < needed:
            break
        inliers = refined
        fit = _fit(rows, rhs, inliers, config)
    return _Consensus(OK if fit is not None else ILL_CONDITIONED, inliers, fit)


def _fit(rows: np.ndarray, rhs: np.ndarray, inliers: np.ndarray,
         config: VelocityConfig) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Least squares on *inliers*, or None when their bearings cannot tell vx from vy."""
    rows, rhs = rows[inliers], rhs[inliers]
    normal = rows.T @ rows
    if len(rows) < 2 or _condition(normal) > config.max_condition:
        return None
    fit = _least_squares(rows, rhs, normal)
    if config.bearing_noise_rad > 0.0:
        fit = _weighted_by_bearing(rows, rhs, fit[0], config)
    return fit


def _weighted_by_bearing(rows: np.ndarray, rhs: np.ndarray, v: np.ndarray,
                         config: VelocityConfig) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`_least_squares` again, each row weighted by the inverse of its
    right-hand side's variance at the velocity *v* (2,) m/s: the Doppler's own and the bearing's
    error times d(rhs)/d(bearing) = vy cos(b) - vx sin(b) (rows are (cos b, sin b)).  The weights
    are scaled to a mean of one: the residual variance is then a point of average weight's, in
    m^2/s^2, and the quantisation floor of :func:`estimate_velocity` applies to it."""
    slope = rows[:, 0] * v[1] - rows[:, 1] * v[0]
    weight = 1.0 / (config.doppler_noise_mps ** 2 + (slope * config.bearing_noise_rad) ** 2)
    weight /= weight.mean()
    return _least_squares(rows, rhs, (rows * weight[:, None]).T @ rows, weight)


def _well_conditioned(rows: np.ndarray, config: VelocityConfig) -> bool:
    if len(rows) < 2:
        return False
    return _condition(rows.T @ rows) <= config.max_condition


def _zero_covariance(rows: np.ndarray, config: VelocityConfig) -> np.ndarray:
    """Covariance of a zero-velocity decision: the threshold's spread over the points."""
    sigma2 = config.zero_velocity_threshold_mps ** 2 / 3.0
    normal = rows.T @ rows
    if np.linalg.cond(normal) > 1e12:
        return np.eye(2) * sigma2
    return sigma2 * np.linalg.inv(normal) * len(rows) / max(len(rows) - 2, 1)


def _ransac(rows: np.ndarray, rhs: np.ndarray, config: VelocityConfig,
            rng: np.random.Generator) -> np.ndarray | None:
    """Inlier mask (n,) of the best two-point hypothesis, or None if all were degenerate."""
    n = len(rhs)
    m = config.ransac_iterations
    i = rng.integers(0, n, m)
    j = (i + rng.integers(1, n, m)) % n  # a second, different point
    a11, a12, a21, a22 = rows[i, 0], rows[i, 1], rows[j, 0], rows[j, 1]
    det = a11 * a22 - a12 * a21  # sin of the bearing difference
    good = np.abs(det) > math.sin(math.radians(3.0))
    if not good.any():
        return None
    det, i, j = det[good], i[good], j[good]
    vx = (rhs[i] * a22[good] - rhs[j] * a12[good]) / det
    vy = (rhs[j] * a11[good] - rhs[i] * a21[good]) / det
    residual = np.abs(rows @ np.stack([vx, vy]) - rhs[:, None])  # (n, hypotheses)
    within = residual < config.inlier_threshold_mps
    counts = within.sum(axis=0)
    # Among the largest consensus sets, the one that fits them most tightly.
    best = np.flatnonzero(counts == counts.max())
    if len(best) > 1:
        best = best[np.argmin(np.where(within[:, best], residual[:, best], 0.0).sum(axis=0))]
    else:
        best = best[0]
    return within[:, best]
