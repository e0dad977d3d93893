"""ColoRadar's coupling calibration (calib/single_chip/coupling_calib.txt): read as the dataset's
tools read it, and removed from single_chip_adc frames as its official processing removes it
(behind a periodic Blackman window, from FFT bins 1 .. num_range_bins).

The coupling here is synthetic and known: a static leakage tone added to every chirp of a
simulated run, and the file written from it the way the dataset defines the values.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from coloradar_synth import write_run

from radarodom.antenna import TX_OFFSETS_HALF_WAVELENGTHS
from radarodom.calibration import RangeCoupling
from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.coloradar.coupling import FIRST_BIN, coupling_file_text, periodic_blackman, read_coupling
from radarodom.driver.sim.scene import scene_from_dict
from radarodom.driver.sim.simulator import Simulator
from radarodom.driver.sources import open_source
from radarodom.dsp.processor import FrameProcessor
from radarodom.errors import CaptureFormatError, ConfigError
from radarodom.pipeline import FrameProducts

#: The synthetic leakage's beat range, m: far enough out to make a point if left in.
LEAK_RANGE_M = 1.0


def leakage(cfg: RadarConfig, seed: int = 5) -> np.ndarray:
    """A static tone at LEAK_RANGE_M on every element, its own amplitude and phase on each:
    complex (tx_slots, rx, samples), ADC counts, the same for every chirp."""
    rng = np.random.default_rng(seed)
    n = np.arange(cfg.num_samples)
    cycles = LEAK_RANGE_M / cfg.range_resolution_m / cfg.num_samples  # beat cycles per sample
    amp = rng.uniform(150, 300, (cfg.num_tx_slots, cfg.num_rx)) * np.exp(1j * rng.uniform(0, 2 * np.pi, (cfg.num_tx_slots, cfg.num_rx)))
    return amp[..., None] * np.exp(2j * np.pi * cycles * n)[None, None, :]


def coupling_values(signal: np.ndarray, n_bins: int) -> np.ndarray:
    """The dataset's definition: the signal behind a periodic Blackman window, unnormalised FFT,
    bins 1 .. n_bins (DC skipped)."""
    spectrum = np.fft.fft(signal * periodic_blackman(signal.shape[-1]), axis=-1)
    return spectrum[..., FIRST_BIN:FIRST_BIN + n_bins]


# ------------------------------------------------------------------ the file
def test_file_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    values = rng.normal(size=(3, 4, 64)) + 1j * rng.normal(size=(3, 4, 64))
    path = tmp_path / "coupling_calib.txt"
    path.write_text(coupling_file_text(values, 128))
    c = read_coupling(path, 128)
    np.testing.assert_allclose(c.values, values.astype(np.complex64))
    assert c.first_bin == 1 and c.values.shape == (3, 4, 64) and not c.is_zero
    np.testing.assert_allclose(c.window, 0.42 - 0.5 * np.cos(2 * np.pi * np.arange(128) / 128)
                               + 0.08 * np.cos(4 * np.pi * np.arange(128) / 128), atol=1e-7)
    # The dataset writes "key: value" with or without the space; the data comma-separated.
    text = path.read_text().replace(": ", ":")
    path.write_text(text)
    np.testing.assert_allclose(read_coupling(path, 128).values, c.values)


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace("num_rx: 4", "num_rx: four"), "num_rx must be a positive integer"),
    (lambda t: t.replace("num_range_bins: 64", "num_range_bins: 65"), "holds 1536 numbers"),
    (lambda t: t.replace("data: ", "data: x,"), "numbers separated by commas"),
    (lambda t: t.replace("num_doppler_bins: 128\n", ""), "missing num_doppler_bins"),
    (lambda t: t + "gain: 3\n", "expected one of"),
    (lambda t: t.replace("data: ", "data: nan,").replace(",0.0\n", "\n", 1), "not finite"),
    # It overflowed the DSP's float32, and the error blamed the ADC frame's samples.
    (lambda t: t.replace("data: 0.0,", "data: 1e300,"), r"data's number 1 is 1e\+300, more than 1e\+09"),
])
def test_file_errors_name_the_file(tmp_path, edit, words):
    path = tmp_path / "coupling_calib.txt"
    path.write_text(edit(coupling_file_text(np.zeros((3, 4, 64)), 128)))
    with pytest.raises(CaptureFormatError, match=words) as info:
        read_coupling(path, 128)
    assert str(path) in str(info.value)


def test_more_bins_than_the_fft_is_refused(tmp_path):
    path = tmp_path / "coupling_calib.txt"
    path.write_text(coupling_file_text(np.zeros((3, 4, 64)), 16))
    with pytest.raises(CaptureFormatError, match="do not fit"):
        read_coupling(path, 64)


# ------------------------------------------------------------------ removing it
def test_the_processor_removes_the_coupling_exactly(shipped_cfg):
    """A frame of nothing but the leakage: behind the coupling's window, the bins the file covers
    come out empty in every chirp's range spectrum; bins it does not cover keep the leakage."""
    signal = leakage(shipped_cfg)
    cube = np.broadcast_to(signal[None], shipped_cfg.cube_shape).astype(np.complex64)
    level = np.abs(FrameProcessor(shipped_cfg).range_fft(cube)).max()
    leak_bin = round(LEAK_RANGE_M / shipped_cfg.range_resolution_m)
    for n_bins in (shipped_cfg.num_samples // 2, leak_bin - 4):
        coupling = RangeCoupling(coupling_values(signal, n_bins), FIRST_BIN, periodic_blackman(shipped_cfg.num_samples))
        proc = FrameProcessor(shipped_cfg, coupling=coupling)
        np.testing.assert_array_equal(proc.w_range, coupling.window)
        spectrum = proc.range_fft(cube)
        assert np.abs(spectrum[..., FIRST_BIN:FIRST_BIN + n_bins]).max() < 1e-4 * level
    # The short file ends four bins before the leakage's peak: the peak stays.
    assert np.abs(spectrum[..., leak_bin]).max() > 0.1 * level


def test_a_zero_coupling_changes_nothing(shipped_cfg):
    zero = RangeCoupling(np.zeros((3, 4, 128)), FIRST_BIN, periodic_blackman(256))
    assert zero.is_zero
    proc = FrameProcessor(shipped_cfg, coupling=zero)
    np.testing.assert_array_equal(proc.w_range, FrameProcessor(shipped_cfg).w_range)  # the usual window


def test_a_coupling_that_does_not_fit_the_cfg_is_refused(shipped_cfg, small_cfg):
    coupling = RangeCoupling(np.ones((3, 4, 8), np.complex64), FIRST_BIN, periodic_blackman(256), origin="c.txt")
    with pytest.raises(ConfigError, match="c.txt"):
        FrameProcessor(small_cfg, coupling=coupling)  # 16 samples
    from radarodom.dsp.config import DspConfig

    with pytest.raises(ConfigError, match="zero"):
        FrameProcessor(shipped_cfg, DspConfig(range_fft_size=512), coupling=coupling)
    with pytest.raises(ConfigError, match="tx_slots, rx, bins"):
        RangeCoupling(np.ones((3, 8)), FIRST_BIN, periodic_blackman(256))


def _run_with_leakage(tmp_path, cfg, coupling_file: str):
    """A ColoRadar run of a simulated corner reflector whose ADC frames carry the leakage, with
    *coupling_file* as its calib/single_chip/coupling_calib.txt."""
    scene = scene_from_dict({"objects": [{"type": "corner_reflector", "position": [4.0, 1.0, 0.4]}],
                             "trajectory": {"segments": [{"pause": 1.0}]}})
    sim = Simulator(cfg, scene)
    signal = leakage(cfg)
    cubes = [(sim.layout.decode(sim.frame(i).raw) + signal[None]).transpose(1, 2, 0, 3) for i in range(3)]
    p = cfg.profile
    waveform = {"adc_sample_frequency": cfg.sample_rate_hz, "start_frequency": cfg.start_frequency_hz,
                "idle_time": p.idle_time_us * 1e-6, "adc_start_time": p.adc_start_time_us * 1e-6,
                "ramp_end_time": p.ramp_end_time_us * 1e-6, "frequency_slope": cfg.slope_hz_per_s}
    run = write_run(tmp_path, "leaky_run", frames=3, adc={"single_chip": cubes},
                    times={"single_chip/adc_samples": np.arange(3) * 0.1},
                    waveforms={"single_chip": waveform},
                    tx_positions={"single_chip": [TX_OFFSETS_HALF_WAVELENGTHS[t - 1] for t in cfg.tx_order]})
    (tmp_path / "calib" / "single_chip" / "coupling_calib.txt").write_text(coupling_file)
    return run, signal


def _points(run) -> list[np.ndarray]:
    url = f"coloradar://{run}?velocity=single_chip_adc&heatmap=single_chip_adc&rate=max"
    with open_source(url) as source:
        products = FrameProducts(source.config, coupling=source.coupling)
        return [products(frame).points.copy() for frame in source if frame.role == "velocity"]


def test_single_chip_adc_frames_have_their_coupling_removed(tmp_path):
    """End to end through coloradar://: with the run's coupling file the leakage makes no point;
    with a file of zeros (nothing to remove) it makes one at its range in every frame."""
    cfg = RadarConfig.from_file(shipped_config_path())
    signal = leakage(cfg)
    n_bins = cfg.num_samples // 2
    good = coupling_file_text(coupling_values(signal, n_bins), cfg.num_loops)
    run, _ = _run_with_leakage(tmp_path / "a", cfg, good)
    with open_source(f"coloradar://{run}?velocity=single_chip_adc&heatmap=single_chip_adc") as source:
        assert source.coupling is not None and source.coupling.values.shape == (3, 4, n_bins)
    for points in _points(run):
        assert not np.any(np.abs(points["range"] - LEAK_RANGE_M) < 0.15), points[["range", "snr_db"]]
        assert np.any(np.abs(points["range"] - math.hypot(4.0, 1.0)) < 0.1)  # the reflector stays
    zeros = coupling_file_text(np.zeros((3, 4, n_bins)), cfg.num_loops)
    leaky, _ = _run_with_leakage(tmp_path / "b", cfg, zeros)
    for points in _points(leaky):
        assert np.any(np.abs(points["range"] - LEAK_RANGE_M) < 0.15)
