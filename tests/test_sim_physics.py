"""The simulator's physics against a minimal reference processing written from
docs/conventions.md (tests/sim_helpers.py): range and Doppler bins, Doppler sign,
azimuth and elevation with their signs, -v.u for static points seen while
moving, and the TDM-MIMO phase between TX slots.

One-point scenes built with ``scene_from_dict``; expected values come from
the trajectory's true pose at the frame's middle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from sim_helpers import (ANGLE_FFT, decode, detect, frame_mid_time, point_scene, range_doppler,
                         rd_power, sensor_coords, truth)

from radarodom.driver.sim.simulator import Simulator

STILL = [{"pause": 2.0}]
FORWARD_1MPS = [{"straight": 5.0, "speed": 1.0}]
#: Half an FFT bin plus the window's (and the frame's motion) tolerance.
BIN_TOL = 0.6
#: Azimuth: half the zero-padded grid step (Wx grid 2/N) plus a little.
WX_TOL = 1.0 / ANGLE_FFT + 0.01


def _cfg(request, name):
    return request.getfixturevalue(name)


def _one_frame(cfg, scene, i=1, seed=7):
    sim = Simulator(cfg, scene, seed=seed)
    f = sim.frame(i)
    return sim, f, decode(sim, f)


def _wz_tol(cfg) -> float:
    """Elevation tolerance: the TDM compensation uses the integer Doppler bin, so a
    Doppler residual of up to BIN_TOL bins leaves a phase of 2 pi d t / (N_tx N_d)
    on TX slot t (slot 2 is the raised row): Wz off by up to 2 d * 2 / (N_tx N_d)."""
    loops, slots = cfg.cube_shape[:2]
    return 0.02 + 4 * BIN_TOL / (slots * loops)


# ------------------------------------------------------------ range, Doppler
@pytest.mark.parametrize("cfg_name", ["shipped_cfg", "small_cfg"])
@pytest.mark.parametrize("point", [(3.0, 0.0, 0.4), (5.2, -1.0, 0.7), (7.9, 2.0, 0.1)])
def test_static_target_range_bin_and_zero_doppler(request, cfg_name, point):
    cfg = _cfg(request, cfg_name)
    scene = point_scene([point], STILL)
    _, f, cube = _one_frame(cfg, scene)
    tr = truth(scene, cfg, point, f.timestamp)
    det = detect(cfg, cube)
    assert abs(det.range_bin - tr["r"] / cfg.range_resolution_m) <= BIN_TOL
    assert tr["v_r"] == 0.0
    assert det.doppler_bin == 0


@pytest.mark.parametrize("cfg_name", ["shipped_cfg", "small_cfg"])
@pytest.mark.parametrize("point", [(3.0, 0.0, 0.4), (4.0, -1.0, 0.9), (6.0, 1.5, 0.2)])
def test_approaching_target_range_and_negative_doppler(request, cfg_name, point):
    cfg = _cfg(request, cfg_name)
    scene = point_scene([point], FORWARD_1MPS)
    _, f, cube = _one_frame(cfg, scene, i=2)
    tr = truth(scene, cfg, point, f.timestamp)
    assert tr["v_r"] < -0.5  # the sensor drives toward the point
    det = detect(cfg, cube)
    assert abs(det.range_bin - tr["r"] / cfg.range_resolution_m) <= BIN_TOL
    assert abs(det.doppler_bin - tr["v_r"] / cfg.velocity_resolution_mps) <= BIN_TOL
    assert det.doppler_bin < 0, "an approaching target must have a negative Doppler bin"


@pytest.mark.parametrize("cfg_name", ["shipped_cfg", "small_cfg"])
def test_static_points_doppler_is_minus_v_dot_u(request, cfg_name):
    """Sensor driving forward at 1 m/s; static points at azimuths -40, 0, +40 and
    +60 deg at well separated ranges: each one's Doppler is -v . u."""
    cfg = _cfg(request, cfg_name)
    spacing = max(1.0, 3 * cfg.range_resolution_m)
    azimuths = [-40.0, 0.0, 40.0, 60.0]  # TI azimuth, positive to the right
    ranges = [2.5 + i * spacing for i in range(len(azimuths))]
    frame = 3
    # Where the sensor is at that frame's middle (the trajectory does not depend on the points).
    x_mid = float(point_scene([], FORWARD_1MPS).trajectory.pose(
        frame_mid_time(cfg, frame * cfg.frame_period_s))[0])
    # World (x forward, y left) of the start pose: right is -y.
    points = [(x_mid + r * math.cos(math.radians(a)), -r * math.sin(math.radians(a)), 0.4)
              for r, a in zip(ranges, azimuths)]
    scene = point_scene(points, FORWARD_1MPS)
    sim, f, cube = _one_frame(cfg, scene, i=frame)
    rd = range_doppler(cfg, cube)
    pw = rd_power(rd)
    traj = scene.trajectory
    tm = frame_mid_time(cfg, f.timestamp)
    x, y, yaw = (float(v) for v in traj.pose(tm))
    vx, vy, _ = (float(v) for v in traj.velocity(tm))
    # Sensor velocity in the TI frame: x_TI = -body y, y_TI = body x.
    fwd = math.cos(yaw) * vx + math.sin(yaw) * vy
    left = -math.sin(yaw) * vx + math.cos(yaw) * vy
    v_ti = np.array([-left, fwd, 0.0])
    assert v_ti[1] == pytest.approx(1.0, abs=1e-6)
    for point, az in zip(points, azimuths):
        p = sensor_coords(point, x, y, yaw, traj.height)
        u = p / np.linalg.norm(p)
        assert math.degrees(math.atan2(p[0], p[1])) == pytest.approx(az, abs=0.5)
        v_r = -float(v_ti @ u)
        assert v_r == pytest.approx(truth(scene, cfg, point, f.timestamp)["v_r"], abs=1e-3)
        rb = int(round(np.linalg.norm(p) / cfg.range_resolution_m))
        col = pw[:, rb - 1:rb + 2].max(axis=1)
        d_bin = int(np.argmax(col)) - cube.shape[0] // 2
        assert abs(d_bin - v_r / cfg.velocity_resolution_mps) <= BIN_TOL, (az, d_bin, v_r)
        if v_r / cfg.velocity_resolution_mps <= -1.0:
            assert d_bin < 0


