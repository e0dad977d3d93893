"""The board's channel calibration (compRangeBiasAndRxChanPhase): the line as numbers, the
DSP applying it as TI's firmware does, and the simulator's imperfect boards.

The simulated board is the reference: its paths' gains are known, so the line that corrects
it is known (Board.calibration), and a calibrated imperfect board must look like a perfect one.
"""

from __future__ import annotations

import math
from importlib import resources

import numpy as np
import pytest
from sim_helpers import truth

from radarodom import cfg_commands as cc
from radarodom.calibration import ChannelCalibration, uncalibrated_note
from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.recordings.capture_dir import CaptureWriter
from radarodom.driver.sim.board import BUILTIN_BOARDS, Board, board_from_dict, load_board
from radarodom.driver.sim.scene import load_scene, scene_from_dict
from radarodom.driver.sim.simulator import Simulator
from radarodom.driver.sources import open_source
from radarodom.dsp.config import DspConfig
from radarodom.dsp.heatmap import CartesianGrid, HeatmapMaker
from radarodom.dsp.processor import FrameProcessor
from radarodom.errors import ConfigError, SourceError

#: The calibration scene's reflectors: world [x forward, y left, z up], the sensor 0.4 m high.
CALIBRATION_REFLECTORS = [(3.0, 0.0, 0.4), (5.0, -1.5, 0.4), (4.0, 2.0, 0.4), (6.0, 0.5, 1.0), (8.0, -3.0, 0.4)]


def with_tx_order(cfg: RadarConfig, masks) -> RadarConfig:
    """*cfg* with its three chirps transmitting on TX masks *masks* (chirp order)."""
    text = cfg.to_text()
    for i, mask in enumerate(masks):
        old = next(ln for ln in text.splitlines() if ln.startswith(f"chirpCfg {i} {i} "))
        text = text.replace(old, " ".join(old.split()[:-1] + [str(mask)]))
    return RadarConfig.from_text(text)


def calibrated(cfg: RadarConfig, calibration: ChannelCalibration) -> RadarConfig:
    return cfg.replace(calibration.to_command())


def cube_of(cfg, scene, board, frame=0, seed=0):
    sim = Simulator(cfg, scene, seed=seed, board=board)
    return sim.layout.decode(sim.frame(frame).raw)


# ------------------------------------------------------------------ the line as numbers
def test_pair_t4_plus_r_corrects_physical_tx_t_whatever_the_chirp_order(shipped_cfg):
    """TI's firmware reorders the table by txAntOrder: slot s gets the pairs of the TX it transmits on."""
    coefficients = np.array([[complex(t + 1, r + 1) / 10 for r in range(4)] for t in range(3)])
    cal = ChannelCalibration(0.0, coefficients)
    for masks in ((1, 4, 2), (1, 2, 4), (2, 1, 4), (4, 2, 1)):
        cfg = with_tx_order(shipped_cfg, masks)
        table = cal.for_array(cfg.virtual_array)
        for slot, mask in enumerate(masks):
            tx = mask.bit_length()  # TX number
            np.testing.assert_array_equal(table[slot], coefficients[tx - 1].astype(np.complex64))


def test_line_round_trips_through_the_cfg(shipped_cfg):
    board = load_board("uncalibrated")
    cal = board.calibration()
    cfg = calibrated(shipped_cfg, cal)
    back = cfg.channel_calibration
    assert back.range_bias_m == pytest.approx(board.range_bias_m, abs=1e-5)
    np.testing.assert_allclose(back.coefficients, cal.coefficients, atol=1e-5)
    # Written again from the parsed line: the same line.
    assert back.cfg_line() == cal.cfg_line() and back.to_command() == cal.to_command()
    assert RadarConfig.from_text(cfg.to_text()).channel_calibration.cfg_line() == cal.cfg_line()
    assert not back.is_identity and uncalibrated_note(cfg) is None


def test_identity_and_missing_line(shipped_cfg, small_cfg):
    for cfg in (shipped_cfg, small_cfg):  # the identity line, and no line at all
        cal = cfg.channel_calibration
        assert cal.is_identity
        np.testing.assert_array_equal(cal.coefficients, np.ones((3, 4)))
        assert uncalibrated_note(cfg) is not None
    assert "is the identity" in uncalibrated_note(shipped_cfg)
    assert "is missing" in uncalibrated_note(small_cfg)


