"""Simulated sequences for the estimator experiment: record, run the DSP once, cache.

A sequence is a capture directory written by ``radar-sim`` (exact fidelity, with
groundtruth.tum; a simulated board of its own with ``board``) and, beside it,
``dsp-<key>.npz``: every frame's point cloud and range-azimuth heatmap (intensity
and dominant Doppler), made by the pipeline radar-capture runs, so that estimator variants can be compared without
repeating the DSP.  The key names what made it: the DSP's source files, its FFT
backend, the DspConfig and the radar cfg the recording is read with (its own, or
another one: the same recording with and without a calibration line); a cache
from anything else is made anew.  The ground truth at a sequence's frames: :func:`truth` (poses)
and :func:`true_velocities` (bench/heading_diagnosis.py --true-velocity).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
import sys
import zipfile
from dataclasses import dataclass

import numpy as np

from radarodom import dsp
from radarodom.cfg import RadarConfig
from radarodom.driver.sources import open_source
from radarodom.dsp.config import DspConfig
from radarodom.dsp.fft import resolve_backend
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.evaluation import associate
from radarodom.estimator.velocity import VelocityEstimate, VelocityStatus, estimate_velocity
from radarodom.pipeline import FrameResult, Pipeline, Sink
from radarodom.products import POINT_DTYPE, RangeAzimuth
from radarodom.tum import TumTrajectory, read_tum


@dataclass
class Sequence:
    name: str
    directory: str
    times: np.ndarray  # (n,) s
    points: list  # n arrays of POINT_DTYPE
    intensity: np.ndarray  # (n, n_range, n_az) float32
    doppler: np.ndarray  # (n, n_range, n_az) float32, m/s
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    groundtruth: TumTrajectory
    #: (n, n_range, n_az) float32, rad: each cell's elevation; None without a raised antenna row.
    elevation: np.ndarray | None = None

    def heatmap(self, i: int) -> RangeAzimuth:
        return RangeAzimuth(self.intensity[i], self.intensity[i], self.doppler[i], self.range_m,
                            self.azimuth_rad, None if self.elevation is None else self.elevation[i])

    def __len__(self) -> int:
        return len(self.times)


def record(scene: str, seed: int, directory: str, duration: float | None = None, board: str = "ideal",
           fidelity: str = "exact") -> None:
    """Simulate *scene* on *board* with ``radar-sim`` (at *fidelity*) unless *directory* already
    holds it."""
    if os.path.exists(os.path.join(directory, "capture.json")):
        return
    # Into a temporary directory first: a recording cut short must not pass for a whole one.
    tmp = directory.rstrip(os.sep) + ".tmp"
    cmd = [sys.executable, "-m", "radarodom.tools.radar_sim", scene, "--seed", str(seed),
           "--board", board, "--fidelity", fidelity, "--out", tmp, "--overwrite", "-q"]
    if duration is not None:
        cmd += ["--duration", str(duration)]
    subprocess.run(cmd, check=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    os.replace(tmp, directory)


def chosen_variants(parser, names: list[str], only: list[str] | None) -> list[str]:
    """The variants ``--only`` names, in the order of *names* (all of them without it); a name not
    among them is refused through the argparse *parser* (exit 2) with the list of names."""
    unknown = [n for n in only or [] if n not in names]
    if unknown:
        parser.error(f"--only: no variant named {', '.join(map(repr, unknown))}; the variants are:\n  "
                     + "\n  ".join(names))
    return [n for n in names if not only or n in only]


def digest_sources(digest, folder: str, names: list[str] | None = None) -> None:
    """Feed *digest* the Python sources of *folder* (only *names*, when given), each by its name
    and content, in name order."""
    for name in sorted(os.listdir(folder) if names is None else names):
        if name.endswith(".py"):
            with open(os.path.join(folder, name), "rb") as fh:
                digest.update(name.encode() + b"\0" + fh.read())


def dsp_fingerprint() -> str:
    """What makes the DSP's output: the dsp package's sources and the FFT backend in use."""
    digest = hashlib.sha256()
    digest_sources(digest, os.path.dirname(dsp.__file__))
    return f"{digest.hexdigest()[:16]}/{resolve_backend('auto')}"


def _key(dsp_config: DspConfig | None, cfg: RadarConfig | None) -> str:
    """What makes a cache: the DSP's sources and backend, its settings, the cfg."""
    digest = hashlib.sha256((dsp_fingerprint() + "/estimator-heatmaps").encode())
    digest.update(json.dumps((dsp_config or DspConfig()).to_dict(), sort_keys=True).encode())
    digest.update(b"" if cfg is None else cfg.to_text().encode())
    return digest.hexdigest()[:16]


class _Arrays(Sink):
    """Every frame's time, point cloud and heatmap (intensity, dominant Doppler and, with a
    raised antenna row, elevation; float32)."""

    # The heatmaps radar-capture gives the estimator: every cell's intensity (and elevation),
    # the dominant Doppler of its strongest cells (FeatureConfig.doppler_cells), for far less
    # time than the full map, which gives every cell a Doppler the estimator never reads.
    wants_heatmaps, full_heatmaps = True, False

    def __init__(self) -> None:
        self.times, self.points, self.intensity, self.doppler, self.elevation = [], [], [], [], []
        self.heatmap: RangeAzimuth | None = None

    def write(self, result: FrameResult, stats) -> None:
        self.times.append(result.frame.timestamp)
        self.points.append(result.points.copy())
        self.heatmap = result.heatmap
        self.intensity.append(result.heatmap.intensity.astype(np.float32))
        self.doppler.append(result.heatmap.doppler_mps.astype(np.float32))
        if result.heatmap.elevation_rad is not None:
            self.elevation.append(result.heatmap.elevation_rad.astype(np.float32))


