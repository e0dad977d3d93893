"""The range of every numeric estimator setting (estimator/config_limits.py), end to end: each
number at the extremes a settings file may hold (1e308, 1e30, 0, -1) and at the ends of its
range is either refused by the loader, naming the field and its range, or runs through a real
RadarOdometry over simulated frames with no error and no RuntimeWarning.

Before the limits the loader checked types and signs only: some 366 such values passed it, and
some crashed the estimator frames later ("internal error"): noises of 1e308 (OverflowError
squaring them), a velocity history or RANSAC count of 1e30, a yaw acceleration of 1e308 or a
manoeuvre start probability of 0 (NaN model weights, then an IndexError sampling the heatmap), a
CFAR threshold of 1e30 dB (10^(dB/10) overflowed as the settings were made).

The frames: the corridor's left turn (as in test_estimator_e2e, simulated once per module at fast
fidelity), its straight lead-in short so that most frames turn, and two blind frames (no points,
a heatmap of noise alone: the radar covered) so that the held velocity, the held yaw rate and the
bridge across them run too.  Settings that only act with an option on are tried with it on:
``point_yaw.*`` with ``point_yaw.use``, the wheeled base's with ``base`` "wheeled" off the axis,
the CFAR sections' with the "cfar" method.
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
import tomllib
import types
import typing
import warnings
from importlib import resources

import numpy as np
import pytest

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.sim.scene import scene_from_dict
from radarodom.driver.sim.simulator import Simulator
from radarodom.dsp.cfar import CfarParams
from radarodom.dsp.heatmap import HeatmapMaker
from radarodom.dsp.processor import FrameProcessor
from radarodom.errors import ConfigError, quoted
from radarodom.estimator import config_limits
from radarodom.estimator.config import EstimatorConfig, paper_variants
from radarodom.estimator.odometry import RadarOdometry
from radarodom.products import RangeAzimuth

#: Frames each setting runs: six, the two blind ones and one after them.
FRAMES = 9
#: Frames replaced by blind ones.
BLIND = (6, 7)
#: Settings whose ends take a second a frame (a search of the points' map over half a turn every
#: 0.1 degree, or over 8 degrees every 1e-4 rad), run over fewer frames.
SLOW = {"point_yaw.search_rad": 3, "point_yaw.step_rad": 3}
#: Other settings with which a value at the end of its range is valid: eps_min below eps_max, one
#: yaw model (the manoeuvre model's acceleration is above the steady one's), the step below the
#: search, the largest noise at least the least.
PARTNERS = {"features.max_range_m": {"min_range_m": 0.0}, "icp.eps_max": {"eps_min": 0.0},
            "odometry.yaw_accel_std_radps2": {"yaw_manoeuvre_accel_std_radps2": None},
            "point_yaw.search_rad": {"step_rad": config_limits.MIN_SEARCH_STEP_RAD},
            "point_yaw.step_rad": {"search_rad": math.pi}, "point_yaw.min_noise_rad": {"max_noise_rad": 1.0},
            "point_yaw.max_noise_rad": {"min_noise_rad": 1e-6}}
SECTIONS = {"velocity": config_limits.VELOCITY, "features": config_limits.FEATURES, "icp": config_limits.ICP,
            "odometry": config_limits.ODOMETRY, "point_yaw": config_limits.POINT_YAW,
            "wall_map": config_limits.WALL_MAP}
#: The CFAR sections' numbers the CFAR's own checks bound (pfa in (0, 1), os_rank up to 2 train, threshold_db in [0, 200]
#: dB).
CFAR_OWN = ("pfa", "os_rank", "threshold_db")
WHEELED = ("mount_x_m", "mount_y_m", "mount_yaw_rad", "min_lever_arm_m", "doppler_yaw_rate_noise_radps",
           "doppler_yaw_min_rate_radps", "axis_learn_frames", "axis_straight_radps", "axis_min_speed_mps",
           "no_slip_angle_std_rad")


def _numbers(cls: type) -> dict[str, type]:
    """The numeric fields of a settings class (Optional ones too): name -> int or float."""
    hints = typing.get_type_hints(cls)
    out = {}
    for f in dataclasses.fields(cls):
        hint = hints[f.name]
        kinds = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
        if f.init and bool not in kinds and (int in kinds or float in kinds):
            out[f.name] = int if int in kinds else float
    return out


def _fields() -> list[tuple[str, type]]:
    """Every numeric setting, by its path in a settings file, with its kind."""
    cfg = EstimatorConfig()
    out = [(f"{section}.{name}", kind) for section in SECTIONS
           for name, kind in _numbers(type(getattr(cfg, section))).items()]
    cfar = {"guard": int, "train": int, "threshold_db": float, "pfa": float, "os_rank": int, "channels": int}
    assert set(cfar) == set(_numbers(CfarParams)), "a CFAR number this test does not know"
    return out + [(f"features.{section}.{name}", kind) for section in ("cfar", "cfar_azimuth")
                  for name, kind in cfar.items()]


FIELDS = _fields()


def _limit(path: str) -> config_limits.Limit | None:
    parts = path.split(".")
    text = config_limits.CFAR.get(parts[-1]) if len(parts) == 3 else SECTIONS[parts[0]].get(parts[-1])
    return None if text is None else config_limits.limit(text)


def _settings(path: str, value) -> dict:
    """A settings file's contents giving *path* the *value*, with the option that makes it act."""
    defaults = EstimatorConfig().to_dict()
    section, *rest = path.split(".")
    name = rest[-1]
    if len(rest) == 2:  # a CFAR section is given whole
        cfar = {**defaults["features"][rest[0]], name: value}
        if name == "pfa":
            cfar["threshold_db"] = None
        if name == "os_rank":
            cfar["method"] = "os"
        return {"features": {"method": "cfar", rest[0]: cfar}}
    settings = {section: {name: value}}
    if section in ("point_yaw", "wall_map"):
        settings[section]["use"] = True
    if section == "odometry" and name in WHEELED:
        settings["odometry"] = {"base": "wheeled", "mount_x_m": 0.3, "axis_learn_frames": 3, name: value}
    return settings


