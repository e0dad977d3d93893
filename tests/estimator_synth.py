"""Synthetic inputs for the estimator tests: point clouds and range-azimuth heatmaps of
point reflectors seen from a known sensor pose, with no simulator (fast, exact truth).

Frames and signs follow ``docs/conventions.md``: positions and velocities
given here are in the body frame (REP-103: x forward, y left); the point clouds and the
heatmaps come out in the TI sensor frame (azimuth = -bearing, positive to the right) with
radial velocity v_r = -v . u (positive receding).
"""

from __future__ import annotations

import math

import numpy as np
from radarodom.dsp.heatmap import RangeAzimuth
from radarodom.dsp.processor import POINT_DTYPE
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.odometry import RadarOdometry


def heatmap_chain(**changes) -> EstimatorConfig:
    """The default settings with *changes* (by section, as ``EstimatorConfig.with_``) and the
    heatmaps' registration alone (``point_yaw.blend`` 0, ``wall_map.use`` off): for the tests of
    that chain's ways whose point clouds are random static points (:func:`static_cloud`), not their
    scene's, in which the points' registration, blended by default, would see the radar never turn,
    and the map of wall directions would take chance alignments of them for walls."""
    return EstimatorConfig().with_(**changes).with_(point_yaw={"blend": 0.0}, wall_map={"use": False})