def test_measured_coefficients_line_the_paths_up():
    """conj(x) min|x| / |x|^2: every corrected path has the weakest one's magnitude and one phase."""
    rng = np.random.default_rng(3)
    response = (10 ** (rng.uniform(-1.5, 1.5, (3, 4)) / 20)) * np.exp(1j * rng.uniform(-np.pi, np.pi, (3, 4)))
    cal = ChannelCalibration.from_response(response, 0.05)
    corrected = response * cal.coefficients
    np.testing.assert_allclose(np.abs(corrected), np.abs(response).min(), rtol=1e-12)
    np.testing.assert_allclose(np.angle(corrected * np.conj(corrected[0, 0])), 0.0, atol=1e-12)
    assert cal.coefficients[0, 0].imag == 0 and cal.coefficients[0, 0].real > 0
    assert np.all(np.abs(cal.coefficients) <= 1 + 1e-12)
    # What the line corrects, relative to TX1 RX1, is the response itself.
    np.testing.assert_allclose(cal.response, response / response[0, 0], rtol=1e-12)


def test_coefficients_too_large_for_the_firmware_are_scaled_together():
    cal = ChannelCalibration(0.0, np.full((3, 4), 1.5 + 0.5j))
    command = cal.to_command()
    parts = np.array([[v.real, v.imag] for v in command.rx_chan_phase])
    assert np.abs(parts).max() == pytest.approx(1.0)
    cfg = RadarConfig.from_file(shipped_config_path()).replace(command)  # the cfg parser accepts it
    np.testing.assert_allclose(np.angle(cfg.channel_calibration.coefficients), math.atan2(0.5, 1.5), atol=1e-4)


def test_a_zero_coefficient_is_refused():
    pairs = [complex(1, 0)] * 11 + [0j]
    with pytest.raises(ConfigError, match="TX3 RX4 is 0"):
        ChannelCalibration.from_command(cc.CompRangeBiasAndRxChanPhase(0.0, tuple(pairs)))


# ------------------------------------------------------------------ the DSP applies it
def _nearest(points, p):
    d = np.hypot(points["x"] - p[0], points["y"] - p[1])
    return points[int(np.argmin(d))]


def _check_reflectors(cfg, points, scene, t0, *, range_bins=1.0, azimuth_deg=4.0, elevation_deg=4.0):
    """Every reflector of the calibration scene has a point within *range_bins* bins and
    *azimuth_deg* of it, with its elevation within *elevation_deg*; returns the worst errors."""
    worst = np.zeros(3)
    for world in CALIBRATION_REFLECTORS:
        tr = truth(scene, cfg, world, t0)
        p = tr["p"]
        q = _nearest(points, p)
        err = np.array([abs(float(q["range"]) - tr["r"]) / cfg.range_resolution_m,
                        abs(math.degrees(float(q["azimuth"]) - math.atan2(p[0], p[1]))),
                        abs(math.degrees(float(q["elevation"]) - math.asin(p[2] / tr["r"])))])
        worst = np.maximum(worst, err)
    ok = worst[0] <= range_bins and worst[1] <= azimuth_deg and worst[2] <= elevation_deg
    return ok, worst


@pytest.mark.parametrize("masks", [(1, 4, 2), (2, 1, 4)], ids=["TI-order", "TX2-first"])
def test_calibrated_board_finds_every_reflector_at_its_place(shipped_cfg, masks):
    """An uncalibrated board whose cfg carries its line finds every corner reflector of the
    calibration scene within one range bin and 4 degrees, with the right elevation; without
    the line (the identity) it does not."""
    cfg = with_tx_order(shipped_cfg, masks)
    scene = load_scene("calibration")
    board = load_board("uncalibrated")
    cube = cube_of(cfg, scene, board)
    with_line = FrameProcessor(calibrated(cfg, board.calibration())).process(cube).points
    ok, worst = _check_reflectors(cfg, with_line, scene, 0.0)
    assert ok, worst
    # Range, azimuth and elevation as good as a perfect board's (docs/calibration.md, "Accuracy").
    assert worst[0] <= 0.5 and worst[1] <= 1.0 and worst[2] <= 1.0, worst
    without = FrameProcessor(cfg).process(cube).points
    ok, worst = _check_reflectors(cfg, without, scene, 0.0)
    assert not ok and worst[2] > 8.0, worst  # the uncorrected phases put the reflectors far off in elevation


