"""Estimator configuration (estimator/config.py) and streaming odometry
(estimator/odometry.py) on synthetic sequences.

A sequence is point reflectors in a world seen along a known trajectory
(tests/estimator_synth.py): each frame gives a TI-frame point cloud with the static
world's Doppler and an AWR1843-like range-azimuth heatmap.  Poses are the body frame
(REP-103) in the world frame = the body frame at the first frame (docs/conventions.md).
"""

from __future__ import annotations

import itertools
import json
import math

import estimator_synth as synth
import numpy as np
import pytest
from estimator_synth import (AZIMUTH_RAD, RANGE_M, SCENE_WORLD, Trajectory, blind_heatmap, points_polar,
                             run_sequence, scene_heatmap, static_cloud)
from radarodom.dsp.cfar import CfarParams
from radarodom.dsp.heatmap import RangeAzimuth
from radarodom.errors import ConfigError, TimeOrderError
from radarodom.estimator import config as config_mod
from radarodom.estimator import odometry as odo_mod
from radarodom.estimator.keyframe import ChainStep
from radarodom.estimator.velocity_track import VelocityHistory
from radarodom.estimator.yaw_measurement import CurrentFrame
from radarodom.estimator.yaw_rate import FilteredYaw, YawRateFilter
from radarodom.estimator.config import (
    EstimatorConfig,
    FeatureConfig,
    IcpConfig,
    OdometryConfig,
    VelocityConfig,
)
from radarodom.estimator.odometry import OdometryState, RadarOdometry
from radarodom.estimator.features import heatmap_doppler_points, strongest_points
from radarodom.estimator.velocity import VelocityEstimate, estimate_velocity

DEG = math.radians(1.0)


# =========================================================================== config
class TestConfig:
    def test_dump_load_round_trip(self, tmp_path):
        cfg = EstimatorConfig().with_(
            velocity={"seed": 7, "elevation_projection": "paper"},
            features={"method": "raymax", "max_range_m": 9.5, "weighting": "db"},
            icp={"two_way": False, "alpha": 50.0},
            odometry={"hold_s": 0.25, "velocity_sync": "nearest"})
        path = tmp_path / "est.json"
        cfg.dump(path)
        data = json.loads(path.read_text())
        assert data["features"]["max_range_m"] == 9.5 and data["icp"]["two_way"] is False
        assert isinstance(data["features"]["cfar"], dict)
        back = EstimatorConfig.load(path)
        assert back == cfg
        assert back.to_dict() == cfg.to_dict()

    @pytest.mark.parametrize("variant", [{}, {"method": "cfar"}, {"method": "raymax", "sampling": False},
                                         {"two_way": False}])
    def test_round_trip_of_paper_variants(self, tmp_path, variant):
        cfg = EstimatorConfig.paper(**variant)
        cfg.dump(tmp_path / "p.json")
        assert EstimatorConfig.load(tmp_path / "p.json") == cfg

    def test_default_round_trip_and_partial_file(self, tmp_path):
        EstimatorConfig().dump(tmp_path / "d.json")
        assert EstimatorConfig.load(tmp_path / "d.json") == EstimatorConfig()
        # A file may give only what it changes.
        (tmp_path / "part.json").write_text(json.dumps({"icp": {"iterations": 7}}))
        part = EstimatorConfig.load(tmp_path / "part.json")
        assert part.icp.iterations == 7
        assert part.features == EstimatorConfig().features

    def test_cfar_params_round_trip(self, tmp_path):
        cfg = EstimatorConfig().with_(features={"method": "cfar", "cfar": CfarParams(
            method="os", guard=1, train=6, pfa=1e-4)})
        cfg.dump(tmp_path / "c.json")
        back = EstimatorConfig.load(tmp_path / "c.json")
        assert back.features.cfar.method == "os" and back.features.cfar.pfa == 1e-4
        assert back == cfg

    @pytest.mark.parametrize("data,name", [
        ({"bogus": 1}, "bogus"),
        ({"icp": {"bogus": 1}}, "bogus"),
        ({"features": {"kk": 3}}, "kk"),
        ({"features": {"cfar": {"method": "ca", "guard": 1, "train": 4, "threshold_db": 10, "wat": 1}}}, "wat"),
    ])
    def test_unknown_keys(self, data, name):
        with pytest.raises(ConfigError, match=name):
            EstimatorConfig.from_dict(data)

    @pytest.mark.parametrize("section,fld,value", [
        ("velocity", "min_points", 1),
        ("velocity", "ransac_iterations", 0),
        ("velocity", "inlier_threshold_mps", 0.0),
        ("velocity", "min_inlier_ratio", 1.5),
        ("velocity", "zero_velocity_ratio", 0.0),
        ("velocity", "max_elevation_rad", 2.0),
        ("velocity", "bearing_noise_rad", -0.1),
        ("velocity", "bearing_noise_rad", 2.0),
        ("velocity", "doppler_noise_mps", 0.0),
        ("velocity", "max_condition", 1.0),
        ("velocity", "max_accel_mps2", 0.0),
        ("velocity", "elevation_projection", "multiply"),
        ("features", "method", "sift"),
        ("features", "k", 0),
        ("features", "min_range_m", -1.0),
        ("features", "max_range_m", 0.1),
        ("features", "max_azimuth_rad", 0.0),
        ("features", "weighting", "log"),
        ("features", "parallax", "height"),
        ("features", "dynamic_rejection_mps", 0.0),
        ("icp", "alpha", 0.0),
        ("icp", "beta", -1.0),
        ("icp", "eps_min", 30.0),
        ("icp", "iterations", 0),
        ("icp", "tolerance_rad", 0.0),
        ("icp", "min_matches", 0),
        ("icp", "weight", "target"),
        ("icp", "initial_guess", "imu"),
        ("icp", "max_rotation_rad", 0.0),
        ("icp", "max_rotation_rad", 100.0),  # beyond half a turn: 82 degrees after four frames
        ("icp", "field_search_rad", 4.0),
        ("icp", "scan_step_rad", 1e-7),  # its grid took 24 GB
        ("icp", "field_step_rad", 1e-300),
        ("icp", "field_smoothing_bins", 1e300),  # scipy could not size its kernel
        ("icp", "field_window", "scan"),
        ("velocity", "seed", -1),
        ("point_yaw", "step_rad", 1e-300),
        ("point_yaw", "relocate_step_rad", 1e-6),
        ("point_yaw", "search_rad", 7.0),
        ("point_yaw", "gap_widen_rad", 1e5),
        ("point_yaw", "relocate_widen_rad", 1e300),
        ("odometry", "keyframe_search_rad", 1e5),  # 16.6 GiB for its scan grid
        ("odometry", "yaw_manoeuvre_accel_std_radps2", 0.1),  # not above yaw_accel_std_radps2
        ("odometry", "hold_s", -0.1),
        ("odometry", "min_features", 1),
        ("odometry", "velocity_sync", "spline"),
        ("odometry", "keyframe_start", "icp"),
        ("odometry", "keyframe_noise_rad", 0.0),
        ("odometry", "velocity_fallback", "zero"),
        ("odometry", "fallback_cells", 1),
    ])
    def test_bad_values_name_the_field(self, tmp_path, section, fld, value):
        with pytest.raises(ConfigError) as exc:
            EstimatorConfig.from_dict({section: {fld: value}})
        assert exc.value.field == f"{section}.{fld}"  # the path a user finds in the file
        assert f"{section}.{fld}" in str(exc.value)
        # From a file: the error also names the file.
        path = tmp_path / "bad.json"
        path.write_text(json.dumps({section: {fld: value}}))
        with pytest.raises(ConfigError) as exc:
            EstimatorConfig.load(path)
        assert exc.value.field == f"{section}.{fld}" and str(path) in str(exc.value)

    def test_unreadable_file(self, tmp_path):
        path = tmp_path / "broken.json"
        path.write_text("{ not json")
        with pytest.raises(ConfigError, match="broken.json"):
            EstimatorConfig.load(path)
        path.write_text("[1, 2]")
        with pytest.raises(ConfigError):
            EstimatorConfig.load(path)
        with pytest.raises(ConfigError):
            EstimatorConfig.load(tmp_path / "missing.json")

    @pytest.mark.parametrize("data,fld", [({"velocity": 5}, "velocity"), ({"features": {"k": 2.5}}, "features.k"),
                                          ({"features": {"k": "many"}}, "features.k")])
    def test_wrong_types_name_the_field(self, data, fld):
        with pytest.raises(ConfigError) as exc:
            EstimatorConfig.from_dict(data)
        assert exc.value.field == fld

    def test_with_replaces_and_validates(self):
        base = EstimatorConfig()
        new = base.with_(icp={"two_way": False, "iterations": 3}, features={"k": 50})
        assert new.icp.two_way is False and new.icp.iterations == 3 and new.features.k == 50
        assert base.icp.two_way == EstimatorConfig().icp.two_way  # the original is untouched
        assert base.features.k == 200
        assert new.velocity == base.velocity and new.odometry == base.odometry
        with pytest.raises(ConfigError) as exc:
            base.with_(features={"k": 0})
        assert exc.value.field == "features.k"
        with pytest.raises(ConfigError, match="nonsense"):
            base.with_(nonsense={"k": 1})

    def test_with_unknown_field(self):
        with pytest.raises(ConfigError, match="bogus"):
            EstimatorConfig().with_(icp={"bogus": 1})

    @pytest.mark.parametrize("method", config_mod.FEATURE_METHODS)
    @pytest.mark.parametrize("sampling", [True, False])
    @pytest.mark.parametrize("two_way", [True, False])
    def test_paper_variants(self, method, sampling, two_way):
        cfg = EstimatorConfig.paper(method=method, sampling=sampling, two_way=two_way)
        assert cfg.features.method == method
        assert cfg.icp.sampling is sampling and cfg.icp.two_way is two_way
        # Nothing beyond the paper.
        assert cfg.icp.initial_guess == "zero"
        assert cfg.features.peaks_only is False and cfg.features.subbin is False
        assert cfg.features.dynamic_rejection_mps is None
        assert cfg.odometry.velocity_fallback == "hold" and cfg.odometry.bridge_s == 0.0
        assert cfg.velocity.elevation_projection in config_mod.PROJECTIONS
        assert cfg.velocity.bearing_noise_rad == 0.0
        assert cfg.features.k == 200

    def test_paper_default_is_topk_sampling_mwicp(self):
        cfg = EstimatorConfig.paper()
        assert (cfg.features.method, cfg.icp.sampling, cfg.icp.two_way) == ("topk", True, True)
        with pytest.raises(ConfigError):
            EstimatorConfig.paper(method="orb")

    def test_defaults_beyond_the_paper(self):
        # The measured best combination (docs/estimator.md): the heatmap's Doppler stands in for a failed
        # point-cloud velocity.
        odo = EstimatorConfig().odometry
        assert odo.velocity_fallback == "heatmap" and odo.fallback_cells == 50

    def test_sections_construct_alone(self):
        for cls in (VelocityConfig, FeatureConfig, IcpConfig, OdometryConfig):
            obj = cls()
            assert cls.from_dict(obj.to_dict()) == obj


