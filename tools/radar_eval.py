"""radar-eval: compare an estimated trajectory with ground truth.

    radar-eval EST.tum GT.tum|SOURCE_URL [--odom ODOM.jsonl [--measured-at S]] [--plot DIR [--name NAME]]
               [--json FILE [--overwrite]]
               [--delta-m M] [--max-diff S] [--mount X,Y,Z,YAW_DEG] [-v|-q]

The ground truth is a TUM file, or the source URL the estimate was made from when that source
knows the truth: ``coloradar://RUN_DIR?heatmap=...`` (the heatmap radar's poses from the run's
lidar ground truth and calib transforms), ``replay://DIR`` (a recording's groundtruth.tum) or
``sim://SCENE?seed=...&duration=...`` (the poses the simulator drives, no frame made).

Prints a table of relative pose errors (per frame and per distance), the
yaw-increment error, the absolute trajectory error after Umeyama alignment and
the final drift, then the heading figures of docs/heading.md (the straight drives' heading bias,
the turns' measured share, the drift each kind of frame makes; straight drives and turns in
place told by the motion of the base the radar sits on, ``--mount``); with ``--odom`` (the
estimator's odometry messages, one JSON object per line, as ``radar-capture --odom-json`` writes
them; ``--flags`` is the same option) how their reported covariances cover the errors
(estimator/consistency.py). ``--json`` writes the same numbers, ``--plot`` PNGs (``report.png`` has
them all), titled ``--name`` (default: the estimate's file name) and with the messages' quality
flags.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
from typing import Sequence

import numpy as np

from ..driver.recordings.capture_writer import json_text
from ..errors import UsageError
from ..mount import Mount
from ..plain_numbers import time_text
from ..estimator.consistency import MAX_MEASURED_AT_S, odometry_consistency
from ..estimator.evaluation import EvaluationResult, associate, evaluate
from ..estimator.heading_metrics import drift_parts, heading_metrics
from ..driver.sources import live_scheme, open_source
from ..tum import TumTrajectory, read_tum
from . import cli, plots
from .eval_summary import format_covariance, format_heading, format_table

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
                             "(coloradar://RUN_DIR?heatmap=..., replay://DIR with a groundtruth.tum, "
                             "sim://SCENE?seed=...&duration=... as the estimate's run had them)")
    parser.add_argument("--plot", metavar="DIR",
                        help="write PNG plots into DIR: report.png (all on one page) and one file per plot "
                             "(needs matplotlib)")
    parser.add_argument("--name", metavar="NAME",
                        help="the run's name on the plots (default: the estimate's file name without .tum)")
    parser.add_argument("--odom", "--flags", dest="odom", metavar="ODOM.jsonl",
                        help="the estimator's odometry messages, one JSON object per line (radar-capture --odom-json, "
                             "radar-echo --json odom): their covariances checked against the ground truth, and "
                             "their quality flags on the plots")
    parser.add_argument("--measured-at", type=cli.float_in(-MAX_MEASURED_AT_S, MAX_MEASURED_AT_S, unit="s"),
                        metavar="S",
                        help="with --odom: each message describes the radar S s after its t (the middle of the "
                             "frame's chirps: radar-cfg prints it as \"chirps' middle\", 0.01344 s with the "
                             "shipped cfg); the covariance check compares it with the truth there, interpolated "
                             "(default: a source URL's, where its frames are raw and it has a cfg; else 0, the "
                             "truth at t)")
    parser.add_argument("--json", metavar="FILE", help="write the numbers as JSON to FILE (a new file)")
    cli.add_overwrite(parser)
    parser.add_argument("--delta-m", type=cli.positive_float, default=1.0, metavar="M",
                        help="path length of the per-distance RPE, m (default 1)")
    parser.add_argument("--max-diff", type=cli.positive_float, default=0.01, metavar="S",
                        help="largest time difference of two associated poses, s (default 0.01)")
    parser.add_argument("--mount", type=cli.mount, default=Mount(), metavar="X,Y,Z,YAW_DEG",
                        help="where the radar sits on the robot (as radar-capture's --mount): the heading figures "
                             "tell straight drives and turns in place by the base's motion (a radar ahead of a "
                             "wheeled base's axis moves in its turns in place; default: the radar is the base)")
    cli.add_verbosity(parser)
    return parser


def _main(args: argparse.Namespace) -> int:
    if args.plot:
        plots.require_matplotlib()  # before the work, not after it
    elif args.name:
        raise UsageError("--name is for the plots: add --plot DIR")
    if args.measured_at is not None and not args.odom:
        raise UsageError("--measured-at is for the covariance check: add --odom ODOM.jsonl")
    files = [(None, args.estimate)] + ([] if "://" in args.reference else [(None, args.reference)])
    for option, path in files + ([("--odom", args.odom)] if args.odom else []):
        if not os.path.isfile(path):  # (a pipe with no writer waited forever; /dev/zero filled the memory)
            said = "not a file" if os.path.exists(path) else "no such file"
            if option is None and path == args.reference and os.path.isdir(path):  # a recording: give its URL
                said += f" (a recording's ground truth: give replay://{path})"
            raise UsageError(f"{option + ' ' if option else ''}{path}: {said}")
    _check_outputs(args)
    estimate = read_tum(args.estimate)
    if "://" in args.reference:
        reference, chirps_middle_s = _source_groundtruth(args.reference)
    else:
        reference, chirps_middle_s = read_tum(args.reference), 0.0
    measured_at = chirps_middle_s if args.measured_at is None else args.measured_at
    odom_log = plots.read_odometry_log(args.odom) if args.odom else None
    # Coordinates near the float limit make lengths overflow: one warning below, not numpy's
    # one per operation.
    with np.errstate(over="ignore", invalid="ignore"):
        result = evaluate(estimate, reference,
                          delta_m=args.delta_m, max_diff=args.max_diff)
        on_base = (args.mount.x, args.mount.y, args.mount.yaw)
        heading = heading_metrics(result.times, result.ref, result.est, radar_on_base=on_base)
        parts = drift_parts(result.times, result.ref, result.est, radar_on_base=on_base)
        table = format_table(result) + "\n\n" + format_heading(heading, parts)
        covariance = None if odom_log is None else odometry_consistency(
            odom_log.times, odom_log.poses, odom_log.pose_covariance, odom_log.twist_covariance,
            odom_log.yaw_rates, odom_log.frames, reference, source=odom_log.source,
            measured_at_s=measured_at)
        if covariance is not None:
            table += "\n\n" + format_covariance(covariance[0], odom_log.source, covariance[1], len(odom_log))
        overflow = not all(math.isfinite(v) for v in (result.ref_path_m, result.est_path_m, result.drift_m))
        if not overflow and covariance is not None and _not_finite_in(covariance[0]):
            smallest = _smallest_variance(odom_log)
            if smallest < TINY_VARIANCE:  # the errors overflow divided by it, not the coordinates
                log.warning("%s: its variances are too small to divide by (the smallest %.3g), so its normalized "
                            "errors show as inf or nan%s", odom_log.source, smallest,
                            " and are null in --json" if args.json else "")
            else:
                overflow = True
        # (json_text writes standard JSON: an undefined figure becomes null)
        data = {**result.to_dict(), "heading": {**heading.to_dict(), "drift_parts": parts},
                **({} if covariance is None else {"covariance": covariance[0]})} if args.json else None
    if overflow and args.plot:  # matplotlib cannot scale an axis of inf (an internal error)
        raise UsageError("--plot: the coordinates are too large to draw: lengths overflow (are the files in "
                         "metres?); without --plot the table shows what can be computed")
    if overflow:
        log.warning("the coordinates are too large to compute with: lengths overflow, so figures show as "
                    "inf or nan%s (are the files in metres?)", " and are null in --json" if args.json else "")
    if args.plot and odom_log is not None:  # (messages of another stretch are refused before any output)
        odom_log = _on_the_evaluation_clock(odom_log, estimate, reference, result)
    print(table)
    if args.json:
        if args.plot:  # the --json file may be one of its files
            plots.make_directory(args.plot)
        cli.write_output(args.json, json_text(data), overwrite=args.overwrite)  # the numbers are above
    if args.plot:
        name = args.name or os.path.splitext(os.path.basename(args.estimate))[0]
        written = plots.plot_evaluation(result, args.plot, name=name, flags=odom_log)
        if not args.quiet:
            print(f"plots: {', '.join(written)}")
    return 0


def _check_outputs(args: argparse.Namespace) -> None:
    """--json is a new file (or, with --overwrite, a file to replace); --plot a directory (made
    when it is not there) whose plots replace those of the same names; neither writes over an
    input or the other: checked before the work."""
    if args.plot and os.path.exists(args.plot) and not os.path.isdir(args.plot):
        raise UsageError(f"--plot {args.plot} is a file, not a directory")
    if args.plot:
        cli.check_writable_directory(args.plot, "--plot")
    outputs = [("--json", args.json)] if args.json else []
    if args.plot:
        outputs += [(f"--plot's {name}", os.path.join(args.plot, name))
                    for name in plots.file_names(flags=bool(args.odom))]
        for what, path in outputs[bool(args.json):]:  # replaced where they are: a plot's own files only
            if os.path.lexists(path) and not os.path.isfile(path):
                raise UsageError(f"{what} {path} is there and is not a file (a directory, a pipe, a device): "
                                 "move it away or choose another --plot directory")
    if not outputs:
        return
    url = "://" in args.reference  # a recording or a run the ground truth is read from
    inputs = cli.read_paths([("EST.tum", args.estimate), ("--odom", args.odom),
                             ("GT.tum", None if url else args.reference)],
                            args.reference if url else None, source_option="GT.tum|URL")
    cli.check_distinct(([("--plot", args.plot)] if args.plot else []) + outputs, inputs)
    if args.json:  # (it may go into a --plot directory the run makes)
        plot = [(args.plot, "directory", "--plot")] if args.plot else []
        cli.check_new_outputs(plot + [(args.json, "file", "--json")], overwrite=args.overwrite)


def _source_groundtruth(url: str) -> tuple[TumTrajectory, float]:
    """The ground truth a frame source knows (its frames are not read), and when after a frame's
    stamp its odometry describes the radar, s: the middle of the frame's chirps where the DSP makes
    its products from raw frames by the source's cfg (``RadarConfig.measured_at_s``), else 0."""
    scheme = live_scheme(url)
    if scheme:  # before a radar is looked for
        raise UsageError(f"{url}: a live radar ({scheme}://) knows no ground truth; give the truth as GT.tum, "
                         f"or a source that has one (replay:// of a simulation's recording, sim://, coloradar://)")
    with open_source(url) as source:
        truth = source.groundtruth()
        raw = source.heatmaps_from_raw and source.config is not None
        chirps_middle_s = source.config.measured_at_s if raw else 0.0
    if truth is None:
        raise UsageError(f"{url}: the source knows no ground truth (a recording's groundtruth.tum, a ColoRadar "
                         f"run's groundtruth/ folder, a simulation's own); give the truth as GT.tum instead")
    if len(truth) == 0:
        raise UsageError(f"{url}: no frame falls inside the ground truth")
    return truth, chirps_middle_s


