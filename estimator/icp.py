"""Rotation-only weighted ICP with the paper's sampling, one way or both (mwICP).

The translation between two heatmap frames is known from the Doppler velocity
(the previous frame's features are rectified, paper eq. 3), so only a rotation
R about the sensor is left: ``y = R x`` maps source points x onto target
points y.  Correspondences use the paper's polar error (eq. 4)

    e_ij = alpha (r_i - r_j)^2 + beta (theta_i - theta_j)^2

and each source point is, by its smallest error (eq. 5): removed (e_min >
eps_max), neglected for this iteration (e_min < eps_min, or outside the
target's region of interest) or matched.  The weighted rotation is the SVD
solution of eq. 6.  :func:`register_rotation` is one registration (pure, no
state); :func:`register_two_way` averages previous->current and
current->previous.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .angles import wrap
from .config import IcpConfig
from .config_limits import search_reach
from .features import Features
from .log_heatmap import LogHeatmap
from .quality import TextEnum



class RegistrationStatus(TextEnum):
    """How a registration ended."""

    OK = "ok"
    #: Fewer matched pairs than ``min_matches``: no rotation.
    FEW_MATCHES = "few_matches"
    #: ``iterations`` ran out before the rotation settled; the best rotation found stands.
    NOT_CONVERGED = "not_converged"


OK, FEW_MATCHES, NOT_CONVERGED = RegistrationStatus.OK, RegistrationStatus.FEW_MATCHES, RegistrationStatus.NOT_CONVERGED


@dataclass
class Region:
    """Where the target can see: range and body-frame bearing limits, m and rad."""

    min_range_m: float
    max_range_m: float
    max_bearing_rad: float

    def contains(self, range_m: np.ndarray, bearing_rad: np.ndarray) -> np.ndarray:
        return self.in_range(range_m) & self.in_bearing(bearing_rad)

    def in_range(self, range_m: np.ndarray) -> np.ndarray:
        return (range_m >= self.min_range_m) & (range_m <= self.max_range_m)

    def in_bearing(self, bearing_rad: np.ndarray) -> np.ndarray:
        return np.abs(bearing_rad) <= self.max_bearing_rad


@dataclass
class Registration:
    """Result of one registration: ``y = R(rotation) x``."""

    rotation_rad: float
    iterations: int
    status: RegistrationStatus
    matches: int = 0
    removed: int = 0
    neglected: int = 0
    #: Variance of the rotation from the weighted angular residuals, rad^2.
    variance: float = math.inf

    @property
    def ok(self) -> bool:
        return self.status == OK


def rotation_svd(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    """The angle of the rotation R in SO(2) minimising sum w |y - R x|^2 (paper eq. 6):
    H = sum w x y^T = U D V^T, R = V U^T (a reflection is corrected to a rotation).
    x, y (n, 2); w (n,).  This is the reference; the ICP loop uses :func:`rotation_2d`."""
    h = (x * w[:, None]).T @ y
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    r = vt.T @ np.diag([1.0, d]) @ u.T
    return math.atan2(r[1, 0], r[0, 0])


def rotation_2d(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    """The same rotation as :func:`rotation_svd` in closed form: in SO(2) the SVD solution
    maximises tr(R^T H^T), whose maximiser is atan2(H01 - H10, H00 + H11) (no 2x2 SVD
    call per iteration: it costs more than the rest of the step)."""
    wx = x * w[:, None]
    h00, h01 = float(wx[:, 0] @ y[:, 0]), float(wx[:, 0] @ y[:, 1])
    h10, h11 = float(wx[:, 1] @ y[:, 0]), float(wx[:, 1] @ y[:, 1])
    return math.atan2(h01 - h10, h00 + h11)


def register_rotation(source: Features, target: Features, config: IcpConfig, *,
                      initial_rad: float = 0.0, region: Region | None = None) -> Registration:
    """Rotate *source* onto *target* (both in the same sensor position after rectification).

    With ``config.neglect_aligned`` (the paper) the aligned points (e_min < eps_min) sit
    out each step, which can make the iteration cycle; then the rotation of the cycle with
    the smallest mean error over all usable points is returned (status not_converged)."""
    if len(source) == 0 or len(target) == 0:
        return Registration(initial_rad, 0, FEW_MATCHES)
    rotation = float(initial_rad)
    xy_src = source.xy
    tgt_xy = target.xy
    sqrt_alpha, sqrt_beta = math.sqrt(config.alpha), math.sqrt(config.beta)
    # With sampling, points beyond eps_max are removed whatever their nearest target, so
    # only targets that near need be searched.
    nearest_of = _NearestTargets(sqrt_alpha * target.range_m, sqrt_beta * target.bearing_rad,
                                 sqrt_alpha * source.range_m,
                                 math.sqrt(config.eps_max) if config.sampling else math.inf)
    in_range = None if region is None else region.in_range(source.range_m)
    status, matched, removed, neglected = NOT_CONVERGED, 0, 0, 0
    iteration = 0
    pairs = None
    best = (math.inf, rotation, None)  # (mean error, rotation, pairs) of the best iterate
    for iteration in range(1, config.iterations + 1):
        bearing = wrap(source.bearing_rad + rotation)
        e_min, nearest = nearest_of(sqrt_beta * bearing)
        match, usable, aligned, removed = _sample(e_min, bearing, in_range, region, config)
        matched = int(np.count_nonzero(match))
        neglected = len(source) - removed - matched
        if matched < config.min_matches:
            # Fewer pairs to fit than needed: fine if that is because the rest sits on its
            # targets already, a failure if nothing usable is left.
            status = OK if aligned + matched >= config.min_matches else FEW_MATCHES
            break
        w_usable = source.weight[usable]
        error = float(w_usable @ e_min[usable]) / float(w_usable.sum())
        if error < best[0]:
            best = (error, rotation, pairs)
        y = tgt_xy[nearest[match]]
        w = source.weight[match]
        if config.weight == "product":
            w = w * target.weight[nearest[match]]
        # The whole rotation from the unturned source (eq. 6 on this iteration's pairs): the
        # same as turning the source by the current rotation and solving for the step.
        step = float(wrap(rotation_2d(xy_src[match], y, w) - rotation))
        rotation += step
        pairs = (match, nearest, w)
        if abs(step) < config.tolerance_rad:
            status = OK
            break
    if status == NOT_CONVERGED and config.sampling and best[2] is not None:
        _, rotation, pairs = best
    return Registration(rotation, iteration, status, matched, removed, neglected,
                        _variance(source, target, rotation, pairs))


class _NearestTargets:
    """Each source point's nearest target by the error of eq. 4 (squared distance in the
    polar space scaled by sqrt(alpha), sqrt(beta)), searched within *bound*.

    Rotation changes only the sources' bearings, so the targets within *bound* in range
    of each source (targets sorted by range, a band each) are listed once, with their
    squared range differences; a query is then a difference, a square and a minimum over
    each band (a k-d tree costs three times as much to build and query for a few hundred
    points).  Without a bound every band is every target.  Bearings are wrapped into
    [-pi, pi) and a radar sees a half-plane, so bearing differences need no wrapping."""

    def __init__(self, target_r: np.ndarray, target_b: np.ndarray, source_r: np.ndarray, bound: float) -> None:
        """Scaled target ranges and bearings (m,), scaled source ranges (n,), bound (scaled)."""
        order = np.argsort(target_r, kind="stable")
        sorted_r = target_r[order]
        lo = np.searchsorted(sorted_r, source_r - bound, "left")
        hi = np.searchsorted(sorted_r, source_r + bound, "right")
        width = int((hi - lo).max(initial=0))
        cand = lo[:, None] + np.arange(width)  # (n, width) into the sorted targets
        inside = cand < hi[:, None]
        cand = np.where(inside, cand, 0)  # padding: any target, at infinite error
        self._dr2 = np.where(inside, (source_r[:, None] - sorted_r[cand]) ** 2, np.inf)
        self._bearing = target_b[order][cand]
        self._index = order[cand]
        self._rows = np.arange(len(source_r))

    def __call__(self, source_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Smallest errors (n,) and the nearest targets' indices (n,), for scaled source
        bearings (n,).  Where no target is within the bound the error exceeds the bound's
        square (inf when no target is within it in range) and the index is meaningless."""
        if self._dr2.shape[1] == 0:
            return np.full(len(source_b), np.inf), np.zeros(len(source_b), np.intp)
        e = source_b[:, None] - self._bearing
        e *= e
        e += self._dr2
        best = e.argmin(axis=1)
        return e[self._rows, best], self._index[self._rows, best]