# =========================================================================== helpers
def empty_heatmap() -> RangeAzimuth:
    z = np.zeros((len(RANGE_M), len(AZIMUTH_RAD)), np.float32)
    return RangeAzimuth(z, z, np.full_like(z, np.nan), RANGE_M.copy(), AZIMUTH_RAD.copy())


def few_points_cloud() -> np.ndarray:
    return points_polar(np.radians([10.0, 20.0]), 0.0, (1.0, 0.0))


def finite_state(s: OdometryState) -> bool:
    values = [s.x, s.y, s.yaw, s.vx, s.vy, s.yaw_rate, s.yaw_increment, s.compute_s]
    return (all(math.isfinite(v) for v in values) and np.all(np.isfinite(s.pose_covariance))
            and np.all(np.isfinite(s.twist_covariance)))


#: A configuration pinned for the trajectory test (not the moving default): the paper's
#: method plus the options that make it work on an 8-element array.
TRAJECTORY_CONFIG = EstimatorConfig.paper().with_(
    features={"peaks_only": True, "subbin": True, "dynamic_rejection_mps": 0.15},
    icp={"initial_guess": "constant_rate"})

STRAIGHT_ARC_TURN = Trajectory([(3.0, 1.0, 0.0), (3.0, 1.0, 20 * DEG), (3.0, 0.0, 30 * DEG)])


# =========================================================================== odometry
@pytest.fixture(scope="module")
def run():
    return run_sequence(TRAJECTORY_CONFIG, STRAIGHT_ARC_TURN)


