"""radar-eval: compare an estimated trajectory with ground truth.

    radar-eval EST.tum GT.tum|SOURCE_URL [--plot DIR] [--json FILE] [--delta-m M] [--max-diff S] [-v|-q]

The ground truth is a TUM file, or the source URL the estimate was made from when that source
knows the truth: ``coloradar://RUN_DIR?heatmap=...`` (the heatmap radar's poses from the run's
lidar ground truth and calib transforms) or ``replay://DIR`` (a recording's groundtruth.tum).

Prints a table of relative pose errors (per frame and per distance), the
yaw-increment error, the absolute trajectory error after Umeyama alignment and
the final drift; ``--json`` writes the same numbers, ``--plot`` PNGs.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
from typing import Sequence

import numpy as np

from ..driver.recordings.capture_dir import write_json_atomically
from ..errors import CaptureError, UsageError
from ..estimator.evaluation import EvaluationResult, Stats, evaluate
from ..driver.sources import open_source
from ..tum import TumTrajectory, read_tum
from . import cli, plots

log = logging.getLogger("radarodom.tools.radar_eval")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-eval",
        description="Evaluate an estimated trajectory against ground truth (TUM files, planar SE(2)): "
                    "relative pose error per frame and per distance, yaw-increment error, absolute "
                    "trajectory error after Umeyama alignment, final drift. Numbers follow evo "
                    "(evo_rpe, evo_ape -a).")
    parser.add_argument("estimate", metavar="EST.tum", help="the estimated trajectory")
    parser.add_argument("reference", metavar="GT.tum|URL",
                        help="the ground truth: a TUM file, or the source URL the estimate came from "
                             "(coloradar://RUN_DIR?heatmap=..., replay://DIR with a groundtruth.tum)")
    parser.add_argument("--plot", metavar="DIR", help="write PNG plots into DIR (needs matplotlib)")
    parser.add_argument("--json", metavar="FILE", help="write the numbers as JSON to FILE")
    parser.add_argument("--delta-m", type=cli.positive_float, default=1.0, metavar="M",
                        help="path length of the per-distance RPE, m (default 1)")
    parser.add_argument("--max-diff", type=cli.positive_float, default=0.01, metavar="S",
                        help="largest time difference of two associated poses, s (default 0.01)")
    cli.add_verbosity(parser)
    return parser


def _main(args: argparse.Namespace) -> int:
    if args.plot:
        plots.require_matplotlib()  # before the work, not after it
    for path in (args.estimate,) if "://" in args.reference else (args.estimate, args.reference):
        if not os.path.isfile(path):
            raise UsageError(f"{path}: {'not a file' if os.path.exists(path) else 'no such file'}")
    estimate = read_tum(args.estimate)
    reference = _source_groundtruth(args.reference) if "://" in args.reference else read_tum(args.reference)
    # Coordinates near the float limit make lengths overflow: one warning below, not numpy's
    # one per operation.
    with np.errstate(over="ignore", invalid="ignore"):
        result = evaluate(estimate, reference,
                          delta_m=args.delta_m, max_diff=args.max_diff)
        table = format_table(result)
        overflow = not all(math.isfinite(v) for v in (result.ref_path_m, result.est_path_m, result.drift_m))
        data = result.to_dict() if args.json else None
    if overflow:
        log.warning("the coordinates are too large to compute with: lengths overflow, so figures show as "
                    "inf or nan%s (are the files in metres?)", " and are null in --json" if args.json else "")
    print(table)
    if args.json:
        try:
            write_json_atomically(args.json, data)  # standard JSON: null for an undefined figure
        except OSError as exc:
            raise CaptureError(f"cannot write {args.json}: {exc.strerror or exc}") from None
    if args.plot:
        written = plots.plot_evaluation(result, args.plot)
        if not args.quiet:
            print(f"plots: {', '.join(written)}")
    return 0


def _source_groundtruth(url: str) -> TumTrajectory:
    """The ground truth a frame source knows (its frames are not read)."""
    with open_source(url) as source:
        truth = source.groundtruth()
    if truth is None:
        raise UsageError(f"{url}: the source knows no ground truth")
    if len(truth) == 0:
        raise UsageError(f"{url}: no frame falls inside the ground truth")
    return truth


_COLUMNS = ("rmse", "mean", "median", "std", "min", "max")


def _row(label: str, stats: Stats) -> str:
    cells = "".join(f"{'-' if math.isnan(v) else format(v, '.4f'):>10}"
                    for v in (getattr(stats, c) for c in _COLUMNS))
    return f"{label:<32}{cells}{stats.n:>7}"


def format_table(r: EvaluationResult) -> str:
    """The human summary of an evaluation."""
    d = f"{r.delta_m:g} m"
    lines = [
        f"{r.est_source} against {r.ref_source}",
        (f"  {r.matched} poses matched (estimate {r.est_poses}, ground truth {r.ref_poses}, within "
         f"{r.max_diff_s:g} s) over {r.duration_s:.1f} s; path {r.ref_path_m:.2f} m "
         f"(estimate {r.est_path_m:.2f} m)"),
        "",
        f"{'':<32}" + "".join(f"{c:>10}" for c in _COLUMNS) + f"{'n':>7}",
        _row("RPE per frame, translation m", Stats.of(r.rpe_frame.translation_m)),
        _row("RPE per frame, rotation deg", Stats.of(r.rpe_frame.rotation_deg)),
        _row(f"RPE per {d}, translation m", Stats.of(r.rpe_distance.translation_m)),
        _row(f"RPE per {d}, translation %", Stats.of(r.rpe_distance.translation_pct)),
        _row(f"RPE per {d}, rotation deg", Stats.of(r.rpe_distance.rotation_deg)),
        _row("yaw-increment error deg", Stats.of(r.yaw_error_deg)),
        _row("ATE (Umeyama-aligned) m", Stats.of(r.ate_m)),
        "",
    ]
    pct = "-" if math.isnan(r.drift_pct) else f"{r.drift_pct:.2f}"
    lines.append(f"final drift (aligned at the first pose): {r.drift_m:.3f} m = {pct} % of the path, "
                 f"yaw {r.drift_yaw_deg:+.2f} deg")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