def _on_the_evaluation_clock(flags: plots.OdometryLog, estimate: TumTrajectory, reference: TumTrajectory,
                             result: EvaluationResult) -> plots.OdometryLog:
    """*flags* with times from the first matched pose (the plots' clock), those of the evaluated
    span only; a file none of whose steps fall in it is refused (another run's?)."""
    t0 = float(associate(estimate, reference, result.max_diff_s)[1].times[0])
    inside = flags.since(t0).within(-result.max_diff_s, result.duration_s + result.max_diff_s)
    if not len(inside):
        raise UsageError(f"{flags.source}: its {len(flags)} odometry messages (t {time_text(flags.times[0])} .. "
                         f"{time_text(flags.times[-1])} s) fall outside the evaluated poses (t {time_text(t0)} .. "
                         f"{time_text(t0 + result.duration_s)} s); are they of this run?")
    if len(inside) < len(flags):
        log.info("%s: %d of %d odometry messages fall outside the evaluated poses", flags.source,
                 len(flags) - len(inside), len(flags))
    return inside


#: A variance below this (an error divided by its square root overflows a double) is no measure.
TINY_VARIANCE = 1e-150


def _smallest_variance(odom_log) -> float:
    """The smallest variance above 0 the messages state (their covariances' diagonals)."""
    diagonals = [np.diagonal(np.asarray(c, float), axis1=-2, axis2=-1).ravel()
                 for c in (odom_log.pose_covariance, odom_log.twist_covariance) if c is not None]
    values = np.concatenate(diagonals) if diagonals else np.zeros(0)
    values = values[np.isfinite(values) & (values > 0)]
    return float(values.min()) if len(values) else math.nan


def _not_finite_in(figures) -> bool:
    """Whether a nested dict (or list) of figures holds an inf or a nan (None is "not computed")."""
    if isinstance(figures, dict):
        return any(_not_finite_in(v) for v in figures.values())
    if isinstance(figures, (list, tuple)):
        return any(_not_finite_in(v) for v in figures)
    return isinstance(figures, float) and not math.isfinite(figures)


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
