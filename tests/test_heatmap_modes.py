"""The heatmap's fast mode (dominant Doppler for the strongest cells only) agrees with
the full computation where it gives values."""

from __future__ import annotations

import numpy as np
import pytest

from radarodom.driver.sim.scene import load_scene
from radarodom.driver.sim.simulator import Simulator
from radarodom.dsp.heatmap import HeatmapMaker
from radarodom.dsp.processor import FrameProcessor
from radarodom.errors import UsageError


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


def _reference_range_azimuth(proc, spectrum, static_bins):
    """Cell by cell, from the definition: each range bin's TDM-compensated azimuth row
    through the zero-padded azimuth FFT (fftshifted), power summed over Doppler (all),
    over the static rows, and the Doppler bin of the strongest power; range bins up to the
    processor's detection range."""
    nd, slots, nrx, _ = spectrum.shape
    nr = proc.heatmap_range_bins
    flat = spectrum[..., :nr].reshape(nd, slots * nrx, nr).astype(np.complex128)
    row = flat[:, proc.az_elements, :]  # (n_doppler, row, n_range)
    if proc.params.tdm_compensation:  # slot m of Doppler bin k lags by 2 pi k m / (slots n_doppler)
        slot = np.repeat(np.arange(slots), nrx)[proc.az_elements]
        row = row * np.exp(-2j * np.pi * np.outer(proc.doppler_bins, slot) / (slots * proc.n_doppler))[:, :, None]
    padded = np.zeros((nd, proc.n_az, nr), np.complex128)
    padded[:, proc.az_h, :] = row
    power = np.abs(np.fft.fftshift(np.fft.fft(padded, axis=1), axes=1)) ** 2  # (n_doppler, n_az, n_range)
    centre = proc.n_doppler // 2
    static = power[centre - static_bins:centre + static_bins + 1].sum(axis=0).T
    # Cells whose strongest Doppler bin leads the next by 0.1 % or more: float32 must agree.
    top2 = np.sort(power, axis=0)[-2:]
    clear = (top2[1] > 1.001 * top2[0]).T
    return power.sum(axis=0).T, static, proc.velocity_mps[power.argmax(axis=0).T], clear


@pytest.mark.parametrize("tx_masks, doppler_size", [((1, 4, 2), None), ((1, 2, 4), 67)])
def test_both_modes_match_the_definition(tx_masks, doppler_size):
    """Full and fast modes against a direct float64 computation, for the shipped TX order
    (azimuth row = elements 0-7) and for TX1, TX2, TX3 (azimuth row = elements 0-3 and
    8-11, not consecutive), with an odd, zero-padded Doppler size and two static bins."""
    from radarodom.cfg import RadarConfig, shipped_config_path
    from radarodom.dsp.config import DspConfig

    text = open(shipped_config_path(), encoding="utf-8").read()
    for i, mask in enumerate(tx_masks):
        old = next(ln for ln in text.splitlines() if ln.startswith(f"chirpCfg {i} {i} "))
        text = text.replace(old, " ".join(old.split()[:-1] + [str(mask)]))
    cfg = RadarConfig.from_text(text)
    sim = Simulator(cfg, load_scene("lab"), seed=3, fidelity="fast")
    proc = FrameProcessor(cfg, DspConfig(doppler_fft_size=doppler_size))
    spectrum = proc.process(sim.layout.decode(sim.frame(60).raw)).spectrum
    if tx_masks == (1, 2, 4):
        assert proc.az_elements.tolist() == [0, 1, 2, 3, 8, 9, 10, 11]
    intensity, static, dominant, clear = _reference_range_azimuth(proc, spectrum, static_bins=2)
    assert clear.mean() > 0.99
    full = HeatmapMaker(proc, static_bins=2).range_azimuth(spectrum)
    fast_maker = HeatmapMaker(proc, static_bins=2, doppler_cells=300)
    fast_maker.range_azimuth(spectrum)
    fast = fast_maker.range_azimuth(spectrum)  # twice: the work buffers are reused
    for heatmap in (full, fast):
        np.testing.assert_allclose(heatmap.intensity, intensity, rtol=1e-4, atol=1e-6 * intensity.max())
        np.testing.assert_allclose(heatmap.static, static, rtol=1e-4, atol=1e-6 * static.max())
        assert heatmap.intensity.dtype == heatmap.static.dtype == heatmap.doppler_mps.dtype == np.float32
        assert heatmap.intensity.flags.c_contiguous and heatmap.static.flags.c_contiguous
    np.testing.assert_array_equal(full.doppler_mps[clear], dominant[clear].astype(np.float32))
    known = ~np.isnan(fast.doppler_mps)
    assert known.sum() == 300
    np.testing.assert_array_equal(fast.doppler_mps[known & clear], dominant[known & clear].astype(np.float32))


