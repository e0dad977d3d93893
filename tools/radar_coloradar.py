"""radar-coloradar: the paper's two-radar pipeline on a ColoRadar run, and its two tables.

    radar-coloradar RUN_DIR [--calib DIR] [--heatmap cascade|single_chip|single_chip_adc]
                    [--velocity single_chip|single_chip_adc] [--out DIR] [--json FILE] [--overwrite]

Velocity from the single-chip radar's point clouds (about 10 Hz; ``--velocity
single_chip_adc``: radarodom's DSP on its ADC frames), yaw from the heatmaps of
``--heatmap`` (the cascade radar's, about 5 Hz, as in the paper; ``single_chip_adc``:
radarodom's DSP and heatmaps on the single-chip ADC frames),
ground truth from the run's lidar poses moved into the heatmap radar's frame with
the calib transforms.  Every variant of the paper's tables runs on the same data:
yaw RMSE by preprocessing (CFAR, Ray-max, Top-k; sampling + mwICP) and relative
pose error by ICP variant (wICP, sampling + wICP, sampling + mwICP; Top-k), and
radarodom's default estimator beside them.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import os
import sys
from urllib.parse import urlencode
from typing import Sequence

import numpy as np

from .. import strict_json
from ..driver.coloradar.run import ColoRadarRun
from ..driver.coloradar.source import HEATMAP_MODES, VELOCITY_MODES, ColoRadarSource
from ..errors import CaptureError, ConfigError, SourceError, UsageError, kind_of_file, why_not_written
from ..estimator.config import EstimatorConfig, paper_variants
from ..estimator.evaluation import evaluate
from ..estimator.odometry import RadarOdometry
from ..driver.sources import Frame
from ..pipeline import FrameResult, OdometryFeed, Pipeline, Sink
from ..pipeline.products import check_features_fit
from ..products import Products
from ..tum import TumTrajectory, TumWriter
from . import cli
from .replaced_outputs import ReplacedOutputs

#: The paper's numbers (Tables III and IV), by run name.
PAPER = {
    "ec_hallways_run0": {"yaw_rmse_deg": {"CFAR": 4.66, "Ray-max": 3.09, "Top-k": 2.06},
                         "rpe_m": {"wICP": 0.0836, "Sampling + wICP": 0.0124, "Sampling + mwICP": 0.0086}},
    "aspen_run5": {"yaw_rmse_deg": {"CFAR": 1.86, "Ray-max": 1.94, "Top-k": 1.35},
                   "rpe_m": {"wICP": 0.0505, "Sampling + wICP": 0.0077, "Sampling + mwICP": 0.0066}},
}


def variants() -> dict[str, tuple[str, EstimatorConfig]]:
    """Name -> (table, config): the paper's two tables and radarodom's default."""
    return {**paper_variants(), "radarodom default": ("both", EstimatorConfig())}


class _Collected(Sink):
    """Every frame's products, kept for the estimator variants (without the raw bytes)."""

    wants_heatmaps = True

    def __init__(self) -> None:
        self.items: list[tuple[Frame, Products]] = []

    def write(self, result: FrameResult, stats) -> None:
        f = result.frame
        self.items.append((Frame(f.index, f.timestamp, None, None, role=f.role),
                           Products(result.points, result.heatmap)))


def _check_variants_fit(source: ColoRadarSource, run: ColoRadarRun) -> None:
    """Every variant's features can run on the source's heatmaps: said before the run is read, of
    the file that sets them (a CFAR window wider than the heatmaps stopped it after)."""
    for name, (_, config) in variants().items():
        try:
            check_features_fit(source, config.features)
        except ConfigError as exc:
            where = (run.calib_path("single_chip", "waveform_cfg.txt") if source.heatmaps_from_raw
                     else run.calib_path(source.sensor, "heatmap_cfg.txt"))
            why = exc.message.split(": choose ")[0]  # (the settings' own fix is not this program's)
            raise UsageError(f"{where}: the {name!r} variant cannot run on these heatmaps: {why} "
                             "(radar-coloradar runs the paper's settings as they are; radar-capture --source "
                             "coloradar://RUN --estimator-config FILE runs others)") from None


