"""The UART path (``tidemo://``, TI's demo firmware's points and static heatmap) against the raw path:
its per-frame cost on the host, and the default estimator's accuracy on the simulator's scenes.

    python bench/bench_tidemo.py cost [--rounds 3] [--frames 40]
    python bench/bench_tidemo.py accuracy [--scenes corridor room lab] [--seeds 0 1 2]
                                          [--thresholds 15 10] [--duration S] [--json FILE]

``cost``: per frame, the host's share of each path.  UART: framing a packet, parsing it, its points
and static antenna values, and their heatmap (``dsp.static_heatmap``); raw: the DSP on the cube
(``FrameProcessor.process``) and the estimator's heatmap (``HeatmapMaker``, its strongest cells'
Doppler).  Both on the same simulated corridor frames of the tidemo cfg below, as multiples of an
anchor timed in the same round: ``bench_estimator.py``'s scipy 2-D FFT (one thread).

``accuracy``: each scene and seed simulated once (``fidelity=exact``), every frame through the raw
path and through the emulated demo (``driver.emulators.demo_frames``: the chip's CFAR at each
``--thresholds`` dB in the cfg's cfarCfg lines, its zero-Doppler azimuth map), then the same
default estimator (``EstimatorConfig()``); yaw-increment RMSE (deg per frame) and drift (% of the
path) against the ground truth (``radarodom.estimator.evaluation``), and the points per frame.

The cfg: the shipped one with 128 ADC samples (``configs/awr1843_raw.cfg`` at 10 frames/s; its 256
samples make an 8 KB heatmap the 921600-baud UART cannot carry in the 73 ms between frames), the
same for both paths.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_estimator import anchor_ms  # noqa: E402  (bench/ is not a package)

from radarodom.cfg import RadarConfig, shipped_config_path  # noqa: E402
from radarodom.driver import open_source  # noqa: E402
from radarodom.driver.emulators.demo_frames import DemoFrameMaker  # noqa: E402
from radarodom.driver.sources import Source  # noqa: E402
from radarodom.driver.tidemo.framer import TlvFramer  # noqa: E402
from radarodom.driver.tidemo.layout import DEFAULT_BAUD, DemoGeometry, gui_selection, uart_budget  # noqa: E402
from radarodom.driver.tidemo.products import PacketFrames  # noqa: E402
from radarodom.dsp.heatmap import HeatmapMaker  # noqa: E402
from radarodom.dsp.processor import FrameProcessor  # noqa: E402
from radarodom.dsp.static_heatmap import StaticHeatmapMaker  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.estimator.evaluation import evaluate  # noqa: E402
from radarodom.pipeline import Pipeline  # noqa: E402
from radarodom.tum import TumTrajectory  # noqa: E402

SHIPPED_PROFILE = "profileCfg 0 77 100 6 40 0 0 96 1 256 8000 0 0 30"
TIDEMO_PROFILE = "profileCfg 0 77 100 6 40 0 0 96 1 128 8000 0 0 30"


def tidemo_cfg(threshold_db: float = 15.0) -> RadarConfig:
    """The shipped cfg with 128 samples and both cfarCfg thresholds at *threshold_db*."""
    text = open(shipped_config_path(), encoding="utf-8").read().replace(SHIPPED_PROFILE, TIDEMO_PROFILE)
    text = text.replace("cfarCfg -1 0 2 8 4 3 0 15 1", f"cfarCfg -1 0 2 8 4 3 0 {threshold_db:g} 1")
    text = text.replace("cfarCfg -1 1 0 8 4 4 1 15 1", f"cfarCfg -1 1 0 8 4 4 1 {threshold_db:g} 1")
    return RadarConfig.from_text(text, f"tidemo_{threshold_db:g}dB.cfg")


class _Held(Source):
    """A source that only holds a cfg: the pipeline's products are built from it, frames are fed
    to :meth:`Pipeline.process` one by one."""

    carries_raw = False

    def __init__(self, config: RadarConfig, calibrated: bool | None) -> None:
        super().__init__()
        self.config, self.calibrated = config, calibrated

    def __iter__(self):
        return iter(())


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
def cost(rounds: int, n_frames: int) -> dict:
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
    rows = []
    for r in range(rounds):
        anchor = anchor_ms()
        t_uart, t_raw = [], []
        for f, data in zip(raws, packets):
            start = time.perf_counter()
            frame = uart.frame(data, f.timestamp)
            static.range_azimuth(frame.static_antennas)
            t_uart.append(time.perf_counter() - start)
            start = time.perf_counter()
            heatmaps.range_azimuth(proc.process(f.cube()).spectrum)
            t_raw.append(time.perf_counter() - start)
        u, w = 1e3 * float(np.median(t_uart)), 1e3 * float(np.median(t_raw))
        rows.append({"round": r, "anchor_ms": anchor, "uart_ms": u, "raw_ms": w, "uart_x_anchor": u / anchor,
                     "raw_x_anchor": w / anchor})
        print(f"round {r}: anchor {anchor:.2f} ms; UART path {u:.3f} ms ({u / anchor:.3f} x anchor); raw path "
              f"{w:.2f} ms ({w / anchor:.2f} x anchor); packet {np.mean([len(p) for p in packets]):.0f} bytes")
    return {"rounds": rows, "frames": len(raws), "cfg": cfg.path}


# ------------------------------------------------------------------ accuracy
def _trajectory(results: list, name: str) -> TumTrajectory:
    se2 = np.array([(st.x, st.y, st.yaw) for _, st in results])
    return TumTrajectory.from_se2(np.array([t for t, _ in results]), se2, source=name)


def accuracy(scenes: list[str], seeds: list[int], thresholds: list[float], duration: float | None) -> dict:
    out: dict = {}
    for scene in scenes:
        for seed in seeds:
            key = f"{scene}/{seed}"
            cfgs = {t: tidemo_cfg(t) for t in thresholds}
            base = cfgs[thresholds[0]]
            url = f"sim://{scene}?seed={seed}&rate=max" + (f"&duration={duration:g}" if duration else "")
            started = time.monotonic()
            with open_source(url, base) as source:
                est = EstimatorConfig()
                raw = Pipeline(source, estimator=est)
                paths = {t: (UartPath(c), Pipeline(_Held(c, source.calibrated), estimator=est))
                         for t, c in cfgs.items()}
                got = {"raw": []} | {t: [] for t in thresholds}
                truth = []
                for f in source:
                    truth.append((f.timestamp, f.pose))
                    got["raw"].append((f.timestamp, raw.process(f).state))
                    for t, (uart, pipe) in paths.items():
                        frame = uart.frame(uart.packet(f.raw, f.index + 1, f.timestamp), f.timestamp)
                        got[t].append((f.timestamp, pipe.process(frame).state))
            poses = np.array([p for _, p in truth])
            ref = TumTrajectory(np.array([t for t, _ in truth]), poses[:, :3], poses[:, 3:], source=key)
            row = {}
            for name, results in got.items():
                res = evaluate(_trajectory(results, f"{key} {name}"), ref)
                row[str(name)] = {"yaw_rmse_deg": res.yaw_rmse_deg, "drift_pct": res.drift_pct,
                                  "path_m": res.ref_path_m, "flagged": sum(not st.ok for _, st in results)}
                if name != "raw":
                    uart = paths[name][0]
                    budget = next(n for n in range(400, -1, -1)
                                  if uart_budget(cfgs[name], uart.geometry.layout(gui_selection(cfgs[name])),
                                                 DEFAULT_BAUD, n).fits)
                    pts = np.array(uart.points)
                    row[str(name)] |= {"points_mean": float(pts.mean()), "points_p90": float(np.percentile(pts, 90)),
                                       "frames_without_points": int(np.sum(pts == 0)),
                                       "frames_over_uart_budget": int(np.sum(pts > budget)),
                                       "uart_budget_points": budget}
            out[key] = row
            print(f"{key} ({time.monotonic() - started:.0f} s): " + "; ".join(
                f"{n}: yaw {v['yaw_rmse_deg']:.2f} deg, drift {v['drift_pct']:.1f} %"
                + (f", {v['points_mean']:.1f} points" if "points_mean" in v else "") for n, v in row.items()),
                flush=True)
    return out


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
    a.add_argument("--duration", type=float, default=None)
    for p in (c, a):
        p.add_argument("--json", metavar="FILE")
    args = parser.parse_args(argv)
    result = (cost(args.rounds, args.frames) if args.what == "cost"
              else accuracy(args.scenes, args.seeds, args.thresholds, args.duration))
    result = {"machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_version()}",
              "date": time.strftime("%Y-%m-%d"), "what": args.what, "result": result}
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
