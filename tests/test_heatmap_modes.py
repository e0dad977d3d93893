"""The heatmap's fast mode (dominant Doppler for the strongest cells only) agrees with
the full computation where it gives values."""

from __future__ import annotations

import numpy as np
import pytest

from radarodom.driver.sim.scene import load_scene
from radarodom.driver.sim.simulator import Simulator
from radarodom.dsp.heatmap import HeatmapMaker
from radarodom.dsp.processor import FrameProcessor


@pytest.fixture(scope="module")
def spectrum_and_processor():
    from radarodom.cfg import RadarConfig, shipped_config_path

    cfg = RadarConfig.from_file(shipped_config_path())
    sim = Simulator(cfg, load_scene("lab"), seed=3, fidelity="fast")  # a person walks through
    proc = FrameProcessor(cfg)
    return proc.process(sim.layout.decode(sim.frame(60).raw)).spectrum.copy(), proc


def test_strong_cells_mode_matches_the_full_heatmap(spectrum_and_processor):
    spectrum, proc = spectrum_and_processor
    full = HeatmapMaker(proc).range_azimuth(spectrum)
    fast = HeatmapMaker(proc, doppler_cells=200).range_azimuth(spectrum)
    scale = full.intensity.max()
    np.testing.assert_allclose(fast.intensity, full.intensity, rtol=1e-3, atol=1e-5 * scale)
    np.testing.assert_allclose(fast.static, full.static, rtol=1e-3, atol=1e-5 * full.static.max())
    known = ~np.isnan(fast.doppler_mps)
    assert known.sum() == 200
    # The cells with a Doppler value are the 200 strongest.
    assert fast.intensity[known].min() >= np.sort(fast.intensity.ravel())[-200] * (1 - 1e-6)
    np.testing.assert_allclose(fast.doppler_mps[known], full.doppler_mps[known], atol=1e-6)


def test_strong_cells_mode_with_more_cells_than_the_map(spectrum_and_processor):
    spectrum, proc = spectrum_and_processor
    fast = HeatmapMaker(proc, doppler_cells=10**9).range_azimuth(spectrum)
    assert not np.isnan(fast.doppler_mps).any()
