"""The radar simulator: a scene, a trajectory and a cfg in, DCA1000 bytes and
ground truth out, frame by frame and deterministic for a seed.

Per frame: the sensor pose at every chirp's time; the scatterers seen from
the frame's middle (inside the unambiguous range, in front of the antenna,
not hidden by a wall); their amplitude ``sqrt(RCS) / R^2`` times the antenna
pattern and the reflectivity at the angle of incidence; optional one-bounce
multipath images; the beat signal (:mod:`.physics`); the board's own
imperfections (:mod:`.board`: path gains, range bias, TX-to-RX leakage);
thermal noise; and int16 quantization, scaled down only where a frame would
otherwise clip.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ...cfg import SPEED_OF_LIGHT, RadarConfig
from ...errors import UsageError
from ...rawframe import INT16_MAX, RawLayout
from ...tum import yaw_quaternion
from .board import Board
from .physics import AntennaPattern, FmcwSynthesizer
from .scene import Scene

log = logging.getLogger(__name__)

#: Range at which ``Scene.snr_db`` is defined for a 1 m^2 target, m.
SNR_REFERENCE_RANGE_M = 5.0
#: Closest range a scatterer is simulated at, m (the far-field model's limit).
MIN_RANGE_M = 0.3
#: Pattern gains below this are not worth synthesizing.
MIN_PATTERN_GAIN = 1e-3
#: Paths whose SNR after integrating a whole frame (all samples, chirps and
#: virtual antennas) stays below this are skipped, dB.
MIN_INTEGRATED_SNR_DB = -10.0
#: Most frames a simulation makes: about eleven days at 10 Hz.
MAX_FRAMES = 10_000_000


@dataclass(frozen=True)
class SimFrame:
    index: int
    #: Time of the frame's first chirp, s from the start of the trajectory.
    timestamp: float
    #: The frame as the DCA1000 streams it.
    raw: bytes
    #: Body-frame pose relative to the first frame: (x, y, z, qx, qy, qz, qw).
    pose: tuple[float, ...]
    #: Paths synthesized (scatterers and multipath images).
    num_paths: int
    #: Factor the frame was scaled by to fit int16 (1.0 almost always).
    scale: float


def world_to_sensor(points: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray,
                    height: float, out: np.ndarray | None = None) -> np.ndarray:
    """World points to the TI sensor frame of poses (x, y, yaw) at *height*.

    points: (K, 3) (fixed in the world) or (C, K, 3); poses: (C,).  Returns
    float32 (3, C, K): the planes x right, y boresight (body forward), z up,
    each contiguous (the synthesis reads them plane by plane), filled into
    *out* when given.  float32 keeps ranges to about 1 um at 20 m.
    """
    pts = points if points.ndim == 3 else points[None]
    c = np.cos(yaw).astype(np.float32)[:, None]
    s = np.sin(yaw).astype(np.float32)[:, None]
    if out is None:
        out = np.empty((3, len(x), pts.shape[1]), np.float32)
    # Differences in float64 first: world coordinates are large, their differences small.
    dx = (pts[..., 0] - x[:, None]).astype(np.float32)
    dy = (pts[..., 1] - y[:, None]).astype(np.float32)
    # x_TI = -(body y) = s dx - c dy;  y_TI = body x = c dx + s dy
    np.multiply(s, dx, out=out[0])
    out[0] -= c * dy
    np.multiply(c, dx, out=out[1])
    out[1] += s * dy
    out[2] = pts[..., 2] - height
    return out


def _crossings(origin: np.ndarray, targets_xy: np.ndarray, wall_a: np.ndarray, wall_b: np.ndarray):
    """Where the 2-D segments origin->target cross the wall segments a->b.

    Returns (t, u, ok), each (K, W): t along origin->target (0..1), u along the
    wall (0..1), ok False where the two are parallel.
    """
    d = targets_xy - origin  # (K, 2)
    e = wall_b - wall_a  # (W, 2)
    f = wall_a - origin  # (W, 2)
    denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (K, W)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (f[None, :, 0] * e[None, :, 1] - f[None, :, 1] * e[None, :, 0]) / denom
        u = (f[None, :, 0] * d[:, None, 1] - f[None, :, 1] * d[:, None, 0]) / denom
    return t, u, np.abs(denom) > 1e-12


def _occluded(sensor_xy: np.ndarray, targets_xy: np.ndarray, wall_a: np.ndarray, wall_b: np.ndarray) -> np.ndarray:
    """True for targets whose line of sight crosses a wall segment strictly
    before reaching them (a target on a wall does not hide itself)."""
    if len(wall_a) == 0 or len(targets_xy) == 0:
        return np.zeros(len(targets_xy), bool)
    t, u, ok = _crossings(sensor_xy, targets_xy, wall_a, wall_b)
    d = targets_xy - sensor_xy
    dist = np.hypot(d[:, 0], d[:, 1])[:, None]
    margin = 0.02 / np.maximum(dist, 1e-9)  # 2 cm: the target's own wall does not count
    hit = ok & (t > 1e-9) & (t < 1.0 - margin) & (u >= 0.0) & (u <= 1.0)
    return hit.any(axis=1)


def _mirror(points_xy: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mirror images of 2-D points across the line through a and b."""
    d = (b - a) / np.hypot(*(b - a))
    rel = points_xy - a
    along = rel[..., 0] * d[0] + rel[..., 1] * d[1]  # not a BLAS product: the same bytes with any threads
    return a + 2 * along[..., None] * d - rel