def test_calibrated_board_looks_like_a_perfect_one(shipped_cfg):
    """Points and heatmaps of the uncalibrated board with its line against the perfect board's:
    the same reflectors at the same places, the heatmap's peaks in the same cells, its range
    axis starting at minus the bias."""
    scene = load_scene("calibration")
    board = load_board("uncalibrated")
    cfg = calibrated(shipped_cfg, board.calibration())
    proc, ideal_proc = FrameProcessor(cfg), FrameProcessor(shipped_cfg)
    res = proc.process(cube_of(shipped_cfg, scene, board))
    ideal = ideal_proc.process(cube_of(shipped_cfg, scene, Board()))
    assert len(res.points) == len(ideal.points) == 5
    for q in ideal.points:
        p = _nearest(res.points, (q["x"], q["y"]))
        # Both on their own range grid (the bias moves it by 1.3 bins): each within half a bin of
        # the truth, so within a bin of each other.
        assert abs(p["range"] - q["range"]) <= shipped_cfg.range_resolution_m + 1e-6
        assert abs(p["azimuth"] - q["azimuth"]) <= math.radians(1.0)
        assert abs(p["elevation"] - q["elevation"]) <= math.radians(1.0)
    hm = HeatmapMaker(proc).range_azimuth(res.spectrum)
    assert hm.range_m[0] == pytest.approx(-board.range_bias_m)
    step = shipped_cfg.range_resolution_m
    for q in ideal.points:  # each reflector's heatmap peak: in the same azimuth cell, range within a bin
        a = int(np.argmin(np.abs(hm.azimuth_rad - q["azimuth"])))
        rows = np.flatnonzero(np.abs(hm.range_m - q["range"]) <= 2 * step)
        cols = np.arange(max(a - 3, 0), min(a + 4, len(hm.azimuth_rad)))
        i, j = np.unravel_index(np.argmax(hm.static[np.ix_(rows, cols)]), (len(rows), len(cols)))
        assert abs(hm.range_m[rows[i]] - q["range"]) <= 1.5 * step
        assert abs(cols[j] - a) <= 1
    # The Cartesian grid reads the offset range axis: the 3 m reflector's peak lands at 3 m.
    grid = CartesianGrid(hm.range_m, hm.azimuth_rad, resolution_m=0.02, max_range_m=4.0)
    image = grid.resample(hm.static)
    ahead = (np.abs(grid.x)[None, :] < 0.3) & (grid.y[:, None] > 1.0)  # past the leakage at zero range
    iy, ix = np.unravel_index(np.argmax(image * ahead), image.shape)
    assert grid.y[iy] == pytest.approx(3.0, abs=shipped_cfg.range_resolution_m)


def test_calibrated_board_heatmap_shows_each_reflector_at_its_elevation(shipped_cfg):
    """The range-azimuth-elevation heatmap of the uncalibrated board whose cfg carries its line:
    each reflector's peak (the raised one at 6 m, 1 m high, 5.7 degrees up, among them) in the
    perfect board's cells, within a range bin of the truth and in the elevation cell nearest it;
    without the line the uncorrected phases put every reflector 9-15 degrees off in elevation."""
    scene = load_scene("calibration")
    board = load_board("uncalibrated")
    step = shipped_cfg.range_resolution_m

    def peaks(cfg, b):
        """Per reflector: (range m, azimuth deg, elevation deg) of its static heatmap peak."""
        proc = FrameProcessor(cfg)
        maker = HeatmapMaker(proc, elevation_bins=64)  # 1.8-degree cells near boresight
        hm = maker.range_azimuth_elevation(proc.process(cube_of(shipped_cfg, scene, b)).spectrum)
        found = []
        for world in CALIBRATION_REFLECTORS:
            r = truth(scene, shipped_cfg, world, 0.0)["r"]
            rows = np.flatnonzero(np.abs(hm.range_m - r) <= 2 * step)
            i, e, a = np.unravel_index(np.argmax(hm.static[rows]), hm.static[rows].shape)
            found.append((hm.range_m[rows[i]], math.degrees(hm.azimuth_rad[a]), math.degrees(hm.elevation_rad[e])))
        return np.array(found)

    perfect = peaks(shipped_cfg, Board())
    with_line = peaks(calibrated(shipped_cfg, board.calibration()), board)
    identity = peaks(shipped_cfg, board)
    for world, p, q, u in zip(CALIBRATION_REFLECTORS, perfect, with_line, identity):
        tr = truth(scene, shipped_cfg, world, 0.0)
        elevation = math.degrees(math.asin(tr["p"][2] / tr["r"]))
        assert abs(q[0] - tr["r"]) <= step and abs(q[0] - p[0]) <= step, (world, q, p)
        assert q[1] == p[1] and q[2] == p[2], (world, q, p)  # the same azimuth and elevation cells
        assert abs(q[2] - elevation) <= 1.0, (world, q, elevation)  # within the nearest cell
        assert abs(u[2] - elevation) > 8.0, (world, u, elevation)
    assert with_line[3][2] > 4.0  # the raised reflector is raised