def _sample(e_min: np.ndarray, bearing: np.ndarray, in_range: np.ndarray | None, region: Region | None,
            config: IcpConfig) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The paper's sampling (eq. 5) of the source points by their smallest errors: which are
    matched and which usable (matched or aligned, for the mean error), both (n,) bool, and
    how many are aligned and how many removed.  The rest of the points are neglected."""
    if not config.sampling:
        every = np.ones(len(e_min), bool)
        return every, every, 0, 0
    usable = ~(e_min > config.eps_max)
    removed = len(e_min) - int(np.count_nonzero(usable))
    if region is not None:
        usable &= in_range
        usable &= region.in_bearing(bearing)
    aligned = usable & (e_min < config.eps_min)
    match = usable & ~aligned if config.neglect_aligned else usable
    return match, usable, int(np.count_nonzero(aligned)), removed


def _variance(source: Features, target: Features, rotation: float, pairs) -> float:
    """Weighted variance of the matched pairs' bearing residuals over their effective number."""
    if pairs is None:
        return math.inf
    match, nearest, w = pairs
    residual = wrap(source.bearing_rad[match] + rotation - target.bearing_rad[nearest[match]])
    w = w / w.sum()
    n_eff = 1.0 / float(w @ w)
    return float(w @ (residual * residual)) / max(n_eff - 1.0, 1.0)