# ----------------------------------------------------------------------------- the frames
@dataclasses.dataclass
class Frames:
    times: list[float]
    points: list[np.ndarray]
    spectra: list[np.ndarray | None]  # None: a blind frame
    heatmaps: list[RangeAzimuth]
    processor: FrameProcessor
    range_bins: int
    made: dict[int, list[RangeAzimuth]] = dataclasses.field(default_factory=dict)

    def heatmaps_for(self, config: EstimatorConfig) -> list[RangeAzimuth]:
        """The heatmaps as radar-capture makes them for *config*: its features' Doppler cells."""
        cells = config.features.doppler_cells
        if cells == EstimatorConfig().features.doppler_cells:
            return self.heatmaps
        if cells not in self.made:
            maker = HeatmapMaker(self.processor, doppler_cells=cells)
            self.made[cells] = [hm if spectrum is None else maker.range_azimuth(spectrum)
                                for spectrum, hm in zip(self.spectra, self.heatmaps)]
        return self.made[cells]


def _blind(hm: RangeAzimuth, rng: np.random.Generator) -> RangeAzimuth:
    """*hm*'s axes seeing nothing (the radar covered): noise at its median level, no Doppler."""
    level = float(np.median(hm.intensity))
    noise = (level * rng.exponential(size=hm.intensity.shape)).astype(hm.intensity.dtype)
    return RangeAzimuth(noise, noise / 16, np.full_like(hm.doppler_mps, np.nan), hm.range_m, hm.azimuth_rad,
                        hm.elevation_rad)


@pytest.fixture(scope="module")
def frames() -> Frames:
    ref = resources.files("radarodom.driver.sim").joinpath("scenes", "corridor.toml")
    spec = tomllib.loads(ref.read_text(encoding="utf-8"))
    spec["trajectory"]["start"] = [14.0, 0.0, 0.0]
    spec["trajectory"]["segments"] = [{"straight": 0.4, "speed": 1.0}, {"turn": 90, "radius": 0.8, "speed": 0.8}]
    cfg = RadarConfig.from_file(shipped_config_path())
    sim = Simulator(cfg, scene_from_dict(spec, where="corridor-turn"), seed=0, duration_s=FRAMES * 0.1,
                    fidelity="fast")
    processor = FrameProcessor(cfg)
    maker = HeatmapMaker(processor, doppler_cells=EstimatorConfig().features.doppler_cells)
    out = Frames([], [], [], [], processor, 0)
    rng = np.random.default_rng(0)
    for i in range(min(FRAMES, sim.num_frames)):
        frame = sim.frame(i)
        result = processor.process(sim.layout.decode(frame.raw))
        hm = maker.range_azimuth(result.spectrum)
        blind = i in BLIND
        out.times.append(frame.timestamp)
        out.points.append(result.points[:0].copy() if blind else result.points.copy())  # the processor's buffer
        out.spectra.append(None if blind else result.spectrum.copy())
        out.heatmaps.append(_blind(hm, rng) if blind else hm)
    out.range_bins = len(out.heatmaps[0].range_m)
    return out


