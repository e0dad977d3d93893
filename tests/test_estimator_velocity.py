"""Doppler ego-velocity (paper III-A; estimator/velocity.py) on synthetic point clouds.

Conventions pinned here (docs/conventions.md): points are in the TI sensor frame (azimuth
positive to the right), radial velocity is positive receding and a static point seen
from a sensor moving at v has v_r = -v . u; the estimate is in the body frame
(REP-103: vx forward, vy left).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from estimator_synth import points, points_polar
from hypothesis import given, settings
from hypothesis import strategies as st
from radarodom.dsp.processor import POINT_DTYPE
from radarodom.estimator import velocity as vel
from radarodom.estimator.config import EstimatorConfig, VelocityConfig
from radarodom.estimator.velocity import estimate_velocity

#: The AWR1843's Doppler bin in the project's usual configuration, m/s.
DOPPLER_BIN = 0.07


def estimate(cloud, config: VelocityConfig | None = None, seed: int = 0, t: float = 1.0):
    return estimate_velocity(cloud, t, config or VelocityConfig(), np.random.default_rng(seed))


def spread_bearings(n: int, rng: np.random.Generator, half_width_deg: float = 60.0) -> np.ndarray:
    return np.radians(rng.uniform(-half_width_deg, half_width_deg, n))


def raw_points(azimuth, velocity, elevation=0.0) -> np.ndarray:
    """POINT_DTYPE by hand (no helper), to pin the conventions independently."""
    out = np.zeros(len(azimuth), POINT_DTYPE)
    out["azimuth"] = azimuth
    out["elevation"] = elevation
    out["velocity"] = velocity
    return out


# --------------------------------------------------------------------------- signs
def test_forward_motion_sees_approaching_points_ahead():
    # Moving forward at 1 m/s: points ahead approach (negative radial velocity), those at
    # +/- 60 degrees approach at half the speed.
    az = np.radians([-60.0, -30.0, 0.0, 0.0, 30.0, 60.0])
    cloud = raw_points(az, -np.cos(az))
    est = estimate(cloud)
    assert est.status == vel.OK and est.ok
    assert est.vx == pytest.approx(1.0, abs=1e-6)
    assert est.vy == pytest.approx(0.0, abs=1e-6)


def test_leftward_motion_sees_left_points_approaching():
    # Moving left (body +y) at 0.5 m/s: points on the left have negative TI azimuth and
    # approach; points on the right recede.
    az = np.radians([-70.0, -45.0, -20.0, 20.0, 45.0, 70.0])
    cloud = raw_points(az, -0.5 * np.sin(-az))
    assert np.all(cloud["velocity"][az < 0] < 0) and np.all(cloud["velocity"][az > 0] > 0)
    est = estimate(cloud)
    assert est.ok
    assert est.vx == pytest.approx(0.0, abs=1e-6)
    assert est.vy == pytest.approx(0.5, abs=1e-6)


def test_helper_follows_the_conventions():
    # The synthetic helper agrees with the hand-built convention: a point 30 degrees to the
    # body's left is at TI azimuth -30 degrees, x_TI < 0.
    p = points(np.array([[math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0]]), (1.0, 0.0))
    assert p["azimuth"][0] == pytest.approx(math.radians(-30.0), abs=1e-6)
    assert p["x"][0] < 0 and p["y"][0] > 0
    assert p["velocity"][0] == pytest.approx(-math.cos(math.radians(30)), abs=1e-6)


@pytest.mark.parametrize("v", [(1.0, 0.0), (0.0, 0.6), (-0.8, 0.3), (1.5, -1.2), (0.2, 0.05), (-2.0, -2.0)])
def test_exact_recovery_of_body_velocity(v):
    rng = np.random.default_rng(1)
    cloud = points_polar(spread_bearings(60, rng), 0.0, v, range_m=rng.uniform(1, 10, 60))
    est = estimate(cloud)
    assert est.status == vel.OK
    assert est.vx == pytest.approx(v[0], abs=1e-6)
    assert est.vy == pytest.approx(v[1], abs=1e-6)
    assert est.n_points == 60 and est.inliers == 60 and est.inlier_ratio == 1.0
    assert est.inlier_mask.dtype == bool and est.inlier_mask.all()
    np.testing.assert_allclose(est.velocity, v, atol=1e-6)
    assert est.t == 1.0


def test_design_rows_are_body_bearings():
    rows, rhs = vel.design(np.radians([30.0]), np.radians([0.0]), np.array([-0.5]))
    # TI azimuth +30 (right) is body bearing -30.
    np.testing.assert_allclose(rows, [[math.cos(math.radians(-30)), math.sin(math.radians(-30))]])
    np.testing.assert_allclose(rhs, [0.5])


# --------------------------------------------------------------------------- elevation
def test_elevation_divide_projection_is_exact_others_are_not():
    rng = np.random.default_rng(2)
    n = 80
    v = (1.2, -0.4)
    el = np.radians(rng.uniform(-35.0, 35.0, n))
    cloud = points_polar(spread_bearings(n, rng), el, v, range_m=rng.uniform(1, 8, n))
    errors = {}
    for projection in ("divide", "paper", "none"):
        est = estimate(cloud, VelocityConfig(elevation_projection=projection, inlier_threshold_mps=0.5))
        assert est.ok, projection
        errors[projection] = float(np.hypot(est.vx - v[0], est.vy - v[1]))
    assert errors["divide"] < 1e-6
    assert errors["paper"] > 0.02
    assert errors["none"] > 0.02


def test_points_above_max_elevation_are_not_used():
    rng = np.random.default_rng(3)
    n = 30
    low = points_polar(spread_bearings(n, rng), 0.0, (1.0, 0.0))
    # High points with nonsense Doppler: if they were used, the fit would suffer.
    high = points_polar(spread_bearings(n, rng), math.radians(60.0), (1.0, 0.0),
                        radial_velocity=rng.uniform(-3, 3, n))
    cloud = np.concatenate([low, high])
    est = estimate(cloud, VelocityConfig(max_elevation_rad=math.radians(40.0)))
    assert est.ok and est.n_points == n
    assert est.vx == pytest.approx(1.0, abs=1e-6) and est.vy == pytest.approx(0.0, abs=1e-6)
    assert est.inlier_mask.shape == (2 * n,)
    assert est.inlier_mask[:n].all() and not est.inlier_mask[n:].any()


# --------------------------------------------------------------------------- robustness
@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("moving_share", [0.2, 0.4])
def test_robust_to_moving_points(seed, moving_share):
    rng = np.random.default_rng(100 + seed)
    n = 120
    v = rng.uniform(-1.5, 1.5, 2)
    b = spread_bearings(n, rng, 65.0)
    el = rng.uniform(-0.2, 0.2, n)
    static_truth = -np.cos(el) * (v[0] * np.cos(b) + v[1] * np.sin(b))
    moving = np.zeros(n, bool)
    moving[rng.choice(n, round(moving_share * n), replace=False)] = True
    radial = np.where(moving, rng.uniform(-3.0, 3.0, n), static_truth)
    radial = DOPPLER_BIN * np.round((radial + 0.01 * rng.standard_normal(n)) / DOPPLER_BIN)
    cloud = points_polar(b, el, (0.0, 0.0), radial_velocity=radial)
    est = estimate(cloud, seed=seed)
    assert est.status == vel.OK
    assert abs(est.vx - v[0]) < 0.03 and abs(est.vy - v[1]) < 0.03, (est.vx, est.vy, v)
    # The inlier mask is the static world (plus the odd mover that happens to agree).
    assert est.inlier_mask[~moving].mean() > 0.95
    agreeing = np.abs(radial - static_truth) < 2 * VelocityConfig().inlier_threshold_mps
    assert not np.any(est.inlier_mask & moving & ~agreeing)
    assert est.inliers == int(est.inlier_mask.sum())
    assert est.inlier_ratio == pytest.approx(est.inliers / n)


def test_coherent_moving_object_is_rejected():
    # 35 % of the points belong to one object moving with its own velocity (a person walking
    # across): a consistent second "world" that RANSAC must not choose.
    rng = np.random.default_rng(7)
    n_static, n_obj = 65, 35
    v = (0.8, 0.0)
    b_static = spread_bearings(n_static, rng)
    b_obj = np.radians(rng.uniform(-10.0, 10.0, n_obj))
    obj_v = np.array([0.8, 0.0]) - np.array([0.0, 1.5])  # relative velocity of the object's points
    static = points_polar(b_static, 0.0, v, quantum=DOPPLER_BIN, noise_mps=0.01, rng=rng)
    obj = points_polar(b_obj, 0.0, obj_v, quantum=DOPPLER_BIN, noise_mps=0.01, rng=rng)
    est = estimate(np.concatenate([static, obj]))
    assert est.ok
    assert abs(est.vx - v[0]) < 0.03 and abs(est.vy - v[1]) < 0.03
    assert est.inlier_mask[:n_static].mean() > 0.95


def _handful_with_a_person(rng: np.random.Generator) -> tuple[np.ndarray, tuple[float, float]]:
    """What TI's demo gives a robot at 0.8 m/s with a person walking past: 3 static points and
    4 of the person, who makes the larger consensus (2.8 m/s ahead)."""
    v = (0.8, 0.0)
    static = points_polar(np.radians([-40.0, 5.0, 45.0]), 0.0, v, quantum=DOPPLER_BIN)
    person = points_polar(np.radians(rng.uniform(-25.0, 25.0, 4)), 0.0, (2.8, 0.0), quantum=DOPPLER_BIN)
    return np.concatenate([static, person]), v


def test_a_velocity_the_platform_cannot_reach_is_refused_for_the_static_points():
    cloud, v = _handful_with_a_person(np.random.default_rng(21))
    config = VelocityConfig(min_points=3)
    alone = estimate(cloud, config)
    assert alone.ok and alone.vx == pytest.approx(2.8, abs=0.1)  # the person wins without the gate
    # 0.1 s after 0.8 m/s at 5 m/s^2: within 0.5 m/s (plus the last one's noise) of it.
    expected = vel.ReachableVelocity(np.array(v), 5.0 * 0.1 + 0.05)
    est = estimate_velocity(cloud, 1.0, config, np.random.default_rng(0), expected)
    assert est.status == vel.OK
    assert np.hypot(est.vx - v[0], est.vy - v[1]) < 0.1
    np.testing.assert_array_equal(est.inlier_mask, [True] * 3 + [False] * 4)
    assert est.inliers == 3


def test_only_unreachable_points_give_an_implausible_velocity():
    rng = np.random.default_rng(22)
    cloud = points_polar(spread_bearings(8, rng), 0.0, (2.8, 0.0), quantum=DOPPLER_BIN)
    expected = vel.ReachableVelocity(np.array([0.8, 0.0]), 0.55)
    est = estimate_velocity(cloud, 1.0, VelocityConfig(), np.random.default_rng(0), expected)
    assert est.status == vel.IMPLAUSIBLE and not est.ok
    # A consensus within reach is not refitted: the same answer as without the gate.
    near = vel.ReachableVelocity(np.array([2.6, 0.0]), 0.55)
    assert estimate_velocity(cloud, 1.0, VelocityConfig(), np.random.default_rng(0), near).vx == estimate(cloud).vx


def test_zero_velocity():
    rng = np.random.default_rng(4)
    n = 80
    cloud = points_polar(spread_bearings(n, rng), 0.0, (0.0, 0.0), quantum=DOPPLER_BIN, noise_mps=0.01, rng=rng)
    est = estimate(cloud)
    assert est.status == vel.ZERO and est.ok
    assert est.vx == 0.0 and est.vy == 0.0
    assert np.all(np.isfinite(est.covariance))
    assert np.all(np.linalg.eigvalsh(est.covariance) > 0)
    np.testing.assert_array_equal(est.inlier_mask, np.abs(cloud["velocity"]) < 0.04)


def test_zero_velocity_with_moving_people():
    rng = np.random.default_rng(5)
    n = 100
    radial = np.zeros(n)
    radial[:25] = rng.uniform(0.5, 2.0, 25) * rng.choice([-1, 1], 25)
    cloud = points_polar(spread_bearings(n, rng), 0.0, (0.0, 0.0), radial_velocity=radial,
                         quantum=DOPPLER_BIN, noise_mps=0.01, rng=rng)
    est = estimate(cloud)
    assert est.ok
    assert abs(est.vx) < 0.03 and abs(est.vy) < 0.03
    assert not est.inlier_mask[:25].any()


def test_slow_motion_is_not_taken_for_standing_still():
    # 0.2 m/s forward is three Doppler bins ahead: not zero.
    rng = np.random.default_rng(6)
    cloud = points_polar(spread_bearings(80, rng, 45.0), 0.0, (0.2, 0.0), quantum=DOPPLER_BIN,
                         noise_mps=0.005, rng=rng)
    est = estimate(cloud)
    assert est.status == vel.OK
    assert est.vx == pytest.approx(0.2, abs=0.03)


# --------------------------------------------------------------------------- refusals
@pytest.mark.parametrize("n", [0, 1, 4])
def test_few_points(n):
    rng = np.random.default_rng(8)
    cloud = points_polar(spread_bearings(n, rng), 0.0, (1.0, 0.0))
    est = estimate(cloud)
    assert est.status == vel.FEW_POINTS and not est.ok
    assert est.vx == 0.0 and est.vy == 0.0
    assert est.inlier_mask.shape == (n,) and not est.inlier_mask.any()
    assert est.inliers == 0 and est.inlier_ratio == 0.0


@pytest.mark.parametrize("azimuths_deg", [[20.0], [20.0, 21.5], [-40.0, -37.0, -35.0]])
def test_points_at_one_azimuth_are_refused(azimuths_deg):
    # The Doppler of points along one (or nearly one) bearing tells only one component of
    # the velocity: the answer must be a refusal, never a confident wrong velocity.
    rng = np.random.default_rng(9)
    n = 60
    b = np.radians(rng.choice(azimuths_deg, n) + rng.uniform(-0.3, 0.3, n))
    cloud = points_polar(b, 0.0, (1.0, 0.5), quantum=DOPPLER_BIN, noise_mps=0.01, rng=rng)
    est = estimate(cloud)
    assert est.status in (vel.ILL_CONDITIONED, vel.NO_CONSENSUS)
    assert not est.ok


@pytest.mark.parametrize("n", [3, 40])
def test_sideways_motion_seen_only_ahead_is_not_standing_still(n):
    rng = np.random.default_rng(15)
    b = np.radians(rng.uniform(-1.5, 1.5, n))
    cloud = points_polar(b, 0.0, (0.0, 1.0), quantum=DOPPLER_BIN)
    est = estimate(cloud)
    assert not (est.ok and np.hypot(est.vx, est.vy - 1.0) > 0.5), (est.status, est.vx, est.vy)


def test_no_consensus_among_random_velocities():
    rng = np.random.default_rng(10)
    n = 60
    cloud = points_polar(spread_bearings(n, rng), 0.0, (0.0, 0.0), radial_velocity=rng.uniform(-4, 4, n))
    est = estimate(cloud)
    assert est.status == vel.NO_CONSENSUS and not est.ok


@settings(max_examples=60)
@given(centre=st.floats(-60.0, 60.0), width=st.floats(0.0, 25.0), n=st.integers(5, 60),
       vx=st.floats(-2.0, 2.0), vy=st.floats(-2.0, 2.0), seed=st.integers(0, 2 ** 16))
def test_never_a_confident_wrong_answer(centre, width, n, vx, vy, seed):
    """Whatever the spread of bearings: either a refusal, or an answer whose covariance
    covers its error."""
    rng = np.random.default_rng(seed)
    b = np.radians(centre + rng.uniform(-width / 2, width / 2, n))
    cloud = points_polar(b, 0.0, (vx, vy), quantum=DOPPLER_BIN, noise_mps=0.01, rng=rng)
    est = estimate(cloud, seed=seed)
    assert np.isfinite(est.vx) and np.isfinite(est.vy)
    if est.status == vel.OK:
        err = np.array([est.vx - vx, est.vy - vy])
        # Mahalanobis distance of the error under the reported covariance (6 sigma, plus a
        # little for the quantisation's systematic part).
        m2 = float(err @ np.linalg.inv(est.covariance + np.eye(2) * 1e-4) @ err)
        assert m2 < 36.0, (est, vx, vy)


# --------------------------------------------------------------------------- bearing errors
def _cloud_with_merged_returns(v):
    """Points every 2 degrees over +/- 60 at velocity *v*, five of those beyond 40 degrees to the
    right reporting their bearing 5 degrees further out (two returns merged in one beam)."""
    bearing = np.radians(np.linspace(-60.0, 60.0, 61))
    cloud = points_polar(bearing, 0.0, v)
    off = np.flatnonzero(np.degrees(bearing) < -40.0)[::2]
    cloud["azimuth"][off] += math.radians(5.0)  # TI azimuth: positive to the right
    return cloud


def test_bearing_errors_mislead_the_weighted_fit_less():
    # A radar ahead of a wheeled base's axis in a moving turn: its sideways speed is its yaw rate.
    v = (0.8, 0.24)
    cloud = _cloud_with_merged_returns(v)
    plain = estimate(cloud, VelocityConfig(bearing_noise_rad=0.0))
    weighted = estimate(cloud)
    assert plain.ok and weighted.ok and weighted.inliers == plain.inliers == len(cloud)
    assert abs(plain.vy - v[1]) > 0.01  # the plain fit's sideways speed is 6 % off
    assert abs(weighted.vy - v[1]) < 0.6 * abs(plain.vy - v[1])
    assert abs(weighted.vx - v[0]) < abs(plain.vx - v[0])


def test_the_paper_and_ti_demo_presets_fit_unweighted():
    # The paper's fit is plain least squares; TI's demo's 6-12 points a frame on its angle bins need
    # the points across the motion (docs/tidemo.md).
    cloud = _cloud_with_merged_returns((0.8, 0.24))
    plain = estimate(cloud, VelocityConfig(bearing_noise_rad=0.0))
    for config in (EstimatorConfig.paper(), EstimatorConfig.tidemo()):
        est = estimate(cloud, config.velocity)
        assert (est.vx, est.vy) == (plain.vx, plain.vy)


def test_weighted_fit_is_weighted_least_squares():
    # The weighted fit, and its covariance, against weighted least squares written out here (the
    # noise above the covariance's floor, and within the inlier threshold).
    rng = np.random.default_rng(21)
    v = (0.8, 0.24)
    cloud = points_polar(np.radians(rng.uniform(-60.0, 60.0, 40)), 0.0, v, noise_mps=0.05, rng=rng)
    config = VelocityConfig(inlier_threshold_mps=0.12)
    est = estimate(cloud, config)
    assert est.ok and est.inliers == len(cloud)
    rows, rhs = vel.design(cloud["azimuth"], cloud["elevation"], cloud["velocity"])
    plain = np.linalg.lstsq(rows, rhs, rcond=None)[0]
    slope = rows[:, 0] * plain[1] - rows[:, 1] * plain[0]  # d(rhs)/d(bearing)
    w = 1.0 / (config.doppler_noise_mps ** 2 + (slope * config.bearing_noise_rad) ** 2)
    w = w / w.mean()
    normal = (rows * w[:, None]).T @ rows
    solution = np.linalg.solve(normal, (rows * w[:, None]).T @ rhs)
    residual = rhs - rows @ solution
    sigma2 = float(w @ residual ** 2) / (len(rhs) - 2)
    assert sigma2 > config.inlier_threshold_mps ** 2 / 12.0
    np.testing.assert_allclose(est.velocity, solution, atol=1e-12)
    np.testing.assert_allclose(est.covariance, sigma2 * np.linalg.inv(normal), rtol=1e-9)


def test_weighted_covariance_matches_the_spread_under_bearing_errors():
    rng = np.random.default_rng(22)
    v = np.array([0.8, 0.0])
    errors, reported = [], []
    for _ in range(300):
        cloud = points_polar(np.radians(rng.uniform(-60.0, 60.0, 60)), 0.0, tuple(v), noise_mps=0.02, rng=rng)
        cloud["azimuth"] += np.radians(rng.normal(0.0, 4.0, len(cloud))).astype(np.float32)
        est = estimate(cloud)
        assert est.ok
        errors.append(est.velocity - v)
        reported.append(est.covariance)
    ratio = np.diag(np.cov(np.array(errors).T)) / np.diag(np.mean(reported, axis=0))
    assert np.all((ratio > 0.6) & (ratio < 1.6)), ratio


@pytest.mark.parametrize("noise_deg", [0.0, 1.0, 4.0, 10.0])
def test_weights_do_not_bias_consistent_points(noise_deg):
    v = (0.6, -0.35)
    cloud = points_polar(np.radians(np.linspace(-70.0, 70.0, 50)), 0.0, v)
    est = estimate(cloud, VelocityConfig(bearing_noise_rad=math.radians(noise_deg)))
    assert est.ok
    np.testing.assert_allclose(est.velocity, v, atol=1e-9)


# --------------------------------------------------------------------------- covariance
def test_covariance_positive_definite_and_shrinks_with_more_points():
    rng = np.random.default_rng(11)
    v = (0.7, 0.2)
    covs = []
    for n in (15, 60, 240):
        cloud = points_polar(spread_bearings(n, rng), 0.0, v, noise_mps=0.03, rng=rng)
        est = estimate(cloud)
        assert est.ok
        c = est.covariance
        np.testing.assert_allclose(c, c.T, atol=1e-15)
        assert np.all(np.linalg.eigvalsh(c) > 0)
        covs.append(np.trace(c))
    assert covs[0] > covs[1] > covs[2]
    assert covs[0] / covs[2] > 6.0  # about 16 for 16 times the points


def test_covariance_matches_the_spread_of_estimates():
    rng = np.random.default_rng(12)
    v = np.array([1.0, -0.3])
    # Noise above the covariance's floor (the quantisation variance it assumes, threshold^2 / 12)
    # and well inside the inlier threshold.
    n, trials, noise = 40, 150, 0.035
    errors, reported = [], []
    for _ in range(trials):
        cloud = points_polar(spread_bearings(n, rng), 0.0, tuple(v), noise_mps=noise, rng=rng)
        est = estimate(cloud, VelocityConfig(inlier_threshold_mps=0.12))
        assert est.ok
        errors.append(est.velocity - v)
        reported.append(est.covariance)
    empirical = np.cov(np.array(errors).T)
    mean_reported = np.mean(reported, axis=0)
    ratio = np.diag(empirical) / np.diag(mean_reported)
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio


# --------------------------------------------------------------------------- reproducibility
def test_same_seed_same_result():
    rng = np.random.default_rng(13)
    n = 100
    radial = rng.uniform(-3, 3, n)
    b = spread_bearings(n, rng)
    static = points_polar(b, 0.0, (0.9, 0.4), quantum=DOPPLER_BIN, noise_mps=0.01, rng=rng)
    radial[:60] = static["velocity"][:60]
    cloud = points_polar(b, 0.0, (0.0, 0.0), radial_velocity=radial)
    a = estimate(cloud, seed=42)
    b_ = estimate(cloud, seed=42)
    assert (a.vx, a.vy, a.inliers, a.status) == (b_.vx, b_.vy, b_.inliers, b_.status)
    np.testing.assert_array_equal(a.covariance, b_.covariance)
    np.testing.assert_array_equal(a.inlier_mask, b_.inlier_mask)


def test_input_is_not_modified():
    rng = np.random.default_rng(14)
    cloud = points_polar(spread_bearings(30, rng), 0.1, (1.0, 0.0), quantum=DOPPLER_BIN)
    before = cloud.copy()
    estimate(cloud)
    np.testing.assert_array_equal(cloud, before)