def register_two_way(previous: Features, current: Features, config: IcpConfig, *,
                     initial_rad: float = 0.0, region: Region | None = None
                     ) -> tuple[Registration, Registration | None]:
    """previous->current and, with ``config.two_way``, current->previous (negated, so
    both estimate the same rotation).  Returns (combined, forward)."""
    forward = register_rotation(previous, current, config, initial_rad=initial_rad, region=region)
    if not config.two_way:
        return forward, forward
    backward = register_rotation(current, previous, config, initial_rad=-initial_rad, region=region)
    if forward.status != FEW_MATCHES and backward.status != FEW_MATCHES:
        mean = 0.5 * (forward.rotation_rad - backward.rotation_rad)
        spread = 0.25 * (forward.rotation_rad + backward.rotation_rad) ** 2
        variance = 0.25 * (forward.variance + backward.variance) + spread
        status = OK if forward.ok and backward.ok else NOT_CONVERGED
        return Registration(mean, forward.iterations + backward.iterations, status,
                            forward.matches + backward.matches, forward.removed + backward.removed,
                            forward.neglected + backward.neglected, variance), forward
    if forward.ok:
        return forward, forward
    if backward.ok:
        return Registration(-backward.rotation_rad, backward.iterations, OK, backward.matches,
                            backward.removed, backward.neglected, backward.variance), forward
    return forward, forward


def correlation_guess(previous_profile: np.ndarray, current_profile: np.ndarray, step_rad: float,
                      max_rad: float, centre_rad: float = 0.0) -> float | None:
    """Rotation (source -> target convention) that best aligns two azimuth power profiles
    sampled every *step_rad*: the shift s maximising the normalised correlation of
    previous(b) and current(b + s), searched over centre +/- max, refined by a parabola.
    None when the profiles share too little."""
    n = len(previous_profile)
    centre = int(round(centre_rad / step_rad))
    reach = int(math.ceil(max_rad / step_rad))
    shifts = np.arange(centre - reach, centre + reach + 1)
    scores = np.full(len(shifts), -np.inf)
    for i, s in enumerate(shifts):
        if abs(s) >= n // 2:
            continue
        a = previous_profile[max(0, -s):n - max(0, s)]
        b = current_profile[max(0, s):n - max(0, -s)]
        ok = np.isfinite(a) & np.isfinite(b)
        if ok.sum() < n // 4:
            continue
        a, b = a[ok] - a[ok].mean(), b[ok] - b[ok].mean()
        denom = math.sqrt(float(a @ a) * float(b @ b))
        if denom > 0:
            scores[i] = float(a @ b) / denom
    best = _peak(scores)
    return None if best is None else best * step_rad + shifts[0] * step_rad


def scan_guess(source: Features, target: LogHeatmap, step_rad: float, max_rad: float,
               centre_rad: float = 0.0, common_support: bool = False) -> tuple[float, float] | None:
    """Rotation (source -> target) that puts the rectified *source* points on the brightest
    part of the target heatmap: the maximum of the weighted mean log intensity sampled at
    the rotated points, searched over centre +/- max every *step_rad*, refined by a parabola
    (*common_support*: see :func:`_scores`).

    Returns (rotation, score), the score being that mean log intensity over the target's
    median (natural-log units: ~0 when the heatmaps hold only noise), or None when too
    few points stay inside the heatmap."""
    shifts = centre_rad + _offsets(max_rad, step_rad)
    scores = _scores(source, target, shifts, common_support)
    best = _peak_at(scores, shifts)
    return None if best is None else (best, float(np.max(scores)))


