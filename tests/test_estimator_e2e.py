"""The estimator on the simulator's own frames, end to end: Simulator (fast fidelity, as
the robustness matrix records; cheaper than exact) -> FrameProcessor -> HeatmapMaker (as
radar-capture makes them) -> RadarOdometry, against the simulator's ground truth.

Two short sequences of the ``corridor`` scene, made once per module:

- ``straight``: the scene's own trajectory, 3.5 s: 1 s standing still, then speeding up to
  1.2 m/s straight along the corridor (2.5 m);
- ``turn``: the same walls, the sensor starting 13 m along the corridor, 1.5 m ahead and
  then the corridor's left turn (90 degrees on a 0.8 m radius at 0.8 m/s: 57 deg/s), 3.5 s.

Poses are the body frame (REP-103) in the first frame's (docs/conventions.md).
"""

from __future__ import annotations

import functools
import hashlib
import math
import multiprocessing
import tomllib
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from importlib import resources

import numpy as np
import pytest
from sim_helpers import point_scene, scattered_points, truth

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.sim.scene import Scene, load_scene, scene_from_dict
from radarodom.driver.sim.simulator import Simulator
from radarodom.dsp.heatmap import HeatmapMaker, RangeAzimuth
from radarodom.dsp.processor import FrameProcessor
from radarodom.estimator import odometry as odo_mod
from radarodom.estimator.config import EstimatorConfig, VelocityConfig
from radarodom.estimator.odometry import OdometryState, RadarOdometry
from radarodom.estimator.velocity import VelocityEstimate, estimate_velocity

DEG = math.radians(1.0)
DURATION_S = 3.5


@dataclass
class Sequence:
    cfg: RadarConfig
    scene: Scene
    times: np.ndarray  # (n,) frame start times, s
    points: list[np.ndarray]
    heatmaps: list[RangeAzimuth]
    truth: np.ndarray  # (n, 3) x, y, yaw of the body in the first frame's frame

    def __len__(self) -> int:
        return len(self.times)

    def body_velocity(self, i: int) -> np.ndarray:
        """True (vx, vy) in the body frame in the middle of frame *i*'s chirps."""
        t = self.times[i] + self.cfg.active_frame_time_s / 2.0
        traj = self.scene.trajectory
        vx, vy, _ = (float(v) for v in traj.velocity(t))
        yaw = float(traj.pose(t)[2])
        c, s = math.cos(yaw), math.sin(yaw)
        return np.array([c * vx + s * vy, -s * vx + c * vy])

    @property
    def path_m(self) -> float:
        return float(np.hypot(*np.diff(self.truth[:, :2], axis=0).T).sum())


def _simulate(scene: Scene) -> Sequence:
    cfg = RadarConfig.from_file(shipped_config_path())
    sim = Simulator(cfg, scene, seed=0, duration_s=DURATION_S, fidelity="fast")
    processor = FrameProcessor(cfg)
    # As radar-capture makes them for the estimator.
    maker = HeatmapMaker(processor, doppler_cells=4 * EstimatorConfig().features.k)
    times, points, heatmaps, truth = [], [], [], []
    for i in range(sim.num_frames):
        frame = sim.frame(i)
        result = processor.process(sim.layout.decode(frame.raw))
        times.append(frame.timestamp)
        points.append(result.points.copy())  # the processor's buffer
        heatmaps.append(maker.range_azimuth(result.spectrum))
        x, y, _, qx, qy, qz, qw = frame.pose
        truth.append((x, y, 2.0 * math.atan2(qz, qw)))
    return Sequence(cfg, scene, np.array(times), points, heatmaps, np.array(truth))


def _simulate_turn() -> Sequence:
    ref = resources.files("radarodom.driver.sim").joinpath("scenes", "corridor.toml")
    spec = tomllib.loads(ref.read_text(encoding="utf-8"))
    spec["trajectory"]["start"] = [13.0, 0.0, 0.0]
    spec["trajectory"]["segments"] = [{"straight": 1.5, "speed": 1.2},
                                      {"turn": 90, "radius": 0.8, "speed": 0.8},
                                      {"straight": 3.0, "speed": 1.0}]
    return _simulate(scene_from_dict(spec, where="corridor-turn"))


@pytest.fixture(scope="module")
def sequences() -> dict[str, Sequence]:
    """Both sequences, made at the same time: ``turn`` in a process of its own (spawned, not
    forked from this one's threads) while this one makes ``straight``; each is made whole in one
    process (fast fidelity's BLAS sums may differ in an ADC count from process to process)."""
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        turn = pool.submit(_simulate_turn)
        straight = _simulate(load_scene("corridor"))
        return {"straight": straight, "turn": turn.result(timeout=600)}