class TestTrajectory:
    def test_follows_the_trajectory(self, run):
        states, truths = run
        path = STRAIGHT_ARC_TURN.path_length()
        end, truth = states[-1], truths[-1]
        assert math.hypot(end.x - truth[0], end.y - truth[1]) < 0.03 * path
        assert abs(end.yaw - truth[2]) < 5 * DEG
        # Every step along the way stays close too (never a jump, never a flipped sign).
        for s, (x, y, yaw) in zip(states, truths):
            assert math.hypot(s.x - x, s.y - y) < 0.05 * path
            assert abs(s.yaw - yaw) < 6 * DEG

    def test_phases(self, run):
        states, _ = run
        # After the straight phase (3 s at 1 m/s): 3 m ahead, no turn.
        s = states[30]
        assert s.x == pytest.approx(3.0, abs=0.1) and abs(s.y) < 0.1 and abs(s.yaw) < 1.5 * DEG
        assert s.vx == pytest.approx(1.0, abs=0.03) and abs(s.vy) < 0.03
        # In the arc (turning left, counter-clockwise): y grows, yaw rate about +20 deg/s.
        arc = states[35:58]
        assert np.median([a.yaw_rate for a in arc]) == pytest.approx(20 * DEG, abs=2 * DEG)
        assert states[58].y > 1.0
        # Turning in place at 30 deg/s: no translation, positive yaw rate.
        turn = states[62:]
        assert np.median([a.yaw_rate for a in turn]) == pytest.approx(30 * DEG, abs=3 * DEG)
        assert math.hypot(turn[-1].x - turn[0].x, turn[-1].y - turn[0].y) < 0.05
        assert all(abs(a.vx) < 0.05 and abs(a.vy) < 0.05 for a in turn)

    def test_first_state_and_bookkeeping(self, run):
        states, _ = run
        first = states[0]
        assert first.flags == (odo_mod.FIRST_FRAME,) and first.ok
        assert (first.x, first.y, first.yaw, first.frame) == (0.0, 0.0, 0.0, 0)
        assert [s.frame for s in states] == list(range(len(states)))
        assert all(finite_state(s) for s in states)
        assert all(s.compute_s > 0 for s in states)
        assert all(s.features > 0 for s in states)
        for a, b in itertools.pairwise(states):
            assert b.t > a.t
            assert b.yaw == pytest.approx(a.yaw + b.yaw_increment, abs=1e-12)
            assert b.yaw_rate == pytest.approx(b.yaw_increment / (b.t - a.t), rel=1e-9)
        # The pose covariance grows along the way.
        traces = [np.trace(s.pose_covariance) for s in states]
        assert traces[0] == 0.0 and traces[-1] > traces[10] > 0
        assert all(np.all(np.linalg.eigvalsh(s.pose_covariance) > -1e-12) for s in states)

    def test_world_frame_is_the_first_body_frame(self):
        # The same motion started somewhere else in the world, facing elsewhere, gives the
        # same odometry: it is relative to the first frame.
        short = Trajectory([(1.0, 1.0, 0.0), (1.0, 1.0, 20 * DEG)])
        a, truth = run_sequence(TRAJECTORY_CONFIG, short, seed=3)
        b, _ = run_sequence(TRAJECTORY_CONFIG, short, seed=3, start_pose=(4.0, -2.0, 1.2))
        for sa, sb in zip(a, b):
            assert sb.x == pytest.approx(sa.x, abs=0.02)
            assert sb.y == pytest.approx(sa.y, abs=0.02)
            assert sb.yaw == pytest.approx(sa.yaw, abs=0.5 * DEG)
        assert a[-1].x == pytest.approx(truth[-1][0], abs=0.06)
        assert a[-1].y == pytest.approx(truth[-1][1], abs=0.06)

    @pytest.mark.xfail(strict=True, reason="LIMITATION of the paper's method (Top-k cells, sampling "
                       "+ mwICP, zero initial guess) loses the yaw on this sensor's heatmaps once the "
                       "sensor both moves and turns: in a 1 m/s, 20 deg/s arc it measures about 0.2 "
                       "deg per frame instead of 2 (tens of degrees of yaw error)")
    def test_paper_method_follows_the_trajectory(self):
        states, truths = run_sequence(EstimatorConfig.paper(), STRAIGHT_ARC_TURN)
        assert abs(states[-1].yaw - truths[-1][2]) < 5 * DEG

    # With the default's bound on the yaw-rate filter's lag (1 degree, docs/heading.md item 36) this
    # sequence (150 degrees in all) ends 2.3 degrees off with keyframes and 1.6 frame to frame alone;
    # unbounded, 1.2 and -0.7.  Bounded, the heading is 0.9 degrees ahead at the arc's end (0.2
    # unbounded) and the turn in place adds 1.45 (1.0): a LIMITATION, the bounded heading turns a
    # percent and a half long on these point reflectors (why less unbounded was not measured).
    @pytest.mark.parametrize(("keyframes", "tolerance_deg"), [
        pytest.param(0.5, 3.0, id="default"),
        pytest.param(0.0, 3.0, id="no-keyframes"),
    ])
    def test_default_config_follows_the_trajectory(self, keyframes, tolerance_deg):
        cfg = EstimatorConfig().with_(odometry={"keyframe_distance_m": keyframes})
        states, truths = run_sequence(cfg, STRAIGHT_ARC_TURN)
        assert abs(states[-1].yaw - truths[-1][2]) < tolerance_deg * DEG
        assert all(finite_state(s) for s in states)

    def test_the_keyframes_paying_the_filters_lag_follows_the_trajectory(self):
        # keyframe_pays_lag (the default: docs/heading.md, item 36), unbounded and with the default's
        # bound of a degree on the filter's lag: the heading still follows, and the option changes it
        # (on this sequence by little: the end 2.35 -> 2.34 degrees off with the bound; what it does
        # is tested on the filter, test_a_keyframes_correction_toward_the_lag_is_not_given_again).
        unpaid = EstimatorConfig().with_(odometry={"keyframe_pays_lag": False, "yaw_filter_max_lag_rad": None})
        before, _ = run_sequence(unpaid, STRAIGHT_ARC_TURN)
        for extra, tolerance_deg in (({"yaw_filter_max_lag_rad": None}, 2.0), ({}, 3.0)):
            cfg = EstimatorConfig().with_(odometry={"keyframe_pays_lag": True, **extra})
            states, truths = run_sequence(cfg, STRAIGHT_ARC_TURN)
            assert abs(states[-1].yaw - truths[-1][2]) < tolerance_deg * DEG
            assert any(a.yaw != b.yaw for a, b in zip(states, before))


