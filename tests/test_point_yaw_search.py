"""The point map's search (``point_yaw``, heading.md item 31): each (point, map point) pair's score
at a turn from five terms worked out once, and the turns searched coarse first, then fine about the
best, against the plain sums and the full grid."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_point_yaw import _map_and_frame

from radarodom.estimator import point_search


def _room():
    """A room's points' map and a frame's points in it: the part, the points (n, 2) m, the map's
    centres and inverse covariances, the sensor's position, the pairs within reach and the turns."""
    rng = np.random.default_rng(8)
    part, xy = _map_and_frame(rng, 40, 5.0, (0.03, 0.01), (1.2, 0.4, math.radians(30.0)), 2.0, 6.0, 12)
    centres, inverse, sigma = part.map.arrays()
    origin = np.array([1.5, 0.2])
    point, near = point_search.pairs_within_reach(xy, origin, 0.5, centres, sigma, math.radians(8.0))
    return part, xy, centres, inverse, origin, point, near, 0.5 + np.radians(np.linspace(-8.0, 8.0, 33))


def test_a_pairs_score_at_any_turn_is_its_points_rotated_under_the_maps_gaussians():
    # The score's five per-pair terms against the rotation and quadratic form written out, on a
    # room's map: the same at every turn, to rounding.
    part, xy, centres, inverse, origin, point, near, yaws = _room()
    score = point_search.PairScore(xy, origin, centres, inverse, point, near, part._floor).at(yaws)
    expected = []
    for yaw in yaws:
        c, s = math.cos(yaw), math.sin(yaw)
        e = origin + xy[point] @ np.array([[c, s], [-s, c]]) - centres[near]  # (pairs, 2) m
        likelihood = np.zeros(len(xy))
        np.add.at(likelihood, point, np.exp(-0.5 * np.einsum("pi,pij,pj->p", e, inverse[near], e)))
        expected.append(np.log(np.maximum(likelihood, math.exp(-0.5 * part._config.outlier_sigmas ** 2))).sum())
    assert 0 < len(point) and np.ptp(score) > 1.0
    assert score == pytest.approx(np.array(expected), rel=1e-9, abs=1e-9)


def test_a_crowded_frames_pairs_are_scored_in_runs_of_points_to_the_same_figures(monkeypatch):
    # A frame of many points near the same map points makes (turns x pairs) exponents that took
    # gigabytes at once: scored a run of whole points at a time, each point's sum and so the score
    # are the same to the last bit, runs of one point (the budget below one point's pairs) too.
    part, xy, centres, inverse, origin, point, near, yaws = _room()
    whole = point_search.PairScore(xy, origin, centres, inverse, point, near, part._floor).at(yaws)
    assert len(point) * len(yaws) < point_search._CHUNK_ELEMENTS  # one run as shipped
    for budget in (len(yaws) * len(point) // 3, len(yaws) * 5, 1):
        monkeypatch.setattr(point_search, "_CHUNK_ELEMENTS", budget)
        scores = point_search.PairScore(xy, origin, centres, inverse, point, near, part._floor)
        assert scores.at(yaws).tolist() == whole.tolist(), budget
        # No turn asked (the climb's fine window all scored already): no score, in runs or not.
        assert scores.at(yaws[:0]).shape == (0,)


def _score_calls(values):
    """A score over a grid given by *values* (T,), and the indices it was asked for, in order."""
    asked = []

    def score_at(i):
        asked.extend(i.tolist())
        return values[i]
    return score_at, asked


@pytest.mark.parametrize("peak", [0, 3, 57, 100, 159, 160])
def test_the_coarse_then_fine_search_finds_a_single_peak_anywhere_scoring_a_fraction(peak):
    # One smooth peak on 161 turns (the prior flat): every fifth turn, then about the best, finds
    # the full grid's best wherever it lies (at either edge too, which the caller rejects), and the
    # turns either side of it are scored for the parabola, each turn at most once.
    values = -((np.arange(161) - peak) / 20.0) ** 2
    score_at, asked = _score_calls(values)
    score, best = point_search.climb(score_at, np.zeros(161), 5)
    assert best == peak
    assert all(np.isfinite(score[max(best - 1, 0):best + 2]))
    assert len(asked) == len(set(asked)) and len(asked) < 50
    assert score[asked] == pytest.approx(values[asked]) and np.isneginf(np.delete(score, asked)).all()
    full, everywhere = point_search.climb(score_at, np.zeros(161), 1)
    assert everywhere == peak and full == pytest.approx(values)


def test_the_coarse_then_fine_search_weighs_the_prior_as_the_full_one_does():
    # Two equal peaks: the prior about the middle picks the nearer, as on the full grid; off the
    # coarse grid (peaks at 62 and 108) too.
    for low, high in ((60, 110), (62, 108)):
        twin = np.maximum(-((np.arange(161) - low) / 5.0) ** 2, -((np.arange(161) - high) / 5.0) ** 2)
        prior = -0.5 * ((np.arange(161) - 80) / 40.0) ** 2
        score_at, _ = _score_calls(twin)
        assert point_search.climb(score_at, prior, 5)[1] == point_search.climb(score_at, prior, 1)[1] == low


@pytest.mark.parametrize("size", [161, 163, 164, 167])
def test_the_coarse_grid_holds_both_ends_and_the_predicted_turn_whatever_the_grid_size(size):
    # A score still rising at the search's high edge (no peak: look_beyond's cue) is found there on
    # a grid whose last turn is no multiple of the coarse step from the first, as the full grid
    # finds it; and the middle turn (the prediction) is a coarse one.
    rising = np.arange(size) / 10.0
    score_at, asked = _score_calls(rising)
    assert point_search.climb(score_at, np.zeros(size), 5)[1] == size - 1
    assert {0, (size - 1) // 2, size - 1} <= set(asked)
    falling = -rising
    score_at, _ = _score_calls(falling)
    assert point_search.climb(score_at, np.zeros(size), 5)[1] == 0
