"""Settings files as users write them.  A file names only what it changes, a CFAR section too: the
section's keys go over the field's default CFAR (they were refused as "missing key(s) method,
guard, train", and once those were added, the other CFAR's threshold was named as missing).  A key
put in the wrong section is named with where it goes."""

from __future__ import annotations

import json
import subprocess

import pytest
from conftest import console_command

from radarodom.dsp.config import DspConfig
from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig


def test_a_partial_cfar_section_keeps_the_default_cfars_other_keys():
    default = EstimatorConfig().features.cfar
    cfar = EstimatorConfig.from_dict({"features": {"cfar": {"threshold_db": 12}}}).features.cfar
    assert (cfar.method, cfar.guard, cfar.train, cfar.threshold_db, cfar.pfa) == \
        (default.method, default.guard, default.train, 12.0, None)
    assert EstimatorConfig().with_(features={"cfar": {"threshold_db": 12}}).features.cfar == cfar


def test_a_threshold_given_replaces_the_defaults_pfa_and_the_other_way_round():
    assert DspConfig().range_cfar.pfa is not None  # the DSP's default range CFAR is by Pfa
    cfar = DspConfig.from_dict({"range_cfar": {"threshold_db": 13}}).range_cfar
    assert (cfar.threshold_db, cfar.pfa, cfar.method, cfar.os_rank) == (13.0, None, "os", DspConfig().range_cfar.os_rank)
    azimuth = EstimatorConfig.from_dict({"features": {"cfar_azimuth": {"pfa": 1e-3}}}).features.cfar_azimuth
    default_guard = EstimatorConfig().features.cfar_azimuth.guard
    assert (azimuth.pfa, azimuth.threshold_db, azimuth.guard) == (1e-3, None, default_guard)


def test_another_method_drops_the_ordered_statistics_rank():
    cfar = DspConfig.from_dict({"range_cfar": {"method": "ca"}}).range_cfar
    assert (cfar.method, cfar.os_rank) == ("ca", None)


@pytest.mark.parametrize("section,message", [
    ({"guard": -1}, "features.cfar.guard: must be at least 0, got -1"),
    ({"threshold_db": 3, "pfa": 0.1},
     "features.cfar.threshold_db: give exactly one of threshold_db and pfa (both given)"),
    ({"nope": 1}, "features.cfar: unknown key(s) nope"),
    (5, "features.cfar: must be an object of CfarParams settings, got 5"),
])
def test_a_bad_key_of_a_partial_cfar_section_is_named(section, message):
    with pytest.raises(ConfigError) as err:
        EstimatorConfig.from_dict({"features": {"cfar": section}})
    assert str(err.value).startswith(message), str(err.value)


def test_a_partial_cfar_section_in_a_file_loads_and_round_trips(tmp_path):
    path = tmp_path / "estimator.json"
    path.write_text(json.dumps({"features": {"method": "cfar", "cfar": {"threshold_db": 12}}}))
    config = EstimatorConfig.load(path)
    assert config.features.method == "cfar" and config.features.cfar.threshold_db == 12.0
    config.dump(tmp_path / "again.json")
    assert EstimatorConfig.load(tmp_path / "again.json") == config


@pytest.mark.parametrize("data,message", [
    ({"icp": {"yaw_noise_rad": 0.1}}, "unknown estimator setting(s): icp.yaw_noise_rad (it is odometry.yaw_noise_rad)"),
    ({"blend": 0}, "unknown estimator setting(s): blend (it is point_yaw.blend)"),
    ({"features": {"icp": {}}}, "unknown estimator setting(s): features.icp (it is icp)"),
    ({"icp": {"nothing_like_it": 1}}, "unknown estimator setting(s): icp.nothing_like_it"),
    ({"zzz": 1, "blend": 0}, "unknown estimator setting(s): blend (it is point_yaw.blend), zzz"),
])
def test_an_unknown_key_is_named_with_where_such_a_key_goes(data, message):
    with pytest.raises(ConfigError) as err:
        EstimatorConfig.from_dict(data)
    assert str(err.value) == message


