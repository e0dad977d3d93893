"""A Python user's wrong arguments to the library's entry points: each is the package's own error
naming the argument or setting and how to give it, raised before anything runs, and a pipeline
that cannot be built leaves nothing behind (its sinks' files taken back, a source it opened
closed)."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
from conftest import make_capture
from live_helpers import URL_TIMEOUTS, port_is_free
from radarodom.cfg import RadarConfig
from radarodom.driver.emulators.rig import HOST_IP, EmulatedRig
from radarodom.driver.sources import Source, open_source
from radarodom.dsp.cfar_params import CfarParams
from radarodom.dsp.config import DspConfig
from radarodom.dsp.processor import FrameProcessor, heatmap_range_bins
from radarodom.errors import CaptureError, ConfigError, EvaluationError, SourceError, UsageError
from radarodom.estimator.config import EstimatorConfig, FeatureConfig, IcpConfig
from radarodom.estimator.evaluation import evaluate
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.velocity import VelocityEstimate
from radarodom.pipeline import FrameProducts, HeatmapSink, LatencyMeter, Pipeline, PointsCsvSink, Sink, TumSink
from radarodom.pipeline.sinks import OdometryJsonSink
from radarodom.products import POINT_DTYPE, RangeAzimuth
from radarodom.tum import TumTrajectory, TumWriter

SIM = "sim://corridor?rate=max&duration=0.5"
#: A CFAR window longer than any heatmap's range axis: refused when the pipeline is built.
TOO_LONG_CFAR = EstimatorConfig(features=FeatureConfig(
    method="cfar", cfar=CfarParams(method="ca", guard=100, train=100, threshold_db=10.0)))


# ------------------------------------------------------------------ settings built in Python
@pytest.mark.parametrize("make, field, words", [
    (lambda: FeatureConfig(k="200"), "k", "must be an integer, got '200'"),
    (lambda: FeatureConfig(k=2.5), "k", "must be an integer, got 2.5"),
    (lambda: IcpConfig(iterations=2.5), "iterations", "must be an integer"),
    (lambda: IcpConfig(alpha=math.inf), "alpha", "must be a finite number"),
    (lambda: DspConfig(min_range_m="0.3"), "min_range_m", "must be a number, got '0.3'"),
    (lambda: DspConfig(min_range_m=math.nan), "min_range_m", "must be a finite number"),
    (lambda: EstimatorConfig(icp={"iterations": 3}), "icp", "must be IcpConfig settings (IcpConfig.from_dict"),
    (lambda: EstimatorConfig(icp=None), "icp", "got NoneType None"),
    (lambda: IcpConfig(initial_guess=None), "initial_guess", "must be a string, got None"),
    (lambda: DspConfig(range_cfar={"method": "ca"}), "range_cfar", "must be CfarParams settings"),
])
def test_settings_built_in_python_are_checked_as_those_read_from_json(make, field, words):
    with pytest.raises(ConfigError) as info:
        make()
    assert info.value.field == field
    assert words in str(info.value), str(info.value)


def test_numpy_numbers_are_taken_as_the_plain_ones_they_are():
    features = FeatureConfig(k=np.int64(50), min_range_m=np.float32(0.75))
    assert features.k == 50 and type(features.k) is int
    assert type(features.min_range_m) is float
    assert EstimatorConfig(features=features).to_dict()["features"]["k"] == 50


def test_dsp_ffts_shorter_than_the_cfgs_chirps_or_loops_are_refused_by_name(shipped_cfg):
    loops, _, _, samples = shipped_cfg.cube_shape
    with pytest.raises(ConfigError) as info:
        FrameProcessor(shipped_cfg, DspConfig(range_fft_size=samples // 2))
    assert info.value.field == "range_fft_size"
    assert f"at least the cfg's {samples} ADC samples" in str(info.value)
    with pytest.raises(ConfigError) as info:
        heatmap_range_bins(shipped_cfg, DspConfig(doppler_fft_size=loops - 1))
    assert info.value.field == "doppler_fft_size" and f"cfg's {loops} loops" in str(info.value)
    # Zero padding (longer FFTs) stays what it was.
    assert FrameProcessor(shipped_cfg, DspConfig(range_fft_size=2 * samples)).n_range == 2 * samples


def test_the_dsps_parts_name_what_they_take(shipped_cfg):
    from radarodom.dsp.heatmap import HeatmapMaker
    from radarodom.rawframe import RawLayout

    for cfg in (None, "configs/awr1843_raw.cfg"):
        with pytest.raises(UsageError, match=r"cfg: a RadarConfig \(RadarConfig.from_file\(path\) reads one\), got"):
            FrameProcessor(cfg)
        with pytest.raises(UsageError, match=r"cfg: a RadarConfig"):
            RawLayout.from_config(cfg)
    layout = RawLayout.from_config(shipped_cfg)
    for buf in ("abc", None, [1, 2, 3]):
        with pytest.raises(UsageError, match=r"decode: a frame's bytes \(bytes, bytearray, memoryview or a uint8 "
                                             r"array\), got"):
            layout.decode(buf)
    proc = FrameProcessor(shipped_cfg)
    spectrum = proc.doppler_fft(proc.range_fft(np.ones(shipped_cfg.cube_shape, np.complex64)))
    maker = HeatmapMaker(proc)
    assert maker.range_azimuth(spectrum).intensity.shape == (len(maker.range_m), len(maker.azimuth_rad))
    for bad in (None, spectrum.tolist(), spectrum[..., :10], spectrum.real):
        with pytest.raises(UsageError, match=r"spectrum: the processor's Doppler spectrum \(FrameProcessor.doppler_fft"
                                             r"\), complex \(n_doppler, tx_slots, rx, n_range\) = "):
            maker.range_azimuth(bad)


@pytest.mark.parametrize("bad, words", [
    (np.inf, "hold 1 NaN or infinite value(s) of 196608 (the first at loop 0, TX slot 0, RX 0, sample 5)"),
    (complex(0, np.nan), "hold 1 NaN or infinite value(s) of 196608 (the first at loop 0, TX slot 0, RX 0, sample 5)"),
    (None, "reach 1e+20, too large for the DSP's float32 power (a radar's 16-bit samples reach 32768); "
           "scale the cube down"),
])
def test_a_cube_the_dsp_cannot_take_is_said_in_its_terms_without_numpys_warnings(shipped_cfg, bad, words):
    """Once numpy's RuntimeWarnings (invalid value in multiply, overflow in square) and then
    "power_rd holds NaN or infinite values", an array the caller never saw."""
    proc = FrameProcessor(shipped_cfg)
    cube = np.ones(shipped_cfg.cube_shape, np.complex64)
    if bad is None:
        cube[:] = 1e20
    else:
        cube[0, 0, 0, 5] = bad  # loop 0: where the Doppler window is zero (inf x 0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning would be raised instead of the package's error
        with pytest.raises(UsageError) as info:
            proc.process(cube)
    assert str(info.value).startswith("FrameProcessor.process: the frame's ADC samples "), str(info.value)
    assert words in str(info.value) and "power_rd" not in str(info.value), str(info.value)
    # The next frame's points are a fresh processor's: no NaN left behind in its buffers.
    good = np.ones(shipped_cfg.cube_shape, np.complex64)
    np.testing.assert_array_equal(proc.process(good).points, FrameProcessor(shipped_cfg).process(good).points)


@pytest.mark.parametrize("cube, got", [([[1j]], "got list"), ("cube.npy", "got str"),
                                       (np.zeros((64, 3, 4, 256), "U1"), "got <U1 array")])
def test_a_cube_that_is_no_numeric_array_is_refused(shipped_cfg, cube, got):
    with pytest.raises(UsageError) as info:
        FrameProcessor(shipped_cfg).process(cube)
    assert str(info.value) == (f"FrameProcessor.process: cube must be a complex array shaped {shipped_cfg.cube_shape} "
                               f"(Frame.cube() gives one), {got}")


@pytest.mark.parametrize("params", [{"min_range_m": 1.0}, {}, EstimatorConfig()])
def test_the_dsp_takes_only_its_settings_class(shipped_cfg, params):
    with pytest.raises(UsageError, match="must be a DspConfig .DspConfig.from_dict makes one"):
        FrameProcessor(shipped_cfg, params)


@pytest.mark.parametrize("config", [{"icp": {}}, {}, True])
def test_the_estimator_takes_only_its_settings_class(config):
    with pytest.raises(UsageError, match="must be an EstimatorConfig .EstimatorConfig.from_dict makes one"):
        RadarOdometry(config)


# ------------------------------------------------------------------ sources
@pytest.mark.parametrize("url", [None, 123, b"sim://corridor"])
def test_a_source_url_that_is_not_text_is_a_source_error(url):
    with pytest.raises(SourceError, match="a source URL is a str"):
        open_source(url)


def test_a_cfg_path_given_for_the_cfg_says_how_to_read_it():
    with pytest.raises(SourceError, match=r"RadarConfig.from_file\(path\) reads one"):
        open_source("sim://corridor", "configs/awr1843_raw.cfg")


# ------------------------------------------------------------------ the pipeline
@pytest.mark.parametrize("kwargs, words", [
    (dict(estimator={"icp": {}}), "estimator: an EstimatorConfig (EstimatorConfig.from_dict"),
    (dict(dsp={"min_range_m": 1.0}), "dsp: a DspConfig"),
    (dict(max_frames=0), "max_frames: a whole number of frames >= 1"),
    (dict(max_frames=-1), "max_frames"),
    (dict(max_frames="3"), "max_frames"),
    (dict(max_frames=2.0), "max_frames"),
    (dict(max_duration_s=-1.0), "max_duration_s: a number of seconds > 0"),
    (dict(max_duration_s=math.nan), "max_duration_s"),
    (dict(max_duration_s="0.2"), "max_duration_s"),
    (dict(sinks=["odom.tum"]), "sinks[0]: a Sink, got str 'odom.tum' (a sink is made from a path: TumSink(path)"),
    (dict(sinks=[None]), "sinks[0]: a Sink, got NoneType None"),
    (dict(sinks=5), "sinks: a list of Sinks, got int"),
    # Each once ended at the first frame: TypeError: TumSink.write() missing 1 required positional argument.
    (dict(sinks=[TumSink]), "sinks[0]: a Sink, got the class TumSink itself; make one: TumSink(path)"),
    # A bare NotImplementedError at the first frame.
    (dict(sinks=[type("Mute", (Sink,), {})()]), "sinks[0]: Mute subclasses Sink but has no write of its own"),
])
def test_wrong_pipeline_arguments_are_usage_errors_naming_them(kwargs, words):
    with pytest.raises(UsageError) as info:
        Pipeline.from_url(SIM, estimator=kwargs.pop("estimator", EstimatorConfig()), **kwargs)
    assert words in str(info.value), str(info.value)


def test_a_sink_given_twice_is_refused_and_its_file_taken_back(tmp_path):
    """Accepted, every pose was written twice: a TUM file radar-eval then refused (time not after
    the previous pose's)."""
    sink = TumSink(tmp_path / "odom.tum")
    with pytest.raises(UsageError, match=r"sinks\[1\] is sinks\[0\], TumSink: a sink given twice writes each result "):
        Pipeline.from_url(SIM, estimator=EstimatorConfig(), sinks=[sink, sink])
    assert not (tmp_path / "odom.tum").exists()


@pytest.mark.parametrize("frame", [None, np.zeros((2, 3), np.complex64)])
def test_what_is_no_frame_is_refused_by_the_products_and_the_pipeline(shipped_cfg, frame):
    products = FrameProducts.for_estimator(shipped_cfg, EstimatorConfig().features)
    with pytest.raises(UsageError, match="frame: a source's Frame .* got (NoneType|ndarray)"):
        products(frame)
    with Pipeline.from_url(SIM, estimator=EstimatorConfig()) as pipe, \
            pytest.raises(UsageError, match="frame: a source's Frame"):
        pipe.process(frame)
    with pytest.raises(UsageError, match=r"features: a FeatureConfig \(EstimatorConfig's .features\), got "
                                         "EstimatorConfig"):
        FrameProducts.for_estimator(shipped_cfg, EstimatorConfig())


def test_a_url_given_as_the_source_points_to_from_url():
    with pytest.raises(UsageError, match=r"Pipeline.from_url opens one from a URL"):
        Pipeline("sim://corridor")


@pytest.mark.parametrize("build", [
    lambda path: Pipeline.from_url(SIM, estimator=TOO_LONG_CFAR, sinks=[TumSink(path)]),
    lambda path: Pipeline.from_url(SIM, estimator=EstimatorConfig(), sinks=[TumSink(path)], max_frames=0),
    lambda path: Pipeline.from_url(SIM, sinks=TumSink(path)),
    lambda path: Pipeline.from_url(SIM, sinks=[TumSink(path), "second.tum"]),
])
def test_a_pipeline_that_cannot_be_built_takes_back_its_sinks_files(tmp_path, build):
    path = tmp_path / "odom.tum"
    with pytest.raises((UsageError, ConfigError)):
        build(path)
    assert not path.exists(), "the empty TUM file would block the next run"
    with Pipeline.from_url(SIM, estimator=EstimatorConfig(), sinks=[TumSink(path)], max_frames=3) as pipe:
        assert pipe.run().frames == 3
    assert len(path.read_text().splitlines()) == 3


def test_a_pipeline_that_cannot_be_built_closes_the_radar_it_opened(tmp_path, small_cfg: RadarConfig):
    with EmulatedRig("sim://corridor?rate=max", config=small_cfg) as rig:
        source = open_source(rig.url(**URL_TIMEOUTS), small_cfg)  # held here: not freed by the collector
        with pytest.raises(ConfigError, match="features.cfar"):
            Pipeline(source, estimator=TOO_LONG_CFAR, owns_source=True)
        assert port_is_free(HOST_IP, rig.data_port), "the DCA1000 data socket was left open"
        assert not any(line.startswith("sensorStart") for line in rig.radar.received), rig.radar.received


def test_the_calibration_measurement_names_a_wrong_argument(shipped_cfg):
    """Were AttributeError ('str' has no 'tx_order') and TypeError ('must be real number, not str')."""
    from radarodom.dsp.calibrate import ChannelCalibrator, measure
    from radarodom.errors import CalibrationError

    for args, kwargs, words in [(("x.cfg", [], 3.0), {}, "cfg: a RadarConfig (RadarConfig.from_file(path) reads one), "
                                                       "got str"),
                                ((shipped_cfg, [], "3"), {}, "distance_m: a number, got str '3'"),
                                ((shipped_cfg, [], 3.0), {"max_azimuth_deg": "8"},
                                 "max_azimuth_deg: a number, got str")]:
        with pytest.raises(UsageError) as info:
            measure(*args, **kwargs)
        assert words in str(info.value), str(info.value)
    with pytest.raises(CalibrationError, match="no frame to measure: none was added"):
        ChannelCalibrator(shipped_cfg, 3.0).result()


def test_source_estimator_names_a_wrong_argument():
    """Were AttributeErrors from inside, and {} silently the defaults."""
    from radarodom.pipeline import source_estimator

    with open_source(SIM) as source:
        for args, words in [(("sim://corridor",), "source: a Source, got the str 'sim://corridor' (open_source opens "
                                                  "one from a URL)"),
                            ((source, {"velocity": {}}), "config: an EstimatorConfig (EstimatorConfig.from_dict makes "
                                                         "one from a dict) or None, got dict"),
                            ((source, {}), "got dict"), ((source, EstimatorConfig), "got type")]:
            with pytest.raises(UsageError) as info:
                source_estimator(*args)
            assert words in str(info.value), str(info.value)
        assert source_estimator(source) == EstimatorConfig()


def test_a_pipelines_on_frame_is_checked_before_the_first_frame():
    pipe = Pipeline.from_url(SIM, estimator=EstimatorConfig(), max_frames=2)
    with pytest.raises(UsageError, match=r"on_frame: a function of \(FrameResult, PipelineStats\) or None, got str"):
        pipe.run("notcallable")
    assert pipe.stats.frames == 0
    assert pipe.run().frames == 2  # refused before it ran: it may still run once
    pipe.close()


def test_a_pipeline_runs_once(tmp_path):
    pipe = Pipeline.from_url(SIM, estimator=EstimatorConfig(), sinks=[TumSink(tmp_path / "odom.tum")], max_frames=2)
    assert pipe.run().frames == 2
    with pytest.raises(UsageError, match="a Pipeline runs once, and this one has run: build a new one"):
        pipe.run()
    pipe.close()
    closed = Pipeline.from_url(SIM, max_frames=2)
    closed.close()
    with pytest.raises(UsageError, match="this one has been closed"):
        closed.run()


# ------------------------------------------------------------------ the estimator's inputs
@pytest.mark.parametrize("call, words", [
    (lambda o: o.add_points("0.1", np.zeros(3, POINT_DTYPE)), "a time is a number of seconds, got str"),
    (lambda o: o.add_points(None, np.zeros(3, POINT_DTYPE)), "got NoneType"),
    (lambda o: o.add_points(0.1, None), "points: a (n,) structured array with fields azimuth, elevation, velocity"),
    (lambda o: o.add_points(0.1, np.zeros((3, 3))), "got ndarray (3, 3)"),
    (lambda o: o.add_points(0.1, np.zeros((2, 3), POINT_DTYPE)), "got ndarray (2, 3)"),
    (lambda o: o.add_heatmap(0.1, None), "heatmap: a range-azimuth heatmap"),
    (lambda o: o.add_heatmap(0.1, RangeAzimuth(np.ones((4, 3)), np.ones((4, 3)), np.zeros((4, 3)), np.arange(3.0),
                                                np.zeros(3))), "its intensity (4, 3) must be (range bins, azimuth bins)"),
    # The cells' other arrays and the axes, which the features read after the intensity.
    (lambda o: o.add_heatmap(0.1, RangeAzimuth(np.ones((4, 3)), np.ones((4, 3)), np.zeros((4, 2)), np.arange(4.0),
                                                np.zeros(3))), "heatmap: doppler_mps (4, 2) must be the intensity's shape"),
    (lambda o: o.add_heatmap(0.1, RangeAzimuth(np.ones((4, 3)), np.ones((4, 3)), np.zeros((4, 3)), np.arange(4.0),
                                                np.zeros(3), np.zeros(3))), "heatmap: elevation_rad (3,) must be"),
    (lambda o: o.add_heatmap(0.1, RangeAzimuth(np.ones((4, 3)), np.ones((4, 3)), np.zeros((4, 3)), [0.0, 1, 2, 3],
                                                np.zeros(3))), "heatmap: range_m must be a (n,) numpy array of numbers, "
                                                               "got list"),
    # The points' yaw (the blend's, on by default) reads each point's place too.
    (lambda o: o.add_points(0.1, np.zeros(3, POINT_DTYPE)[["azimuth", "elevation", "velocity"]]),
     "with fields azimuth, elevation, velocity, x, y"),
    (lambda o: o.add_points(0.1, np.zeros(3, [("azimuth", "f4"), ("elevation", "f4"), ("velocity", "U8"),
                                              ("x", "f4"), ("y", "f4")])),
     "points: field velocity must be a real number a point (float), got <U8"),
    (lambda o: o.add_velocity(None), "velocity: a VelocityEstimate (radarodom.estimator.velocity), got NoneType"),
    # A velocity measured otherwise, given with the points in place of their fit.
    (lambda o: o.add_points(0.1, np.zeros(3, POINT_DTYPE), velocity=0.8),
     "velocity: a VelocityEstimate (radarodom.estimator.velocity), got float"),
    (lambda o: o.add_points(0.1, np.zeros(3, POINT_DTYPE), velocity=VelocityEstimate(t=0.2, vx=0.8, status="ok")),
     "velocity at t=0.2 given with the point cloud at t=0.1"),
])
def test_the_estimators_inputs_are_checked_where_they_come_in(call, words):
    with pytest.raises(UsageError) as info:
        call(RadarOdometry())
    assert words in str(info.value), str(info.value)



def test_nan_or_inf_where_a_measurement_goes_is_none_said_once(caplog):
    """A ROS cloud pads with NaN points; a heatmap cell may come as NaN or inf: such points count
    as absent and such cells as no power, the same odometry as without them, without numpy's
    warnings, the caller's arrays untouched and one warning logged."""
    from estimator_synth import Trajectory, frame, scene
    trajectory = Trajectory([(1.0, 0.6, 0.0), (1.5, 0.6, math.radians(30)), (1.0, 0.6, 0.0)])
    world, amplitude = scene(trajectory, 30, seed=3)
    rng = np.random.default_rng(7)
    frames = []
    for i in range(36):
        x, y, yaw = trajectory.pose(i / 10)
        vx, vy, _ = trajectory.twist(i / 10)
        frames.append(frame(world, amplitude, (x, y, yaw), (vx, vy), rng))
    clean, padded = RadarOdometry(), RadarOdometry()
    cells = (np.array([5, 9, 20]), np.array([1, 7, 3]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for i, (cloud, hm) in enumerate(frames):
            t = i / 10
            zeroed = dataclasses.replace(hm, intensity=hm.intensity.copy(), static=hm.static.copy())
            zeroed.intensity[cells] = 0
            zeroed.static[cells] = 0
            bad = dataclasses.replace(hm, intensity=hm.intensity.copy(), static=hm.static.copy())
            bad.intensity[cells] = [np.nan, np.inf, -np.inf]
            bad.static[cells] = np.nan
            nan_points = np.zeros(5, POINT_DTYPE)
            nan_points["x"], nan_points["y"], nan_points["azimuth"] = np.nan, np.nan, np.nan
            nan_points["velocity"][2] = np.inf
            # A garbled packet's number: finite, but its map covariance could not be inverted.
            nan_points["x"][3:], nan_points["y"][3:], nan_points["azimuth"][3:] = [1e30, 3.0], [2.0, 1e30], 0.5
            nan_points["velocity"][4] = -1e20
            a = clean.step(t, cloud, zeroed)
            with caplog.at_level("DEBUG", logger="radarodom.estimator.odometry"):
                b = padded.step(t, np.concatenate([cloud, nan_points]), bad)
            assert (a.x, a.y, a.yaw, a.vx, a.vy) == (b.x, b.y, b.yaw, b.vx, b.vy), i
            assert np.isnan(bad.intensity[5, 1]) and np.isinf(bad.intensity[9, 7])
    assert abs(b.yaw - trajectory.pose(3.5)[2]) < math.radians(3)  # a real run, not a blind one
    said = [r for r in caplog.records if r.name == "radarodom.estimator.odometry"]
    assert [r.levelname for r in said].count("WARNING") == 1, [r.getMessage() for r in said]
    assert "5 of " in said[0].getMessage() and "left out" in said[0].getMessage()
    assert len(said) == 2 * len(frames)  # the points and the heatmap each frame, at debug after the first


def test_repeated_points_and_a_clouds_weakest_past_the_bound_are_left_out_said_once(caplog):
    """A source that sends each point many times (fuzzing's 20 000 copies of a frame's points took
    3 GB in the points' map, more ended the process) gives the odometry of its cloud without the
    copies; a cloud of more than MAX_CLOUD_POINTS distinct points gives that of its strongest; one
    warning for each, the rest at debug level."""
    from estimator_synth import Trajectory, frame, scene

    from radarodom.estimator.inputs import MAX_CLOUD_POINTS
    trajectory = Trajectory([(1.0, 0.6, 0.0), (1.5, 0.6, math.radians(30)), (1.0, 0.6, 0.0)])
    world, amplitude = scene(trajectory, 30, seed=3)
    rng = np.random.default_rng(7)
    clean, repeated, crowded, strongest = (RadarOdometry() for _ in range(4))
    for i in range(36):
        t = i / 10
        x, y, yaw = trajectory.pose(t)
        vx, vy, _ = trajectory.twist(t)
        cloud, hm = frame(world, amplitude, (x, y, yaw), (vx, vy), rng)
        # Weak, distinct points far off: the strongest are the cloud's own.
        extra = np.zeros(MAX_CLOUD_POINTS + 50, POINT_DTYPE)
        extra["x"] = 40.0 + np.arange(len(extra)) * 0.5
        extra["azimuth"], extra["snr_db"] = 0.1, -30.0
        if i == 0:
            first = len(cloud)
        with caplog.at_level("DEBUG", logger="radarodom.estimator.odometry"):
            b = repeated.step(t, np.resize(cloud, 40 * len(cloud)), hm)
            if i < 4:  # a crowded cloud's search is slow: a few frames tell
                c = crowded.step(t, np.concatenate([extra[:25], cloud, extra[25:]]), hm)
        a = clean.step(t, cloud, hm)
        assert (a.x, a.y, a.yaw, a.vx, a.vy) == (b.x, b.y, b.yaw, b.vx, b.vy), i
        if i < 4:
            d = strongest.step(t, np.concatenate([extra[:25], cloud, extra[25:MAX_CLOUD_POINTS - len(cloud)]]), hm)
            assert (c.x, c.y, c.yaw, c.vx, c.vy) == (d.x, d.y, d.yaw, d.vx, d.vy), i
    assert abs(b.yaw - trajectory.pose(3.5)[2]) < math.radians(3)
    said = [r.getMessage() for r in caplog.records if r.name == "radarodom.estimator.odometry"]
    warned = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warned) == 2 and len(said) == 36 + 4, said[:3]
    assert f"{39 * first} of {40 * first} points repeat another in azimuth/elevation/velocity/x/y" in warned[0]
    assert f"{first + len(extra)} points: the {MAX_CLOUD_POINTS} strongest taken" in warned[1]


@pytest.mark.parametrize("seed", range(5))
def test_a_clouds_repeats_are_the_points_equal_to_an_earlier_one_in_every_field_read(seed):
    from radarodom.estimator.inputs import POINT_YAW_FIELDS, distinct_points
    rng = np.random.default_rng(seed)
    cloud = np.zeros(200, POINT_DTYPE)
    for name in POINT_YAW_FIELDS:  # few values, so that many points repeat one in one field or more
        cloud[name] = rng.integers(0, 2, len(cloud)) * 0.5
    cloud["snr_db"] = np.arange(len(cloud))  # not read: no part of what makes a repeat
    seen, first = set(), []
    for i, point in enumerate(cloud):
        key = tuple(float(point[name]) for name in POINT_YAW_FIELDS)
        if key not in seen:
            seen.add(key)
            first.append(i)
    assert distinct_points(cloud, POINT_YAW_FIELDS)["snr_db"].tolist() == first
    whole = cloud[first]
    assert distinct_points(whole, POINT_YAW_FIELDS) is whole


@pytest.mark.parametrize("change, words", [
    # Each ended deep in the log-polar resampling: ZeroDivisionError, IndexError, numpy's TypeError.
    (dict(azimuth_rad=np.zeros(3)), "heatmap: azimuth_rad must hold at least 2 bins, increasing (0 .. 0 given"),
    (dict(range_m=np.full(4, 2.0)), "heatmap: range_m must hold at least 2 bins, increasing (2 .. 2 given"),
    (dict(range_m=np.arange(4.0)[::-1].copy()), "range_m must hold at least 2 bins, increasing (3 .. 0 given"),
    (dict(intensity=np.ones((1, 1)), static=np.ones((1, 1)), doppler_mps=np.zeros((1, 1)), range_m=np.ones(1),
          azimuth_rad=np.zeros(1)), "heatmap: range_m must hold at least 2 bins, increasing (1 given)"),
    (dict(intensity=np.ones((4, 3)).astype(object)), "heatmap: intensity must hold real numbers, got object"),
    (dict(intensity=np.ones((4, 3), complex)), "heatmap: intensity must hold real numbers, got complex128"),
    (dict(elevation_rad=np.full((4, 3), "up")), "heatmap: elevation_rad must hold real numbers, got <U2"),
])
def test_a_heatmap_the_resampling_cannot_read_is_refused(change, words):
    cells = dict(intensity=np.ones((4, 3)), static=np.ones((4, 3)), doppler_mps=np.zeros((4, 3)),
                 range_m=np.arange(1.0, 5.0), azimuth_rad=np.linspace(-0.5, 0.5, 3))
    cells.update(change)
    with pytest.raises(UsageError) as info:
        RadarOdometry().add_heatmap(0.1, RangeAzimuth(**cells))
    assert words in str(info.value), str(info.value)


def test_a_heatmap_axis_with_nan_is_refused():
    hm = RangeAzimuth(np.ones((4, 3)), np.ones((4, 3)), np.zeros((4, 3)), np.array([1.0, 2.0, np.nan, 4.0]),
                      np.zeros(3))
    with pytest.raises(UsageError, match="heatmap: range_m holds NaN or inf"):
        RadarOdometry().add_heatmap(0.1, hm)

# ------------------------------------------------------------------ trajectories and evaluation
def _line(n: int = 3) -> TumTrajectory:
    return TumTrajectory.from_se2(np.arange(n, dtype=float), [[i, 0.0, 0.0] for i in range(n)])


def test_evaluation_takes_trajectories_and_says_how_to_read_a_file():
    with pytest.raises(EvaluationError, match=r"est: a TumTrajectory \(radarodom.tum.read_tum reads a TUM file\)"):
        evaluate("est.tum", _line())
    for kwargs in ({"delta_m": "1"}, {"max_diff": None}):
        with pytest.raises(EvaluationError, match="must be a"):
            evaluate(_line(), _line(), **kwargs)


@pytest.mark.parametrize("column, value", [("times", math.nan), ("positions", math.nan), ("positions", math.inf),
                                           ("quaternions", math.nan)])
def test_a_trajectory_built_with_nan_or_inf_is_refused_by_the_evaluation(column, value):
    """Every ATE figure came out NaN (the alignment poisoned), and a NaN time dropped its pose."""
    line = _line(5)
    getattr(line, column)[2] = value
    with pytest.raises(EvaluationError, match=r"<trajectory>: pose 2 \(t .* s\) holds NaN or inf"):
        evaluate(line, _line(5))
    with pytest.raises(EvaluationError, match="pose 2"):
        evaluate(_line(5), line)


def test_a_trajectorys_poses_and_the_quaternion_helpers_name_a_wrong_index_or_shape():
    from radarodom.tum import quaternion_yaw, yaw_quaternion

    line = _line(4)
    assert line.pose(-1)[0] == 3.0 and len(line.take([0, 2])) == 2 and len(line.take(line.times > 1)) == 2
    for call, words in ((lambda: line.pose(99), "pose 99: an index of the trajectory's 4 poses"),
                        (lambda: line.pose("1"), "pose '1': an index of the trajectory's 4 poses"),
                        (lambda: line.where(99), "pose 99: an index of the trajectory's 4 poses"),
                        (lambda: line.take([99]), "take: indices of the trajectory's 4 poses, or a mask"),
                        (lambda: line.take("x"), "take: indices of the trajectory's 4 poses, or a mask"),
                        (lambda: yaw_quaternion("x"), "yaw: a number or an array of numbers (rad), got str"),
                        (lambda: quaternion_yaw(np.zeros(3)), "quaternions: an array (..., 4) of xyzw, got shape (3,)")):
        with pytest.raises(UsageError) as info:
            call()
        assert words in str(info.value), str(info.value)


def test_trajectories_take_lists_and_refuse_what_is_no_pose():
    lists = TumTrajectory([0, 1], [[0, 0, 0], [1, 0, 0]], [[0, 0, 0, 1], [0, 0, 0, 1]])
    assert lists.positions.dtype == float and len(lists) == 2
    with pytest.raises(UsageError, match=r"planar poses must be \(n, 3\): x, y, yaw; got \(2, 2\)"):
        TumTrajectory.from_se2([0, 1], [[0, 0], [1, 0]])
    with pytest.raises(UsageError, match="positions must be numbers"):
        TumTrajectory([0, 1], [[0, "a", 0], [1, 0, 0]], [[0, 0, 0, 1], [0, 0, 0, 1]])


@pytest.mark.parametrize("make", [lambda: TumSink(None), lambda: PointsCsvSink(None), lambda: OdometryJsonSink(3),
                                  lambda: HeatmapSink(None)])
def test_an_output_without_a_path_says_so(make):
    with pytest.raises(CaptureError, match="expected a (file|directory) path, got"):
        make()


# ------------------------------------------------------------------ settings helpers, statistics
def test_settings_helpers_raise_config_errors(tmp_path):
    with pytest.raises(ConfigError, match="cannot write DSP settings: No such file or directory"):
        DspConfig().dump(tmp_path / "missing" / "dsp.json")
    with pytest.raises(ConfigError, match="cannot write DSP settings"):
        DspConfig().dump(tmp_path)
    with pytest.raises(ConfigError, match="settings are named by strings, got 1"):
        EstimatorConfig.from_dict({1: 2})
    with pytest.raises(ConfigError, match="the changes to a section are a dict of its settings, got int"):
        EstimatorConfig().with_(icp=5)
    with pytest.raises(ConfigError, match="unknown estimator preset"):
        EstimatorConfig().preset(["tidemo"])


@pytest.mark.parametrize("q", [-10, 150, "50", float("nan")])
def test_a_latency_percentile_outside_0_to_100_is_refused(q):
    meter = LatencyMeter()
    meter.add(0.01)
    with pytest.raises(UsageError, match="a percentile is a number from 0 to 100"):
        meter.percentiles_ms(q)
    assert meter.percentiles_ms(0, 100) == (10.0, 10.0)


def test_cfg_and_tum_writers_refuse_what_they_cannot_write(tmp_path, shipped_cfg):
    with pytest.raises(ConfigError, match="expected a cfg file path, got NoneType"):
        shipped_cfg.write(None)
    with pytest.raises(ConfigError, match="cannot write the cfg: No such file or directory"):
        shipped_cfg.write(tmp_path / "missing" / "radar.cfg")
    with pytest.raises(UsageError, match=r"not a typed cfg command: 'frameCfg 0 1 2' .*RadarConfig.from_text"):
        shipped_cfg.replace("frameCfg 0 1 2")
    with TumWriter(tmp_path / "odom.tum") as writer:
        for args in (("0", 0.0, 0.0, 0.0), (0.0, [1.0, 2.0], 0.0, 0.0)):
            with pytest.raises(UsageError, match="a TUM pose is numbers"):
                writer.write(*args)
        writer.write(0.0, 1.0, 2.0, 0.0)
    assert (tmp_path / "odom.tum").read_text().startswith("0.000000000 1 2 0 ")


# ------------------------------------------------------------------ from the review of these checks
class _FailingClose(Sink):
    """A sink of the user's own whose close fails (a disk gone)."""

    def write(self, result, stats) -> None:
        pass

    def close(self, stats) -> None:
        raise OSError("the disk went away")


def test_a_close_that_fails_after_a_bad_argument_leaves_the_arguments_error_raised():
    with pytest.raises(UsageError, match="max_frames") as info:
        Pipeline.from_url(SIM, sinks=[_FailingClose()], max_frames=0)
    assert any("then closing the outputs failed too: the disk went away" in note
               for note in getattr(info.value, "__notes__", [])), info.value


def test_every_source_closed_refuses_to_stream_again(tmp_path, small_cfg):
    """A source streams until closed, then says so and how to go on: a recording's, a demo
    stream's file (whose memory map is gone: numpy's "mmap closed" before) and a simulation alike,
    as the radars' own sources do (test_live_stop, test_tidemo_source)."""
    from test_tidemo_replay import packets
    from tidemo_helpers import TIDEMO_CFG

    make_capture(tmp_path / "rec", small_cfg, 3)
    demo_cfg = RadarConfig.from_text(TIDEMO_CFG, "tidemo.cfg")
    (tmp_path / "uart.bin").write_bytes(b"".join(packets(demo_cfg, range(1, 4))))
    for url, cfg in ((f"replay://{tmp_path / 'rec'}?rate=max", None),
                     (f"replay://{tmp_path / 'uart.bin'}?format=tidemo&rate=max", demo_cfg),
                     ("sim://corridor?rate=max&duration=0.15", small_cfg)):
        source = open_source(url, cfg)
        assert not source.closed and len(list(source)) == 3, url
        source.close()
        source.close()  # twice: nothing more
        assert source.closed
        with pytest.raises(UsageError, match=r"the source is closed; open a new one \(open_source\)"):
            iter(source)


def test_numpy_booleans_and_scipy_window_tuples_are_taken():
    assert IcpConfig(sampling=np.True_).sampling is True
    assert DspConfig(range_window=("kaiser", 8.0)).range_window == ("kaiser", 8.0)


class _DuckSink:
    """A result sink that does not subclass Sink and says nothing of heatmaps."""

    takes_raw = False

    def __init__(self) -> None:
        self.frames = 0

    def write(self, result, stats) -> None:
        self.frames += 1

    def close(self, stats) -> None:
        pass


class _DuckRecorder:
    takes_raw = True

    def __init__(self) -> None:
        self.roles: list[str] = []

    def write_raw(self, frame, stats) -> None:
        self.roles.append(frame.role)

    def close(self, stats) -> None:
        pass


def test_sinks_need_not_subclass_sink():
    duck = _DuckSink()
    with Pipeline.from_url(SIM, estimator=EstimatorConfig(), sinks=[duck], max_frames=3) as pipe:
        pipe.run()
    assert duck.frames == 3


class _Frames(Source):
    """A Source of the user's own: frames already in memory."""

    def __init__(self, frames, config) -> None:
        super().__init__()
        self.frames, self.config = frames, config

    def _frames(self):
        return iter(self.frames)


def test_a_recording_alone_takes_frames_of_any_role(small_cfg):
    with open_source("sim://corridor?rate=max", small_cfg) as source:
        frames = [dataclasses.replace(frame, role="raw") for frame, _ in zip(source, range(3))]
    recorder = _DuckRecorder()
    Pipeline(_Frames(frames, small_cfg), sinks=[recorder]).run()
    assert recorder.roles == ["raw"] * 3
    with pytest.raises(CaptureError, match="frame 0: role 'raw' is not one of"):
        Pipeline(_Frames(frames, small_cfg), estimator=EstimatorConfig()).run()


def test_a_keyword_the_pipeline_does_not_take_closes_the_radar_from_url_opened(small_cfg):
    with EmulatedRig("sim://corridor?rate=max", config=small_cfg) as rig:
        with pytest.raises(TypeError, match="sink"):
            Pipeline.from_url(rig.url(**URL_TIMEOUTS), small_cfg, sink=[])
        # The traceback (held by pytest) keeps the source alive: the port is free only if it was closed.
        assert port_is_free(HOST_IP, rig.data_port), "the DCA1000 data socket was left open"


def test_the_paper_estimator_needs_no_point_places():
    points = np.zeros(3, POINT_DTYPE)[["azimuth", "elevation", "velocity"]]
    RadarOdometry(EstimatorConfig.paper()).add_points(0.1, points)