class RunData:
    """A run's two streams, read once through the ``coloradar://`` source: point clouds
    (velocity, in the heatmap radar's frame) and polar heatmaps (yaw); ADC frames go through
    radarodom's DSP once."""

    def __init__(self, run: ColoRadarRun, heatmap: str, velocity: str = "single_chip") -> None:
        try:
            source = ColoRadarSource(run, velocity=velocity, heatmap=heatmap, rate=math.inf)
        except SourceError as exc:
            raise UsageError(str(exc)) from None
        self.run, self.sensor = run, source.sensor
        _check_variants_fit(source, run)
        # Through radar-capture's pipeline, so both give the same trajectory on the same frames.
        collected = _Collected()
        with source:
            truth = source.groundtruth()
            if truth is None:  # before the run's frames are read
                raise UsageError(f"{run.run_dir}: the run has no ground truth (no groundtruth/ folder), which "
                                 f"radar-coloradar measures the odometry against; radar-capture --source "
                                 f"coloradar://{run.run_dir} estimates without one")
            Pipeline(source, sinks=[collected]).run()
            self.groundtruth = source.groundtruth()
        #: (frame, products) of every frame, in time order.
        self.frames = collected.items
        self.heatmap_times = np.array([f.timestamp for f, _ in self.frames if f.role != "velocity"])
        self.kept = np.isin(self.heatmap_times, self.groundtruth.times)

    def estimate(self, config: EstimatorConfig) -> tuple[TumTrajectory, np.ndarray]:
        """The estimated trajectory at the heatmap times kept by the ground truth, and the
        estimator's time per heatmap frame (s)."""
        feed = OdometryFeed(RadarOdometry(config))
        poses, times, compute = [], [], []
        kept = iter(self.kept)
        for frame, products in self.frames:
            state = feed(frame, products)
            if state is not None and next(kept):
                poses.append((state.x, state.y, state.yaw))
                times.append(state.t)
                compute.append(state.compute_s)
        return TumTrajectory.from_se2(np.array(times), np.array(poses).reshape(-1, 3), source=self.run.name), \
            np.array(compute)


def _paper_numbers(name: str) -> dict | None:
    for key, numbers in PAPER.items():
        if name.endswith(key):
            return numbers
    return None


def _tables(name: str, results: dict) -> str:
    paper = _paper_numbers(name)
    lines = [f"ColoRadar {name}: yaw RMSE [deg] by preprocessing (sampling + mwICP)", "",
             "| | CFAR | Ray-max | Top-k | radarodom default |", "| --- | ---: | ---: | ---: | ---: |",
             "| radarodom | " + " | ".join(f"{results[k]['yaw_rmse_deg']:.2f}"
                                           for k in ("CFAR", "Ray-max", "Top-k", "radarodom default")) + " |"]
    if paper:
        lines.append("| paper | " + " | ".join(f"{paper['yaw_rmse_deg'][k]:.2f}" for k in ("CFAR", "Ray-max", "Top-k"))
                     + " | |")
    lines += ["", f"ColoRadar {name}: relative pose error [m] per frame by ICP variant (Top-k)", "",
              "| | wICP | Sampling + wICP | Sampling + mwICP | radarodom default |",
              "| --- | ---: | ---: | ---: | ---: |",
              "| radarodom | " + " | ".join(f"{results[k]['rpe_m']:.4f}" for k in
                                           ("wICP", "Sampling + wICP", "Sampling + mwICP", "radarodom default")) + " |"]
    if paper:
        lines.append("| paper | " + " | ".join(f"{paper['rpe_m'][k]:.4f}"
                                               for k in ("wICP", "Sampling + wICP", "Sampling + mwICP")) + " | |")
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-coloradar",
        description="Run the paper's pipeline (velocity from the single-chip point clouds, yaw from "
                    "heatmaps) and radarodom's default on a ColoRadar run; print the paper's two tables.")
    parser.add_argument("run", metavar="RUN_DIR", help="a ColoRadar run directory (e.g. ec_hallways_run0)")
    parser.add_argument("--calib", metavar="DIR", help="the calib directory (default: beside the run, or in it)")
    parser.add_argument("--heatmap", choices=HEATMAP_MODES, default="cascade",
                        help="whose heatmaps give the yaw: the cascade radar's (default, as in the paper), "
                             "the single-chip radar's as shipped, or radarodom's from its ADC frames")
    parser.add_argument("--velocity", choices=VELOCITY_MODES, default="single_chip",
                        help="what gives the velocity: the single-chip radar's on-chip point clouds (default, "
                             "as in the paper) or radarodom's DSP on its ADC frames (with a single-chip heatmap)")
    parser.add_argument("--out", metavar="DIR",
                        help="write each variant's trajectory and the ground truth (heatmap radar's frame) as "
                             "TUM files here, for radar-eval")
    parser.add_argument("--json", metavar="FILE", help="write the numbers as JSON (a new file)")
    cli.add_overwrite(parser)
    cli.add_verbosity(parser)
    return parser


def _tum_name(variant: str) -> str:
    """The file --out writes a variant's trajectory to: "Sampling + wICP" -> sampling_wicp.tum."""
    return variant.lower().replace(" + ", "_").replace(" ", "_") + ".tum"


