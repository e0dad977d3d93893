"""The point map's search for a frame's turn (``point_yaw``, docs/heading.md item 31): the turns
tried, the (point, map point) pairs that can score at any of them, each pair's score at a turn
from five terms worked out once, and the climb that scores the grid coarse first, then fine about
the best.  Arrays in, arrays out: :class:`~.point_yaw.PointYaw` holds the map and the state."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .angles import wrap

#: Map points further than this many of their largest standard deviation from where a point can
#: lie are left out of its likelihood (see :func:`pairs_within_reach`).
_REACH_SIGMAS = 6.0

#: The most (turn, pair) exponents :meth:`PairScore.at` holds at once (32 MB of each array): a
#: crowded frame's pairs are scored a run of points at a time, which sums each point's the same.
_CHUNK_ELEMENTS = 1 << 22


def search_grid(search_rad: float, step_rad: float) -> np.ndarray:
    """The turns tried about the predicted one: every *step_rad* within *search_rad*, rad."""
    return np.arange(-search_rad, search_rad + 0.5 * step_rad, step_rad)


def climb(score_at: Callable[[np.ndarray], np.ndarray], prior: np.ndarray,
          coarse: int) -> tuple[np.ndarray, int]:
    """The scores (T,) on a grid of T turns where computed (-inf elsewhere) and the index of the
    best score plus *prior* (T,): every *coarse* turn first (counted from the grid's middle, the
    predicted turn, and both ends: a score rising to an edge is no peak), then every turn within
    *coarse* of the best of those.  That best is inside the fine window (its edges are coarse
    turns it beat) unless it is the grid's edge, so its two neighbours are scored, for the
    parabola.  A point's likelihood spans degrees of turn (``bearing_noise_rad``), so a coarse
    grid of a fraction of that finds the peak a full one would at a fraction of the cost, all but
    where two peaks score nearly the same.  *score_at* gives the scores at an index array."""
    score = np.full(len(prior), -np.inf)
    if coarse <= 1:
        score[:] = score_at(np.arange(len(prior)))
        return score, int(np.argmax(score + prior))
    grid = np.union1d(np.arange((len(prior) - 1) // 2 % coarse, len(prior), coarse), [0, len(prior) - 1])
    score[grid] = score_at(grid)
    centre = int(grid[np.argmax(score[grid] + prior[grid])])
    fine = np.arange(max(centre - coarse, 0), min(centre + coarse, len(prior) - 1) + 1)
    todo = fine[np.isneginf(score[fine])]
    score[todo] = score_at(todo)
    return score, int(fine[np.argmax(score[fine] + prior[fine])])


def pairs_within_reach(xy: np.ndarray, origin: np.ndarray, yaw: float, centres: np.ndarray,
                       sigma: np.ndarray, search_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """The (point, map point) pairs, as two index arrays sorted by point, that can score at some
    turn searched: a point at *xy* (n, 2) m from the sensor at *origin* (2,) m, turned by *yaw*
    (rad) give or take *search_rad*, sweeps an arc about it; map points at *centres* (m, 2)
    m further from that arc than ``_REACH_SIGMAS`` of their largest standard deviation *sigma*
    (m,) m add less than exp(-18) to its likelihood, and are left out (a long map's points are
    mostly far from any one point)."""
    reach = _REACH_SIGMAS * sigma
    rho = np.hypot(xy[:, 0], xy[:, 1])
    offset = centres - origin
    distance = np.hypot(offset[:, 0], offset[:, 1])  # (m,)
    # The pairs within reach in range first (most of a long map's are not), then in bearing.
    point, near = np.nonzero(np.abs(distance - rho[:, None]) <= reach)
    gap = wrap(np.arctan2(offset[:, 1], offset[:, 0])[near] - (yaw + np.arctan2(xy[:, 1], xy[:, 0]))[point])
    # Points on a circle at angles apart are at least 2/pi of the smaller radius times the angle apart.
    beyond = (np.abs(gap) - search_rad) * np.minimum(rho[point], distance[near]) * (2.0 / math.pi)
    inside = beyond <= reach[near]
    return point[inside], near[inside]


class PairScore:
    """The log-likelihood of a frame's static points under the map at any turn, from their
    (point, map point) pairs (:func:`pairs_within_reach`).

    A pair's Mahalanobis distance at yaw t is e W e with e = d + R(t) p (d the sensor's position
    less the map point's, p the point in the sensor's axes, W the map point's inverse covariance):
    a constant plus terms in cos t, sin t, cos 2t and sin 2t, whose five coefficients a pair
    computes once, so each turn tried costs five products a pair rather than the rotation and the
    quadratic form."""

    def __init__(self, xy: np.ndarray, origin: np.ndarray, centres: np.ndarray, inverse: np.ndarray,
                 point: np.ndarray, near: np.ndarray, floor: float, log_weight: np.ndarray | None = None) -> None:
        p = xy[point]  # (pairs, 2) m
        jp = np.stack([-p[:, 1], p[:, 0]], 1)  # p turned a quarter
        d = origin - centres[near]  # (pairs, 2) m
        w = inverse[near]  # (pairs, 2, 2) m^-2
        w00, w01, w11 = w[:, 0, 0], w[:, 0, 1], w[:, 1, 1]

        def form(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # a W b of each pair (W symmetric)
            return a[:, 0] * (w00 * b[:, 0] + w01 * b[:, 1]) + a[:, 1] * (w01 * b[:, 0] + w11 * b[:, 1])

        pwp, jwj = form(p, p), form(jp, jp)
        # Times -1/2: the Gaussian's exponent, (5, pairs).
        self._terms = -0.5 * np.stack([form(d, d) + 0.5 * (pwp + jwj), 2.0 * form(d, p), 2.0 * form(d, jp),
                                       0.5 * (pwp - jwj), form(p, jp)])
        if log_weight is not None:  # each map point's weight (``density_weighted``), in its constant
            self._terms[0] += log_weight[near]
        self._n = len(xy)
        counts = np.bincount(point, minlength=self._n)
        self._has = np.flatnonzero(counts)  # the points with pairs, and where their pairs start
        self._starts = np.concatenate([[0], np.cumsum(counts)[:-1]])[self._has]
        self._floor = floor  # a point's likelihood at the least (``outlier_sigmas``)

    def at(self, yaws: np.ndarray) -> np.ndarray:
        """The score (T,) at each sensor yaw in *yaws* (T,) rad: each point's log of its pairs'
        likelihood sum, at least the outlier's, summed over the points."""
        k = self._terms
        c, s = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
        c2, s2 = np.cos(2.0 * yaws)[:, None], np.sin(2.0 * yaws)[:, None]
        likelihood = np.zeros((len(yaws), self._n))  # (T, n)
        pairs, budget = k.shape[1], _CHUNK_ELEMENTS // max(len(yaws), 1)
        first = 0  # the first point of the run, of those with pairs
        while first < len(self._starts):
            # The run's points, whole, up to the budget's pairs (one point's at the least).
            last = max(int(np.searchsorted(self._starts, self._starts[first] + budget, side="right")), first + 1)
            a, b = self._starts[first], (self._starts[last] if last < len(self._starts) else pairs)
            t = k[:, a:b]
            exponent = t[0] + c * t[1] + s * t[2] + c2 * t[3] + s2 * t[4]  # (T, run's pairs)
            likelihood[:, self._has[first:last]] = np.add.reduceat(np.exp(exponent), self._starts[first:last] - a,
                                                                  axis=1)
            first = last
        return np.log(np.maximum(likelihood, self._floor)).sum(axis=1)