def _run(config: EstimatorConfig, frames: Frames, count: int = FRAMES) -> None:
    """*config* through the odometry over the first *count* frames: no error, no RuntimeWarning,
    finite poses."""
    odometry = RadarOdometry(config)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        for t, points, hm in list(zip(frames.times, frames.points, frames.heatmaps_for(config)))[:count]:
            state = odometry.step(t, points, hm)
            assert all(math.isfinite(v) for v in (state.x, state.y, state.yaw)), state


def _refused_or_runs(path: str, value, frames: Frames, *, in_range: bool) -> None:
    settings = _settings(path, value)
    if in_range:
        settings[path.split(".")[0]].update(PARTNERS.get(path, {}))
    try:
        config = EstimatorConfig.from_dict(settings)
        config.features.check_heatmap_range(frames.range_bins)  # what radar-capture checks before the frames
    except ConfigError as exc:
        if in_range:  # only a condition between fields (the steady yaw model below the manoeuvre one's
            # least acceleration) or the heatmap (a CFAR window longer than its range axis) may refuse it
            assert not exc.message.startswith("must be in"), str(exc)
            assert exc.field.split(".")[0] == path.split(".")[0], str(exc)
            return
        assert exc.field == path, str(exc)
        limit = _limit(path)
        if limit is not None and len(path.split(".")) == 2:  # the CFAR's own checks say theirs first
            spelled = f"{value:g}" if isinstance(value, float) else quoted(value)  # 10^308: cut
            assert exc.message == f"must be in {limit.text}, got {spelled}", str(exc)
        return
    _run(config, frames, SLOW.get(path, FRAMES))


def _extremes(kind: type) -> tuple:
    return (10 ** 308, 10 ** 30, 0, -1) if kind is int else (1e308, 1e30, 0.0, -1.0)


@pytest.mark.parametrize("path,value", [(p, v) for p, kind in FIELDS for v in _extremes(kind)],
                         ids=lambda x: x if isinstance(x, str) else f"{x:.0e}" if abs(x) > 1e6 else repr(x))
def test_an_extreme_value_is_refused_naming_the_field_or_runs(path, value, frames):
    _refused_or_runs(path, value, frames, in_range=False)


def _ends(path: str, kind: type) -> list:
    """The ends of *path*'s range, or the nearest values inside an open end; the smallest
    positive float above an open 0."""
    limit = _limit(path)
    if limit is None:
        return []
    if kind is int:
        return [int(limit.low) + limit.low_open, int(limit.high) - limit.high_open]
    low = math.nextafter(limit.low, math.inf) if limit.low_open else limit.low
    return [low, math.nextafter(limit.high, -math.inf) if limit.high_open else limit.high]


@pytest.mark.parametrize("path,value", [(p, v) for p, kind in FIELDS for v in _ends(p, kind)],
                         ids=lambda x: x if isinstance(x, str) else f"{x:.6g}")
def test_the_ends_of_a_range_run(path, value, frames):
    _refused_or_runs(path, value, frames, in_range=True)


def test_every_numeric_setting_has_a_range():
    for path, _ in FIELDS:
        assert _limit(path) is not None or path.split(".")[-1] in CFAR_OWN, path
    for section, table in SECTIONS.items():  # and every range a setting
        assert set(table) <= set(_numbers(type(getattr(EstimatorConfig(), section)))), section


@pytest.mark.parametrize("config", [EstimatorConfig(), EstimatorConfig.paper(), EstimatorConfig.tidemo(),
                                    *(c for _, c in paper_variants().values())], ids=lambda c: "")