def test_the_dsps_misplaced_key_is_named_too():
    with pytest.raises(ConfigError) as err:
        DspConfig.from_dict({"range_cfar": {"threshold_db": 13}, "cfar": {}})
    assert "unknown DSP setting(s): cfar" in str(err.value)


def test_radar_capture_names_the_file_and_where_the_key_goes(tmp_path):
    path = tmp_path / "estimator.json"
    path.write_text(json.dumps({"blend": 0}))
    proc = subprocess.run(console_command("radar-capture") + ["--source", "sim://corridor?rate=max&duration=0.3",
                                                              "--no-publish", "--estimator-config", str(path)],
                          capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL, cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"radar-capture: error: {path}: unknown estimator setting(s): blend (it is point_yaw.blend)"], proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["estimator.json"]


def test_a_training_window_given_alone_keeps_the_ordered_statistics_quantile():
    """The DSP's range CFAR takes the median of its 16 training cells (os_rank 8): train 3 was
    refused for an os_rank the user never wrote, train 16 kept rank 8 of 32 (a quartile)."""
    default = DspConfig().range_cfar
    assert (default.method, default.train, default.os_rank) == ("os", 8, 8)
    assert DspConfig.from_dict({"range_cfar": {"train": 3}}).range_cfar.os_rank == 3
    assert DspConfig.from_dict({"range_cfar": {"train": 16}}).range_cfar.os_rank == 16
    assert DspConfig.from_dict({"range_cfar": {"train": 16, "os_rank": 5}}).range_cfar.os_rank == 5


def test_with_changes_a_cfar_over_this_configs_cfar_not_the_default():
    """with_ laid a CFAR's changes over the default CFAR: a config's own method and threshold were
    lost without a word."""
    mine = EstimatorConfig().with_(features={"cfar": {"method": "os", "guard": 3, "threshold_db": 15}})
    cfar = mine.with_(features={"cfar": {"guard": 4}}).features.cfar
    assert (cfar.method, cfar.guard, cfar.threshold_db) == ("os", 4, 15.0)
    cfar = mine.with_(features={"cfar": {"pfa": 1e-4}}).features.cfar
    assert (cfar.threshold_db, cfar.pfa, cfar.guard) == (None, 1e-4, 3)
    with pytest.raises(ConfigError) as info:
        mine.with_(features={"cfar": {"guard": -1}})
    assert str(info.value) == "features.cfar.guard: must be at least 0, got -1"


def test_features_beyond_the_heatmaps_reach_are_refused_before_the_run(tmp_path):
    """features.min_range_m of 100 m with a 10 m cfg ran with no feature and no word."""
    from radarodom.pipeline import Pipeline

    with pytest.raises(ConfigError) as info:
        Pipeline.from_url("sim://corridor?rate=max&duration=0.2",
                          estimator=EstimatorConfig().with_(features={"min_range_m": 100.0}))
    assert str(info.value) == ("features.min_range_m: 100 m: the heatmaps reach 9.99 m at most, so no cell would "
                               "be a feature; features nearer than it are left out (default 0.5 m)")
    path = tmp_path / "estimator.json"
    path.write_text(json.dumps({"features": {"min_range_m": 100}}))
    proc = subprocess.run(console_command("radar-capture") + ["--source", "sim://corridor?rate=max&duration=0.3",
                                                              "--no-publish", "--estimator-config", str(path),
                                                              "--odom-out", str(tmp_path / "odom.tum")],
                          capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL, cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert f"error: {path}: features.min_range_m: 100 m: the heatmaps reach 9.99 m" in proc.stderr
    assert not (tmp_path / "odom.tum").exists()


def test_a_method_given_in_capitals_keeps_the_ordered_statistics_quantile():
    """'OS' is the ordered statistic as 'os' is: given with a training window it lost the median
    (rank 24 of 32 instead of 16), alone it took 12 instead of 8."""
    for method in ("os", "OS", "Os"):
        assert DspConfig.from_dict({"range_cfar": {"method": method, "train": 16}}).range_cfar.os_rank == 16
        assert DspConfig.from_dict({"range_cfar": {"method": method}}).range_cfar.os_rank == 8