class Simulator:
    """Frames of a scene seen by the radar of *cfg* along the scene's trajectory."""

    def __init__(self, cfg: RadarConfig, scene: Scene, *, seed: int = 0,
                 duration_s: float | None = None, pattern: AntennaPattern | None = None,
                 fidelity: str = "exact", board: Board | None = None, noise_seed: int | None = None) -> None:
        self.cfg = cfg
        self.scene = scene
        self.seed = seed
        #: The thermal noise's own seed (None: *seed*'s): another draw of the noise over the same
        #: scene, scatterers and path, which tells what in a result is the noise's.
        self.noise_seed = noise_seed
        #: The board's imperfections (default: the perfect board).
        self.board = board or Board()
        self.synth = FmcwSynthesizer(cfg, fidelity=fidelity, extra_path_m=2.0 * self.board.range_bias_m)
        # The board's path gains per cube element (None: all 1) and its leakage, the same in
        # every chirp (None: none): (1, tx_slots, rx, 1) and (1, tx_slots, rx, samples).
        gains = self.board.for_array(cfg.virtual_array)
        self._gains = gains[None, :, :, None] if self.board.has_channel_errors else None
        self._leakage = None
        if self.board.leakage_counts > 0:
            tau = 2.0 * (self.board.leakage_range_m + self.board.range_bias_m) / SPEED_OF_LIGHT
            carrier = np.exp(2j * np.pi * self.synth.f_c * tau)
            tone = self.synth.beat_tone(np.array([tau]))[0] * carrier * self.board.leakage_counts * math.sqrt(2.0)
            self._leakage = (gains[:, :, None] * tone[None, None, :]).astype(np.complex64)[None]
        self.pattern = pattern or scene.pattern
        self.layout = RawLayout.from_config(cfg)
        self.period = cfg.frame_period_s
        span = scene.trajectory.duration_s if duration_s is None else duration_s
        frames = span / self.period
        if not (0 < span and frames <= MAX_FRAMES):  # also NaN; ceil() of infinity would overflow
            raise UsageError(f"duration {float(span):g} s: expected more than 0 and at most "
                             f"{MAX_FRAMES * self.period:g} s ({MAX_FRAMES} frames of {self.period:g} s)")
        self.num_frames = max(1, math.ceil(frames - 1e-9))
        if duration_s is not None and duration_s > scene.trajectory.duration_s + self.period:
            log.warning("duration %g s is longer than scene %s's trajectory (%.1f s): the sensor stands at its end "
                        "for the rest (shorten it, or loop a sim:// stream with loop=N)", duration_s,
                        scene.name, scene.trajectory.duration_s)
        self._warn_if_too_fast(cfg, scene)
        self.max_range_m = cfg.unambiguous_range_m
        amp_ref = scene.noise_counts * math.sqrt(2.0) * 10 ** (scene.snr_db / 20.0)
        #: ADC counts of a 1 m^2 target at 1 m on boresight.
        self.gain_counts = amp_ref * SNR_REFERENCE_RANGE_M**2
        samples_per_frame = int(np.prod(cfg.cube_shape))
        #: Paths weaker than this (ADC counts) stay below MIN_INTEGRATED_SNR_DB after a frame's
        #: coherent integration and are not synthesized.
        self.min_amplitude = scene.noise_counts * math.sqrt(
            2.0 * 10 ** (MIN_INTEGRATED_SNR_DB / 10) / samples_per_frame)
        self._cube = np.empty(cfg.cube_shape, np.complex64)
        self._noise = np.empty(cfg.cube_shape, np.complex64)
        x0, y0, yaw0 = scene.trajectory.pose(0.0)
        self._origin = (float(x0), float(y0), float(yaw0))
        self._clip_warned = False

    @staticmethod
    def _warn_if_too_fast(cfg: RadarConfig, scene: Scene) -> None:
        """A path faster than the cfg's unambiguous radial velocity folds the static world's
        Doppler over: the frames are right for that cfg, and no velocity can be measured from them."""
        trajectory = scene.trajectory
        vx, vy, _ = trajectory.velocity(trajectory.times)
        fastest = float(np.max(np.hypot(vx, vy), initial=0.0))
        if fastest > cfg.max_velocity_mps:
            log.warning("scene %s drives the radar at up to %.2f m/s, beyond the cfg's unambiguous radial velocity "
                        "of +/-%.2f m/s: the static world's Doppler folds over and its velocity cannot be measured "
                        "(slow the path, or give a cfg with a shorter chirp period)", scene.name, fastest,
                        cfg.max_velocity_mps)

    def frame_time(self, i: int) -> float:
        return i * self.period

    def groundtruth(self, t) -> tuple[float, ...]:
        """Body pose at time *t* relative to the body at the first frame (TUM order)."""
        x, y, yaw = (float(v) for v in self.scene.trajectory.pose(t))
        x0, y0, yaw0 = self._origin
        c, s = math.cos(yaw0), math.sin(yaw0)
        dx, dy = x - x0, y - y0
        q = yaw_quaternion(yaw - yaw0)
        return (c * dx + s * dy, -s * dx + c * dy, 0.0, *map(float, q))

    def _to_sensor(self, points: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray,
                   out: np.ndarray | None = None) -> np.ndarray:
        """:func:`world_to_sensor` at the trajectory's height; in a flat scene every point at that
        height (no elevation anywhere: a diagnosis of what the elevation does)."""
        rel = world_to_sensor(points, x, y, yaw, self.scene.trajectory.height, out=out)
        if self.scene.flat:
            rel[2] = 0.0
        return rel

    def paths(self, t0: float):
        """Propagation paths of the frame starting at *t0*: (p_tx, p_rx, amp) as
        :meth:`FmcwSynthesizer.synthesize` takes them (p_rx None: all direct);
        positions are (3, chirps, paths) in the TI frame."""
        scene, traj = self.scene, self.scene.trajectory
        times = t0 + self.synth.chirp_offsets_s
        x, y, yaw = traj.pose(times)
        mid = len(times) // 2
        centre = (x[mid:mid + 1], y[mid:mid + 1], yaw[mid:mid + 1])
        sensor_xy = np.array([x[mid], y[mid]])

        st = scene.static
        movers = [m.positions(times) for m in scene.movers]
        # Geometry at the frame's middle decides visibility and amplitude.
        pts_mid = np.concatenate([st.pos] + [m[mid] for m in movers]) if (len(st.rcs) or movers) else np.zeros((0, 3))
        rcs = np.concatenate([st.rcs] + [m.body_rcs for m in scene.movers])
        phase = np.concatenate([st.phase] + [m.phases for m in scene.movers])
        normal = np.concatenate([st.normal] + [np.zeros((len(m.BODY), 3)) for m in scene.movers])
        expo = np.concatenate([st.exponent] + [np.zeros(len(m.BODY)) for m in scene.movers])
        pointlike = np.concatenate([st.pointlike] + [np.ones(len(m.BODY), bool) for m in scene.movers])
        rel = self._to_sensor(pts_mid, *centre)[:, 0]  # (3, K)
        r = np.sqrt((rel**2).sum(axis=0))
        az = np.arctan2(rel[0], rel[1])
        el = np.arcsin(np.clip(rel[2] / np.maximum(r, 1e-9), -1, 1))
        gain = self.pattern.amplitude(az, el)
        keep = (r > MIN_RANGE_M) & (r < self.max_range_m) & (gain > MIN_PATTERN_GAIN)
        keep[keep] &= ~_occluded(sensor_xy, pts_mid[keep, :2], scene.wall_a, scene.wall_b)
        idx = np.flatnonzero(keep)

        # Reflectivity at the angle of incidence, for surfaces with a normal.
        sensor3 = np.array([x[mid], y[mid], traj.height])
        to_sensor = sensor3 - pts_mid[idx]
        to_sensor /= np.linalg.norm(to_sensor, axis=1, keepdims=True)
        cos_i = np.abs(np.einsum("kx,kx->k", normal[idx], to_sensor))
        has_normal = np.any(normal[idx] != 0, axis=1)
        incidence = np.where(has_normal, cos_i ** expo[idx], 1.0)
        amp = (self.gain_counts * np.sqrt(rcs[idx]) * incidence * gain[idx] / r[idx] ** 2
               * np.exp(1j * phase[idx]))
        # A path far below the noise even after the full coherent integration of a
        # frame changes no range-Doppler-angle cell visibly: skip it.
        audible = np.abs(amp) >= self.min_amplitude
        idx, amp, incidence = idx[audible], amp[audible], incidence[audible]

        # Positions at every chirp's time: static points are fixed in the world.
        n_static = len(st.rcs)
        s_idx, m_idx = idx[idx < n_static], idx[idx >= n_static] - n_static
        p = np.empty((3, len(times), len(idx)), np.float32)
        self._to_sensor(st.pos[s_idx], x, y, yaw, out=p[:, :, :len(s_idx)])
        moving = np.concatenate(movers, axis=1)[:, m_idx] if movers else np.zeros((len(times), 0, 3))
        if movers:
            self._to_sensor(moving, x, y, yaw, out=p[:, :, len(s_idx):])
        if not scene.multipath or len(scene.wall_a) == 0:
            return p, None, amp

        # One bounce off a wall on the TX or the RX leg, for compact targets.
        images_tx, images_rx, images_amp = [p], [p], [amp]
        strong = np.flatnonzero(pointlike[idx])
        for a, b in zip(scene.wall_a, scene.wall_b):
            if not len(strong):
                break
            img_mid = _mirror(pts_mid[idx[strong], :2], a, b)
            # The bounce point must lie on the wall: the sensor-to-image line crosses it.
            t, u, ok = (v[:, 0] for v in _crossings(sensor_xy, img_mid, a[None], b[None]))
            ok &= (t > 0) & (t < 1) & (u >= 0) & (u <= 1)
            if not ok.any():
                continue
            sel = strong[ok]
            img_world = self._world_at_chirps(sel, s_idx, moving, len(times))
            img_world[..., :2] = _mirror(img_world[..., :2], a, b)
            p_img = self._to_sensor(img_world, x, y, yaw)
            rel_img = p_img[:, mid]
            r_img = np.sqrt((rel_img**2).sum(axis=0))
            g_img = self.pattern.amplitude(np.arctan2(rel_img[0], rel_img[1]),
                                           np.arcsin(np.clip(rel_img[2] / r_img, -1, 1)))
            a_img = (scene.wall_reflection * self.gain_counts * np.sqrt(rcs[idx[sel]]) * incidence[sel]
                     * np.sqrt(gain[idx[sel]] * g_img) / (r[idx[sel]] * r_img)
                     * np.exp(1j * phase[idx[sel]]))
            images_tx += [p_img, p[:, :, sel]]
            images_rx += [p[:, :, sel], p_img]
            images_amp += [a_img, a_img]
        return np.concatenate(images_tx, axis=2), np.concatenate(images_rx, axis=2), np.concatenate(images_amp)

    def _world_at_chirps(self, sel: np.ndarray, s_idx: np.ndarray, moving: np.ndarray, chirps: int) -> np.ndarray:
        """World positions (chirps, len(sel), 3) of the synthesized paths *sel*
        (columns: the static paths *s_idx* first, then the moving ones)."""
        out = np.empty((chirps, len(sel), 3))
        static = sel < len(s_idx)
        out[:, static] = self.scene.static.pos[s_idx[sel[static]]][None]
        out[:, ~static] = moving[:, sel[~static] - len(s_idx)]
        return out

    def frame(self, i: int) -> SimFrame:
        """Frame *i*: its bytes, time and ground truth."""
        if not 0 <= i < self.num_frames:
            raise IndexError(f"frame {i} of {self.num_frames}")
        t0 = self.frame_time(i)
        p_tx, p_rx, amp = self.paths(t0)
        cube = self.synth.synthesize(p_tx, p_rx, amp, out=self._cube)
        if self._gains is not None:
            cube *= self._gains
        if self._leakage is not None:
            cube += self._leakage
        rng = np.random.default_rng([self.seed if self.noise_seed is None else self.noise_seed, i])
        noise = self._noise
        noise.real[...] = rng.standard_normal(cube.shape, dtype=np.float32)
        noise.imag[...] = rng.standard_normal(cube.shape, dtype=np.float32)
        noise *= np.float32(self.scene.noise_counts)
        cube += noise
        peak = max(float(np.abs(cube.real).max()), float(np.abs(cube.imag).max()))
        scale = 1.0
        if peak > INT16_MAX:
            scale = INT16_MAX / peak
            cube *= np.float32(scale)
            if not self._clip_warned:
                log.warning("frame %d would clip the 16-bit ADC; scaled by %.3g (lower the scene's radar.snr_db or "
                            "noise_counts)", i, scale)
                self._clip_warned = True
        return SimFrame(i, t0, self.layout.encode(cube), self.groundtruth(t0), len(amp), scale)