#: The AWR1843 heatmap axes: 64 azimuth bins at sin(az) = 2k/64, 256 range bins of 5 cm.
N_AZ = 64
AZIMUTH_RAD = np.arcsin(2.0 * np.arange(-N_AZ // 2, N_AZ // 2) / N_AZ)  # = azimuth_axis(64)
RANGE_M = 0.05 * np.arange(256)
#: Azimuth elements of the virtual array (half-wavelength spacing).
N_ELEMENTS = 8
#: Reflectors beyond this bearing are not seen (the antenna's field of view), rad.
FOV_RAD = math.radians(80.0)


def rot(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def polar_body(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Range and body-frame bearing of body-frame points (n, 2)."""
    return np.hypot(xy[:, 0], xy[:, 1]), np.arctan2(xy[:, 1], xy[:, 0])


def world_to_body(world_xy: np.ndarray, pose: tuple[float, float, float]) -> np.ndarray:
    """Body-frame positions (n, 2) of world points seen from *pose* (x, y, yaw)."""
    x, y, yaw = pose
    return (np.asarray(world_xy, float) - [x, y]) @ rot(yaw)  # rows: R(yaw)^T (p - t)


def azimuth_axis(n_az: int = N_AZ) -> np.ndarray:
    """Azimuth bins of an *n_az*-point FFT over a half-wavelength array: sin(az) = 2k/n_az."""
    return np.arcsin(2.0 * np.arange(-n_az // 2, n_az // 2) / n_az)


def azimuth_beam(az0_rad: np.ndarray, azimuth_rad: np.ndarray = AZIMUTH_RAD,
                 elements: int = N_ELEMENTS) -> np.ndarray:
    """Power response (n, n_az) of the azimuth FFT of *elements* half-wavelength elements to
    reflectors at TI azimuths *az0_rad* (n,): |sum_h exp(j pi h (sin az - sin az0))|^2 / elements^2,
    1 at the peak; *elements* = 0 gives an ideal narrow beam instead."""
    if elements == 0:  # an ideal pencil beam: a Gaussian of 0.3 degrees rms in sin(azimuth)
        d = np.sin(azimuth_rad)[None, :] - np.sin(az0_rad)[:, None]
        return np.exp(-0.5 * (d / math.radians(0.3)) ** 2)
    h = np.arange(elements)
    phase = np.pi * h[None, None, :] * (np.sin(azimuth_rad)[None, :, None] - np.sin(az0_rad)[:, None, None])
    return np.abs(np.exp(1j * phase).sum(axis=-1)) ** 2 / elements ** 2


def range_beam(r0_m: np.ndarray) -> np.ndarray:
    """Power response (n, n_range) of a Hann-windowed range FFT to reflectors at *r0_m*:
    the window's kernel 0.5 sinc(d) + 0.25 sinc(d - 1) + 0.25 sinc(d + 1), d the offset in bins."""
    d = (RANGE_M[None, :] - np.asarray(r0_m)[:, None]) / (RANGE_M[1] - RANGE_M[0])
    kernel = 0.5 * np.sinc(d) + 0.25 * np.sinc(d - 1.0) + 0.25 * np.sinc(d + 1.0)
    return kernel ** 2 / 0.25


def heatmap(body_xy: np.ndarray, amplitude: np.ndarray | float = 1.0, *,
            velocity_xy: tuple[float, float] | None = (0.0, 0.0),
            radial_velocity: np.ndarray | None = None, noise: float = 1e-4,
            rng: np.random.Generator | None = None, n_az: int = N_AZ,
            elements: int = N_ELEMENTS, doppler_channel: bool = True) -> RangeAzimuth:
    """A RangeAzimuth heatmap of point reflectors at body-frame positions *body_xy* (n, 2).

    Each reflector adds amplitude x range beam x azimuth beam.  The Doppler channel of a
    cell holds the radial velocity of the reflector that contributes most to it (static
    reflectors seen from a sensor moving at *velocity_xy*, body frame, unless
    *radial_velocity* (n,) is given), NaN where no reflector stands above the floor.  The
    floor is *noise*, exponentially distributed per cell when *rng* is given.  *n_az* and
    *elements* make other arrays (e.g. a cascade radar's 86 elements on 512 bins); without
    *doppler_channel* every cell's Doppler is NaN (unknown).
    """
    body_xy = np.atleast_2d(np.asarray(body_xy, float)).reshape(-1, 2)
    r, bearing = polar_body(body_xy)
    amp = np.broadcast_to(np.asarray(amplitude, float), r.shape)
    seen = (np.abs(bearing) < FOV_RAD) & (r > 0.2) & (r < RANGE_M[-1])
    r, bearing, amp = r[seen], bearing[seen], amp[seen]
    rr = amp[:, None] * range_beam(r)  # (n, n_range)
    azimuth = azimuth_axis(n_az)
    aa = azimuth_beam(-bearing, azimuth, elements)  # (n, n_az); TI azimuth = -bearing
    shape = (len(RANGE_M), n_az)
    floor = noise * (rng.exponential(1.0, shape) if rng is not None else 1.0)
    intensity = rr.T @ aa + floor
    if radial_velocity is None:
        vx, vy = velocity_xy if velocity_xy is not None else (0.0, 0.0)
        vr = -(vx * np.cos(bearing) + vy * np.sin(bearing))
    else:
        vr = np.asarray(radial_velocity, float)[seen]
    doppler = np.full(intensity.shape, np.nan, np.float32)
    if len(r) and doppler_channel:
        best = np.zeros(shape)
        for i in range(len(r)):  # the strongest contribution of each cell, and its Doppler
            c = np.outer(rr[i], aa[i])
            stronger = c > best
            best[stronger] = c[stronger]
            doppler[stronger] = vr[i]
        doppler[best <= 10.0 * max(noise, 1e-12)] = np.nan
    intensity = intensity.astype(np.float32)
    return RangeAzimuth(intensity, intensity.copy(), doppler, RANGE_M.copy(), azimuth)


def points(body_xyz: np.ndarray, velocity_xy: tuple[float, float], *,
           radial_velocity: np.ndarray | None = None, quantum: float = 0.0, noise_mps: float = 0.0,
           rng: np.random.Generator | None = None) -> np.ndarray:
    """A POINT_DTYPE cloud (TI frame) of reflectors at body-frame *body_xyz* (n, 3) or (n, 2),
    static and seen from a sensor moving at body-frame *velocity_xy* (vz = 0) unless
    *radial_velocity* (n,) is given; Doppler plus Gaussian noise, rounded to *quantum*."""
    p = np.asarray(body_xyz, float)
    if p.ndim == 1:
        p = p[None, :]
    if p.shape[1] == 2:
        p = np.column_stack([p, np.zeros(len(p))])
    r = np.linalg.norm(p, axis=1)
    u = p / r[:, None]
    if radial_velocity is None:
        vr = -(u[:, 0] * velocity_xy[0] + u[:, 1] * velocity_xy[1])
    else:
        vr = np.asarray(radial_velocity, float).copy()
    if noise_mps:
        vr = vr + noise_mps * rng.standard_normal(len(vr))
    if quantum:
        vr = quantum * np.round(vr / quantum)
    out = np.zeros(len(p), POINT_DTYPE)
    x_ti, y_ti, z_ti = -p[:, 1], p[:, 0], p[:, 2]
    out["x"], out["y"], out["z"], out["range"] = x_ti, y_ti, z_ti, r
    out["azimuth"] = np.arctan2(x_ti, y_ti)
    out["elevation"] = np.arcsin(z_ti / r)
    out["velocity"] = vr
    out["snr_db"] = 20.0
    return out


def points_polar(bearing_rad: np.ndarray, elevation_rad: np.ndarray | float, velocity_xy, *,
                 range_m: float | np.ndarray = 5.0, **kwargs) -> np.ndarray:
    """:func:`points` from body-frame bearings and elevations."""
    bearing = np.asarray(bearing_rad, float)
    el = np.broadcast_to(np.asarray(elevation_rad, float), bearing.shape)
    r = np.broadcast_to(np.asarray(range_m, float), bearing.shape)
    xyz = np.column_stack([r * np.cos(el) * np.cos(bearing), r * np.cos(el) * np.sin(bearing), r * np.sin(el)])
    return points(xyz, velocity_xy, **kwargs)


# --------------------------------------------------------------------------- trajectories
class Trajectory:
    """Planar motion in phases of constant body-frame speed (forward) and yaw rate:
    *phases* = [(duration_s, speed_mps, yaw_rate_rps), ...], starting at the origin facing +x.
    ``pose(t)`` integrates it exactly (arcs); ``twist(t)`` is (vx, vy, yaw rate) at t."""

    def __init__(self, phases: list[tuple[float, float, float]]) -> None:
        self.phases = phases
        self.starts = [(0.0, (0.0, 0.0, 0.0))]
        t, pose = 0.0, (0.0, 0.0, 0.0)
        for duration, v, w in phases:
            pose = self._advance(pose, v, w, duration)
            t += duration
            self.starts.append((t, pose))
        self.duration = t

    @staticmethod
    def _advance(pose, v, w, dt):
        x, y, yaw = pose
        if abs(w) < 1e-12:
            return x + v * dt * math.cos(yaw), y + v * dt * math.sin(yaw), yaw
        yaw1 = yaw + w * dt
        return x + v / w * (math.sin(yaw1) - math.sin(yaw)), y - v / w * (math.cos(yaw1) - math.cos(yaw)), yaw1

    def _phase(self, t: float) -> int:
        for i in range(len(self.phases)):
            if t < self.starts[i + 1][0]:
                return i
        return len(self.phases) - 1

    def pose(self, t: float) -> tuple[float, float, float]:
        i = self._phase(t)
        t0, pose0 = self.starts[i]
        _, v, w = self.phases[i]
        return self._advance(pose0, v, w, t - t0)

    def twist(self, t: float) -> tuple[float, float, float]:
        _, v, w = self.phases[self._phase(t)]
        return v, 0.0, w

    def path_length(self) -> float:
        return sum(d * abs(v) for d, v, _ in self.phases)


def scene(trajectory: Trajectory, n: int, *, seed: int, separation_m: float = 2.0,
          clearance_m: float = 1.5, box=((-8.0, -10.0), (14.0, 12.0))) -> tuple[np.ndarray, np.ndarray]:
    """*n* point reflectors (world xy (n, 2), amplitudes (n,)) scattered in *box*, at least
    *separation_m* apart and *clearance_m* from the path."""
    rng = np.random.default_rng(seed)
    path = np.array([trajectory.pose(t)[:2] for t in np.linspace(0.0, trajectory.duration, 60)])
    out: list[np.ndarray] = []
    while len(out) < n:
        p = rng.uniform(box[0], box[1])
        if np.min(np.hypot(*(path - p).T)) < clearance_m:
            continue
        if all(np.hypot(*(p - q)) > separation_m for q in out):
            out.append(p)
    return np.array(out), rng.uniform(0.3, 3.0, n)


def frame(world_xy: np.ndarray, amplitude: np.ndarray, pose, velocity_xy, rng: np.random.Generator, *,
          quantum: float = 0.07, noise_mps: float = 0.01, heatmap_kwargs: dict | None = None
          ) -> tuple[np.ndarray, RangeAzimuth]:
    """The point cloud and heatmap of one frame seen from *pose* moving at body *velocity_xy*."""
    body = world_to_body(world_xy, pose)
    r, b = polar_body(body)
    seen = (np.abs(b) < math.radians(70.0)) & (r > 0.5) & (r < 12.0)
    cloud = points(body[seen], velocity_xy, quantum=quantum, noise_mps=noise_mps, rng=rng)
    hm = heatmap(body, amplitude, velocity_xy=velocity_xy, noise=1e-3, rng=rng, **(heatmap_kwargs or {}))
    return cloud, hm


def frames(trajectory: Trajectory, *, seed: int = 2, n_reflectors: int = 40) -> list:
    """(t, cloud, heatmap) of every frame at 10 Hz along *trajectory* among :func:`scene`'s
    *n_reflectors* (the world of *seed*, the noise of seed + 100)."""
    world, amp = scene(trajectory, n_reflectors, seed=seed)
    rng = np.random.default_rng(seed + 100)
    out = []
    for i in range(round(trajectory.duration * 10) + 1):
        vx, vy, _ = trajectory.twist(i / 10)
        out.append((i / 10, *frame(world, amp, trajectory.pose(i / 10), (vx, vy), rng)))
    return out


#: Twelve point reflectors 2.5-10 m from the origin, over +/- 50 degrees of bearing (m, world): a
#: scene whose heatmaps register (the odometry's and the keyframes' tests).
_SCENE_R = np.array([3.0, 5.0, 7.0, 4.0, 9.0, 6.0, 8.0, 2.5, 5.5, 10.0, 6.5, 3.5])
_SCENE_B = np.radians([-50, -40, -30, -20, -10, 0, 10, 20, 30, 40, 50, -5])
SCENE_WORLD = np.column_stack([_SCENE_R * np.cos(_SCENE_B), _SCENE_R * np.sin(_SCENE_B)])


def scene_heatmap(pose=(0.0, 0.0, 0.0), world: np.ndarray | None = None, **kw) -> RangeAzimuth:
    """The heatmap of *world* (default :data:`SCENE_WORLD`) seen from *pose* (x, y m, yaw rad)."""
    world = SCENE_WORLD if world is None else world
    return heatmap(world_to_body(world, pose), 1.0, noise=1e-4, **kw)


def blind_heatmap() -> RangeAzimuth:
    """A heatmap that sees nothing inside the region of interest (its range axis ends before
    the minimum range of the features)."""
    hm = heatmap(SCENE_WORLD, 1.0, noise=1e-4)
    n = 8
    return RangeAzimuth(hm.intensity[:n], hm.static[:n], hm.doppler_mps[:n], hm.range_m[:n], hm.azimuth_rad)


def static_cloud(v, n: int = 40, seed: int = 0) -> np.ndarray:
    """A noise-free cloud of static points seen moving at body velocity *v*."""
    rng = np.random.default_rng(seed)
    return points_polar(np.radians(rng.uniform(-60, 60, n)), 0.0, v, range_m=rng.uniform(1, 10, n))


def run_sequence(config, trajectory: Trajectory, *, seed: int = 2, rate_hz: float = 10.0,
                 start_pose=(0.0, 0.0, 0.0)):
    """Feed a synthetic sequence through RadarOdometry.step; returns states and true poses
    relative to the first frame."""
    world, amp = scene(trajectory, 40, seed=seed)
    x0, y0, yaw0 = start_pose
    # Move the whole world so that the trajectory starts at start_pose in it.
    world_moved = world @ rot(yaw0).T + [x0, y0]
    rng = np.random.default_rng(seed + 100)
    odom = RadarOdometry(config)
    states, truths = [], []
    n = round(trajectory.duration * rate_hz) + 1
    for i in range(n):
        t = i / rate_hz
        px, py, pyaw = trajectory.pose(t)
        wx, wy = rot(yaw0) @ [px, py] + [x0, y0]
        vx, vy, _ = trajectory.twist(t)
        cloud, hm = frame(world_moved, amp, (wx, wy, pyaw + yaw0), (vx, vy), rng)
        states.append(odom.step(t, cloud, hm))
        truths.append((px, py, pyaw))
    return states, truths