class TestFlags:
    def test_first_frame_flag_and_velocity(self):
        odom = RadarOdometry(EstimatorConfig())
        s = odom.step(0.0, static_cloud((0.5, 0.1)), scene_heatmap())
        assert s.flags == (odo_mod.FIRST_FRAME,)
        assert s.vx == pytest.approx(0.5, abs=1e-5) and s.vy == pytest.approx(0.1, abs=1e-5)
        assert odom.state is s

    def test_few_features(self):
        # More features required than a frame can give: flagged; the field fallback (default)
        # measures the yaw around the scan guess: no turn (test_field_fallback_when_icp_fails
        # has the held rate without it).
        cfg = EstimatorConfig().with_(odometry={"min_features": 10000})
        odom = RadarOdometry(cfg)
        odom.step(0.0, static_cloud((0.0, 0.0)), scene_heatmap())
        s = odom.step(0.1, static_cloud((0.0, 0.0)), scene_heatmap())
        assert odo_mod.FEW_FEATURES in s.flags and not s.ok
        assert abs(s.yaw) < 0.05 * DEG and finite_state(s)

    @pytest.mark.parametrize("config", [
        pytest.param(synth.heatmap_chain(), id="default"),
        pytest.param(EstimatorConfig.paper(), id="paper"),
    ])
    def test_empty_heatmap_is_refused(self, config):
        # A heatmap with nothing in it (all zero): no rotation may be measured from it.
        odom = RadarOdometry(config)
        states = [odom.step(0.1 * i, static_cloud((1.0, 0.0)), empty_heatmap()) for i in range(4)]
        for s in states[1:]:
            assert not s.ok, s.flags
            assert abs(s.yaw) < 1e-9
            assert s.registration is None or not s.registration.ok
            assert finite_state(s)
        assert states[-1].x == pytest.approx(0.3, abs=1e-6)  # the velocity still counts

    @pytest.mark.parametrize("structure, blind", [("two_way", False), ("one_way", False), ("two_way", True)])
    def test_a_frame_of_noise_is_not_registered_against(self, structure, blind):
        # Between two views of the scene, a frame that sees one reflector in its noise. Its
        # strongest cells are mostly noise: the scene's bright cells are not in it (the step
        # to it holds no structure, either way), but its own cells land on the next frame's
        # bright cells well enough to pass a one-way verdict, which measures that step on noise.
        # When that frame's point cloud gives no velocity either (*blind*: it saw nothing), the
        # next frame is registered against the one before it (``bridge_s``).
        rng = np.random.default_rng(0)
        odom = RadarOdometry(synth.heatmap_chain(icp={"scan_structure": structure}))
        states = [odom.step(0.1 * i, few_points_cloud() if blind and i == 2 else static_cloud((0.0, 0.0), seed=i),
                            synth.heatmap(SCENE_WORLD[:1] if i == 2 else SCENE_WORLD, 1.0, noise=1e-4, rng=rng))
                  for i in range(4)]
        assert odo_mod.NO_STRUCTURE not in states[1].flags and odo_mod.NO_STRUCTURE in states[2].flags
        after = states[3]
        if blind:
            assert odo_mod.VELOCITY_FAILED in states[2].flags
            assert after.ok and after.registration is not None and abs(after.yaw) < 0.2 * DEG
        elif structure == "two_way":
            assert odo_mod.NO_STRUCTURE in after.flags and odo_mod.YAW_HELD in after.flags
            assert after.yaw_rate == pytest.approx(states[2].yaw_rate)
        else:
            assert after.ok and after.registration is not None

    @staticmethod
    def _turn_in_noise(noise: float, fraction: float | None) -> tuple[list, float]:
        """Turning in place 2 degrees a frame for 29 steps over the scene's reflectors in noise of
        *noise*: the states and the turn measured, degrees (58 true)."""
        rng = np.random.default_rng(0)
        odom = RadarOdometry(synth.heatmap_chain(icp={"scan_score_fraction": fraction}))
        states = [odom.step(0.1 * i, static_cloud((0.0, 0.0), seed=i),
                            synth.heatmap(synth.world_to_body(SCENE_WORLD, (0.0, 0.0, 2.0 * DEG * i)), 1.0,
                                          noise=noise, rng=rng)) for i in range(30)]
        return states, math.degrees(states[-1].yaw - states[0].yaw)

    def test_weak_structure_is_judged_against_the_frames_own(self):
        # In a noise floor of 0.07 (the reflectors peak at 1; 1e-4 elsewhere in these tests) the
        # scene's steps score about 0.9 (7.8 with the usual floor): below min_scan_score, a fixed
        # threshold leaves most of the turn unmeasured; judged against the frames' own usual
        # score every step is measured.
        states, turned = self._turn_in_noise(0.07, None)
        assert sum(odo_mod.NO_STRUCTURE in s.flags for s in states) > 10 and turned < 40.0
        states, turned = self._turn_in_noise(0.07, 0.3)
        assert not any(odo_mod.NO_STRUCTURE in s.flags for s in states) and turned == pytest.approx(58.0, abs=1.0)
        # At a floor of 0.3 the reflectors no longer stand out: the steps score about 0 and none
        # is registered.
        states, turned = self._turn_in_noise(0.3, 0.3)
        assert all(odo_mod.NO_STRUCTURE in s.flags for s in states[1:]) and turned == 0.0

    def test_a_held_velocity_does_not_call_the_static_world_moving(self):
        # Braking from 1 m/s to 0.2 m/s and turning, the point clouds give no velocity: the last
        # one (1 m/s) is held. The heatmap's Doppler says the world moves at 0.2 m/s; against the
        # held velocity every static cell would count as moving (icp.reject_moving_mps), the
        # heatmap would be blank and the turn not measured.
        trajectory = Trajectory([(0.5, 1.0, 0.0), (0.5, 0.2, 30 * DEG)])
        odom = RadarOdometry(synth.heatmap_chain())
        rng = np.random.default_rng(1)
        states = []
        for i in range(10):
            t = 0.1 * i
            v = trajectory.twist(t)[0]
            cloud = static_cloud((v, 0.0), seed=i) if i < 5 else few_points_cloud()
            states.append(odom.step(t, cloud, scene_heatmap(trajectory.pose(t), velocity_xy=(v, 0.0), rng=rng)))
        for s in states[5:]:
            assert odo_mod.VELOCITY_FAILED in s.flags and odo_mod.NO_STRUCTURE not in s.flags, s.flags
        assert states[-1].yaw == pytest.approx(trajectory.pose(0.9)[2], abs=1.5 * DEG)

    def test_velocity_failure_holds_then_motion_lost(self):
        cfg = EstimatorConfig().with_(odometry={"hold_s": 0.25, "velocity_fallback": "hold"})
        odom = RadarOdometry(cfg)
        hm = scene_heatmap()
        dt = 0.1
        # Good velocity (0.4 m/s forward) for 3 frames, then the point cloud fails.
        states = []
        for i in range(10):
            cloud = static_cloud((0.4, 0.0)) if i < 3 else few_points_cloud()
            states.append(odom.step(i * dt, cloud, hm))
        for s in states[1:3]:
            assert s.ok and s.vx == pytest.approx(0.4, abs=1e-5)
        last_good_t = 0.2
        for s in states[3:]:
            assert odo_mod.VELOCITY_FAILED in s.flags and not s.ok
            assert finite_state(s)
            if s.t - last_good_t <= 0.25 + 1e-9:
                assert odo_mod.VELOCITY_HELD in s.flags and odo_mod.MOTION_LOST not in s.flags
                assert s.vx == pytest.approx(0.4, abs=1e-5)
            else:
                assert odo_mod.MOTION_LOST in s.flags and odo_mod.VELOCITY_HELD not in s.flags
                assert s.vx == 0.0 and s.vy == 0.0
        # While lost the position stands still.
        lost = [s for s in states if odo_mod.MOTION_LOST in s.flags]
        assert len(lost) >= 4
        assert all(s.x == lost[0].x for s in lost[1:])
        # Recovery: a good cloud again clears the flags.
        s = odom.step(1.0, static_cloud((0.4, 0.0)), hm)
        assert odo_mod.VELOCITY_FAILED not in s.flags

    def test_no_velocity_ever_measured_is_motion_lost(self):
        # A radar whose first point clouds give no velocity: its steps' zero velocity is no
        # evidence of standing, and says so like a hold that ran out.
        odom = RadarOdometry(EstimatorConfig().with_(odometry={"velocity_fallback": "hold"}))
        hm = scene_heatmap()
        states = [odom.step(i * 0.1, few_points_cloud(), hm) for i in range(4)]
        for s in states[1:]:
            assert odo_mod.VELOCITY_FAILED in s.flags and odo_mod.MOTION_LOST in s.flags, s.flags
            assert odo_mod.VELOCITY_HELD not in s.flags and s.vx == 0.0 and s.vy == 0.0
        s = odom.step(0.4, static_cloud((0.4, 0.0)), hm)
        assert odo_mod.MOTION_LOST not in s.flags and odo_mod.VELOCITY_FAILED not in s.flags

    # Driving at 0.6 m/s, then braking at 1.5 m/s^2 to a stop while the point cloud has too few
    # points to fit (as it has when the static world crowds into a few Doppler bins).
    BRAKE_T, DECEL = 0.3, 1.5

    @classmethod
    def speed(cls, t):
        return max(0.6 - cls.DECEL * max(t - cls.BRAKE_T, 0.0), 0.0)

    @classmethod
    def distance(cls, t):
        """Driven: 0.6 t until the brake, then the braking parabola until the stop."""
        tb = min(max(t - cls.BRAKE_T, 0.0), 0.6 / cls.DECEL)
        return 0.6 * min(t, cls.BRAKE_T) + 0.6 * tb - 0.5 * cls.DECEL * tb * tb

    def brake(self, config, heatmap_at):
        """The states of ten frames 0.1 s apart through the braking; *heatmap_at(t)* each
        frame's heatmap."""
        odom = RadarOdometry(config)
        states = []
        for i in range(10):
            t = i * 0.1
            cloud = static_cloud((self.speed(t), 0.0)) if t <= self.BRAKE_T + 1e-9 else few_points_cloud()
            states.append(odom.step(t, cloud, heatmap_at(t)))
        assert all(odo_mod.VELOCITY_FAILED in s.flags for s in states[4:])
        return states

    def assert_follows_the_braking(self, states):
        assert all(odo_mod.VELOCITY_FROM_HEATMAP in s.flags for s in states[4:])
        for prev, s in itertools.pairwise(states[3:]):
            # The mid-step speed, as the point clouds' velocity would give it (eq. 2).
            assert s.vx == pytest.approx(0.5 * (self.speed(prev.t) + self.speed(s.t)), abs=0.03)
            assert abs(s.vy) < 0.03
            assert finite_state(s)
        assert states[-1].x == pytest.approx(self.distance(states[-1].t), abs=0.02)

    @pytest.mark.parametrize("fallback", ["hold", "heatmap"])
    def test_velocity_fallback_while_slowing_down(self, fallback):
        # The heatmap's Doppler still shows the speed: the "heatmap" fallback follows it, where
        # "hold" carries 0.6 m/s on for hold_s and overshoots the stop.
        states = self.brake(EstimatorConfig().with_(odometry={"velocity_fallback": fallback}),
                            lambda t: scene_heatmap((self.distance(t), 0.0, 0.0), velocity_xy=(self.speed(t), 0.0)))
        if fallback == "hold":
            assert all(odo_mod.VELOCITY_HELD in s.flags for s in states[4:7])
            assert states[4].vx == pytest.approx(0.6, abs=1e-3)
            assert states[-1].x - self.distance(states[-1].t) > 0.1  # the held speed overshoots
        else:
            self.assert_follows_the_braking(states)

    def test_heatmap_fallback_in_a_weak_scene(self):
        # A weak scene: besides the static world's 12 reflectors, 80 maxima ten times weaker
        # whose Doppler is noise's (random).  The 50 strongest maxima hold the static world
        # under the fit's inlier ratio; their strongest half holds it over (docs/heading.md, item
        # 23), and the fallback follows the braking where it used to give up and hold 0.6 m/s.
        rng = np.random.default_rng(3)
        r, b = rng.uniform(1.0, 10.0, 80), rng.uniform(-1.0, 1.0, 80)
        clutter = np.column_stack([r * np.cos(b), r * np.sin(b)])
        clutter_mps = rng.uniform(-1.5, 1.5, 80)

        def heatmap_at(t):
            body = np.vstack([synth.world_to_body(SCENE_WORLD, (self.distance(t), 0.0, 0.0)), clutter])
            _, bearing = synth.polar_body(body)
            radial = np.r_[-self.speed(t) * np.cos(bearing[:len(SCENE_WORLD)]), clutter_mps]
            amplitude = np.r_[np.ones(len(SCENE_WORLD)), np.full(len(clutter), 0.1)]
            return synth.heatmap(body, amplitude, radial_velocity=radial, noise=1e-4)

        config = EstimatorConfig()
        for t in np.arange(4, 10) * 0.1:  # the 50 strongest alone give no velocity
            points = heatmap_doppler_points(heatmap_at(t), config.features, config.odometry.fallback_cells)
            assert not estimate_velocity(points, t, config.velocity, np.random.default_rng(0)).ok
            # The retries take their fewer cells from these: the same cells, in the same order,
            # as picking that many from the heatmap.
            for cells in (25, 12):
                fewer = heatmap_doppler_points(heatmap_at(t), config.features, cells)
                assert len(fewer) == cells
                np.testing.assert_array_equal(strongest_points(points, cells), fewer)
        self.assert_follows_the_braking(self.brake(config, heatmap_at))

    def test_heatmap_fallback_without_doppler_holds(self):
        # A heatmap without a Doppler channel (NaN everywhere) gives no fallback: the last good
        # velocity is held as before.
        odom = RadarOdometry(EstimatorConfig().with_(odometry={"velocity_fallback": "heatmap"}))
        states = [odom.step(0.1 * i, static_cloud((0.4, 0.0)) if i < 3 else few_points_cloud(),
                            scene_heatmap(doppler_channel=False)) for i in range(5)]
        for s in states[3:]:
            assert odo_mod.VELOCITY_HELD in s.flags and odo_mod.VELOCITY_FROM_HEATMAP not in s.flags
            assert s.vx == pytest.approx(0.4, abs=1e-5)

    def test_yaw_rate_held_then_lost(self):
        # Turning in place at 30 deg/s with a good heatmap, then heatmaps with too few features:
        # the last good yaw rate is carried for hold_s, then no rotation is reported.
        cfg = TRAJECTORY_CONFIG.with_(odometry={"hold_s": 0.25})
        odom = RadarOdometry(cfg)
        rate = 30 * DEG
        states = []
        for i in range(12):
            t = 0.1 * i
            hm = scene_heatmap((0.0, 0.0, rate * t)) if i < 5 else blind_heatmap()
            states.append(odom.step(t, static_cloud((0.0, 0.0)), hm))
        good_rates = [s.yaw_rate for s in states[1:5]]
        assert np.all(np.abs(np.array(good_rates) - rate) < 5 * DEG)
        for s in states[5:]:
            assert odo_mod.FEW_FEATURES in s.flags
            if s.t - 0.4 <= 0.25 + 1e-9:
                assert odo_mod.YAW_HELD in s.flags
                assert s.yaw_rate == pytest.approx(states[4].yaw_rate)
            else:
                assert odo_mod.MOTION_LOST in s.flags and s.yaw_rate == 0.0
            assert finite_state(s)

    @pytest.mark.parametrize("rate_before_dps, rate_after_dps, gap_s", [
        (30.0, 0.0, 1.0), (30.0, 0.0, 2.0),    # stopped turning as the link stalled
        (45.0, 0.0, 0.5),                      # (22.5 degrees off the last rate's turn)
        (30.0, 30.0, 1.0), (30.0, 30.0, 2.0),  # kept turning
        (0.0, 30.0, 1.0), (0.0, 20.0, 2.0),    # started turning
    ], ids=["stopped-1s", "stopped-2s", "stopped-0.5s", "kept-1s", "kept-2s", "started-1s", "started-2s"])
    def test_a_gap_in_the_frames_finds_the_turn_made_in_it(self, rate_before_dps, rate_after_dps, gap_s):
        # No frames for a while (a stalled link): the step over the gap searches around the last
        # rate's turn out to every turn 90 deg/s faster or slower would make (gap_yaw_rate_radps),
        # and finds the one made.
        odom = RadarOdometry(synth.heatmap_chain())
        before, after_rate = rate_before_dps * DEG, rate_after_dps * DEG
        turning = [odom.step(0.1 * i, static_cloud((0.0, 0.0)), scene_heatmap((0.0, 0.0, before * 0.1 * i)))
                   for i in range(6)]
        assert turning[-1].yaw == pytest.approx(0.5 * before, abs=1.5 * DEG)
        after = []
        for k in range(5):
            t = 0.5 + gap_s + 0.1 * k
            after.append(odom.step(t, static_cloud((0.0, 0.0)),
                                   scene_heatmap((0.0, 0.0, 0.5 * before + after_rate * (t - 0.5)))))
        assert [s.frame for s in after] == [6, 7, 8, 9, 10]
        assert after[0].yaw_increment == pytest.approx(after_rate * gap_s, abs=1.0 * DEG)
        assert after[0].yaw == pytest.approx(0.5 * before + after_rate * gap_s, abs=2.0 * DEG)
        assert all(finite_state(s) for s in after)
        if not after_rate:  # (turning, the scene leaves the field of view)
            assert after[-1].yaw == pytest.approx(0.5 * before, abs=1.5 * DEG)

    @pytest.mark.parametrize("dt, widen_deg", [(0.1, 0.0), (1 / 6, 0.0), (0.2, 3.0), (0.5, 30.0), (1.0, 45.0),
                                               (3.0, 45.0)])
    def test_how_much_wider_a_long_step_is_searched(self, dt, widen_deg):
        # 90 deg/s either way over the step, less the usual +/- 15 degrees, 45 degrees at most
        # (docs/estimator.md, "Frames lost").
        assert math.degrees(RadarOdometry(EstimatorConfig())._gap_doubt(dt)) == pytest.approx(widen_deg, abs=1e-9)

    @pytest.mark.parametrize("gap_s", [0.3, 5.0, 30.0])
    def test_standing_still_across_a_gap_stays_put(self, gap_s):
        # A standing radar whose link stalls, for however long: the wider search after the gap
        # still finds no turn (the same view scores best).
        odom = RadarOdometry(EstimatorConfig())
        still = [odom.step(0.1 * i, static_cloud((0.0, 0.0)), scene_heatmap()) for i in range(6)]
        after = [odom.step(0.5 + gap_s + 0.1 * k, static_cloud((0.0, 0.0)), scene_heatmap()) for k in range(3)]
        for s in still + after:
            assert abs(s.yaw) < 0.2 * DEG and finite_state(s)

    def test_the_gap_options_are_checked(self):
        for field, value in (("gap_yaw_rate_radps", -0.1), ("gap_yaw_rate_radps", math.inf),
                             ("gap_search_rad", -0.1), ("gap_search_rad", 4.0), ("gap_search_rad", math.nan)):
            with pytest.raises(ConfigError, match=field):
                EstimatorConfig().with_(odometry={field: value})

    def test_never_nan_on_garbage(self):
        rng = np.random.default_rng(5)
        odom = RadarOdometry(EstimatorConfig())
        for i in range(25):
            kind = i % 5
            if kind == 0:
                cloud, hm = few_points_cloud(), empty_heatmap()
            elif kind == 1:
                cloud = points_polar(rng.uniform(-1, 1, 30), 0.0, (0, 0), radial_velocity=rng.uniform(-5, 5, 30))
                hm = synth.heatmap(np.zeros((0, 2)), noise=1.0, rng=rng)
            elif kind == 2:
                cloud = points_polar(np.full(20, 0.3), 0.0, (1.0, 0.0))  # one azimuth
                hm = scene_heatmap()
            elif kind == 3:
                cloud = few_points_cloud()[:0]
                hm = scene_heatmap((rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)))
            else:
                cloud = static_cloud((rng.uniform(-2, 2), rng.uniform(-2, 2)))
                hm = synth.heatmap(rng.uniform(-10, 10, (5, 2)), 1.0, noise=1e-3, rng=rng)
            s = odom.step(0.1 * i, cloud, hm)
            assert finite_state(s), s
            assert s.compute_s > 0