@pytest.fixture(scope="module")
def straight(sequences) -> Sequence:
    return sequences["straight"]


@pytest.fixture(scope="module")
def turn(sequences) -> Sequence:
    return sequences["turn"]


def run(seq: Sequence, config: EstimatorConfig, *, heatmap_every: int = 1
        ) -> tuple[list[VelocityEstimate], list[OdometryState], list[int]]:
    """Velocity from every frame's points; heatmaps from every *heatmap_every*-th frame.
    Returns the velocity estimates, the odometry states and the frames of the states."""
    odom = RadarOdometry(config)
    velocities, states, frames = [], [], []
    for i, t in enumerate(seq.times):
        velocities.append(odom.add_points(float(t), seq.points[i]))
        if i % heatmap_every == 0:
            states.append(odom.add_heatmap(float(t), seq.heatmaps[i]))
            frames.append(i)
    return velocities, states, frames


def pose_array(states: list[OdometryState]) -> np.ndarray:
    return np.array([(s.x, s.y, s.yaw) for s in states])


def finite(s: OdometryState) -> bool:
    values = [s.t, s.x, s.y, s.yaw, s.vx, s.vy, s.yaw_rate, s.yaw_increment, s.compute_s]
    return (all(math.isfinite(v) for v in values) and bool(np.all(np.isfinite(s.pose_covariance)))
            and bool(np.all(np.isfinite(s.twist_covariance))))


def fingerprint(states: list[OdometryState]) -> list[tuple]:
    """Everything a state reports except the time it took."""
    return [(s.t, s.frame, s.x, s.y, s.yaw, s.vx, s.vy, s.yaw_rate, s.yaw_increment, s.flags, s.features,
             s.pose_covariance.tobytes(), s.twist_covariance.tobytes()) for s in states]


def input_digest(seq: Sequence) -> str:
    h = hashlib.sha256()
    for p, hm in zip(seq.points, seq.heatmaps):
        h.update(p.tobytes())
        for a in (hm.intensity, hm.static, hm.doppler_mps, hm.range_m, hm.azimuth_rad):
            h.update(a.tobytes())
    return h.hexdigest()


CONFIGS = {"default": EstimatorConfig(), "paper": EstimatorConfig.paper()}


@pytest.fixture(scope="module")
def runs(sequences):
    """``runs(sequence, config)``: ``run(sequences[sequence], CONFIGS[config])``, made once for the
    tests that read it (never changed). The same input gives the same output (TestReproducible,
    which runs afresh), so a run shared is the run each test would make."""
    @functools.cache
    def get(sequence: str, config: str):
        return run(sequences[sequence], CONFIGS[config])
    return get


# ----------------------------------------------------------------- Doppler speed bias
@pytest.mark.parametrize("speed,half_width_deg", [(0.6, 60.0), (0.8, 60.0), (0.6, 85.0)])
def test_straight_drive_doppler_speed_unbiased(speed, half_width_deg):
    """40 static points ahead (+/-*half_width_deg*, 3-9 m, 0-1.4 m high; the sensor 0.4 m high)
    and the sensor driving straight at *speed*: over 20 frames the points' radial velocities are
    unbiased to 0.03 Doppler bin and the Doppler ego-speed to 0.3 %.

    0.6 and 0.8 m/s are 8.51 and 11.35 bins: with bin-centre velocities the points near the
    heading (where cos is flat, so their rounding errors do not average out) all round down,
    and the speed came out 2.2 % and 0.9 % low (points 0.13 and 0.06 bin slow on average).
    Out to 85 deg, azimuths on the FFT grid (DspConfig.azimuth_interpolation off) gave 0.43 %
    too fast (0.15 % with them between bins): off boresight the grid is coarse and the forward
    component cos(azimuth) is curved in the measured Wx = sin(azimuth)."""
    cfg = RadarConfig.from_file(shipped_config_path())
    world = scattered_points(40, half_width_deg=half_width_deg)
    scene = point_scene(world, [{"straight": 10.0, "speed": speed}], snr_db=25.0)
    sim = Simulator(cfg, scene, seed=3)
    processor = FrameProcessor(cfg)
    config = VelocityConfig()
    errors, speeds = [], []
    for i in range(2, 22):
        frame = sim.frame(i)
        points = processor.process(sim.layout.decode(frame.raw)).points
        truths = [truth(scene, cfg, p, frame.timestamp) for p in world]
        sensor_xy = np.array([tr["p"][:2] for tr in truths])
        for q in points:  # each detection against the world point it is
            d = np.hypot(*(sensor_xy - (q["x"], q["y"])).T)
            k = int(np.argmin(d))
            error = (float(q["velocity"]) - truths[k]["v_r"]) / cfg.velocity_resolution_mps
            if d[k] < 0.3 and abs(error) < 1.0:  # not a sidelobe or a merger of two points
                errors.append(error)
        t_mid = frame.timestamp + cfg.active_frame_time_s / 2.0
        estimate = estimate_velocity(points, t_mid, config, np.random.default_rng(i))
        assert estimate.status == "ok", estimate.status
        speeds.append(math.hypot(estimate.vx, estimate.vy))
    assert len(errors) > 300
    assert abs(np.mean(errors)) < 0.03, np.mean(errors)
    assert np.mean(speeds) == pytest.approx(speed, rel=3e-3)


