"""What the view draws, with Rerun: each frame's point cloud, heatmap and features, the
odometry's trajectory and pose, its time series and quality flags, and the ground truth.

The entity tree follows REP-103 (docs/conventions.md): x forward, y left, z up, metres; its frames
and the arithmetic that puts the radar's motion and the ground truth on the base are the ROS 2
outputs' (radarodom.ros2_frames: the view shows what ``--ros2`` and ``--mcap`` publish).

    world                        the 3-D scene (right-handed, z up)
      odom                       the odometry frame: the robot's base at the first frame
        trajectory/NNNN          the estimate so far, in blocks of poses
        groundtruth/NNNN, groundtruth/pose   the source's true poses, aligned at the first frame
        base_link                the current pose (a transform), with its axes
          radar                  the mounting (static; identity without one)
            fov                  the sensor's field of view
            heatmap              the range-azimuth heatmap on a Cartesian grid, under the points
            points               the point cloud: colour by radial velocity, size by SNR
            features, features/previous   the estimator's features; the previous frame's, moved
    heatmap/polar, heatmap/range the range-azimuth heatmap as an image: range across (labelled),
                                 azimuth down (the radar's left at the top)
    plots/...                    time series: speed, yaw rate, counts, times
    log/flags, log/view          the quality flags as they change; what the view dropped (log/opened:
                                 where the view goes)

Two timelines: ``frame`` (the frame's index) and ``stream_time`` (s since the first frame).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import rerun as rr
import scipy.spatial

from ..cfg import RadarConfig
from ..dsp.heatmap import CartesianGrid
from ..estimator.config import EstimatorConfig
from ..estimator.features import extract
from ..estimator.odometry import OdometryState
from ..estimator.quality import Flag
from ..mount import Mount
from ..products import RangeAzimuth
from ..ros2_frames import Rigid, TruthInOdom, base_pose, ti_to_radar
from .colors import ColorMaps, decibels, normalised
from .frames import Track, ViewHeatmap

ODOM = "world/odom"
BASE = ODOM + "/base_link"
RADAR = BASE + "/radar"

#: How often the view notes in its own log that it dropped frames, s.
_NOTE_PERIOD_S = 1.0
#: Poses per logged block of a trajectory: a frame re-logs only the current block.
_BLOCK = 100
#: The Cartesian heatmap's largest side, cells (its texture is sent every frame).
_GRID_CELLS = 160
#: Rows per azimuth bin of the polar image (range across): a panel-shaped picture.
_POLAR_ROWS = 2
_ESTIMATE = (255, 140, 0)
_TRUTH = (40, 170, 60)
_MATCHED, _UNMATCHED, _PREVIOUS = (60, 200, 90), (250, 120, 40), (150, 150, 170)
#: Each time series entity: its series' names and colours (one Scalars entry per series, NaN
#: where a frame has no value).
SERIES = {"plots/speed": (("speed (m/s)", "true speed"), (_ESTIMATE, _TRUTH)),
          "plots/yaw_rate": (("yaw rate (deg/s)", "true yaw rate"), (_ESTIMATE, _TRUTH)),
          "plots/counts": (("points", "features", "ICP matches"), ((90, 140, 230), _UNMATCHED, _MATCHED)),
          "plots/time_ms": (("latency (ms)", "estimator (ms)"), ((200, 60, 160), (90, 140, 230)))}


class Scene:
    """Draws tracks and frames into the Rerun *recording* (used from one thread).

    *estimator*: its settings (the features are extracted again with them; None: no features);
    *config*: the source's radar configuration (the velocity scale and field of view; None for
    product-only sources); *mount*: the radar on the base (None: the radar is the base);
    *connecting*: a thread still connecting *recording* to a viewer, which :meth:`close` waits for.
    """

    def __init__(self, recording: rr.RecordingStream, *, estimator: EstimatorConfig | None = None,
                 config: RadarConfig | None = None, mount: Mount | None = None,
                 connecting: threading.Thread | None = None) -> None:
        self.rec = recording
        self._connecting = connecting
        self.colors = ColorMaps()
        self._estimator = estimator
        self._config = config
        self._mount = mount or Mount()
        self._velocity_limit = None if config is None else config.max_velocity_mps
        self._t0: float | None = None
        self._flags: tuple[str, ...] = ()
        self._trajectory = _Polyline(recording, ODOM + "/trajectory", _ESTIMATE)
        self._truth = _Polyline(recording, ODOM + "/groundtruth", _TRUTH)
        # The truth as base_link in odom, anchored at the first odometry frame's true pose.
        self._truth_in_odom: TruthInOdom | None = None
        self._truth_last: tuple[float, float, float, float] | None = None  # t, x, y, yaw of the base
        self._grid: CartesianGrid | None = None
        # The last drawn odometry frame's features: (estimator frame, radar pose, xy (n, 2)).
        self._previous: tuple[int, tuple[float, float, float], np.ndarray] | None = None
        self._noted, self._next_note = 0, 0.0
        #: Why the view reaches no viewer, found when it opened (``connect:`` to something that is
        #: not one: :func:`.target.not_a_viewer`); None: it may.  Nothing is drawn then.
        self.unreachable: str | None = None
        self._static()

    def _static(self) -> None:
        log = self.rec.log
        log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        m = self._mount
        log(RADAR, rr.Transform3D(translation=(m.x, m.y, m.z), quaternion=_yaw_quaternion(m.yaw)), static=True)
        log(BASE, rr.TransformAxes3D(0.5), static=True)
        log(ODOM + "/groundtruth/pose", rr.TransformAxes3D(0.3), static=True)
        for entity, (names, colours) in SERIES.items():
            log(entity, rr.SeriesLines(names=names, colors=colours), static=True)

    # ------------------------------------------------------------------ every frame
    def track(self, track: Track) -> None:
        """The frame's odometry, time series, flags and true pose."""
        self._time(track)
        log = self.rec.log
        st = track.state
        truth = (math.nan, math.nan)
        if track.pose is not None and (st is not None or self._truth_in_odom is not None):
            truth = self._true_pose(track)
        nan = math.nan
        if st is not None:
            base = base_pose(st, self._mount)  # the radar's motion moved onto the base, as ROS 2 gets it
            log(BASE, rr.Transform3D(translation=(base.x, base.y, 0.0), quaternion=_yaw_quaternion(base.yaw)))
            self._trajectory.append(base.x, base.y)
            log("plots/speed", rr.Scalars([math.hypot(base.vx, base.vy), truth[0]]))
            log("plots/yaw_rate", rr.Scalars([math.degrees(base.yaw_rate), truth[1]]))
            self._flag_changes(track, st.flags)
        matches = nan if st is None or st.registration is None else st.registration.matches
        log("plots/counts", rr.Scalars([nan if track.points is None else track.points,
                                        nan if st is None else st.features, matches]))
        log("plots/time_ms", rr.Scalars([1e3 * track.latency_s, nan if st is None else 1e3 * st.compute_s]))

    def frame(self, track: Track, points: np.ndarray | None, heatmap: RangeAzimuth | ViewHeatmap | None) -> None:
        """The frame's point cloud (products.POINT_DTYPE), heatmap and features."""
        self._time(track)
        if points is not None:
            self._points(points)
        if heatmap is not None:
            self._heatmap(heatmap)
            if track.state is not None and self._estimator is not None:
                self._features(track.state, heatmap)

    def note(self, text: str, *, warn: bool = False, static: bool = False) -> None:
        """A line in the view's own log (what it dropped); *static*: a heading, at no time."""
        level = rr.TextLogLevel.WARN if warn else rr.TextLogLevel.INFO
        self.rec.log("log/opened" if static else "log/view", rr.TextLog(text, level=level), static=static)

    def dropped(self, dropped: int, offered: int) -> None:
        """Note in the view's own log that frames were dropped (at most once a second)."""
        now = time.monotonic()
        if dropped != self._noted and now >= self._next_note:
            self.note(f"{dropped} of {offered} frames not drawn so far: the view fell behind", warn=True)
            self._noted, self._next_note = dropped, now + _NOTE_PERIOD_S

    def close(self) -> None:
        """Send what is buffered and let go of the viewer, file or server."""
        if self._connecting is not None:
            # Flushed before the connection is set up, the data would stay in Rerun's buffer, and
            # the connection would be made after the disconnect.
            self._connecting.join()
        self.rec.flush()
        self.rec.disconnect()

    # ------------------------------------------------------------------ parts
    def _time(self, track: Track) -> None:
        if self._t0 is None:
            self._t0 = track.t
        self.rec.set_time("frame", sequence=track.frame)
        self.rec.set_time("stream_time", duration=track.t - self._t0)

    def _flag_changes(self, track: Track, flags) -> None:
        bad = tuple(str(f) for f in flags if f != Flag.FIRST_FRAME)
        if bad == self._flags:
            return
        when = f"frame {track.frame} ({track.t - self._t0:.2f} s)"
        if bad:
            self.rec.log("log/flags", rr.TextLog(f"{when}: {', '.join(bad)}", level=rr.TextLogLevel.WARN))
        else:
            self.rec.log("log/flags", rr.TextLog(f"{when}: ok again", level=rr.TextLogLevel.INFO))
        self._flags = bad

    def _true_pose(self, track: Track) -> tuple[float, float]:
        """The source's true pose as base_link in odom, anchored at the first odometry frame as
        the estimate is (radarodom.ros2_frames.TruthInOdom); its speed (m/s) and yaw rate
        (deg/s) from the previous one (NaN at the first)."""
        if self._truth_in_odom is None:
            self._truth_in_odom = TruthInOdom(self._mount)
        base = self._truth_in_odom(track.pose)
        x, y, yaw = base.translation[0], base.translation[1], base.yaw
        self.rec.log(ODOM + "/groundtruth/pose", rr.Transform3D(translation=(x, y, 0.0),
                                                                quaternion=_yaw_quaternion(yaw)))
        self._truth.append(x, y)
        last, self._truth_last = self._truth_last, (track.t, x, y, yaw)
        if last is None or not track.t > last[0]:
            return math.nan, math.nan
        dt = track.t - last[0]
        return math.hypot(x - last[1], y - last[2]) / dt, math.degrees(math.remainder(yaw - last[3], math.tau) / dt)

    def _points(self, points: np.ndarray) -> None:
        xyz = np.column_stack(ti_to_radar(points))  # TI sensor frame -> REP-103
        velocity = points["velocity"]
        limit = self._velocity_limit or max(1.0, float(np.abs(velocity).max(initial=0.0)))
        radii = np.clip(0.02 + 0.003 * points["snr_db"], 0.02, 0.12)
        self.rec.log(RADAR + "/points", rr.Points3D(xyz, colors=self.colors.velocity(velocity, limit), radii=radii))

    def _heatmap(self, heatmap: RangeAzimuth | ViewHeatmap) -> None:
        unit = normalised(decibels(heatmap.intensity))
        if self._grid is None:
            self._start_heatmaps(heatmap)
        # Range across, azimuth down (the radar's left at the top).
        self.rec.log("heatmap/polar", rr.Image(np.repeat(self.colors.heat(unit.T), _POLAR_ROWS, axis=0)))
        cartesian = self._grid.resample(unit)
        height, width = cartesian.shape
        self.rec.log(RADAR + "/heatmap", rr.Mesh3D.from_fields(
            albedo_texture_buffer=self.colors.heat(cartesian).tobytes(),
            albedo_texture_format=rr.components.ImageFormat(width=width, height=height, color_model="RGB",
                                                            channel_datatype="U8")))

    def _start_heatmaps(self, heatmap: RangeAzimuth | ViewHeatmap) -> None:
        """At the first heatmap (its axes are the stream's): the Cartesian grid and the fan of
        triangles it is drawn on (the field of view), the outline, the polar image's labels."""
        r_max = float(heatmap.range_m[-1])
        self._grid = CartesianGrid(heatmap.range_m, heatmap.azimuth_rad, max_range_m=r_max,
                                   resolution_m=max(0.05, 2.0 * r_max / _GRID_CELLS))
        lo, hi = float(heatmap.azimuth_rad[0]), float(heatmap.azimuth_rad[-1])
        fov = self._config.aoa_fov if self._config is not None else None
        if fov is not None:
            lo, hi = max(lo, math.radians(fov.min_azimuth_deg)), min(hi, math.radians(fov.max_azimuth_deg))
        azimuth = np.linspace(lo, hi, 49)
        ti_x, ti_y = r_max * np.sin(azimuth), r_max * np.cos(azimuth)  # TI sensor frame
        arc = np.column_stack([ti_y, -ti_x, np.zeros_like(ti_x)])  # REP-103
        # A fan from the radar along the arc, textured by the grid (its rows run ahead, TI y,
        # its columns to the right, TI x; texture (0, 0) is the first row's first column).
        grid_x, grid_y = self._grid.x, self._grid.y
        u = np.concatenate([[-grid_x[0]], ti_x - grid_x[0]]) / (grid_x[-1] - grid_x[0])
        v = np.concatenate([[-grid_y[0]], ti_y - grid_y[0]]) / (grid_y[-1] - grid_y[0])
        fan = np.column_stack([np.zeros(len(arc)), np.arange(1, len(arc) + 1), np.arange(2, len(arc) + 2)])[:-1]
        vertices = np.vstack([[0.0, 0.0, 0.0], arc]) + [0.0, 0.0, -0.02]  # under the points
        self.rec.log(RADAR + "/heatmap", rr.Mesh3D(vertex_positions=vertices, triangle_indices=fan,
                                                   vertex_texcoords=np.column_stack([u, v])), static=True)
        self.rec.log(RADAR + "/fov", rr.LineStrips3D([np.vstack([[0.0, 0.0, 0.0], arc, [0.0, 0.0, 0.0]])],
                                                     colors=(120, 120, 120), radii=0.01), static=True)
        cols, rows = heatmap.intensity.shape[0], heatmap.intensity.shape[1] * _POLAR_ROWS
        self.rec.log("heatmap/range", rr.Points2D([(0.0, rows + 6.0), (cols - 1.0, rows + 6.0)], radii=0.5,
                                                   labels=[f"{heatmap.range_m[0]:.0f} m", f"{r_max:.1f} m"],
                                                   colors=(200, 200, 200), show_labels=True), static=True)

    def _features(self, state: OdometryState, heatmap: RangeAzimuth | ViewHeatmap) -> None:
        """The features the estimator keeps of this heatmap (extracted again with its settings and
        the step's velocity), in the plane it registers them in (horizontal range and bearing),
        green where one of the previous frame's features, moved by the estimated step, lies within
        the ICP's match gate (eps_max of eq. 4), orange elsewhere."""
        features = extract(heatmap, self._estimator.features, np.array([state.vx, state.vy]))
        xy = np.asarray(features.xy)
        matched = np.zeros(len(xy), bool)
        previous = self._previous
        if previous is not None and previous[0] == state.frame - 1 and len(previous[2]) and len(xy):
            step = Rigid.planar(*previous[1]).inverse() * Rigid.planar(*state.pose)  # the radar's motion
            c, s = math.cos(step.yaw), math.sin(step.yaw)
            d = previous[2] - np.array(step.translation[:2])
            moved = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
            icp = self._estimator.icp
            scale = np.array([math.sqrt(icp.alpha), math.sqrt(icp.beta)])
            tree = scipy.spatial.cKDTree(_polar(moved) * scale)
            distance, _ = tree.query(_polar(xy) * scale, distance_upper_bound=math.sqrt(icp.eps_max))
            matched = np.isfinite(distance)
            self.rec.log(RADAR + "/features/previous", rr.Points3D(_planar(moved), colors=_PREVIOUS, radii=0.025))
        else:
            self.rec.log(RADAR + "/features/previous", rr.Clear(recursive=False))
        colours = np.where(matched[:, None], np.array(_MATCHED, np.uint8), np.array(_UNMATCHED, np.uint8))
        self.rec.log(RADAR + "/features", rr.Points3D(_planar(xy), colors=colours, radii=0.05))
        self._previous = (state.frame, state.pose, xy)