def test_identity_line_costs_no_arithmetic(shipped_cfg):
    """The identity line multiplies nothing: no coefficient table, and the heatmap weights are
    the TDM phases alone (the first TX slot's rows untouched)."""
    proc = FrameProcessor(shipped_cfg)
    assert proc.point_maker.calibration_weights is None and proc.calibration.is_identity
    slots, nrx = shipped_cfg.num_tx_slots, shipped_cfg.num_rx
    tdm = np.exp(-2j * np.pi * np.outer(proc.doppler_bins, np.repeat(np.arange(slots), nrx)) / (slots * proc.n_doppler))
    np.testing.assert_allclose(proc.angle_weights, tdm, atol=1e-6)
    maker = HeatmapMaker(proc)
    assert maker._weighted_rows.start == 4  # TX1's four elements are not multiplied
    board = load_board("uncalibrated")
    off = FrameProcessor(calibrated(shipped_cfg, board.calibration()), DspConfig(channel_calibration=False))
    assert off.point_maker.calibration_weights is None and off.range_m[0] == 0.0


def test_every_point_has_range_equal_to_its_length(shipped_cfg):
    """range = |xyz|, azimuth = atan2(x, y), elevation = asin(z / r) for every exported point,
    reflectors at the edge of the field of view included (one came out 1.7 % long)."""
    objects = [{"type": "corner_reflector", "position": [r * math.cos(math.radians(a)), r * math.sin(math.radians(a)), z],
                "rcs_dbsm": 10.0}
               for r, a, z in ((3.0, 80.0, 0.4), (4.0, -82.0, 1.6), (3.5, 70.0, -0.5), (5.0, 0.0, 3.5),
                               (2.5, -60.0, 2.0), (6.0, 30.0, 0.4))]
    scene = scene_from_dict({"objects": objects, "trajectory": {"segments": [{"pause": 1.0}]}})
    for board in (Board(), load_board("uncalibrated")):
        points = FrameProcessor(shipped_cfg).process(cube_of(shipped_cfg, scene, board)).points
        assert len(points) >= 4
        xyz = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(float)
        r = points["range"].astype(float)
        np.testing.assert_allclose(np.linalg.norm(xyz, axis=1), r, rtol=1e-5)
        np.testing.assert_allclose(points["azimuth"], np.arctan2(points["x"], points["y"]), atol=1e-5)
        np.testing.assert_allclose(points["elevation"], np.arcsin(points["z"] / r), atol=1e-4)