class TestVelocitySync:
    def test_interpolation_to_mid_time(self):
        # Velocity at 10 Hz (t = 0, 0.1, ...), changing linearly; heatmaps at 5 Hz offset by
        # 30 ms.  Paper eq. 2: the step between two heatmaps uses the velocity at their mid-time.
        odom = RadarOdometry(synth.heatmap_chain())
        v_of = lambda t: (0.5 + 0.3 * t, -0.2 + 0.1 * t)
        hm = scene_heatmap()
        events = [(round(0.1 * i, 10), "v") for i in range(25)] + [(round(0.03 + 0.2 * j, 10), "h") for j in range(11)]
        events.sort()
        states = []
        for t, kind in events:
            if kind == "v":
                est = odom.add_points(t, static_cloud(v_of(t), seed=int(t * 10)))
                assert est.ok and est.t == t
            else:
                states.append(odom.add_heatmap(t, hm))
        assert len(states) == 11
        for prev, s in itertools.pairwise(states):
            mid = 0.5 * (prev.t + s.t)
            assert s.vx == pytest.approx(v_of(mid)[0], abs=1e-5)
            assert s.vy == pytest.approx(v_of(mid)[1], abs=1e-5)
            assert s.velocity.t == pytest.approx(mid)
            # The step used it: the position moves by v(mid) dt along the chord of the turn.
            dt = s.t - prev.t
            half = prev.yaw + 0.5 * s.yaw_increment
            step = synth.rot(half) @ np.array(v_of(mid)) * dt
            assert s.x - prev.x == pytest.approx(step[0], abs=1e-6)
            assert s.y - prev.y == pytest.approx(step[1], abs=1e-6)

    @pytest.mark.parametrize("max_accel", [5.0, None])
    def test_a_jump_the_platform_cannot_make_is_not_taken(self, max_accel):
        # 0.8 m/s for a second, then a cloud whose largest consensus says 2.8 m/s (a person
        # walking past a handful of static points) and the static world again.
        cfg = EstimatorConfig().with_(velocity={"min_points": 3, "max_accel_mps2": max_accel})
        odom = RadarOdometry(cfg)
        for i in range(10):
            assert odom.add_points(0.1 * i, static_cloud((0.8, 0.0), seed=i)).ok
        static = points_polar(np.radians([-40.0, 5.0, 45.0]), 0.0, (0.8, 0.0))
        person = points_polar(np.radians([-12.0, -4.0, 3.0, 11.0]), 0.0, (2.8, 0.0))
        est = odom.add_points(1.0, np.concatenate([static, person]))
        assert est.ok
        assert est.vx == pytest.approx(0.8 if max_accel else 2.8, abs=1e-6)
        # A second later the platform may have reached 2.8 m/s: taken.
        assert odom.add_points(2.0, person).vx == pytest.approx(2.8, abs=1e-6)

    def test_nearest_mode(self):
        cfg = EstimatorConfig().with_(odometry={"velocity_sync": "nearest"})
        odom = RadarOdometry(cfg)
        hm = scene_heatmap()
        for t, v in ((0.0, 0.3), (0.1, 0.6), (0.2, 0.9)):
            odom.add_velocity(VelocityEstimate(t=t, vx=v, vy=0.0, covariance=np.eye(2) * 1e-4, status="ok"))
        odom.add_heatmap(0.0, hm)
        s = odom.add_heatmap(0.16, hm)  # mid-time 0.08: nearest estimate is at 0.1
        assert s.vx == pytest.approx(0.6)

    def test_velocity_from_elsewhere(self):
        odom = RadarOdometry(EstimatorConfig())
        hm = scene_heatmap()
        odom.add_velocity(VelocityEstimate(t=0.0, vx=1.0, vy=0.0, covariance=np.eye(2) * 1e-4, status="ok"))
        odom.add_heatmap(0.0, hm)
        odom.add_velocity(VelocityEstimate(t=0.2, vx=2.0, vy=0.0, covariance=np.eye(2) * 1e-4, status="ok"))
        s = odom.add_heatmap(0.2, hm)
        assert s.vx == pytest.approx(1.5)
        assert s.x == pytest.approx(0.3, abs=1e-6)