class _Polyline:
    """A growing line logged in blocks of :data:`_BLOCK` points: each new point re-logs only its
    block, so a frame's cost does not grow with the run (each block starts where the last ended)."""

    def __init__(self, recording: rr.RecordingStream, entity: str, colour: tuple[int, int, int]) -> None:
        self.rec, self.entity, self.colour = recording, entity, colour
        self.block = 0
        self.points: list[tuple[float, float, float]] = []

    def append(self, x: float, y: float) -> None:
        if len(self.points) >= _BLOCK:
            self.block += 1
            self.points = self.points[-1:]
        self.points.append((x, y, 0.0))
        self.rec.log(f"{self.entity}/{self.block:04d}", rr.LineStrips3D([self.points], colors=self.colour, radii=0.03))


def _yaw_quaternion(yaw: float) -> rr.Quaternion:
    return rr.Quaternion(xyzw=[0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)])


def _polar(xy: np.ndarray) -> np.ndarray:
    """(range, bearing) of body-frame points (n, 2)."""
    return np.column_stack([np.hypot(xy[:, 0], xy[:, 1]), np.arctan2(xy[:, 1], xy[:, 0])])


def _planar(xy: np.ndarray) -> np.ndarray:
    """Body-frame points (n, 2) in the radar's plane, (n, 3)."""
    return np.column_stack([xy, np.zeros(len(xy))])
