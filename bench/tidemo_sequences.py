"""Simulated sequences for the UART path's accuracy (``bench_tidemo.py accuracy``): recorded once,
through the emulated demo once per CFAR threshold, cached.

A sequence is a capture directory written by ``radar-sim`` with the tidemo cfg (exact fidelity,
with groundtruth.tum) under ``--data`` (default ``~/.cache/radarodom/tidemo``).  Beside its raw
frames (whose raw-path products ``sequences.load`` caches as for the other experiments):

- ``uart-<T>dB-<key>/``: what the emulated demo sends for each raw frame with both cfarCfg
  thresholds at T dB, as a ``tidemo://`` recording (uart.bin, timestamps.txt, radar.cfg,
  capture.json: what ``radar-capture --source replay://DIR`` plays);
- ``uart-<T>dB-<key>/products-<key>.npz``: that recording replayed through the pipeline's products
  as radar-capture makes them (the chip's points, the static heatmap of ``dsp.static_heatmap``);

the key naming the sources of the dsp package, the tidemo driver and the emulated chip
(``demo_frames.py``): a change to any makes both anew.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys

import numpy as np

import sequences
from radarodom import dsp
from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver import open_source, tidemo
from radarodom.driver.emulators import demo_frames
from radarodom.driver.emulators.demo_frames import DemoFrameMaker
from radarodom.driver.tidemo.recording import UartRecorder
from radarodom.pipeline import Pipeline
from radarodom.products import POINT_DTYPE, RangeAzimuth
from radarodom.tum import read_tum

DATA = os.path.expanduser("~/.cache/radarodom/tidemo")
SHIPPED_PROFILE = "profileCfg 0 77 100 6 40 0 0 96 1 256 8000 0 0 30"
TIDEMO_PROFILE = "profileCfg 0 77 100 6 40 0 0 96 1 128 8000 0 0 30"
RANGE_CFAR, DOPPLER_CFAR = "cfarCfg -1 0 2 8 4 3 0 15 1", "cfarCfg -1 1 0 8 4 4 1 15 1"


def tidemo_cfg(threshold_db: float = 15.0) -> RadarConfig:
    """The shipped cfg with 128 samples (a static heatmap the 921600-baud UART carries at 10
    frames/s) and both cfarCfg thresholds at *threshold_db*."""
    text = open(shipped_config_path(), encoding="utf-8").read().replace(SHIPPED_PROFILE, TIDEMO_PROFILE)
    text = text.replace(RANGE_CFAR, RANGE_CFAR.replace(" 15 1", f" {threshold_db:g} 1"))
    text = text.replace(DOPPLER_CFAR, DOPPLER_CFAR.replace(" 15 1", f" {threshold_db:g} 1"))
    return RadarConfig.from_text(text, f"tidemo_{threshold_db:g}dB.cfg")


def record(scene: str, seed: int, data: str = DATA) -> str:
    """The capture directory of *scene* / *seed* with the tidemo cfg, simulated unless there."""
    directory = os.path.join(data, f"{scene}_s{seed}")
    if not os.path.exists(os.path.join(directory, "capture.json")):
        os.makedirs(data, exist_ok=True)
        cfg_path = os.path.join(data, "tidemo128.cfg")
        tidemo_cfg().write(cfg_path)
        tmp = directory + ".tmp"  # a recording cut short must not pass for a whole one
        subprocess.run([sys.executable, "-m", "radarodom.tools.radar_sim", scene, "--seed", str(seed), "--cfg",
                        cfg_path, "--out", tmp, "--overwrite", "-q"], check=True,
                       env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
        os.replace(tmp, directory)
    return directory


def raw(directory: str) -> sequences.Sequence:
    """The raw path's products of the recording (``sequences.load``'s cache)."""
    return sequences.load(directory)


def _uart_recording(directory: str, threshold_db: float) -> tuple[str, list[int]]:
    """The emulated demo's stream of the recording at *threshold_db*, recorded once; and the
    points each packet carries."""
    out = os.path.join(directory, f"uart-{threshold_db:g}dB-{_fingerprint()}")
    counts = os.path.join(out, "points.txt")
    if not os.path.exists(counts):
        cfg = tidemo_cfg(threshold_db)
        maker = DemoFrameMaker(cfg)
        tmp = out + ".tmp"
        if os.path.isdir(tmp):
            for name in os.listdir(tmp):
                os.remove(os.path.join(tmp, name))
        recorder = UartRecorder(tmp, cfg, source=f"{directory} through the emulated demo at {threshold_db:g} dB")
        n_points = []
        with open_source(f"replay://{directory}?rate=max", None) as source:
            for f in source:
                packet, n = maker.packet(f.raw, f.index + 1, f.timestamp)
                recorder.write_packet(packet, f.index, f.timestamp)
                n_points.append(n)
        recorder.close()
        with open(os.path.join(tmp, "points.txt"), "w", encoding="ascii") as fh:
            fh.write("".join(f"{n}\n" for n in n_points))
        os.replace(tmp, out)
    return out, [int(line) for line in open(counts, encoding="ascii")]


def _fingerprint() -> str:
    """What makes the emulated demo's stream and its products: the sources of the dsp package, the
    tidemo driver and the emulated chip."""
    digest = hashlib.sha256()
    for package in (dsp, tidemo):
        sequences.digest_sources(digest, os.path.dirname(package.__file__))
    sequences.digest_sources(digest, os.path.dirname(demo_frames.__file__), [os.path.basename(demo_frames.__file__)])
    return digest.hexdigest()[:16]


class _Arrays:
    """Each frame's time, points and static heatmap intensity (a pipeline sink)."""

    takes_raw, wants_heatmaps, full_heatmaps = False, True, False

    def __init__(self) -> None:
        self.times, self.points, self.intensity = [], [], []
        self.heatmap: RangeAzimuth | None = None

    def write(self, result, stats) -> None:
        self.times.append(result.frame.timestamp)
        self.points.append(result.points.copy())
        self.heatmap = result.heatmap
        self.intensity.append(result.heatmap.intensity.astype(np.float32))

    def close(self, stats) -> None:
        pass


def uart(directory: str, threshold_db: float) -> tuple[sequences.Sequence, list[int]]:
    """The UART path's products of the recording at *threshold_db*, as radar-capture makes them from
    ``replay://`` of the emulated demo's stream; and the points each packet carried."""
    rec, n_points = _uart_recording(directory, threshold_db)
    cache = os.path.join(rec, f"products-{_fingerprint()}.npz")
    if not os.path.exists(cache):
        arrays = _Arrays()
        with open_source(f"replay://{rec}?rate=max") as source:
            Pipeline(source, sinks=[arrays]).run()
        points = arrays.points
        tmp = cache + ".tmp.npz"
        np.savez(tmp, times=np.array(arrays.times), counts=np.array([len(p) for p in points]),
                 points=np.concatenate(points) if points else np.zeros(0, POINT_DTYPE),
                 intensity=np.stack(arrays.intensity), range_m=arrays.heatmap.range_m,
                 azimuth_rad=arrays.heatmap.azimuth_rad)
        os.replace(tmp, cache)
    data = np.load(cache)
    intensity = data["intensity"]
    seq = sequences.Sequence(f"{os.path.basename(directory)} uart {threshold_db:g} dB", rec, data["times"],
                             np.split(data["points"], np.cumsum(data["counts"])[:-1]), intensity,
                             np.full(intensity.shape[1:], np.nan, np.float32)[None].repeat(len(intensity), 0),
                             data["range_m"], data["azimuth_rad"],
                             read_tum(os.path.join(directory, "groundtruth.tum")))
    return seq, n_points
