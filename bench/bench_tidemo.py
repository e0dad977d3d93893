"""The UART path (``tidemo://``, TI's demo firmware's points and static heatmap) against the raw path:
its per-frame cost on the host, and the odometry's accuracy on the simulator's scenes.

    python bench/bench_tidemo.py cost [--rounds 3] [--frames 40] [--data DIR]
    python bench/bench_tidemo.py accuracy [--scenes corridor room lab] [--seeds 0 1 2]
                                          [--thresholds 15 10] [--data DIR] [--json FILE]
                                          [--settings FILE.json]

``cost``: per frame, the host's share of each path.  UART: framing a packet, parsing it, its points
and static antenna values, and their heatmap (``dsp.static_heatmap``); raw: the DSP on the cube
(``FrameProcessor.process``) and the estimator's heatmap (``HeatmapMaker``, its strongest cells'
Doppler).  Both on the same simulated corridor frames of the tidemo cfg below, as multiples of an
anchor timed in the same round: ``bench_estimator.py``'s scipy 2-D FFT (one thread).  Then the
estimator's time a frame on each path's products (the corridor, seed 0, from the accuracy cache):
the raw path's defaults, the UART path's preset (``EstimatorConfig.tidemo()``).

``accuracy``: each scene and seed simulated once (``radar-sim``, exact fidelity) with the tidemo cfg,
through the raw path (``sequences.load``: the DSP's points and heatmaps) and through the emulated
demo at each of ``--thresholds`` dB (both cfarCfg lines; ``tidemo_sequences.uart``: the packets as a
tidemo recording, replayed into the pipeline's products), all cached under ``--data``.  Then the
estimators: the raw path's defaults (``EstimatorConfig()``), and on the UART path the preset
radar-capture takes for a tidemo source (``pipeline.source_estimator``: ``EstimatorConfig.tidemo()``)
and, for comparison, the defaults.  Yaw-increment RMSE (deg per frame, overall and by kind of step:
straight or turning, moving or not) and drift (% of the path) against the ground truth
(``radarodom.estimator.evaluation``), and the points a frame.  ``--settings FILE.json`` lays
settings over every estimator (``EstimatorConfig.with_``'s sections, e.g. ``{"point_yaw":
{"density_weighted": true}}``) to measure a change on both paths.

The cfg: the shipped one with 128 ADC samples (``configs/awr1843_raw.cfg`` at 10 frames/s; its 256
samples make an 8 KB heatmap the 921600-baud UART cannot carry in the 73 ms between frames), the
same for both paths.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import tidemo_sequences  # noqa: E402  (bench/ is not a package)
from bench_estimator import anchor_ms, frame_times  # noqa: E402
from paper_experiment import run  # noqa: E402
from tidemo_sequences import tidemo_cfg  # noqa: E402

from radarodom.cfg import RadarConfig  # noqa: E402
from radarodom.driver import open_source  # noqa: E402
from radarodom.driver.emulators.demo_frames import DemoFrameMaker  # noqa: E402
from radarodom.driver.tidemo.framer import TlvFramer  # noqa: E402
from radarodom.driver.tidemo.layout import DEFAULT_BAUD, DemoGeometry, gui_selection, uart_budget  # noqa: E402
from radarodom.driver.tidemo.products import PacketFrames  # noqa: E402
from radarodom.dsp.heatmap import HeatmapMaker  # noqa: E402
from radarodom.dsp.processor import FrameProcessor  # noqa: E402
from radarodom.dsp.static_heatmap import StaticHeatmapMaker  # noqa: E402
from radarodom.estimator.angles import wrap  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.estimator.evaluation import evaluate  # noqa: E402


class UartPath:
    """The demo's packets of raw frames, framed and turned into frames as tidemo:// does."""

    def __init__(self, cfg: RadarConfig) -> None:
        self.maker = DemoFrameMaker(cfg)
        self.geometry = DemoGeometry.from_config(cfg)
        self.framer = TlvFramer()
        self.stamp = 0.0
        self.frames = PacketFrames(self.geometry, lambda i, p: self.stamp)
        self.points: list[int] = []

    def packet(self, raw, number: int, t: float) -> bytes:
        data, n = self.maker.packet(raw, number, t)
        self.points.append(n)
        return data

    def frame(self, data: bytes, t: float):
        self.stamp = t
        (packet,) = self.framer.feed(data) + self.framer.idle()
        return self.frames(packet, time.monotonic())