# ------------------------------------------------------------------ the simulated board
def test_board_gains_and_bias_reach_the_samples(shipped_cfg):
    """At a boresight reflector's zero-Doppler cell each element carries its path's gain (the
    board's, in the frame's TX order); the range bias moves the peak by its length."""
    scene = scene_from_dict({"objects": [{"type": "corner_reflector", "position": [4.0, 0.0, 0.4]}],
                             "trajectory": {"segments": [{"pause": 1.0}]}})
    board = Board(range_bias_m=0.1, tx_gain_db=(0.0, -1.0, 2.0), tx_phase_deg=(0.0, 40.0, -70.0),
                  rx_gain_db=(0.0, 0.5, -0.5, 1.0), rx_phase_deg=(0.0, -20.0, 30.0, 90.0))
    proc = FrameProcessor(shipped_cfg, DspConfig(channel_calibration=False))
    spectra = [proc.doppler_fft(proc.range_fft(cube_of(shipped_cfg, scene, b))).copy() for b in (Board(), board)]
    zero = proc.n_doppler // 2
    peaks = [int(np.argmax((np.abs(s[zero]) ** 2).sum(axis=(0, 1)))) for s in spectra]
    assert (peaks[1] - peaks[0]) * shipped_cfg.range_resolution_m == pytest.approx(0.1, abs=shipped_cfg.range_resolution_m)
    # Compare at the same range offset from the peak: the ratio of the two boards' elements.
    ratio = spectra[1][zero, :, :, peaks[1]] / spectra[0][zero, :, :, peaks[0]]
    expected = board.for_array(shipped_cfg.virtual_array)
    rel = (ratio / ratio[0, 0]) / (expected / expected[0, 0])
    np.testing.assert_allclose(np.abs(rel), 1.0, atol=0.02)
    np.testing.assert_allclose(np.angle(rel), 0.0, atol=math.radians(1.0))


def test_board_leakage_makes_no_point(shipped_cfg):
    """The uncalibrated board's TX-to-RX leakage: strong near zero range and, through its
    negative frequencies, at the far end of the range FFT, both outside the detection range."""
    scene = scene_from_dict({"objects": [{"type": "corner_reflector", "position": [4.0, 1.0, 0.4]}],
                             "trajectory": {"segments": [{"pause": 1.0}]}})
    board = load_board("uncalibrated")
    cfg = calibrated(shipped_cfg, board.calibration())
    proc = FrameProcessor(cfg, DspConfig(min_range_m=0.0, max_range_m=20.0))
    everything = proc.process(cube_of(shipped_cfg, scene, board)).points
    near, far = everything["range"] < 0.3, everything["range"] > shipped_cfg.max_range_m
    assert near.any() and far.any(), everything[["range", "velocity", "snr_db"]]  # the leakage is there
    assert np.all(everything["doppler_bin"][near | far] == 0)
    points = FrameProcessor(cfg).process(cube_of(shipped_cfg, scene, board)).points
    assert len(points) == 1 and abs(points[0]["range"] - math.hypot(4.0, 1.0)) < shipped_cfg.range_resolution_m
    hm = HeatmapMaker(FrameProcessor(cfg)).range_azimuth(FrameProcessor(cfg).process(cube_of(shipped_cfg, scene, board)).spectrum)
    assert hm.range_m[-1] <= 10.0  # the cfg's cfarFovCfg: the heatmap ends with the detection range


def test_board_files_and_errors(tmp_path):
    assert BUILTIN_BOARDS == ("ideal", "uncalibrated")
    assert load_board("ideal").is_ideal and not load_board("uncalibrated").is_ideal
    path = tmp_path / "mine.toml"
    path.write_text('range_bias_m = 0.04\nrx_phase_deg = [0, 10, 20, 30]\n')
    board = load_board(str(path))
    assert board.name == "mine" and board.range_bias_m == 0.04 and board.has_channel_errors
    cases = [('rx_phase_deg = [0, 10]\n', "rx_phase_deg", "4 numbers"),
             ('range_bias_m = "x"\n', "range_bias_m", "finite number"),
             ('range_bias_m = 5.0\n', "range_bias_m", "within"),
             ('tx_gains = [0, 0, 0]\n', "tx_gains", "unknown key"),
             ('tx_gain_db = [0, 40, 0]\n', "tx_gain_db", "20 dB"),
             ('rx_gain_db = [0, 0, -25, 0]\n', "rx_gain_db", r"within \+/- 20 dB, got \[0.0, 0.0, -25.0, 0.0\]")]
    for text, field, words in cases:
        path.write_text(text)
        with pytest.raises(ConfigError, match=words) as info:
            load_board(str(path))
        assert info.value.field == field and info.value.path == str(path)
    with pytest.raises(ConfigError, match="no such board"):
        load_board("warped")
    with pytest.raises(ConfigError, match="must be a table"):
        board_from_dict([1], "x.toml")