class TestTimeOrder:
    def test_heatmap_out_of_order_raises(self):
        odom = RadarOdometry(EstimatorConfig())
        hm = scene_heatmap()
        odom.add_heatmap(0.0, hm)
        odom.add_heatmap(0.1, hm)
        with pytest.raises(TimeOrderError):
            odom.add_heatmap(0.05, hm)
        with pytest.raises(TimeOrderError):
            odom.add_heatmap(0.1, hm)

    def test_velocity_out_of_order_raises(self):
        odom = RadarOdometry(EstimatorConfig())
        odom.add_points(0.2, static_cloud((1.0, 0.0)))
        with pytest.raises(TimeOrderError):
            odom.add_points(0.1, static_cloud((1.0, 0.0)))

    @pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
    def test_non_finite_times_raise(self, bad):
        odom = RadarOdometry(EstimatorConfig())
        with pytest.raises(TimeOrderError, match="finite"):
            odom.add_heatmap(bad, scene_heatmap())
        with pytest.raises(TimeOrderError, match="finite"):
            odom.add_points(bad, static_cloud((1.0, 0.0)))
        odom.add_heatmap(0.0, scene_heatmap())  # the refusals left nothing behind
        assert odom.state.frame == 0

    def test_step_out_of_order_raises(self):
        odom = RadarOdometry(EstimatorConfig())
        odom.step(1.0, static_cloud((1.0, 0.0)), scene_heatmap())
        with pytest.raises(TimeOrderError):
            odom.step(0.5, static_cloud((1.0, 0.0)), scene_heatmap())

    def test_refused_heatmap_leaves_no_trace(self):
        odom = RadarOdometry(EstimatorConfig())
        hm = scene_heatmap()
        odom.add_heatmap(0.0, hm)
        odom.add_heatmap(0.1, hm)
        with pytest.raises(TimeOrderError):
            odom.add_heatmap(0.05, hm)
        assert odom.add_heatmap(0.2, hm).frame == 2


