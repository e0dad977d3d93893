"""Helpers for the simulator tests: tiny scenes, the true geometry from a
trajectory, and a minimal reference radar processing written from
docs/conventions.md (not from the simulator's code).

Reference processing of one frame's cube (loops, tx_slots, rx, samples):

- range FFT over the samples with a Hann window, bins 0..N-1 (positive beat
  frequencies for real targets);
- Doppler FFT over the loops, fftshift, signed bin k = index - loops/2
  (positive for a receding target);
- TDM-MIMO compensation: TX slot t times exp(-j 2 pi t k / (N_tx N_doppler));
- azimuth: zero-padded FFT over the virtual array's azimuth row (h = 0..7),
  signed peak k, Wx = 2 k / N, x_TI = r Wx;
- elevation: the same FFT over the raised row (h = 2..5), E at the azimuth
  peak, Wz = angle(A conj(E)) / pi + 2 Wx, z_TI = r Wz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from radarodom.cfg import RadarConfig
from radarodom.driver.sim.scene import Scene, scene_from_dict

#: Zero-padded azimuth FFT length.
ANGLE_FFT = 64


# ------------------------------------------------------------------ scenes
def point_scene(points: Sequence[Sequence[float]], segments: Sequence[dict] | None = None, *,
                rcs: float = 10.0, start=(0.0, 0.0, 0.0), height: float = 0.4,
                smoothing_s: float = 0.001, snr_db: float = 10.0, noise_counts: float = 5.0,
                extra: dict | None = None, seed: int = 0) -> Scene:
    """A scene of ``point`` objects at world positions *points* (x forward, y left,
    z up at the start pose), the sensor following *segments* (default: still)."""
    spec = {
        "name": "test",
        "radar": {"snr_db": snr_db, "noise_counts": noise_counts},
        "objects": [{"type": "point", "position": list(map(float, p)), "rcs": rcs} for p in points],
        "trajectory": {"start": list(start), "height": height, "smoothing_s": smoothing_s,
                       "segments": list(segments or [{"pause": 2.0}])},
    }
    spec.update(extra or {})
    return scene_from_dict(spec, seed=seed)


def scattered_points(n: int, *, seed: int = 1, half_width_deg: float = 60.0,
                     ranges_m: tuple[float, float] = (3.0, 9.0),
                     heights_m: tuple[float, float] = (0.0, 1.4)) -> np.ndarray:
    """*n* world points for :func:`point_scene`, (n, 3): azimuths, ranges and heights drawn
    uniformly within +/- *half_width_deg* ahead of the start pose, *ranges_m* and *heights_m*."""
    rng = np.random.default_rng(seed)
    az = np.radians(rng.uniform(-half_width_deg, half_width_deg, n))
    r = rng.uniform(*ranges_m, n)
    return np.column_stack([r * np.cos(az), r * np.sin(az), rng.uniform(*heights_m, n)])


def sensor_coords(point, x, y, yaw, height) -> np.ndarray:
    """A world point in the TI sensor frame of the body pose (x, y, yaw) at *height*:
    x_TI right (= -body y), y_TI boresight (= body x), z_TI up."""
    dx, dy = point[0] - x, point[1] - y
    fwd = math.cos(yaw) * dx + math.sin(yaw) * dy
    left = -math.sin(yaw) * dx + math.cos(yaw) * dy
    return np.array([-left, fwd, point[2] - height])


def frame_mid_time(cfg: RadarConfig, t0: float) -> float:
    return t0 + cfg.active_frame_time_s / 2.0


def truth(scene: Scene, cfg: RadarConfig, point, t0: float) -> dict:
    """True range, radial velocity (d range / dt) and sensor-frame position of a
    static world *point* at the middle of the frame starting at *t0*."""
    traj = scene.trajectory
    tm = frame_mid_time(cfg, t0)

    def at(t):
        x, y, yaw = (float(v) for v in traj.pose(t))
        return sensor_coords(point, x, y, yaw, traj.height)

    p = at(tm)
    dt = 1e-3
    r = float(np.linalg.norm(p))
    v_r = (np.linalg.norm(at(tm + dt)) - np.linalg.norm(at(tm - dt))) / (2 * dt)
    return {"p": p, "r": r, "v_r": float(v_r), "u": p / r}


# ------------------------------------------------------ reference processing
@dataclass
class Detection:
    range_bin: int
    doppler_bin: int  # signed
    wx: float  # sin(azimuth) cos(elevation) estimate, x_TI / r
    wz: float  # z_TI / r estimate
    power: float


def range_doppler(cfg: RadarConfig, cube: np.ndarray, *, tdm: bool = True) -> np.ndarray:
    """Range-Doppler-virtual cube (doppler (shifted), tx_slots, rx, range)."""
    loops, slots, nrx, ns = cube.shape
    rfft = np.fft.fft(cube * np.hanning(ns).astype(np.float32), axis=-1)
    rd = np.fft.fftshift(np.fft.fft(rfft, axis=0), axes=0)
    if tdm:
        k = np.arange(loops) - loops // 2
        t = np.arange(slots)
        comp = np.exp(-2j * np.pi * np.outer(k, t) / (slots * loops))  # (doppler, slots)
        rd = rd * comp[:, :, None, None]
    return rd


def rd_power(rd: np.ndarray) -> np.ndarray:
    """Non-coherent power over the virtual channels: (doppler, range)."""
    return (np.abs(rd) ** 2).sum(axis=(1, 2))


def angles(cfg: RadarConfig, rd: np.ndarray, d_idx: int, r_bin: int) -> tuple[float, float]:
    """(Wx, Wz) at the range-Doppler cell (d_idx is the shifted index)."""
    va = cfg.virtual_array
    vec = rd[d_idx, :, :, r_bin].reshape(-1)
    az = np.fft.fftshift(np.fft.fft(vec[va.azimuth_row], ANGLE_FFT))
    k_idx = int(np.argmax(np.abs(az)))
    wx = 2.0 * (k_idx - ANGLE_FFT // 2) / ANGLE_FFT
    el = np.fft.fftshift(np.fft.fft(vec[va.elevation_row], ANGLE_FFT))
    a, e = az[k_idx], el[k_idx]
    wz = float(np.angle(a * np.conj(e)) / np.pi + 2.0 * wx)
    return wx, wz


def detect(cfg: RadarConfig, cube: np.ndarray, *, tdm: bool = True,
           range_bins: tuple[int, int] | None = None) -> Detection:
    """The strongest range-Doppler cell (optionally within range bins lo..hi) and its angles."""
    rd = range_doppler(cfg, cube, tdm=tdm)
    pw = rd_power(rd)
    lo, hi = range_bins if range_bins else (1, cube.shape[-1] - 1)
    lo, hi = max(lo, 0), min(hi, pw.shape[1] - 1)
    sub = pw[:, lo:hi + 1]
    d_idx, r_rel = np.unravel_index(int(np.argmax(sub)), sub.shape)
    r_bin = lo + int(r_rel)
    wx, wz = angles(cfg, rd, int(d_idx), r_bin)
    return Detection(r_bin, int(d_idx) - cube.shape[0] // 2, wx, wz, float(sub[d_idx, r_rel]))


def decode(sim, frame) -> np.ndarray:
    return sim.layout.decode(frame.raw)