# --------------------------------------------------------------------------- velocity
class TestVelocity:
    def test_standing_still_is_exactly_zero(self, straight, runs):
        velocities, _, _ = runs("straight", "default")
        still = [i for i in range(len(straight)) if np.hypot(*straight.body_velocity(i)) < 1e-3]
        assert len(still) == 10  # the first second
        for i in still:
            v = velocities[i]
            assert v.status == "zero_velocity" and v.ok, (i, v.status)
            assert (v.vx, v.vy) == (0.0, 0.0)

    def test_matches_the_true_body_velocity(self, straight, runs):
        velocities, _, _ = runs("straight", "default")
        moving = [i for i in range(len(straight)) if np.hypot(*straight.body_velocity(i)) >= 1e-3]
        assert len(moving) == 25
        errors = []
        for i in moving:
            v, true = velocities[i], straight.body_velocity(i)
            assert v.ok, (i, v.status, v.n_points)
            assert abs(v.vx - true[0]) < 0.05, (i, v.vx, true)  # forward: always close
            assert np.all(np.isfinite(v.covariance)) and np.all(np.linalg.eigvalsh(v.covariance) >= 0)
            errors.append(math.hypot(v.vx - true[0], v.vy - true[1]))
        errors = np.array(errors)
        # Measured: 23 of 25 within 0.05 m/s, the largest 0.058 (sideways), median 0.018.
        assert np.mean(errors < 0.05) >= 0.8, errors
        assert errors.max() < 0.1 and np.median(errors) < 0.03, errors

    def test_in_the_turn(self, turn, runs):
        velocities, _, _ = runs("turn", "default")
        ok = [i for i, v in enumerate(velocities) if v.ok]
        # The first frames, barely moving, have too few points for a fit: refused, not guessed.
        assert len(ok) >= 0.85 * len(turn)
        for i, v in enumerate(velocities):
            assert v.ok or v.status in ("few_points", "ill_conditioned", "no_consensus"), v.status
        errors = np.array([math.hypot(*(velocities[i].velocity - turn.body_velocity(i))) for i in ok])
        assert np.mean(errors < 0.05) >= 0.85, errors
        assert errors.max() < 0.1, errors

    def test_paper_config_same_velocity_unweighted(self, straight, runs):
        # The paper's settings change the yaw and leave the velocity fit unweighted: that is all
        # they change of it (docs/heading.md item 20).
        a, _, _ = run(straight, EstimatorConfig().with_(velocity={"bearing_noise_rad": 0.0}))
        b, _, _ = runs("straight", "paper")
        assert [(v.vx, v.vy, v.status) for v in a] == [(v.vx, v.vy, v.status) for v in b]
        weighted, _, _ = runs("straight", "default")
        assert [v.status for v in weighted] == [v.status for v in b]
        # The weights move each velocity within the fit's own noise (above: errors under 0.1 m/s).
        assert max(math.hypot(v.vx - w.vx, v.vy - w.vy) for v, w in zip(weighted, b)) < 0.05


