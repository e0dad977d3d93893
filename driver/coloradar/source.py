"""``coloradar://`` : a ColoRadar run played as a radar stream.

``coloradar://RUN_DIR?velocity=single_chip&heatmap=cascade&rate=1.0&start=0&calib=DIR``

The paper's setup reads two streams: the velocity comes from one, the yaw from the other's
heatmaps.  Their frames are interleaved in time order, each marked with the estimator stream it
feeds (:attr:`Frame.role <radarodom.driver.sources.Frame.role>`).

- ``velocity``: ``single_chip`` (default), the AWR1843's on-chip point clouds, about 10 Hz;
  or ``single_chip_adc``, its ADC frames through radarodom's DSP (only with a single-chip
  heatmap: the DSP's points are in that radar's frame).
- ``heatmap``: ``cascade`` (default, as in the paper), the cascade radar's heatmaps, about
  5 Hz; ``single_chip``, the single-chip heatmaps the dataset ships; or ``single_chip_adc``,
  the ADC frames through radarodom's DSP and heatmaps.
- ``rate``: 1.0 plays in real time from the timestamps, ``max`` as fast as the consumer takes
  frames.
- ``start``: seconds from the run's first frame to start at (``start=20`` or ``20s``).
- ``calib``: the calibration folder (default: ``calib/`` beside the run, or inside it).

With both streams from ADC every frame is a raw frame (``role`` both): the run plays like a
recording of our own and can be recorded with ``--record``.  Otherwise frames carry the
dataset's products (:attr:`Frame.points`, :attr:`Frame.heatmap`).  Point clouds are turned into
the heatmap radar's frame (the bearing offset of the two mounts); poses (:attr:`Frame.pose`,
:meth:`ColoRadarSource.groundtruth`) are those of the heatmap radar, from the lidar ground
truth through the calib transforms.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from ...cfg import RadarConfig
from ...errors import CaptureFormatError, SourceError
from ...rawframe import RawLayout
from ...tum import TumTrajectory
from .files import STREAMS, check_run_file
from .run import ColoRadarRun, adc_to_cube, heatmap_to_polar, pointcloud_to_points, points_in_frame
from .waveform import TI_TX_ORDER, read_antenna_config, tx_order_from_antennas, waveform_to_config
from ...plain_numbers import plain_float
from ..sources import Frame, Pacer, Source
from ..url_options import RATE_EXPECTED, UrlOptions, given_text, one_of, parse_rate

log = logging.getLogger(__name__)

VELOCITY_MODES = ("single_chip", "single_chip_adc")
HEATMAP_MODES = ("cascade", "single_chip", "single_chip_adc")
ADC_STREAM = "single_chip/adc_samples"


@dataclass(frozen=True)
class _Event:
    """One frame to play: a record of one stream, at its time."""

    t: float
    order: int  # at equal times the velocity comes first: the heatmap frame then uses it
    stream: str
    i: int
    role: str


def _check_overlap(run: ColoRadarRun, velocity: list[float], heatmap: list[float]) -> None:
    """Refuse velocity frames that all lie outside the heatmaps' span (a timestamps.txt shifted, or
    not in seconds): the estimator would have no velocity for any heatmap, and said nothing."""
    if not velocity or not heatmap:
        return
    if max(velocity) < min(heatmap) or min(velocity) > max(heatmap):
        raise SourceError(f"{run.run_dir}: the velocity stream's frames run from {min(velocity):.3f} to "
                          f"{max(velocity):.3f} s, the heatmaps' from {min(heatmap):.3f} to {max(heatmap):.3f} s: "
                          "they do not overlap (is each timestamps.txt in seconds of the same clock?)")


class ColoRadarSource(Source):
    """Plays a ColoRadar run's velocity and heatmap streams, interleaved in time."""

    carries_raw = False

    def __init__(self, run: ColoRadarRun, *, velocity: str = "single_chip", heatmap: str = "cascade",
                 rate: float = 1.0, start_s: float = 0.0, config: RadarConfig | None = None) -> None:
        super().__init__()
        if velocity not in VELOCITY_MODES:
            raise SourceError(f"velocity={velocity!r}: one of {', '.join(VELOCITY_MODES)}")
        if heatmap not in HEATMAP_MODES:
            raise SourceError(f"heatmap={heatmap!r}: one of {', '.join(HEATMAP_MODES)}")
        if velocity == "single_chip_adc" and heatmap == "cascade":
            raise SourceError("velocity=single_chip_adc needs heatmap=single_chip or single_chip_adc: "
                              "the DSP's points are in the single-chip radar's frame, not the cascade's")
        self.run, self.velocity, self.heatmap, self.rate = run, velocity, heatmap, rate
        #: The radar whose frame the odometry is in (it gives the yaw).
        self.sensor = "cascade" if heatmap == "cascade" else "single_chip"
        uses_adc = "single_chip_adc" in (velocity, heatmap)
        both_adc = velocity == heatmap == "single_chip_adc"
        self.carries_raw = both_adc
        streams = {"single_chip/pointclouds": velocity == "single_chip",
                   f"{heatmap}/heatmaps": heatmap != "single_chip_adc",
                   ADC_STREAM: uses_adc}
        for stream, wanted in streams.items():
            if wanted and not run.has(stream):
                runs = _runs_inside(run.run_dir)
                if runs:  # the dataset's folder given instead of one of its runs
                    shown = ", ".join(runs[:5]) + (f" and {len(runs) - 5} more" if len(runs) > 5 else "")
                    raise SourceError(f"{run.run_dir}: not a run but a folder of runs ({shown}): give one run")
                times = os.path.join(run.run_dir, *stream.split('/'), 'timestamps.txt')
                why = ("a directory, not a file" if os.path.isdir(times) else
                       "not a regular file (a pipe or a device)" if os.path.exists(times) else "missing")
                raise SourceError(f"{run.run_dir}: the run has no {stream} ({times} is {why})")

        events: list[_Event] = []
        if both_adc:
            events += self._events(ADC_STREAM, 0, "both")
        else:
            if velocity == "single_chip":
                events += self._events("single_chip/pointclouds", 0, "velocity")
            else:
                events += self._events(ADC_STREAM, 0, "velocity")
            if heatmap == "single_chip_adc":
                events += self._events(ADC_STREAM, 1, "heatmap")
            else:
                events += self._events(f"{heatmap}/heatmaps", 1, "heatmap")
        if not both_adc:
            _check_overlap(run, [e.t for e in events if e.role == "velocity"],
                           [e.t for e in events if e.role == "heatmap"])
        events.sort(key=lambda e: (e.t, e.order))
        if not events:
            raise SourceError(f"{run.run_dir}: the chosen streams hold no frames")
        t0 = events[0].t
        self.events = [e for e in events if e.t - t0 >= start_s - 1e-9]
        if not self.events:
            raise SourceError(f"start={start_s:g}s is past the run's {events[-1].t - t0:.2f} s")

        self.config: RadarConfig | None = None
        self.layout: RawLayout | None = None
        if uses_adc:
            self.config = config if config is not None else self._adc_config()
            wf = run.waveform_config("single_chip")
            adc_shape = (wf.num_chirps_per_frame, wf.num_tx, wf.num_rx, wf.num_adc_samples_per_chirp)
            if self.config.cube_shape != adc_shape:
                raise SourceError(f"the radar configuration's cube {self.config.cube_shape} (loops, tx, rx, "
                                  f"samples) does not match the run's ADC frames {adc_shape}")
            self.layout = RawLayout.from_config(self.config)
            self.coupling = run.coupling("single_chip")
        elif config is not None:
            raise SourceError("a radar configuration applies to ADC frames: this stream uses none "
                              "(give velocity=single_chip_adc or heatmap=single_chip_adc)")
        if heatmap != "single_chip_adc":  # the run's own heatmaps, whose axes its calib gives
            axes = run.heatmap_config(self.sensor)
            self.heatmap_range_bins, self.heatmap_reach_m = axes.num_range_bins, float(axes.range_m[-1])
        self._mount_offset = (run.mount_yaw("single_chip") - run.mount_yaw(self.sensor)
                              if velocity == "single_chip" and self.sensor != "single_chip" else 0.0)
        self._poses = self._truth()
        self.frames_played = 0

    def _events(self, stream: str, order: int, role: str) -> list[_Event]:
        # The whole stream is checked here, before the first frame is played: a broken file met
        # halfway would end a run that has already written its output.
        self.run.check(stream)
        return [_Event(float(t), order, stream, i, role) for i, t in enumerate(self.run.timestamps(stream))]

    def _adc_config(self) -> RadarConfig:
        wf = self.run.waveform_config("single_chip")
        antenna_path = self.run.calib_path("single_chip", "antenna_cfg.txt", required=False)
        if os.path.exists(antenna_path):
            tx_order = tx_order_from_antennas(read_antenna_config(antenna_path))
        else:
            log.warning("%s: missing: assuming TI's TX order %s", antenna_path, TI_TX_ORDER)
            tx_order = TI_TX_ORDER
        times = self.run.timestamps(ADC_STREAM)
        period = float(np.median(np.diff(times))) if len(times) > 1 else 0.1
        return waveform_to_config(wf, tx_order=tx_order, frame_period_s=round(period, 4),
                                  origin=self.run.calib_path("single_chip", "waveform_cfg.txt"),
                                  period_origin=self.run.timestamps_file(ADC_STREAM))

    def _truth(self) -> tuple[TumTrajectory, np.ndarray] | None:
        """The heatmap radar's poses at the event times inside the ground truth, and each
        event's row among them (-1: outside); None when the run has no ground truth."""
        if not self.run.has("groundtruth"):
            times = self.run.timestamps_file("groundtruth")
            if os.path.exists(times):  # there, but no file
                check_run_file(times)
            if os.path.isdir(os.path.dirname(times)):  # a folder without its times: a run cut short
                raise CaptureFormatError(f"{times}: no such file (the run is incomplete: its ground truth "
                                         f"has no timestamps)")
            log.info("%s: no ground truth", self.run.run_dir)
            return None
        traj, kept = self.run.sensor_poses(self.sensor, np.array([e.t for e in self.events]))
        return traj, np.where(kept, np.cumsum(kept) - 1, -1)

    @property
    def heatmaps_from_raw(self) -> bool:
        return self.heatmap == "single_chip_adc"

    def groundtruth(self) -> TumTrajectory | None:
        """The heatmap radar's poses at the times of the frames that give a pose (heatmap
        frames), inside the ground truth's span; None when the run has no ground truth."""
        if self._poses is None:
            return None
        traj, rows = self._poses
        rows = rows[(rows >= 0) & np.array([e.role != "velocity" for e in self.events])]
        return TumTrajectory(traj.times[rows], traj.positions[rows], traj.quaternions[rows], source=traj.source)

    def _frame(self, k: int, e: _Event) -> Frame:
        pose = None
        if self._poses is not None and self._poses[1][k] >= 0:
            traj, rows = self._poses
            pose = (*traj.positions[rows[k]], *traj.quaternions[rows[k]])
        if e.stream == ADC_STREAM:
            cube = adc_to_cube(self.run.adc("single_chip", e.i))
            raw = np.frombuffer(self.layout.encode(cube), np.uint8)
            return Frame(k, e.t, raw, self.layout, pose=pose, role=e.role)
        if e.stream == "single_chip/pointclouds":
            points = pointcloud_to_points(self.run.pointcloud(e.i))
            if self._mount_offset:
                points = points_in_frame(points, self._mount_offset)
            return Frame(k, e.t, None, None, pose=pose, points=points, role=e.role)
        sensor = e.stream.split("/")[0]
        heatmap = heatmap_to_polar(self.run.heatmap(sensor, e.i), self.run.heatmap_config(sensor))
        return Frame(k, e.t, None, None, pose=pose, heatmap=heatmap, role=e.role)

    def _frames(self) -> Iterator[Frame]:
        pacer = Pacer(self.rate, self)
        t0 = self.events[0].t
        for k, e in enumerate(self.events):
            if self.stop_requested:
                return
            pacer.wait(e.t - t0)
            if self.stop_requested:
                return
            yield self._frame(k, e)
            self.frames_played += 1

    def describe(self) -> dict:
        return {"url": self.url, "run": self.run.run_dir, "velocity": self.velocity, "heatmap": self.heatmap,
                "frames": len(self.events), "rate": "max" if self.rate == math.inf else self.rate}