@pytest.mark.parametrize("doppler_cells", [None, 300], ids=["full", "strong cells"])
def test_each_cell_carries_the_elevation_of_its_power(doppler_cells):
    """A reflector's cell says its elevation (from the raised row, as a detection's does), in
    both modes; a 2-TX array has no raised row and says nothing."""
    from sim_helpers import point_scene

    from radarodom.cfg import RadarConfig, shipped_config_path

    cfg = RadarConfig.from_file(shipped_config_path())
    # (x ahead, y left, z up) from a sensor 0.4 m up: elevations about -4, +6, +12, +21 degrees.
    where = [(4.0, 1.5, 0.1), (5.0, -1.0, 0.95), (3.5, 0.0, 1.15), (3.0, -2.0, 1.8)]
    sim = Simulator(cfg, point_scene(where, snr_db=20.0), seed=1)
    proc = FrameProcessor(cfg)
    hm = HeatmapMaker(proc, doppler_cells=doppler_cells).range_azimuth(
        proc.process(sim.layout.decode(sim.frame(3).raw)).spectrum)
    assert hm.elevation_rad is not None and hm.elevation_rad.shape == hm.intensity.shape
    for x, y, z in where:
        dz = z - 0.4
        r = float(np.sqrt(x * x + y * y + dz * dz))
        u = -y / r  # the heatmap's azimuth axis is arcsin of the direction's rightward component
        ri = int(np.argmin(np.abs(hm.range_m - r)))
        ai = int(np.argmin(np.abs(np.sin(hm.azimuth_rad) - u)))
        window = hm.intensity[ri - 1:ri + 2, ai - 1:ai + 2]
        dr, da = np.unravel_index(np.argmax(window), window.shape)
        measured = np.degrees(hm.elevation_rad[ri - 1 + dr, ai - 1 + da])
        assert measured == pytest.approx(np.degrees(np.arcsin(dz / r)), abs=1.5)


def test_a_two_tx_array_gives_no_elevation():
    from radarodom.cfg import RadarConfig, shipped_config_path

    with open(shipped_config_path(), encoding="utf-8") as fh:
        text = fh.read()
    two_tx = (text.replace("channelCfg 15 7 0", "channelCfg 15 5 0").replace("chirpCfg 2 2 0 0 0 0 0 2\n", "")
              .replace("frameCfg 0 2 ", "frameCfg 0 1 "))
    cfg = RadarConfig.from_text(two_tx)
    assert cfg.num_tx == 2
    proc = FrameProcessor(cfg)
    spectrum = np.zeros((proc.n_doppler, 2, 4, proc.n_range), np.complex64)
    for cells in (None, 50):
        assert HeatmapMaker(proc, doppler_cells=cells).range_azimuth(spectrum).elevation_rad is None


@pytest.mark.parametrize("argument, value, wanted", [
    ("doppler_cells", 0, "a whole number >= 1 (the strongest cells given their Doppler), or None for every cell's, "
                         "got 0"),
    ("doppler_cells", "5", "got '5'"),
    ("doppler_cells", 2.5, "got 2.5"),
    ("doppler_cells", True, "got True"),
    ("static_bins", -1, "a whole number of Doppler bins each side of zero Doppler, from 0 to 31, got -1"),
    ("static_bins", 32, "from 0 to 31, got 32"),
    ("static_bins", "2", "got '2'"),
    ("elevation_bins", 0, "a whole number >= 1, or None for the DSP's elevation_fft_size, got 0"),
    ("elevation_bins", "x", "got 'x'"),
])
def test_bad_arguments_are_refused_naming_them(spectrum_and_processor, argument, value, wanted):
    """Once numpy's ValueError or TypeError from inside the first frame (a str, or no cells: a
    matmul's core dimension); now the package's error, when the maker is built."""
    _, proc = spectrum_and_processor
    with pytest.raises(UsageError) as info:
        HeatmapMaker(proc, **{argument: value})
    assert str(info.value).startswith(f"HeatmapMaker: {argument} must be "), str(info.value)
    assert str(info.value).endswith(wanted), str(info.value)


def test_numpy_whole_numbers_are_arguments_too(spectrum_and_processor):
    spectrum, proc = spectrum_and_processor
    maker = HeatmapMaker(proc, static_bins=np.int64(1), doppler_cells=np.int32(50))
    assert maker.doppler_cells == 50 and type(maker.doppler_cells) is int
    assert (~np.isnan(maker.range_azimuth(spectrum).doppler_mps)).sum() == 50


def test_a_processor_is_required():
    with pytest.raises(UsageError, match=r"^HeatmapMaker: processor must be a FrameProcessor \(FrameProcessor\(cfg\) "
                                         r"makes one\), got str 'configs/awr1843_raw.cfg'$"):
        HeatmapMaker("configs/awr1843_raw.cfg")
