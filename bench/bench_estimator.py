"""Estimator time per frame (issue goal: 5 ms), against an FFT anchor timed in the same run.

    python bench/bench_estimator.py [--data DIR] [--scenes corridor room lab] [--seed 0]
                                    [--rounds 3] [--json FILE]

Runs :class:`radarodom.estimator.odometry.RadarOdometry` with the defaults (and with some of them
off: the points' map's density weights, the yaw-rate filter's lag bound, the wall map's gates
widened by the turn since a wall was seen, the map of wall directions, ``wall_map.use``, the
points' registration, the heading options)
and with the paper's method on simulated sequences (recorded with ``radar-sim`` and put through
the DSP once, as ``paper_experiment.py`` does, cached in --data) and reports the median and 90th
percentile of ``OdometryState.compute_s`` (everything the estimator does for a frame: the
velocity, the features, the registrations, the integration).

This VM's speed changes by tens of percent from hour to hour, so every round also times an
anchor: the scipy 2-D FFT (range, then Doppler; one thread) of a cube of the shape
``bench_dsp.py`` uses (the shipped cfg with 128 loops), the same work as its ``scipy_2d_w1``.
The table gives each time as a multiple of the anchor of its round; compare runs by those
ratios.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import numpy as np
import scipy.fft

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import sequences  # noqa: E402  (bench/ is not a package)
from heading_variants import (  # noqa: E402
    FIXED_WALL_GATES, FOUR_OPTIONS_OFF, HEATMAPS_ALONE, LAG_GIVEN_TWICE, NO_DENSITY_WEIGHTS, NO_WALL_MAP)

from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.estimator.odometry import RadarOdometry  # noqa: E402

#: The anchor's cube, (loops, tx, rx, samples): bench_dsp.py's (the shipped cfg, 128 loops).
CUBE_SHAPE = (128, 3, 4, 256)


def anchor_ms(repeats: int = 200) -> float:
    """Median time of the scipy 2-D FFT of a CUBE_SHAPE cube, one thread, ms."""
    rng = np.random.default_rng(0)
    x = (rng.standard_normal(CUBE_SHAPE) + 1j * rng.standard_normal(CUBE_SHAPE)).astype(np.complex64)
    times = np.empty(repeats)
    for i in range(repeats):
        start = time.perf_counter()
        scipy.fft.fft(scipy.fft.fft(x, axis=-1, workers=1), axis=0, workers=1, overwrite_x=True)
        times[i] = time.perf_counter() - start
    return 1e3 * float(np.median(times))


def frame_times(seq: sequences.Sequence, config: EstimatorConfig) -> np.ndarray:
    """compute_s of every frame after the first, ms."""
    heatmaps = [seq.heatmap(i) for i in range(len(seq))]  # made before: not the estimator's time
    odom = RadarOdometry(config)
    out = np.empty(len(seq))
    for i in range(len(seq)):
        out[i] = odom.step(seq.times[i], seq.points[i], heatmaps[i]).compute_s
    return 1e3 * out[1:]


def timed_configs() -> dict[str, EstimatorConfig]:
    """The estimator configs timed: the defaults, each of issue 20's heading changes off for its cost, the paper's."""
    default = EstimatorConfig()
    return {"default": default,
            # Each for its cost: the points' map unweighted by its density (issue 20's item 38 off), ...
            "default, the points' map unweighted by its density": default.with_(**NO_DENSITY_WEIGHTS),
            # ... the yaw-rate filter's lag unbounded and given again after the keyframes (item 36
            # off), ...
            "default, the filter's lag unbounded and given twice": default.with_(**LAG_GIVEN_TWICE),
            # ... the wall map's gates fixed whatever the turn since a wall was seen (item 41 off), ...
            "default, the wall map's gates fixed": default.with_(**FIXED_WALL_GATES),
            # ... the map of wall directions off (item 35), ...
            "default without the wall map": default.with_(**NO_WALL_MAP),
            # ... the heatmaps' registration alone (items 30 and 35 off: the points' cost), ...
            "default, the heatmaps' registration alone": default.with_(**HEATMAPS_ALONE),
            # ... and besides, issue 20's four first heading options off: the defaults of 2026-11-25.
            "default before the heading options": default.with_(**FOUR_OPTIONS_OFF, **HEATMAPS_ALONE),
            "paper (Top-k, sampling + mwICP)": EstimatorConfig.paper()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=os.path.expanduser("~/.cache/radarodom/sim"),
                        help="where the simulated sequences are recorded and cached")
    parser.add_argument("--scenes", nargs="+", default=["corridor", "room", "lab"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", help="write the results here too")
    args = parser.parse_args(argv)
    configs = timed_configs()
    seqs = []
    for scene in args.scenes:
        directory = os.path.join(args.data, f"{scene}_s{args.seed}")
        sequences.record(scene, args.seed, directory)
        seqs.append(sequences.load(directory, f"{scene}_s{args.seed}"))
    rows = []
    for rnd in range(args.rounds):
        before = anchor_ms()
        times = {(name, seq.name): frame_times(seq, cfg) for name, cfg in configs.items() for seq in seqs}
        anchor = min(before, anchor_ms())
        for (name, seq_name), ms in times.items():
            rows.append({"round": rnd, "config": name, "sequence": seq_name, "anchor_ms": anchor,
                         "median_ms": float(np.median(ms)), "p90_ms": float(np.percentile(ms, 90)),
                         "x_anchor": float(np.median(ms)) / anchor})
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"numpy {np.__version__}, scipy {scipy.__version__}")
    print(f"{'round':>5} {'anchor ms':>9}  {'config':<52} {'sequence':<12} {'median ms':>9} {'p90 ms':>7} {'x anchor':>8}")
    for r in rows:
        print(f"{r['round']:>5} {r['anchor_ms']:>9.2f}  {r['config']:<52} {r['sequence']:<12} "
              f"{r['median_ms']:>9.2f} {r['p90_ms']:>7.2f} {r['x_anchor']:>8.2f}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