def _seconds(text: str) -> float:
    value = plain_float(text[:-1] if text.endswith("s") else text)  # float() would take "1_0" as 10
    if value is None or not 0 <= value < math.inf:
        raise ValueError(text)
    return value


def open_coloradar(path: str, options: UrlOptions, config: RadarConfig | None) -> ColoRadarSource:
    velocity = options.take("velocity", one_of(*VELOCITY_MODES), "single_chip", "|".join(VELOCITY_MODES))
    heatmap = options.take("heatmap", one_of(*HEATMAP_MODES), "cascade", "|".join(HEATMAP_MODES))
    rate = options.take("rate", parse_rate, 1.0, RATE_EXPECTED)
    start = options.take("start", _seconds, 0.0, "seconds from the first frame, like 20 or 20s")
    calib = options.take("calib", given_text, None, "the calib directory")
    options.finish()
    if not path:
        raise SourceError(f"{options.url}: no path: use coloradar://RUN_DIR")
    run = ColoRadarRun(os.path.expanduser(path), os.path.expanduser(calib) if calib else None)
    try:
        return ColoRadarSource(run, velocity=velocity, heatmap=heatmap, rate=rate, start_s=start, config=config)
    except SourceError as exc:
        raise SourceError(f"{options.url}: {exc}") from None


def _runs_inside(folder: str) -> list[str]:
    """The names of the subfolders of *folder* that look like ColoRadar runs (one of a run's
    streams in them; not calib/), sorted."""
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return []
    return [name for name in names
            if any(os.path.isdir(os.path.join(folder, name, *stream.split("/"))) for stream in STREAMS)]
