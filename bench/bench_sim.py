"""Simulator speed: can sim:// stream configs/awr1843_raw.cfg in real time?

For each built-in scene, in this process after a warm-up, over frames spread
evenly along the whole trajectory: the median and 90th-percentile time to
make one frame (geometry, synthesis, noise, int16 bytes), the number of
propagation paths, the real-time factor (frame period / median time; above 1
keeps up) and the share of frames made within one frame period.  The anchor, measured in the same run, is a bare complex64
matrix product of the synthesis's own size (chirps x RX rows, paths, samples):
the floor no chunked implementation can go below on this BLAS.

    python bench/bench_sim.py [--frames 40] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import numpy as np

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.sim.scene import BUILTIN_SCENES, load_scene
from radarodom.driver.sim.simulator import Simulator


def _median_s(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--fidelity", choices=("exact", "fast"), default="fast",
                        help="the synthesis mode to time (fast: what real-time sim:// uses)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    cfg = RadarConfig.from_file(shipped_config_path())
    rows = []
    for name in BUILTIN_SCENES:
        sim = Simulator(cfg, load_scene(name, seed=0), seed=0, fidelity=args.fidelity)
        sim.frame(0)  # warm-up: imports, BLAS threads, caches
        # Frames spread over the whole trajectory: start, turns, the busiest views.
        frame_ids = np.linspace(0, sim.num_frames - 1, args.frames).round().astype(int)
        times, counts = [], []
        for i in frame_ids:
            t = time.perf_counter()
            counts.append(sim.frame(int(i)).num_paths)
            times.append(time.perf_counter() - t)
        per_frame = statistics.median(times)
        p90 = float(np.percentile(times, 90))
        paths = int(statistics.median(counts))
        rows_n = cfg.num_chirps_per_frame * cfg.num_rx
        a = (np.ones((rows_n, paths)) * (1 + 1j)).astype(np.complex64)
        b = (np.ones((paths, cfg.num_samples)) * (1 - 1j)).astype(np.complex64)
        a @ b
        anchor = _median_s(lambda: a @ b, max(5, args.frames // 2))
        rows.append({
            "scene": name, "paths": paths, "max_paths": int(max(counts)), "ms_per_frame": per_frame * 1e3,
            "p90_ms": p90 * 1e3, "realtime_factor": cfg.frame_period_s / per_frame,
            "realtime_share": float(np.mean(np.array(times) <= cfg.frame_period_s)),
            "gemm_anchor_ms": anchor * 1e3, "ratio_to_anchor": per_frame / anchor,
        })
    machine = {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
               "python": platform.python_version(), "numpy": np.__version__}
    if args.json:
        print(json.dumps({"machine": machine, "cfg": "configs/awr1843_raw.cfg", "results": rows}, indent=2))
        return
    print(f"machine: {machine}")
    print(f"fidelity: {args.fidelity}")
    print(f"cfg: configs/awr1843_raw.cfg ({cfg.num_loops} loops x {cfg.num_tx_slots} TX x {cfg.num_rx} RX x "
          f"{cfg.num_samples} samples, {cfg.frame_rate_hz:g} Hz)")
    print(f"{'scene':<12} {'paths':>6} {'max':>6} {'median ms':>9} {'p90 ms':>7} {'x real time':>11} "
          f"{'frames in time':>14} {'GEMM anchor ms':>15} {'ratio':>6}")
    for r in rows:
        print(f"{r['scene']:<12} {r['paths']:>6d} {r['max_paths']:>6d} {r['ms_per_frame']:>9.1f} {r['p90_ms']:>7.1f} "
              f"{r['realtime_factor']:>11.2f} {r['realtime_share']:>13.0%} {r['gemm_anchor_ms']:>15.1f} "
              f"{r['ratio_to_anchor']:>6.2f}")


if __name__ == "__main__":
    main()