def _process(directory: str, dsp_config: DspConfig | None, cfg: RadarConfig | None) -> dict:
    arrays = _Arrays()
    with open_source(f"replay://{directory}?rate=max", cfg) as source:
        Pipeline(source, dsp=dsp_config, sinks=[arrays]).run()
    points = arrays.points
    return dict(times=np.array(arrays.times), counts=np.array([len(p) for p in points]),
                points=np.concatenate(points) if points else np.zeros(0, POINT_DTYPE),
                intensity=np.stack(arrays.intensity), doppler=np.stack(arrays.doppler),
                elevation=np.stack(arrays.elevation) if arrays.elevation else np.zeros(0, np.float32),
                range_m=arrays.heatmap.range_m, azimuth_rad=arrays.heatmap.azimuth_rad)


def cache_path(directory: str, dsp_config: DspConfig | None = None, cfg: RadarConfig | None = None) -> str:
    """Where :func:`load` keeps *directory*'s DSP products for these settings and today's DSP."""
    return os.path.join(directory, f"dsp-{_key(dsp_config, cfg)}.npz")


def _cached(path: str):
    """The products kept in *path* (an NpzFile), None when there are none; a damaged file (a run
    killed as it wrote) is said and made again."""
    if not os.path.exists(path):
        return None
    try:
        data = np.load(path)
        data["counts"]  # the index read: a file cut short fails here, not later
        return data
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as exc:
        print(f"{path}: damaged ({type(exc).__name__}: {exc}): the DSP products are made again", file=sys.stderr)
        return None


def load(directory: str, name: str | None = None, *, dsp_config: DspConfig | None = None,
         cfg: RadarConfig | None = None) -> Sequence:
    """The sequence in *directory* through the DSP (*dsp_config*, default settings; the recording
    read with *cfg*, default its own radar.cfg), from its cache, made on first use and again
    whenever what makes it has changed."""
    cache = cache_path(directory, dsp_config, cfg)
    data = _cached(cache)
    if data is None:
        data = _process(directory, dsp_config, cfg)
        tmp = f"{cache}.{os.getpid()}.tmp.npz"  # two programs on one directory each write their own
        np.savez(tmp, **data)
        os.replace(tmp, cache)
        data = np.load(cache)
    splits = np.cumsum(data["counts"])[:-1]
    return Sequence(name or os.path.basename(os.path.normpath(directory)), directory, data["times"],
                    np.split(data["points"], splits), data["intensity"], data["doppler"],
                    data["range_m"], data["azimuth_rad"],
                    read_tum(os.path.join(directory, "groundtruth.tum")),
                    data["elevation"] if data["elevation"].size else None)


def truth(seq: Sequence) -> np.ndarray:
    """The true SE(2) poses (n, 3) at the sequence's frame times."""
    stub = TumTrajectory.from_se2(seq.times, np.zeros((len(seq), 3)), source="frames")
    _, ref = associate(stub, seq.groundtruth, 0.01)
    return ref.se2()


def true_velocities(seq: Sequence, config: EstimatorConfig) -> list[VelocityEstimate]:
    """The radar's velocity at each frame by the ground truth (whose poses are the radar's), body
    frame, as velocity estimates: the central difference of the poses before and after (one-sided
    at the ends), turned into the frame's heading; ``zero_velocity`` under the fit's threshold.
    A cloud without elevation (every point's 0: a 2-TX array) keeps its level fit's forward speed
    as the estimate's level velocity (``level_scale``: the truth's over the fit's), which is what
    the Doppler's elevation reads cells against (docs/heading.md item 26)."""
    poses = truth(seq)
    t = np.asarray(seq.times, dtype=float)
    rng = np.random.default_rng(config.velocity.seed)
    out = []
    for i in range(len(seq)):
        a, b = max(i - 1, 0), min(i + 1, len(seq) - 1)
        world = (poses[b, :2] - poses[a, :2]) / (t[b] - t[a]) if b > a else np.zeros(2)
        c, s = math.cos(poses[i, 2]), math.sin(poses[i, 2])
        vx, vy = c * world[0] + s * world[1], -s * world[0] + c * world[1]
        still = math.hypot(vx, vy) < config.velocity.zero_velocity_threshold_mps
        est = VelocityEstimate(t=float(t[i]), vx=vx, vy=vy, covariance=np.eye(2) * 1e-6,
                               status=VelocityStatus.ZERO if still else VelocityStatus.OK)
        points = seq.points[i]
        if points is not None and len(points) and not np.any(points["elevation"]):
            level = estimate_velocity(points, est.t, config.velocity, rng)
            if level.ok and min(abs(level.vx), abs(vx)) > config.features.doppler_elevation_min_mps:
                est.level_scale = vx / level.vx
        out.append(est)
    return out
