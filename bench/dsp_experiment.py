"""The DSP's settings and the board's calibration, measured by what they do to the odometry.

    python bench/dsp_experiment.py [--data DIR] [--scenes room corridor lab] [--seeds 0 1 2 3 4 5]
                                   [--only NAME ...] [--out DIR]

Each variant reads the same simulated sequences (recorded once with ``radar-sim``, exact
fidelity, as bench/paper_experiment.py does; the uncalibrated board's beside them) through the
DSP with its own settings (cached per sequence and variant), then runs the default estimator
on its point clouds and heatmaps.  Per scene, means over the seeds:

- points a frame;
- the velocity fit: RMSE of the estimator's body velocity (vx, vy) against the ground truth's
  (central differences of its poses), and the share of frames whose point cloud gave no
  velocity (flags velocity_failed / velocity_held / velocity_from_heatmap);
- the odometry: yaw-increment RMSE (deg) and final drift (% of the path), as radar-eval.

Variants: the detection (range CFAR method, azimuth peaks per cell, the usable range) on the
perfect board, and the uncalibrated board (driver/sim/boards/uncalibrated.toml) read with its
recording's identity line (which leaves one azimuth a cell: further peaks need a calibrated
array), with the line radar-calibrate measures on the calibration scene, and with its exact line.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import sequences  # noqa: E402  (bench/ is not a package)

from radarodom.cfg import RadarConfig, shipped_config_path  # noqa: E402
from radarodom.driver.sim.board import load_board  # noqa: E402
from radarodom.driver.sim.scene import load_scene  # noqa: E402
from radarodom.driver.sim.simulator import Simulator  # noqa: E402
from radarodom.dsp.calibrate import measure as measure_line  # noqa: E402
from radarodom.dsp.cfar import CfarParams  # noqa: E402
from radarodom.dsp.config import DspConfig  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.estimator.evaluation import evaluate  # noqa: E402
from radarodom.estimator.odometry import RadarOdometry  # noqa: E402
from radarodom.tum import TumTrajectory, quaternion_yaw  # noqa: E402

VELOCITY_FLAGS = {"velocity_failed", "velocity_held", "velocity_from_heatmap"}


def _cfar(method: str, rank: int | None = None) -> CfarParams:
    return CfarParams(method, guard=2, train=8, pfa=1e-5, cyclic=False, os_rank=rank)


def variants(measured_line) -> dict[str, tuple[str, DspConfig, RadarConfig | None]]:
    """Name -> (board, DSP settings, cfg to read the recording with: None for its own)."""
    d = DspConfig()
    cfg = RadarConfig.from_file(shipped_config_path())
    exact = cfg.replace(load_board("uncalibrated").calibration().to_command())
    return {
        "as before: CAGO range CFAR, one azimuth a cell, detections to 12.4 m (today's Pfa, CFAR at the peaks)": (
            "ideal", dataclasses.replace(d, range_cfar=_cfar("cago"), max_azimuth_peaks=1, max_range_m=12.45,
                                         range_skirt_db=None), None),
        "CAGO, one azimuth a cell": ("ideal", dataclasses.replace(d, range_cfar=_cfar("cago"), max_azimuth_peaks=1), None),
        "CASO, one azimuth a cell": ("ideal", dataclasses.replace(d, range_cfar=_cfar("caso"), max_azimuth_peaks=1), None),
        "CASO, up to 2 azimuths a cell": ("ideal", dataclasses.replace(d, range_cfar=_cfar("caso")), None),
        "OS rank 12 of 16, one azimuth a cell": (
            "ideal", dataclasses.replace(d, range_cfar=_cfar("os", 12), max_azimuth_peaks=1), None),
        "OS rank 12 of 16, up to 2 azimuths a cell": ("ideal", dataclasses.replace(d, range_cfar=_cfar("os", 12)), None),
        "OS rank 10 of 16, up to 2 azimuths a cell": ("ideal", dataclasses.replace(d, range_cfar=_cfar("os", 10)), None),
        "OS median, one azimuth a cell": ("ideal", dataclasses.replace(d, max_azimuth_peaks=1), None),
        "default: OS median, up to 2 azimuths a cell, skirts dropped": ("ideal", d, None),
        "default, skirts kept": ("ideal", dataclasses.replace(d, range_skirt_db=None), None),
        "default, up to 3 azimuths a cell": ("ideal", dataclasses.replace(d, max_azimuth_peaks=3), None),
        "uncalibrated board, identity line (so one azimuth a cell)": ("uncalibrated", d, None),
        "uncalibrated board, line from radar-calibrate": ("uncalibrated", d, cfg.replace(measured_line.to_command())),
        "uncalibrated board, its exact line": ("uncalibrated", d, exact),
    }


def calibrate_on_the_simulator(board: str) -> object:
    """The line radar-calibrate measures for *board* on the calibration scene (10 frames, 3 m)."""
    cfg = RadarConfig.from_file(shipped_config_path())
    sim = Simulator(cfg, load_scene("calibration"), board=load_board(board))
    return measure_line(cfg, (sim.layout.decode(sim.frame(i).raw) for i in range(10)), 3.0).calibration


def true_body_velocity(gt: TumTrajectory, times: np.ndarray) -> np.ndarray:
    """(n, 2) body-frame velocity of the ground truth at *times*, central differences."""
    pos = np.array([np.interp(times, gt.times, gt.positions[:, k]) for k in range(2)]).T
    yaw = np.unwrap(np.array([quaternion_yaw(q) for q in gt.quaternions]))
    yaw = np.interp(times, gt.times, yaw)
    v = np.gradient(pos, times, axis=0)
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1]], axis=1)


def run(seq: sequences.Sequence) -> dict:
    odom = RadarOdometry(EstimatorConfig())
    n = len(seq)
    poses, vel = np.zeros((n, 3)), np.zeros((n, 2))
    failed = 0
    for i in range(n):
        st = odom.step(seq.times[i], seq.points[i], seq.heatmap(i))
        poses[i] = st.x, st.y, st.yaw
        vel[i] = st.vx, st.vy
        failed += bool(VELOCITY_FLAGS & set(st.flags))
    truth = true_body_velocity(seq.groundtruth, seq.times)
    res = evaluate(TumTrajectory.from_se2(seq.times, poses, source=seq.name), seq.groundtruth)
    return {"points": float(np.mean([len(p) for p in seq.points])),
            "velocity_rmse": float(np.sqrt(np.mean(np.sum((vel[1:] - truth[1:]) ** 2, axis=1)))),
            "velocity_failed": failed / n, "yaw_rmse_deg": res.yaw_rmse_deg, "drift_pct": res.drift_pct}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=os.path.expanduser("~/.cache/radarodom/sim"))
    parser.add_argument("--scenes", nargs="+", default=["corridor", "room", "lab"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4, 5])
    parser.add_argument("--only", nargs="+", metavar="VARIANT",
                        help="run only these variants, by their names in the tables (a wrong name is refused with "
                             "the list)")
    parser.add_argument("--out", default="experiment-out")
    args = parser.parse_args(argv)
    started = time.monotonic()
    line = calibrate_on_the_simulator("uncalibrated")
    table = variants(line)
    names = sequences.chosen_variants(parser, list(table), args.only)
    os.makedirs(args.out, exist_ok=True)
    results: dict = {}
    for name in names:
        board, dsp_config, cfg = table[name]
        for scene in args.scenes:
            for seed in args.seeds:
                suffix = "" if board == "ideal" else f"_{board}"
                directory = os.path.join(args.data, f"{scene}_s{seed}{suffix}")
                sequences.record(scene, seed, directory, board=board)
                seq = sequences.load(directory, f"{scene}_s{seed}{suffix}", dsp_config=dsp_config, cfg=cfg)
                results[(name, scene, seed)] = r = run(seq)
                print(f"{name}: {scene} seed {seed}: {r['points']:.1f} points, v RMSE {r['velocity_rmse']:.4f} m/s, "
                      f"yaw {r['yaw_rmse_deg']:.2f} deg, drift {r['drift_pct']:.1f} %", file=sys.stderr)
    head = (f"Simulated {', '.join(args.scenes)}, seeds {', '.join(map(str, args.seeds))}; "
            f"{platform.processor() or platform.machine()}, Python {platform.python_version()}; "
            f"{time.monotonic() - started:.0f} s.\n\nMeasured line: `{line.cfg_line()}`\n\n"
            "**DSP variants** (points a frame / velocity RMSE m/s / frames without a cloud velocity % / "
            "yaw RMSE deg / drift %)\n\n| variant | " + " | ".join(args.scenes) + " |\n| --- |"
            + " ---: |" * len(args.scenes) + "\n")
    body = ""
    for name in names:
        cells = []
        for scene in args.scenes:
            rs = [results[(name, scene, s)] for s in args.seeds if (name, scene, s) in results]
            m = {k: float(np.mean([r[k] for r in rs])) for k in rs[0]}
            cells.append(f"{m['points']:.1f} / {m['velocity_rmse']:.4f} / {100 * m['velocity_failed']:.1f} / "
                         f"{m['yaw_rmse_deg']:.2f} / {m['drift_pct']:.1f}")
        body += f"| {name} | " + " | ".join(cells) + " |\n"
    print(head + body)
    with open(os.path.join(args.out, "dsp_tables.md"), "w", encoding="utf-8") as fh:
        fh.write(head + body)
    with open(os.path.join(args.out, "dsp_results.json"), "w", encoding="utf-8") as fh:
        json.dump([{"variant": v, "scene": s, "seed": sd, **r} for (v, s, sd), r in results.items()], fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