# --------------------------------------------------------------------------- odometry
class TestOdometry:
    @pytest.mark.parametrize("name", list(CONFIGS))
    def test_never_nan_and_bookkeeping(self, straight, turn, runs, name):
        for seq, sequence in ((straight, "straight"), (turn, "turn")):
            _, states, _ = runs(sequence, name)
            assert len(states) == len(seq)
            assert all(finite(s) for s in states)
            assert [s.frame for s in states] == list(range(len(seq)))
            assert [s.t for s in states] == list(seq.times)
            assert states[0].flags == (odo_mod.FIRST_FRAME,)
            assert (states[0].x, states[0].y, states[0].yaw) == (0.0, 0.0, 0.0)
            assert all(s.compute_s > 0 for s in states)
            assert all(np.all(np.linalg.eigvalsh(s.pose_covariance) > -1e-12) for s in states)
            for a, b in zip(states, states[1:]):
                assert b.yaw == pytest.approx(a.yaw + b.yaw_increment, abs=1e-12)

    # Measured on `straight`: default yaw increments within 0.46 deg (RMSE 0.13), end 27 mm and
    # 1.6 deg off (with the keyframe search started from the scan guess, the default before the
    # room's heading diagnosis: RMSE 0.16, end 1.0 deg off; that search over-corrected the
    # room's straights, 7.1 % drift there against 3.7, so the pin moved from 1.5 to 2 deg);
    # the paper's within 0.8 deg, end 0.09 m and 6.2 deg off (its yaw wanders on 15-degree beams).
    @pytest.mark.parametrize("name,max_dyaw_deg,max_yaw_deg,max_pos_pct", [
        ("default", 0.8, 2.0, 2.0),
        ("paper", 2.0, 10.0, 8.0),
    ])
    def test_follows_the_straight_corridor(self, straight, runs, name, max_dyaw_deg, max_yaw_deg, max_pos_pct):
        _, states, _ = runs("straight", name)
        est, truth = pose_array(states), straight.truth
        # The yaw increments, frame by frame, within a couple of degrees of the truth.
        dyaw_err = np.degrees(np.diff(est[:, 2]) - np.diff(truth[:, 2]))
        assert np.abs(dyaw_err).max() < max_dyaw_deg, dyaw_err
        assert abs(math.degrees(est[-1, 2] - truth[-1, 2])) < max_yaw_deg
        # Standing still for the first second: no motion at all.
        assert np.all(est[:10, :2] == 0.0)
        # Then forward; the end within a few % of the 2.5 m travelled.
        assert straight.path_m == pytest.approx(2.52, abs=0.05)
        end_err = math.hypot(*(est[-1, :2] - truth[-1, :2]))
        assert end_err < max_pos_pct / 100 * straight.path_m, end_err
        assert np.all(np.diff(est[:, 0]) >= 0)

    def test_default_follows_the_turn(self, turn, runs):
        _, states, _ = runs("turn", "default")
        est, truth = pose_array(states), turn.truth
        true_dyaw = np.degrees(np.diff(truth[:, 2]))
        dyaw_err = np.degrees(np.diff(est[:, 2])) - true_dyaw
        # In the steady part of the turn (5.7 degrees a frame) the increments are right:
        # measured within 0.95 degrees, median 0.06 short.
        steady = true_dyaw > 5.5
        assert steady.sum() >= 10
        assert np.abs(np.median(dyaw_err[steady])) < 1.0, dyaw_err[steady]
        assert np.abs(dyaw_err[steady]).max() < 1.5, dyaw_err[steady]
        # Over the whole sequence, measured: RMSE 0.48 degree, largest 1.6 (ICP's yaw alone: 1.0
        # and 2.7, at the turn's onset).
        assert np.sqrt(np.mean(dyaw_err ** 2)) < 1.0, dyaw_err
        # A left turn of 90 degrees (measured 90.9; 83.6 with the one-model yaw-rate filter).
        assert math.degrees(truth[-1, 2]) == pytest.approx(90.0, abs=0.5)
        assert 65.0 < math.degrees(est[-1, 2]) < 100.0
        assert est[-1, 1] > 0.5

    # The target, met since the three yaw options became the default (field window
    # spanning ICP and the scan guess, field fallback, two-model yaw-rate filter): measured
    # yaw-increment RMSE 0.483 degree in the corridor's 57 deg/s turn at 10 Hz (0.653 before:
    # the one-model filter lagged at the turn's onset and end), the turn 0.9 degree long at
    # the end (6.4 short before); the same with either FFT backend.
    def test_default_meets_the_yaw_target_in_the_turn(self, turn, runs):
        _, states, _ = runs("turn", "default")
        dyaw_err = np.degrees(np.diff(pose_array(states)[:, 2]) - np.diff(turn.truth[:, 2]))
        assert np.sqrt(np.mean(dyaw_err ** 2)) <= 0.5
        assert abs(math.degrees(states[-1].yaw - turn.truth[-1, 2])) < 5.0


