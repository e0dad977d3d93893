"""Simulator speed: can sim:// stream configs/awr1843_raw.cfg in real time?

For each built-in scene, in this process after a warm-up: the median time to
make one frame (geometry, synthesis, noise, int16 bytes), the number of
propagation paths, and the real-time factor (frame period / time per frame;
above 1 keeps up).  The anchor, measured in the same run, is a bare complex64
matrix product of the synthesis's own size (chirps x RX rows, paths, samples):
the floor no chunked implementation can go below on this BLAS.

    python bench/bench_sim.py [--frames 20] [--json]
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
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    cfg = RadarConfig.from_file(shipped_config_path())
    rows = []
    for name in BUILTIN_SCENES:
        sim = Simulator(cfg, load_scene(name, seed=0), seed=0)
        mid = sim.num_frames // 2
        sim.frame(mid)  # warm-up: imports, BLAS threads, caches
        paths = sim.frame(mid).num_paths
        frame_ids = [(mid + i) % sim.num_frames for i in range(args.frames)]
        it = iter(frame_ids * 2)
        per_frame = _median_s(lambda: sim.frame(next(it)), args.frames)
        rows_n = cfg.num_chirps_per_frame * cfg.num_rx
        a = (np.ones((rows_n, paths)) * (1 + 1j)).astype(np.complex64)
        b = (np.ones((paths, cfg.num_samples)) * (1 - 1j)).astype(np.complex64)
        a @ b
        anchor = _median_s(lambda: a @ b, max(5, args.frames // 2))
        rows.append({
            "scene": name, "paths": paths, "ms_per_frame": per_frame * 1e3,
            "realtime_factor": cfg.frame_period_s / per_frame,
            "gemm_anchor_ms": anchor * 1e3, "ratio_to_anchor": per_frame / anchor,
        })
    machine = {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
               "python": platform.python_version(), "numpy": np.__version__}
    if args.json:
        print(json.dumps({"machine": machine, "cfg": "configs/awr1843_raw.cfg", "results": rows}, indent=2))
        return
    print(f"machine: {machine}")
    print(f"cfg: configs/awr1843_raw.cfg ({cfg.num_loops} loops x {cfg.num_tx_slots} TX x {cfg.num_rx} RX x "
          f"{cfg.num_samples} samples, {cfg.frame_rate_hz:g} Hz)")
    print(f"{'scene':<12} {'paths':>6} {'ms/frame':>9} {'x real time':>11} {'GEMM anchor ms':>15} {'ratio':>6}")
    for r in rows:
        print(f"{r['scene']:<12} {r['paths']:>6d} {r['ms_per_frame']:>9.1f} {r['realtime_factor']:>11.2f} "
              f"{r['gemm_anchor_ms']:>15.1f} {r['ratio_to_anchor']:>6.2f}")


if __name__ == "__main__":
    main()