# ------------------------------------------------------------------- angles
#: Points (world: x forward, y left, z up; sensor 0.4 m high) and the TI-frame
#: signs they must come out with: (sign x_TI, sign z_TI).
ANGLE_POINTS = [
    ((3.0, -1.0, 0.4), (+1, 0)),  # right
    ((3.0, 1.0, 0.4), (-1, 0)),  # left
    ((3.0, 0.0, 1.0), (0, +1)),  # above
    ((3.0, 0.0, 0.0), (0, -1)),  # below
    ((4.0, -0.8, 0.9), (+1, +1)),  # right and above
    ((3.5, 0.7, 0.05), (-1, -1)),  # left and below
    ((4.5, 1.2, 0.9), (-1, +1)),  # left and above
]


def _check_angles(cfg, scene, point, f, det, wz_tol):
    tr = truth(scene, cfg, point, f.timestamp)
    ux, uz = tr["u"][0], tr["u"][2]
    assert abs(det.range_bin - tr["r"] / cfg.range_resolution_m) <= BIN_TOL
    assert abs(det.wx - ux) <= WX_TOL, (det.wx, ux)
    assert abs(det.wz - uz) <= wz_tol, (det.wz, uz)
    return tr


@pytest.mark.parametrize("cfg_name", ["shipped_cfg", "small_cfg"])
@pytest.mark.parametrize("point,signs", ANGLE_POINTS)
def test_azimuth_and_elevation_static(request, cfg_name, point, signs):
    cfg = _cfg(request, cfg_name)
    scene = point_scene([point], STILL)
    _, f, cube = _one_frame(cfg, scene)
    det = detect(cfg, cube)
    tr = _check_angles(cfg, scene, point, f, det, 0.02)
    sx, sz = signs
    r = tr["r"]
    x_est, z_est = r * det.wx, r * det.wz
    if sx:
        assert np.sign(x_est) == sx and np.sign(tr["p"][0]) == sx
        assert math.degrees(math.atan2(x_est, tr["p"][1])) * sx > 5  # clearly off boresight
    else:
        assert abs(x_est) < 0.1
    if sz:
        assert np.sign(z_est) == sz and np.sign(tr["p"][2]) == sz
        assert abs(z_est) > 0.25
    else:
        assert abs(z_est) < 0.1


@pytest.mark.parametrize("point,signs", ANGLE_POINTS)
def test_azimuth_and_elevation_moving(shipped_cfg, point, signs):
    """Driving toward the points at 1 m/s, with TDM compensation, the angles and
    their signs still come out right (shipped cfg: fine Doppler bins)."""
    cfg = shipped_cfg
    scene = point_scene([point], FORWARD_1MPS)
    _, f, cube = _one_frame(cfg, scene, i=2)
    det = detect(cfg, cube)
    assert det.doppler_bin < -5
    tr = _check_angles(cfg, scene, point, f, det, _wz_tol(cfg))
    sx, sz = signs
    if sx:
        assert np.sign(det.wx) == sx
    if sz:
        assert np.sign(det.wz) == sz and abs(tr["r"] * det.wz) > 0.25