def test_reproducible():
    short = Trajectory([(0.5, 1.0, 0.0), (0.5, 1.0, 20 * DEG)])
    a, _ = run_sequence(EstimatorConfig(), short, seed=4)
    b, _ = run_sequence(EstimatorConfig(), short, seed=4)
    assert [(s.x, s.y, s.yaw, s.flags) for s in a] == [(s.x, s.y, s.yaw, s.flags) for s in b]


def test_initial_guess_options_run():
    short = Trajectory([(0.3, 0.0, 30 * DEG)])
    for guess in config_mod.INITIAL_GUESSES:
        cfg = TRAJECTORY_CONFIG.with_(icp={"initial_guess": guess})
        states, truths = run_sequence(cfg, short, seed=5)
        assert all(finite_state(s) for s in states)
        assert abs(states[-1].yaw - truths[-1][2]) < 2 * DEG, guess


# =========================================================================== yaw options
#: The default two-model switch probabilities (OdometryConfig's), and the one model's.
SWITCH = {1: ((1.0,),), 2: ((0.9, 0.1), (0.3, 0.7))}


class TestYawRateFilter:
    def test_one_model_is_the_scalar_kalman_filter(self):
        accel, dt, r = 0.8, 0.1, 0.03
        f = YawRateFilter((accel,))
        assert f.update(0.5, r, dt) == (0.5, r)
        p = r + (accel * dt) ** 2
        gain = p / (p + r)
        rate, var = f.update(0.7, r, dt)
        assert rate == pytest.approx(0.5 + gain * 0.2, rel=1e-12)
        assert var == pytest.approx(p * (1 - gain), rel=1e-12)

    def test_two_models_follow_a_turn_onset_and_stay_smooth_when_steady(self):
        # A rate step (a turn starting) with noisy measurements: the two-model filter catches
        # up within a few frames where the smooth model alone lags; on the steady stretch
        # before it, it smooths about as well (why: its manoeuvre model only takes over when
        # the measurements keep disagreeing with the steady prediction).
        rng = np.random.default_rng(1)
        dt, noise = 0.1, math.radians(1.0) / 0.1
        truth = np.r_[np.zeros(40), np.full(20, math.radians(60.0))]
        z = truth + noise * rng.standard_normal(len(truth))
        out = {}
        for name, models in (("one", (math.radians(50.0),)), ("two", (math.radians(50.0), math.radians(300.0)))):
            f = YawRateFilter(models, SWITCH[len(models)])
            out[name] = np.array([f.update(v, noise ** 2, dt)[0] for v in z])
        lag = {k: np.abs(v[40:45] - truth[40:45]).sum() for k, v in out.items()}
        assert lag["two"] < 0.6 * lag["one"]
        steady = {k: np.sqrt(np.mean((v[10:40] - truth[10:40]) ** 2)) for k, v in out.items()}
        assert steady["two"] < 1.5 * steady["one"] < np.sqrt(np.mean((z[10:40] - truth[10:40]) ** 2))

    def test_the_filter_holds_back_no_more_than_its_lag_bound(self):
        # A turn in place of 90 deg/s starting and ending: the filter's heading lags the measured
        # turn by more than a degree all through it and makes that up after it ends; with
        # yaw_filter_max_lag_rad (the default, 1 degree: docs/heading.md, item 36) it holds
        # back at most that at any frame, and still smooths a straight's noise.
        dt = 0.1
        turn = np.r_[np.zeros(10), np.full(20, math.radians(90.0) * dt), np.zeros(20)]
        noise = math.radians(0.3)
        straight = noise * np.random.default_rng(2).standard_normal(40)
        bound = math.radians(1.0)
        debt, rates = {}, {}
        for name, config in (("bounded", OdometryConfig()), ("unbounded", OdometryConfig(yaw_filter_max_lag_rad=None))):
            f = FilteredYaw(config)
            delivered, rates[name] = np.array([(f(v, noise ** 2, dt)[0], f.filtered) for v in turn]).T
            debt[name] = np.cumsum(turn) - np.cumsum(delivered)
            f.restart()
            smoothed = np.array([f(v, noise ** 2, dt)[0] for v in straight])
            assert np.std(smoothed[10:]) < 0.7 * np.std(straight[10:])
        assert np.max(np.abs(debt["bounded"])) <= bound + 1e-12
        # The filter itself is the same either way: the next search's prediction follows it.
        np.testing.assert_array_equal(rates["bounded"], rates["unbounded"])
        assert np.max(debt["unbounded"][10:30]) > 1.3 * bound  # the turn's start, held back
        assert abs(debt["bounded"][-1]) < 0.5 * bound and abs(debt["unbounded"][-1]) < 1e-3  # each catches up

    @pytest.mark.parametrize(("config", "share"), [
        pytest.param(OdometryConfig(yaw_filter_max_lag_rad=None), 0.05, id="unbounded"),
        # The default's bound gives the lag beyond a degree at once, and with it part of what the
        # keyframe had given (docs/heading.md item 36: counting the payments in the bound too did worse).
        pytest.param(OdometryConfig(), 0.5, id="default"),
    ])
    def test_a_keyframes_correction_toward_the_lag_is_not_given_again(self, config, share):
        # A turn in place of 90 deg/s; after each frame a keyframe that measures the turn so far
        # exactly corrects half of the heading's error.  The filter lags the turn's start, the
        # keyframe makes that up, and the filter then gives its lag again as it catches up: the
        # heading overshoots the turn at its end.  With keyframe_pays_lag (the default: docs/heading.md,
        # item 36) the part given by the keyframe is not given again.
        dt, noise = 0.1, math.radians(0.3)
        turn = np.r_[np.zeros(10), np.full(20, math.radians(90.0) * dt), np.zeros(30)]
        overshoot, rates = {}, {}
        for pays in (False, True):
            f, heading, ahead, rates[pays] = FilteredYaw(config), 0.0, [], []
            for k, v in enumerate(turn):
                heading += f(v, noise ** 2, dt)[0]
                rates[pays].append(f.filtered)
                correction = 0.5 * (turn[:k + 1].sum() - heading)
                heading += correction
                if pays:
                    f.pay(correction)
                ahead.append(heading - turn[:k + 1].sum())
            overshoot[pays] = max(ahead[30:])
            assert abs(ahead[-1]) < 1e-4  # either way the keyframes bring it back at last
        assert overshoot[False] > math.radians(0.3)
        assert overshoot[True] < share * overshoot[False]
        # The filter's own rate, the next search's prediction, is the same either way.
        np.testing.assert_array_equal(rates[True], rates[False])

    def test_a_weak_steps_turn_stays_smoothed_past_the_lag_bound(self):
        # Standing, three weak steps (no velocity of their own: frames braking hard) measure 3 degrees
        # each, as the lab's braking frames at -15 dB err (docs/heading.md).  Bounded at a degree, all
        # but the bound goes into the heading at once, and the filter's catching up then gives a
        # degree more than was measured; with yaw_filter_max_lag_trusted_only (the default) the weak
        # steps' part stays at the filter's pace.  Steps not weak are bounded the same either way.
        dt, noise, bound = 0.1, math.radians(0.3), math.radians(1.0)
        z = np.r_[np.zeros(10), np.full(3, math.radians(3.0)), np.zeros(30)]
        given = {}
        for trusted_only in (False, True):
            config = OdometryConfig(yaw_filter_max_lag_rad=bound, yaw_filter_max_lag_trusted_only=trusted_only)
            for weak in (False, True):
                f = FilteredYaw(config)
                marks = np.r_[np.zeros(10, bool), np.full(3, weak), np.zeros(30, bool)]
                given[trusted_only, weak] = np.cumsum([f(v, noise ** 2, dt, weak=w)[0] for v, w in zip(z, marks)])
        np.testing.assert_array_equal(given[True, False], given[False, False])
        np.testing.assert_array_equal(given[False, True], given[False, False])
        assert given[False, True][12] >= z.sum() - bound - 1e-12
        assert given[True, True][12] < given[False, True][12] - math.radians(0.5)
        assert abs(given[True, True][-1] - z.sum()) < 0.5 * abs(given[False, True][-1] - z.sum())

    def test_huge_innovation_does_not_break_the_filter(self):
        f = YawRateFilter((0.8, 5.0), SWITCH[2])
        f.update(0.0, 1e-4, 0.1)
        rate, var = f.update(1e6, 1e-4, 0.1)  # every model's likelihood underflows
        assert math.isfinite(rate) and math.isfinite(var) and np.all(np.isfinite(f.prob))