# ------------------------------------------------------------------ cost
def cost(rounds: int, n_frames: int, data: str) -> dict:
    cfg = tidemo_cfg()
    uart = UartPath(cfg)
    proc = FrameProcessor(cfg)
    heatmaps = HeatmapMaker(proc, doppler_cells=EstimatorConfig().features.doppler_cells)
    static = StaticHeatmapMaker(proc)
    raws, packets = [], []
    with open_source(f"sim://corridor?rate=max&duration={n_frames * cfg.frame_period_s:g}", cfg) as source:
        for i, f in enumerate(source):
            raws.append(f)
            packets.append(uart.packet(f.raw, i + 1, f.timestamp))
    directory = tidemo_sequences.record("corridor", 0, data)
    raw_seq, (uart_seq, _) = tidemo_sequences.raw(directory), tidemo_sequences.uart(directory, 15.0)
    rows = []
    for r in range(rounds):
        anchor = anchor_ms()
        t_uart, t_raw = [], []
        for f, packet in zip(raws, packets):
            start = time.perf_counter()
            frame = uart.frame(packet, f.timestamp)
            static.range_azimuth(frame.static_antennas)
            t_uart.append(time.perf_counter() - start)
            start = time.perf_counter()
            heatmaps.range_azimuth(proc.process(f.cube()).spectrum)
            t_raw.append(time.perf_counter() - start)
        u, w = 1e3 * float(np.median(t_uart)), 1e3 * float(np.median(t_raw))
        est_uart = float(np.median(frame_times(uart_seq, EstimatorConfig.tidemo())))
        est_raw = float(np.median(frame_times(raw_seq, EstimatorConfig())))
        rows.append({"round": r, "anchor_ms": anchor, "uart_ms": u, "raw_ms": w, "uart_x_anchor": u / anchor,
                     "raw_x_anchor": w / anchor, "uart_estimator_ms": est_uart, "raw_estimator_ms": est_raw,
                     "uart_estimator_x_anchor": est_uart / anchor, "raw_estimator_x_anchor": est_raw / anchor})
        print(f"round {r}: anchor {anchor:.2f} ms; UART path {u:.3f} ms ({u / anchor:.3f} x anchor), its estimator "
              f"{est_uart:.2f} ms ({est_uart / anchor:.2f} x); raw path {w:.2f} ms ({w / anchor:.2f} x anchor), its "
              f"estimator {est_raw:.2f} ms ({est_raw / anchor:.2f} x); packet "
              f"{np.mean([len(p) for p in packets]):.0f} bytes", flush=True)
    return {"rounds": rows, "frames": len(raws), "cfg": cfg.path}


# ------------------------------------------------------------------ accuracy
#: Kinds of step by the truth: turning faster than this a frame, moving faster than this.
TURNING_RAD, MOVING_MPS = math.radians(0.5), 0.1


def step_kinds(seq) -> np.ndarray:
    """Each step's kind by the ground truth, (n - 1,): "straight" or "turn", "moving" or "still"."""
    truth = seq.groundtruth.se2()
    turn = np.abs(wrap(np.diff(truth[:, 2]))) > TURNING_RAD
    moving = np.hypot(*np.diff(truth[:, :2], axis=0).T) / np.diff(seq.times) > MOVING_MPS
    return np.char.add(np.where(turn, "turn_", "straight_"), np.where(moving, "moving", "still"))


def measure(seq, config: EstimatorConfig) -> dict:
    est, _, flagged = run(seq, config)
    res = evaluate(est, seq.groundtruth)
    kinds, errors = step_kinds(seq), res.yaw_error_deg
    by_kind = {}
    if len(kinds) == len(errors):  # every frame matched a ground-truth pose
        by_kind = {k: {"frames": int(np.sum(kinds == k)), "rmse_deg": float(np.sqrt(np.mean(errors[kinds == k] ** 2))),
                       "sum_deg": float(errors[kinds == k].sum())} for k in np.unique(kinds)}
    return {"yaw_rmse_deg": res.yaw_rmse_deg, "drift_pct": res.drift_pct, "path_m": res.ref_path_m,
            "final_yaw_error_deg": float(errors.sum()), "flagged": flagged, "by_kind": by_kind}


def accuracy(scenes: list[str], seeds: list[int], thresholds: list[float], data: str,
             settings: dict | None = None) -> dict:
    raw_config, uart_config = (c.with_(**(settings or {})) for c in (EstimatorConfig(), EstimatorConfig.tidemo()))
    out: dict = {}
    for scene in scenes:
        for seed in seeds:
            key = f"{scene}/{seed}"
            started = time.monotonic()
            directory = tidemo_sequences.record(scene, seed, data)
            row = {"raw": measure(tidemo_sequences.raw(directory), raw_config)}
            for threshold in thresholds:
                seq, points = tidemo_sequences.uart(directory, threshold)
                cfg = tidemo_cfg(threshold)
                layout = DemoGeometry.from_config(cfg).layout(gui_selection(cfg))
                budget = next(n for n in range(400, -1, -1) if uart_budget(cfg, layout, DEFAULT_BAUD, n).fits)
                pts = np.array(points)
                extra = {"points_mean": float(pts.mean()), "points_p90": float(np.percentile(pts, 90)),
                         "frames_without_points": int(np.sum(pts == 0)),
                         "frames_over_uart_budget": int(np.sum(pts > budget)), "uart_budget_points": budget}
                row[f"{threshold:g} dB"] = measure(seq, uart_config) | extra
                row[f"{threshold:g} dB, default estimator"] = measure(seq, raw_config) | extra
            out[key] = row
            print(f"{key} ({time.monotonic() - started:.0f} s): " + "; ".join(
                f"{n}: yaw {v['yaw_rmse_deg']:.2f} deg, drift {v['drift_pct']:.1f} %"
                + (f", {v['points_mean']:.1f} points" if "points_mean" in v else "") for n, v in row.items()),
                flush=True)
    return out


def _settings(path: str | None) -> dict | None:
    if path is None:
        return None
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    c = sub.add_parser("cost")
    c.add_argument("--rounds", type=int, default=3)
    c.add_argument("--frames", type=int, default=40)
    a = sub.add_parser("accuracy")
    a.add_argument("--scenes", nargs="+", default=["corridor", "room", "lab"])
    a.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    a.add_argument("--thresholds", nargs="+", type=float, default=[15.0, 10.0])
    a.add_argument("--settings", metavar="FILE.json", help="settings laid over every estimator (JSON sections)")
    for p in (c, a):
        p.add_argument("--data", default=tidemo_sequences.DATA, help="the simulated sequences' cache")
        p.add_argument("--json", metavar="FILE")
    args = parser.parse_args(argv)
    result = (cost(args.rounds, args.frames, args.data) if args.what == "cost"
              else accuracy(args.scenes, args.seeds, args.thresholds, args.data, _settings(args.settings)))
    result = {"machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_version()}",
              "date": time.strftime("%Y-%m-%d"), "what": args.what, "result": result}
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