def score_back(target: Features, source: LogHeatmap, rotation_rad: float, translation: np.ndarray) -> float:
    """The scan score of *target*'s points taken back to the *source* frame (the inverse of a
    registration source -> target by *rotation_rad* after *translation*, (2,) m) on the source's
    log heatmap; -inf when fewer than a quarter of them fall inside it."""
    back = target.turned(-rotation_rad).shifted(-np.asarray(translation, dtype=float))
    return float(_scores(back, source, np.zeros(1))[0])


def _scores(source: Features, target: LogHeatmap, shifts: np.ndarray, common_support: bool = False) -> np.ndarray:
    """Weighted mean log intensity of *target* at the *source* points rotated by each of
    *shifts*, (len(shifts),); -inf where fewer than a quarter of the points fall inside.

    With *common_support* the mean is over the points inside the heatmap at every shift: a
    mean over the points inside at each shift rises where a shift turns weak points (those at
    the field of view's edge, where the antenna gain falls) out of the heatmap, which favours
    larger rotations (docs/heading.md, item 1)."""
    values, inside = target.sample_rotated(source.slant_m, source.bearing_rad, shifts, source.cos_elevation)
    weight = source.weight.astype(values.dtype)  # float32 values stay float32 (no upcast copy)
    if common_support:
        everywhere = inside.all(axis=0)
        enough = np.count_nonzero(everywhere) >= max(3, len(source) // 4)
        weight = weight * everywhere
        weighted = (values @ weight) / max(float(weight.sum()), 1e-30)
        return np.full(len(shifts), -np.inf) if not enough else weighted
    enough = np.count_nonzero(inside, axis=1) >= max(3, len(source) // 4)
    weighted = (values @ weight) / np.maximum(inside @ weight, 1e-30)
    return np.where(enough, weighted, -np.inf)


def field_rotation(source: Features, target: Features, source_field: LogHeatmap, target_field: LogHeatmap,
                   translation: np.ndarray, centre_rad: float, max_rad: float, step_rad: float,
                   common_support: bool = False) -> float | None:
    """Rotation (source -> target, ``y = R (x - translation)``) within centre +/- max that
    maximises the two-way likelihood field: the mean log intensity of *target_field* at the
    *source* points moved to the target's position and rotated, plus that of *source_field*
    at the *target* points taken back to the source's position; searched every *step_rad*,
    refined by a parabola.  No correspondences: nothing to mismatch along walls.  None when
    too few points fall inside the heatmaps.  *common_support*: see :func:`_scores`."""
    deltas = _offsets(max_rad, step_rad)
    forward = source.shifted(translation)
    # Back to the source: x = R(-centre) y + translation (a turn of the bearings, then the
    # sensor moved by -translation), then rotated by -delta.
    back = target.turned(-centre_rad).shifted(-np.asarray(translation, dtype=float))
    scores = (_scores(forward, target_field, centre_rad + deltas, common_support)
              + _scores(back, source_field, -deltas, common_support))
    best = _peak_at(scores, deltas)
    return None if best is None else centre_rad + best


def _offsets(max_rad: float, step_rad: float) -> np.ndarray:
    """A search grid every *step_rad* over +/- *max_rad* (at least one step each side), rad."""
    reach = search_reach(max_rad, step_rad)
    return step_rad * np.arange(-reach, reach + 1)


def _peak_at(scores: np.ndarray, grid: np.ndarray) -> float | None:
    """The value of *grid* at the (parabola-refined) maximum of *scores* over it, None if
    no score is finite."""
    best = _peak(scores)
    return None if best is None else float(np.interp(best, np.arange(len(grid)), grid))


def _peak(scores: np.ndarray) -> float | None:
    """Fractional index of the maximum of *scores* (a parabola through it and its
    neighbours), None if no score is finite."""
    best = int(np.argmax(scores))
    if not np.isfinite(scores[best]):
        return None
    if 0 < best < len(scores) - 1 and np.isfinite(scores[best - 1]) and np.isfinite(scores[best + 1]):
        left, mid, right = scores[best - 1], scores[best], scores[best + 1]
        curvature = left - 2 * mid + right
        if curvature < 0:
            return best + 0.5 * (left - right) / curvature
    return float(best)