def test_the_shipped_settings_are_inside_the_ranges(config):
    # They are made through the same checks; made again from their own dict, they are equal.
    assert EstimatorConfig.from_dict(config.to_dict()) == config


@pytest.mark.parametrize("settings,message", [
    ({"odometry": {"yaw_noise_rad": 1e308}}, "odometry.yaw_noise_rad: must be in [1e-6, 1] rad, got 1e+308"),
    ({"odometry": {"velocity_history": 10 ** 30}},
     "odometry.velocity_history: must be in [2, 1e6], got 1000000000000000000000000000000"),
    ({"odometry": {"yaw_manoeuvre_start_prob": 0}}, "odometry.yaw_manoeuvre_start_prob: must be in (0, 1), got 0"),
    ({"velocity": {"ransac_iterations": 100000}}, "velocity.ransac_iterations: must be in [1, 1e4], got 100000"),
    ({"features": {"cfar": {"method": "ca", "guard": 2, "train": 8, "threshold_db": 1e30}}},
     "features.cfar.threshold_db: must be in [0, 200] dB, got 1e+30"),
])
def test_the_message_says_the_field_and_its_range(settings, message):
    with pytest.raises(ConfigError) as info:
        EstimatorConfig.from_dict(settings)
    assert str(info.value) == message


def test_radar_capture_names_the_file_the_field_and_its_range(tmp_path):
    path = tmp_path / "estimator.json"
    path.write_text('{"odometry": {"yaw_noise_rad": 1e308}}')
    proc = subprocess.run([sys.executable, "-m", "radarodom.tools.radar_capture", "--source", "sim://corridor",
                           "--no-publish", "--estimator-config", str(path)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2, proc.stderr
    message = "odometry.yaw_noise_rad: must be in [1e-6, 1] rad, got 1e+308"
    assert proc.stderr == f"radar-capture: error: {path}: {message}\n"


@pytest.mark.parametrize("settings,message", [
    # Each ran out of memory ("internal error: MemoryError") or took a gigabyte and a second a frame.
    ({"icp": {"scan_step_rad": 1e-4, "max_rotation_rad": math.pi, "scan_points": 100000}},
     "icp.scan_step_rad: +/- max_rotation_rad 3.14159 every 0.0001 is 62833 rotations of 100000 points "
     "(scan_points): 6.28e+09 scores at once, at most 2e+07; a coarser scan_step_rad, a narrower "
     "max_rotation_rad or fewer scan_points"),
    ({"icp": {"field_step_rad": 1e-4, "field_search_rad": 3.0}}, "icp.field_step_rad: +/- field_search_rad 3 "
     "every 0.0001 is 60001 rotations of 400 points (scan_points)"),
    ({"odometry": {"keyframe_search_rad": 3.0}, "icp": {"scan_step_rad": 1e-4}},
     "icp.scan_step_rad: +/- odometry.keyframe_search_rad 3 every 0.0001 is 60001 rotations of 400 points "
     "(icp.scan_points)"),
    ({"point_yaw": {"search_rad": 3.0, "step_rad": 1e-4, "coarse_step_rad": None}},
     "point_yaw.step_rad: +/- search_rad 3 every 0.0001 is 60001 rotations, each scored against every point "
     "pair at once: at most 2000; a coarser step_rad or a narrower search_rad"),
    ({"point_yaw": {"coarse_step_rad": 0.5, "step_rad": 1e-4}}, "point_yaw.step_rad: +/- coarse_step_rad 0.5 "
     "every 0.0001 is 10001 rotations"),
    ({"point_yaw": {"relocate_step_rad": 1e-4}}, "point_yaw.relocate_step_rad: +/- search_rad 0.139626 every "
     "0.0001 is 2795 rotations"),
])
def test_a_rotation_search_too_large_to_hold_is_refused_naming_its_fields(settings, message):
    with pytest.raises(ConfigError) as info:
        EstimatorConfig.from_dict(settings)
    assert str(info.value).startswith(message)


def test_a_fine_search_that_fits_is_taken():
    config = EstimatorConfig.from_dict({"icp": {"scan_step_rad": 1e-3}, "point_yaw": {"coarse_step_rad": None}})
    assert config.icp.scan_step_rad == 1e-3 and config.point_yaw.coarse_step_rad is None