def _kept(odom: RadarOdometry, heatmap, t: float = 0.0):
    """What *odom* keeps of *heatmap* (as a frame at *t*), and the frame."""
    frame = CurrentFrame(t, heatmap, odom.config)
    return odom.yaw.keep(frame, None), frame


@pytest.mark.parametrize("window", ["icp", "icp_and_scan"])
def test_field_window_spans_the_scan_guess(window):
    # The sensor turned 6 degrees between two frames; ICP says 0 (drawn off by wrong pairs),
    # the scan guess says about 6.  The field searches +/- 3 degrees around ICP ("icp": it
    # ends on the window's edge) or across both ("icp_and_scan": it finds the turn).
    odom = RadarOdometry(EstimatorConfig().with_(icp={"field_window": window}))
    turn = 6 * DEG
    previous, current = scene_heatmap(), scene_heatmap((0.0, 0.0, turn))
    scan = -5.5 * DEG if window == "icp_and_scan" else None  # what add_heatmap passes
    rotation = odom.yaw.field.refine(_kept(odom, previous)[0].field, _kept(odom, current)[0].field, np.zeros(2),
                                     0.0, scan)
    if window == "icp":
        assert rotation == pytest.approx(-3 * DEG, abs=0.1 * DEG)
    else:
        assert rotation == pytest.approx(-turn, abs=0.5 * DEG)


@pytest.mark.parametrize("start", ["scan", "predicted", "predicted_and_scan"])
def test_keyframe_start_reaches_a_drifted_chain(start):
    # Standing still, the sensor has turned 5 degrees since the keyframe, but the frame chain
    # says it has not turned (a chain that drifted, or a filter lagging a turn's start).  From
    # the scan guess (searched within keyframe_search_rad = 3 degrees of the prediction) the
    # field finds the turn but the measurement is refused as more than 3 degrees off the
    # prediction; around the prediction alone the field ends on its window's edge (3 degrees);
    # spanning the prediction and the scan guess it reaches the turn, and the Kalman update
    # moves the yaw towards it.
    cfg = EstimatorConfig().with_(odometry={"keyframe_start": start, "keyframe_noise_rad": 1.0 * DEG})
    odom = RadarOdometry(cfg)
    keyframe = odom.step(0.0, static_cloud((0.0, 0.0)), scene_heatmap())
    heatmap = scene_heatmap((0.0, 0.0, 5 * DEG))
    current, frame = _kept(odom, heatmap, 0.1)
    var_yaw = (3 * DEG) ** 2  # the chain's own uncertainty: the keyframe gets 90 % of the weight
    dyaw, var = odom.keyframes.correct(ChainStep(keyframe.pose, np.zeros(2), 0.1, 0.0, var_yaw), current, frame)
    gain = var_yaw / (var_yaw + (1 * DEG) ** 2)
    if start == "scan":
        assert dyaw == 0.0 and var == var_yaw
    elif start == "predicted":
        assert dyaw == pytest.approx(gain * 3 * DEG, abs=0.1 * DEG)
    else:
        assert dyaw == pytest.approx(gain * 5 * DEG, abs=0.3 * DEG)
        assert var == pytest.approx((1 - gain) * var_yaw)


@pytest.mark.parametrize("fallback", [False, True])
def test_field_fallback_when_icp_fails(fallback):
    # Turning in place at 30 deg/s; ICP refuses every frame (more features required than
    # there are).  Without the fallback the yaw rate is held (zero so far); with it the field
    # search around the scan guess measures the turn, and the frame keeps its flag.
    cfg = synth.heatmap_chain(odometry={"min_features": 10000}, icp={"field_fallback": fallback})
    odom = RadarOdometry(cfg)
    rate = 30 * DEG
    states = [odom.step(0.1 * i, static_cloud((0.0, 0.0)), scene_heatmap((0.0, 0.0, rate * 0.1 * i)))
              for i in range(4)]
    for s in states[1:]:
        assert odo_mod.FEW_FEATURES in s.flags and not s.ok
        assert finite_state(s)
        if fallback:
            assert odo_mod.YAW_HELD not in s.flags and odo_mod.MOTION_LOST not in s.flags
            assert s.yaw_rate == pytest.approx(rate, abs=3 * DEG)
        else:
            assert s.yaw == 0.0


@pytest.mark.parametrize("seed", range(3))
def test_velocity_lookup_nearest_and_interpolated(seed):
    # The velocity store's lookup against a plain numpy reference: the nearest estimate (the
    # first of equal times, the earlier of two as near) and the linear interpolation between
    # the bracketing ones, with repeated times and queries on, between and beyond them.
    rng = np.random.default_rng(seed)
    times = np.sort(np.round(rng.uniform(0.0, 2.0, 40), 1))  # repeats and exact ties
    store = VelocityHistory(32)
    for i, t in enumerate(times):
        store.add(VelocityEstimate(t=float(t), vx=float(i), vy=-float(i), covariance=np.eye(2), status="ok"))
    kept = times[-32:]
    first = len(times) - 32
    for q in np.concatenate([kept, rng.uniform(-0.5, 2.5, 50), (kept[:-1] + kept[1:]) / 2]):
        nearest = store.nearest(float(q))
        assert nearest.vx == first + int(np.argmin(np.abs(kept - q))), q
        k = int(np.searchsorted(kept, q))
        got = store.interpolated(float(q))
        if 0 < k < len(kept):
            a, b = kept[k - 1], kept[k]
            f = (q - a) / (b - a) if b > a else 0.0
            assert got.vx == pytest.approx(first + k - 1 + f * 1.0), q
        else:
            assert got.vx == first + int(np.argmin(np.abs(kept - q))), q


@pytest.mark.parametrize("name", ["score_support", "scan_score_support"])
def test_the_scores_supports_are_checked_and_default_to_the_field_common_and_the_scan_inside(name):
    icp = EstimatorConfig().icp
    assert (icp.score_support, icp.scan_score_support) == ("common", "inside")
    with pytest.raises(ConfigError, match=name):
        EstimatorConfig().with_(icp={name: "everywhere"})