def test_right_target_has_positive_azimuth_bin(small_cfg):
    """The element index grows to the left (x_TI = -h lambda/2): a target to the
    right advances the phase along h, so the plain FFT peaks at a positive bin."""
    cfg = small_cfg
    scene = point_scene([(3.0, -1.5, 0.4)], STILL)
    _, f, cube = _one_frame(cfg, scene)
    rd = range_doppler(cfg, cube)
    pw = rd_power(rd)
    d_idx, rb = np.unravel_index(int(np.argmax(pw)), pw.shape)
    vec = rd[d_idx, :, :, rb].reshape(-1)[cfg.virtual_array.azimuth_row]
    # Phase step between neighbours in the azimuth row: +pi sin(az) for az > 0.
    step = np.angle(np.sum(vec[1:] * np.conj(vec[:-1])))
    u = truth(scene, cfg, (3.0, -1.5, 0.4), f.timestamp)["u"]
    assert step == pytest.approx(math.pi * u[0], abs=0.05)
    assert step > 0


# --------------------------------------------------------------- TDM-MIMO
@pytest.mark.parametrize("point", [(3.0, 0.0, 1.0), (4.0, -0.5, 0.0)])
def test_tdm_compensation_needed_for_moving_target_elevation(shipped_cfg, point):
    """Moving at 1 m/s (Doppler bin ~ -14 of 64) the raised row (TX slot 2)
    carries 2 * 2 pi k / (3 * 64) ~ 0.9 rad of Doppler phase: without the
    compensation the elevation is off by ~0.3 in Wz, with it it is right."""
    cfg = shipped_cfg
    scene = point_scene([point], FORWARD_1MPS)
    _, f, cube = _one_frame(cfg, scene, i=2)
    tr = truth(scene, cfg, point, f.timestamp)
    uz = tr["u"][2]
    good = detect(cfg, cube, tdm=True)
    bad = detect(cfg, cube, tdm=False)
    assert good.range_bin == bad.range_bin and good.doppler_bin == bad.doppler_bin
    assert abs(good.wz - uz) <= _wz_tol(cfg)
    assert abs(bad.wz - uz) > 0.15
    # The error has the sign of the missing phase: -2 * 2 k / (N_tx N_d) in Wz, k < 0.
    expected_err = -4.0 * good.doppler_bin / (cfg.cube_shape[1] * cfg.cube_shape[0])
    assert (bad.wz - uz) == pytest.approx(expected_err, abs=0.08)


def test_tdm_irrelevant_for_static_scene(shipped_cfg):
    cfg = shipped_cfg
    point = (3.0, 0.0, 1.0)
    scene = point_scene([point], STILL)
    _, f, cube = _one_frame(cfg, scene)
    a, b = detect(cfg, cube, tdm=True), detect(cfg, cube, tdm=False)
    assert a.doppler_bin == 0
    assert a.wz == pytest.approx(b.wz, abs=1e-6)
    assert a.wx == pytest.approx(b.wx, abs=1e-9)


# ------------------------------------------------------- range and amplitude
def test_amplitude_falls_with_range_squared(shipped_cfg):
    """Voltage ~ sqrt(rcs) / R^2 on boresight (radar equation): doubling the
    range quarters the peak amplitude (within the window's scalloping)."""
    cfg = shipped_cfg
    peaks = []
    for r in (2.5, 5.0):
        scene = point_scene([(r, 0.0, 0.4)], STILL, snr_db=20.0)
        _, _, cube = _one_frame(cfg, scene)
        peaks.append(math.sqrt(detect(cfg, cube).power))
    assert peaks[0] / peaks[1] == pytest.approx(4.0, rel=0.25)


def test_target_beyond_unambiguous_range_is_not_simulated(small_cfg):
    cfg = small_cfg
    far = cfg.unambiguous_range_m + 1.0
    scene = point_scene([(far, 0.0, 0.4)], STILL)
    sim = Simulator(cfg, scene, seed=1)
    assert sim.frame(0).num_paths == 0
    near = point_scene([(cfg.unambiguous_range_m - 2.0, 0.0, 0.4)], STILL)
    assert Simulator(cfg, near, seed=1).frame(0).num_paths == 1


def test_target_behind_sensor_is_not_simulated(small_cfg):
    scene = point_scene([(-3.0, 0.0, 0.4)], STILL)
    assert Simulator(small_cfg, scene, seed=1).frame(0).num_paths == 0
