"""Frames lost on the way (dropped UDP frames, a link that stalls) or blind (a person right in
front of the radar): the default estimator on the heading matrix's base cells with frames taken
out or blanked.

    python bench/frame_gaps.py [--scenes corridor room lab] [--seeds 0 1 2 3 4 5]
        [--losses none drop5 gap1 gap2 blind1] [--workers N] [--data DIR] [--json OUT]

Each base cell of bench/robustness_matrix.py (the shipped cfg at 0 dB, 0.8 m/s, 45 deg/s: a loop
of straights, a moving left turn, a turn in place of 180 degrees and a moving right turn; recorded
into DATA as the matrix records it, or reused from there) runs through the default estimator with
some of its frames, heatmap and point cloud alike, never delivered or seeing nothing:

- ``none``: every frame;
- ``dropP``: P % of the frames at random (the same ones in every run), as a lost UDP packet loses
  its frame;
- ``gapS``: every frame within S seconds after each 7 s mark from 5 s on (a link that stalls for
  S seconds every 7 s; a gap lands in straights and in turns alike);
- ``blindS``: the same frames delivered, but their heatmap only noise (exponential, its mean the
  frame's median) and their point cloud empty (the radar covered, or a person right in front of it).

Gaps and blind runs start 5 s in and stop 5 s before the end.

Prints, for each loss, the drift (% of the path) and the final heading error (degrees) over the
cells, mean and worst; ``--json`` writes every cell's.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import math
import os
import platform
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from matrix_cells import SimCell  # noqa: E402

#: The gaps' first start and spacing, s.
GAP_FROM_S, GAP_EVERY_S = 5.0, 7.0


def parse_loss(loss: str) -> tuple[str, float]:
    """*loss*'s kind ("none", "drop", "gap" or "blind") and amount (%, s; 0 for "none");
    ValueError for anything else."""
    if loss == "none":
        return loss, 0.0
    kind = next((k for k in ("drop", "gap", "blind") if loss.startswith(k)), "")
    try:
        amount = float(loss[len(kind):]) if kind else math.nan
    except ValueError:
        amount = math.nan
    if not (0 <= amount <= 100 if kind == "drop" else 0 < amount < GAP_EVERY_S):
        raise ValueError(f"loss {loss!r}: none, dropP (P % of frames, 0-100), gapS or blindS (S seconds, "
                         f"under {GAP_EVERY_S:g}, every {GAP_EVERY_S:g} s)")
    return kind, amount


def delivered(times: np.ndarray, loss: str) -> np.ndarray:
    """Which frames (at *times*, (n,) s) arrive under *loss* ("none", "dropP", "gapS", "blindS"):
    (n,) bool, the first frame always; "blindS" delivers all (:func:`blinded` says which see
    nothing)."""
    kind, amount = parse_loss(loss)
    keep = np.ones(len(times), bool)
    if kind == "drop":
        keep[1:] = np.random.default_rng(7).random(len(times) - 1) >= amount / 100.0
    elif kind == "gap":
        keep &= ~_in_gaps(times, amount)
    return keep


def blinded(times: np.ndarray, loss: str) -> np.ndarray:
    """Which frames see nothing under *loss* ("blindS"; none for the others): (n,) bool."""
    kind, amount = parse_loss(loss)
    return _in_gaps(times, amount) if kind == "blind" else np.zeros(len(times), bool)


def _in_gaps(times: np.ndarray, length: float) -> np.ndarray:
    """The frames within *length* s after each mark (``GAP_FROM_S``, every ``GAP_EVERY_S``)."""
    inside = np.zeros(len(times), bool)
    for start in np.arange(times[0] + GAP_FROM_S, times[-1] - GAP_FROM_S, GAP_EVERY_S):
        inside |= (times > start) & (times < start + length)
    return inside


def blind_frame(heatmap, rng: np.random.Generator):
    """*heatmap* as a radar that sees nothing gives it: exponential noise whose mean is its
    median, no Doppler."""
    from radarodom.products import RangeAzimuth
    noise = (float(np.median(heatmap.intensity)) * rng.exponential(1.0, heatmap.intensity.shape)).astype(
        heatmap.intensity.dtype)
    elevation = None if heatmap.elevation_rad is None else np.zeros_like(heatmap.elevation_rad)
    return RangeAzimuth(noise, noise, np.zeros_like(heatmap.doppler_mps), heatmap.range_m, heatmap.azimuth_rad,
                        elevation)


def run(cell: SimCell, losses: list[str], data: str) -> list[dict]:
    """The estimator on *cell*'s frames under each of *losses*: drift and final heading error.
    One worker a cell: its recording is made (or its DSP products cached) and read once, by it
    alone."""
    import robustness_matrix
    import sequences
    seq = sequences.load(robustness_matrix.record(cell, data), cell.name)
    return [_run(cell, seq, loss) for loss in losses]


def _run(cell: SimCell, seq, loss: str) -> dict:
    import robustness_matrix
    from radarodom.estimator.evaluation import associate
    from radarodom.estimator.heading_metrics import heading_metrics
    from radarodom.estimator.odometry import RadarOdometry
    from radarodom.products import POINT_DTYPE
    from radarodom.tum import TumTrajectory
    odom = RadarOdometry(robustness_matrix.estimator_config(cell))
    frames = np.flatnonzero(delivered(seq.times, loss))
    blind = blinded(seq.times, loss)
    rng = np.random.default_rng(3)
    poses = np.zeros((len(frames), 3))
    for j, i in enumerate(frames):
        if blind[i]:
            state = odom.step(seq.times[i], np.zeros(0, POINT_DTYPE), blind_frame(seq.heatmap(i), rng))
        else:
            state = odom.step(seq.times[i], seq.points[i], seq.heatmap(i))
        poses[j] = state.x, state.y, state.yaw
    est, ref = associate(TumTrajectory.from_se2(seq.times[frames], poses, source=cell.name), seq.groundtruth, 0.01)
    metrics = heading_metrics(ref.times, ref.se2(), est.se2())
    return {"cell": cell.name, "loss": loss, "frames": int(len(frames)), "of": int(len(seq.times)),
            "drift_pct": metrics.drift_pct, "final_heading_error_deg": metrics.final_heading_error_deg}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["corridor", "room", "lab"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4, 5])
    ap.add_argument("--losses", nargs="+", default=["none", "drop5", "gap1", "gap2", "blind1"])
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--data", default=os.path.expanduser("~/.cache/radarodom/robustness"),
                    help="where the matrix's recordings are (or go): robustness_matrix.py's --data")
    ap.add_argument("--json", help="write every cell's result here")
    args = ap.parse_args(argv)
    if args.workers < 1:
        ap.error("--workers: at least 1")
    for loss in args.losses:
        try:
            parse_loss(loss)  # a bad name fails here, not in a worker
        except ValueError as exc:
            ap.error(f"--losses: {exc}")
    cells = [SimCell(scene=scene, seed=seed) for scene in args.scenes for seed in args.seeds]
    with concurrent.futures.ProcessPoolExecutor(args.workers) as pool:
        results = [r for rows in pool.map(run, cells, [args.losses] * len(cells), [args.data] * len(cells))
                   for r in rows]
    print(f"{len(cells)} cells; {platform.processor() or platform.machine()}, Python {platform.python_version()}")
    print("| loss | frames delivered | drift %, mean / worst | final heading error deg, mean abs / worst |")
    print("| --- | ---: | ---: | ---: |")
    for loss in args.losses:
        rows = [r for r in results if r["loss"] == loss]
        share = sum(r["frames"] for r in rows) / sum(r["of"] for r in rows)
        drift = [r["drift_pct"] for r in rows]
        heading = [abs(r["final_heading_error_deg"]) for r in rows]
        print(f"| {loss} | {100 * share:.0f} % | {np.mean(drift):.2f} / {max(drift):.1f} | "
              f"{np.mean(heading):.1f} / {max(heading):.1f} |")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump([{k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in r.items()}
                       for r in results], fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