def test_sim_url_takes_a_board(tmp_path):
    with open_source("sim://calibration?board=uncalibrated&rate=max&duration=0.2") as source:
        assert source.describe()["board"] == "uncalibrated"
        assert source.sim.board.range_bias_m == load_board("uncalibrated").range_bias_m
        frames = list(source)
    assert len(frames) == 2
    with pytest.raises(SourceError, match="sim://calibration\\?board=nope.toml: option board='nope.toml': "
                                          "expected ideal, uncalibrated or a board .toml file"):
        open_source("sim://calibration?board=nope.toml")
    with pytest.raises(SourceError, match="bord"):
        open_source("sim://calibration?bord=ideal")


# ------------------------------------------------------------------ one point a reflector
def random_board(seed: int) -> Board:
    """A board like a real one before calibration: paths up to 40 degrees and 1.5 dB apart."""
    rng = np.random.default_rng(seed)
    return Board(name=f"random{seed}", tx_gain_db=tuple(rng.uniform(-1.5, 1.5, 3)),
                 tx_phase_deg=tuple(rng.uniform(-40, 40, 3)), rx_gain_db=tuple(rng.uniform(-1.5, 1.5, 4)),
                 rx_phase_deg=tuple(rng.uniform(-40, 40, 4)))


def test_an_uncalibrated_board_gives_one_point_a_reflector(shipped_cfg):
    """What every new board does (the cfg's identity line on paths tens of degrees apart):
    taking a reflector's plane wave out of its cell leaves a second, false peak of itself, 30-90
    degrees off, so an uncalibrated array gets one azimuth a cell, the five reflectors five
    points.  Told (falsely) that the line fits, most boards show the ghosts; with each board's
    own line, one point each again, every one in its place."""
    scene = load_scene("calibration")
    ghosted = 0
    for seed in range(1, 9):
        board = random_board(seed)
        cube = cube_of(shipped_cfg, scene, board)
        assert not board.fits(shipped_cfg)
        proc = FrameProcessor(shipped_cfg, calibrated=board.fits(shipped_cfg))
        assert not proc.array_calibrated and proc.params.max_azimuth_peaks == 1
        assert len(proc.process(cube).points) == 5, board
        ghosted += len(FrameProcessor(shipped_cfg, calibrated=True).process(cube).points) > 5
        cfg = calibrated(shipped_cfg, board.calibration())
        proc = FrameProcessor(cfg, calibrated=board.fits(cfg))
        assert proc.array_calibrated and proc.params.max_azimuth_peaks == DspConfig().max_azimuth_peaks
        points = proc.process(cube).points
        ok, worst = _check_reflectors(cfg, points, scene, 0.0, azimuth_deg=1.0, elevation_deg=1.0)
        assert len(points) == 5 and ok, (board, worst)
    assert ghosted >= 4


def test_sources_say_whether_the_line_fits_their_board(tmp_path, shipped_cfg):
    """sim:// knows its board; a recording of it keeps the board, so replay:// knows too, with its
    own cfg or another; a recording without a simulated board (a real one's) does not know."""
    board = load_board("uncalibrated")
    line_cfg = calibrated(shipped_cfg, board.calibration())
    with open_source("sim://calibration?duration=0.3", shipped_cfg) as src:
        assert src.calibrated is True
    with open_source("sim://calibration?duration=0.3&board=uncalibrated", shipped_cfg) as src:
        assert src.calibrated is False
        meta = src.recording_metadata()
    with open_source("sim://calibration?duration=0.3&board=uncalibrated", line_cfg) as src:
        assert src.calibrated is True
    sim = Simulator(shipped_cfg, load_scene("calibration"), board=board, duration_s=0.3)
    for name, extra in (("sim", meta), ("real", {})):
        with CaptureWriter(tmp_path / name, shipped_cfg, source="test", extra=extra) as writer:
            for i in range(sim.num_frames):
                f = sim.frame(i)
                writer.write(f.raw, f.timestamp, 0, f.pose)
    with open_source(f"replay://{tmp_path / 'sim'}") as src:
        assert src.calibrated is False
    with open_source(f"replay://{tmp_path / 'sim'}", line_cfg) as src:
        assert src.calibrated is True
    with open_source(f"replay://{tmp_path / 'real'}") as src:
        assert src.calibrated is None
        assert not FrameProcessor(src.config, calibrated=src.calibrated).array_calibrated  # the identity line
    with open_source(f"replay://{tmp_path / 'real'}", line_cfg) as src:
        assert FrameProcessor(src.config, calibrated=src.calibrated).array_calibrated  # a measured line