def _outputs(args: argparse.Namespace, names: Sequence[str]) -> list[tuple[str, str]]:
    """(option, path) of every file the run writes; each new (or, with --overwrite, replaced),
    none an input, checked before the work (a run takes minutes)."""
    outputs = []
    if args.out:
        if os.path.exists(args.out) and not os.path.isdir(args.out):
            raise UsageError(f"--out {args.out} is {kind_of_file(args.out)}, not a directory")
        outputs += [("--out", os.path.join(args.out, name)) for name in ["groundtruth.tum", *map(_tum_name, names)]]
    if args.json:
        outputs.append(("--json", args.json))
    url = f"coloradar://{args.run}" + (f"?{urlencode({'calib': args.calib})}" if args.calib else "")
    inputs = cli.read_paths([], url, source_option="RUN_DIR")
    cli.check_distinct(([("--out", args.out)] if args.out else []) + outputs, inputs)
    directory = [(args.out, "directory", "--out")] if args.out else []
    cli.check_new_outputs(directory + [(path, "file", option) for option, path in outputs], overwrite=args.overwrite)
    return outputs


def _make_out(directory: str | None) -> list[str]:
    """Make --out (and its parents) before the work; the directories made, deepest first."""
    if not directory or os.path.isdir(directory):
        return []
    made = cli.missing_directories(directory)
    try:
        os.makedirs(directory)
    except OSError as exc:
        raise CaptureError(f"cannot create {directory}: {why_not_written(exc, directory)}") from None
    return made


def _main(args: argparse.Namespace) -> int:
    run = ColoRadarRun(args.run, args.calib)
    outputs = _outputs(args, list(variants()))
    made = _make_out(args.out)
    try:
        return _run(args, run, outputs)
    except BaseException:
        for folder in made:  # a run that wrote nothing leaves nothing behind
            if os.listdir(folder):
                break
            os.rmdir(folder)
        raise


def _span(what: str, times: np.ndarray) -> str:
    """"the heatmaps run from 1.000 to 9.000" (or "... hold none")."""
    return f"{what} run from {times[0]:.3f} to {times[-1]:.3f}" if len(times) else f"{what} hold none"


def _run(args: argparse.Namespace, run: ColoRadarRun, outputs: list[tuple[str, str]]) -> int:
    data = RunData(run, args.heatmap, args.velocity)
    if data.kept.sum() < 2:
        times, truth = data.heatmap_times, run.timestamps("groundtruth")
        raise UsageError(f"{run.run_dir}: fewer than two {args.heatmap} heatmaps fall inside the ground truth: "
                         f"{_span('the heatmaps', times)}, {_span('the ground truth', truth)} (s; each "
                         f"timestamps.txt in seconds?)")
    # What --overwrite replaces is set aside: removed once written anew, put back if the run fails.
    aside = ReplacedOutputs([(path, "file") for _, path in outputs] if args.overwrite else [])
    try:
        _evaluate(args, run, data)
    except BaseException:
        for _, path in outputs:  # what this run wrote of them (any earlier one is set aside): the rerun may write it
            with contextlib.suppress(OSError):
                os.remove(path)
        aside.settle_after_error()
        raise
    aside.settle()
    return 0


class _SaidOnce(logging.Filter):
    """Each warning once: the variants estimate the same frames, and each said what the last had."""

    def __init__(self) -> None:
        super().__init__()
        self.said: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno < logging.WARNING:
            return True
        text = record.getMessage()
        if text in self.said:
            return False
        self.said.add(text)
        return True


def _evaluate(args: argparse.Namespace, run: ColoRadarRun, data: RunData) -> None:
    """Each variant's estimate on *data*, each warning said once: the tables printed, the outputs written."""
    handlers = logging.getLogger("radarodom").handlers
    once = _SaidOnce()
    for handler in handlers:
        handler.addFilter(once)
    try:
        _evaluate_variants(args, run, data)
    finally:
        for handler in handlers:
            handler.removeFilter(once)


def _evaluate_variants(args: argparse.Namespace, run: ColoRadarRun, data: RunData) -> None:
    results = {}
    if args.out:
        with TumWriter(os.path.join(args.out, "groundtruth.tum")) as gt:
            for t, p, q in zip(data.groundtruth.times, data.groundtruth.positions, data.groundtruth.quaternions):
                gt.write_pose(t, p, q)
    for i, (name, (_, config)) in enumerate(variants().items()):
        est, compute = data.estimate(config)
        res = evaluate(est, data.groundtruth, warn_planar=i == 0)  # one warning about the ground truth
        results[name] = {"yaw_rmse_deg": res.yaw_rmse_deg,
                         "rpe_m": float(np.sqrt(np.mean(res.rpe_frame.translation_m ** 2))),
                         "drift_pct": res.drift_pct, "estimator_ms": 1e3 * float(np.median(compute))}
        if args.out:
            with TumWriter(os.path.join(args.out, _tum_name(name))) as w:
                for t, (x, y, yaw) in zip(est.times, est.se2()):
                    w.write(t, x, y, yaw)
    print(_tables(run.name, results))
    if args.json:
        # Standard JSON: a figure that cannot be computed (NaN) is written as null.
        cli.write_output(args.json, strict_json.dumps({"run": run.name, "heatmap": args.heatmap,
                                                       "velocity": args.velocity, "results": results,
                                                       "paper": _paper_numbers(run.name)}, indent=2),
                         overwrite=args.overwrite)


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