# --------------------------------------------------------------------- reproducibility
class TestReproducible:
    @pytest.mark.parametrize("name", list(CONFIGS))
    def test_same_input_same_output(self, straight, name):
        digest = input_digest(straight)
        _, a, _ = run(straight, CONFIGS[name])
        _, b, _ = run(straight, CONFIGS[name])
        assert fingerprint(a) == fingerprint(b)
        assert input_digest(straight) == digest  # the estimator leaves its inputs alone

    @pytest.mark.parametrize("config", [
        pytest.param(EstimatorConfig(), id="default"),
        pytest.param(EstimatorConfig.paper(), id="paper"),
        pytest.param(EstimatorConfig.paper(method="cfar", two_way=False), id="paper-cfar-oneway"),
        pytest.param(EstimatorConfig().with_(features={"method": "raymax", "max_range_m": 12.5},
                                             icp={"initial_guess": "profile"}, velocity={"seed": 3}),
                     id="custom"),
    ])
    def test_dump_load_round_trip_gives_the_same_trajectory(self, straight, runs, tmp_path, config):
        path = tmp_path / "estimator.json"
        config.dump(path)
        loaded = EstimatorConfig.load(path)
        assert loaded == config
        shared = [name for name, known in CONFIGS.items() if known == config]  # its run made once
        _, a, _ = runs("straight", shared[0]) if shared else run(straight, config)
        _, b, _ = run(straight, loaded)
        assert fingerprint(a) == fingerprint(b)

    def test_different_configs_differ(self, runs):
        # The trajectories above are not the same whatever the settings.
        _, a, _ = runs("straight", "default")
        _, b, _ = runs("straight", "paper")
        assert [s.yaw for s in a] != [s.yaw for s in b]


# ------------------------------------------------------------------------ multi-rate
class TestMultiRate:
    """Velocity from every frame's points (10 Hz), heatmaps from every second frame (5 Hz)."""

    def test_velocity_is_taken_at_the_mid_time(self, straight):
        velocities, states, frames = run(straight, EstimatorConfig(), heatmap_every=2)
        assert frames == list(range(0, len(straight), 2))
        assert [s.t for s in states] == [straight.times[i] for i in frames]
        assert all(finite(s) for s in states)
        # Between heatmaps i-2 and i the mid-time is frame i-1's: its velocity is the step's.
        for s, i in zip(states[1:], frames[1:]):
            assert s.velocity is not None and s.velocity.t == pytest.approx(straight.times[i - 1])
            assert s.vx == pytest.approx(velocities[i - 1].vx, abs=1e-9)
            assert s.vy == pytest.approx(velocities[i - 1].vy, abs=1e-9)
            assert s.ok, s.flags

    def test_follows_the_straight_corridor(self, straight, runs):
        _, states, frames = run(straight, EstimatorConfig(), heatmap_every=2)
        est, truth = pose_array(states), straight.truth[frames]
        dyaw_err = np.degrees(np.diff(est[:, 2]) - np.diff(truth[:, 2]))
        assert np.abs(dyaw_err).max() < 1.5, dyaw_err  # measured 1.12 (ICP's yaw alone: 0.21)
        assert math.hypot(*(est[-1, :2] - truth[-1, :2])) < 0.03 * straight.path_m  # measured 10 mm
        # And close to the odometry at the full rate.
        _, full, _ = runs("straight", "default")
        full_at = pose_array(full)[frames]
        assert np.abs(est[:, :2] - full_at[:, :2]).max() < 0.03
        assert np.degrees(np.abs(est[:, 2] - full_at[:, 2])).max() < 2.0  # measured 1.5 (ICP's yaw alone: 0.3)

    def test_follows_the_turn(self, turn):
        _, states, frames = run(turn, EstimatorConfig(), heatmap_every=2)
        est, truth = pose_array(states), turn.truth[frames]
        assert all(finite(s) for s in states)
        # 11.5 degrees between heatmaps in the turn; measured: within 1.5, RMSE 0.8, end 3.2 short.
        dyaw_err = np.degrees(np.diff(est[:, 2]) - np.diff(truth[:, 2]))
        assert np.abs(dyaw_err).max() < 3.0, dyaw_err
        assert np.sqrt(np.mean(dyaw_err ** 2)) < 1.5, dyaw_err
        assert abs(math.degrees(est[-1, 2] - truth[-1, 2])) < 8.0
        assert math.hypot(*(est[-1, :2] - truth[-1, :2])) < 0.1 * turn.path_m  # measured 0.06 m of 2.6