def test_a_recordings_board_is_read_from_its_calibration_or_a_builtin_name_only(tmp_path, shipped_cfg):
    """A recording made before the board's calibration was kept names its board: a built-in one
    is known; a name that is a board file's path is not read (a recording's metadata once made
    replay:// read any file it named, and tried /etc/passwd as TOML)."""
    board = load_board("uncalibrated")
    line_cfg = calibrated(shipped_cfg, board.calibration())
    mine = tmp_path / "mine.toml"
    mine.write_text(resources.files("radarodom.driver.sim").joinpath("boards", "uncalibrated.toml").read_text())
    sim = Simulator(shipped_cfg, load_scene("calibration"), board=board, duration_s=0.2)
    for name, named in (("builtin", "uncalibrated"), ("file", str(mine))):
        extra = {"simulator": {"board": named}}
        with CaptureWriter(tmp_path / name, shipped_cfg, source="test", extra=extra) as writer:
            for i in range(sim.num_frames):
                f = sim.frame(i)
                writer.write(f.raw, f.timestamp, 0, f.pose)
    with open_source(f"replay://{tmp_path / 'builtin'}", line_cfg) as src:
        assert src.calibrated is True
    with open_source(f"replay://{tmp_path / 'file'}", line_cfg) as src:
        assert src.calibrated is None


def test_lines_match_within_tolerance_whatever_their_common_phase():
    board = load_board("uncalibrated")
    exact = board.calibration()
    turned = ChannelCalibration(exact.range_bias_m, exact.coefficients * 0.7 * np.exp(1j))  # no angle changes
    assert exact.matches(turned) and turned.matches(exact)
    written = ChannelCalibration.from_command(exact.to_command())  # rounded to 5 decimals
    assert exact.matches(written)
    assert ChannelCalibration.from_description(exact.describe()).matches(exact)
    off = exact.coefficients.copy()
    off[2, 3] *= np.exp(1j * math.radians(2.0))
    assert not exact.matches(ChannelCalibration(exact.range_bias_m, off))
    assert not exact.matches(ChannelCalibration(exact.range_bias_m + 0.01, exact.coefficients))
    assert not exact.matches(ChannelCalibration.identity())
    with pytest.raises(ConfigError, match="12"):
        ChannelCalibration.from_description({"range_bias_m": 0.0, "coefficients": [[1, 0]] * 11})
    # Values a cfg line cannot hold (a recording's capture.json edited): numpy's overflow warnings before.
    for bad in ({"range_bias_m": 0.0, "coefficients": [[1e308, 1e308]] + [[1, 0]] * 11},
                {"range_bias_m": 0.0, "coefficients": [[0, 0]] + [[1, 0]] * 11},
                {"range_bias_m": float("inf"), "coefficients": [[1, 0]] * 12}):
        with pytest.raises(ConfigError, match="within -1..1, none 0 \\+ 0j, and the bias finite"):
            ChannelCalibration.from_description(bad)


def test_a_bad_line_is_reported_at_its_place_in_the_cfg(tmp_path, shipped_cfg):
    """The parser accepts each value of the line; a zero pair is refused with the file and line."""
    text = shipped_cfg.to_text().splitlines()
    at = next(i for i, ln in enumerate(text) if ln.startswith("compRangeBiasAndRxChanPhase"))
    text[at] = "compRangeBiasAndRxChanPhase 0.0 " + " ".join(["1 0"] * 11 + ["0 0"])
    path = tmp_path / "zero.cfg"
    path.write_text("\n".join(text) + "\n")
    cfg = RadarConfig.from_file(path)
    with pytest.raises(ConfigError, match=rf"zero.cfg:{at + 1}: compRangeBiasAndRxChanPhase: .*TX3 RX4 is 0"):
        FrameProcessor(cfg)
