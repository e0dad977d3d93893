"""radar-capture: stream radar frames from a source, run the DSP and the odometry
on them, show a live status, record.

    radar-capture --source replay://DIR [--cfg FILE] [--record OUT] [--odom-out FILE.tum]
                  [--frames N] [--duration S] [--no-odom]

Ctrl-C (or SIGTERM) stops after the current frame and closes the recording;
a second Ctrl-C aborts at once (what was written stays readable).
"""

from __future__ import annotations

import os

# One BLAS thread: the DSP's matrix products are small, and OpenBLAS threads spin and stall
# when the other core is busy with capture (measured: 14 ms instead of 0.2 ms per product).
# Set before numpy loads; an explicit setting in the environment wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402  (after the BLAS setting)
import contextlib
import logging
import math
import sys

from typing import Iterator, Sequence

from ..cfg import RadarConfig
from ..driver.recordings.capture_dir import CaptureWriter
from ..driver.sources import SCHEMES, Source, open_source
from ..errors import CaptureError, ConfigError, RadarodomError, UsageError
from ..estimator.config import EstimatorConfig
from ..pipeline.products import check_features_fit
from ..pipeline import CaptureSink, HeatmapSink, Pipeline, PipelineStats, PointsCsvSink, TumSink, source_estimator
from . import cli, ros_outputs, view_option
from .capture_text import odometry_fields, status_fields, stream_summary
from .replaced_outputs import ReplacedOutputs
from .status import StatusLine
from .zenoh_args import add_zenoh_arguments, options_given


log = logging.getLogger("radarodom.tools.radar_capture")

#: What runs when no source is given and no radar is attached.
DEFAULT_SIM_URL = "sim://corridor"


def _default_source() -> str:
    """The live radar when one is plugged in (through its DCA1000, or its UART without one), else
    the simulator."""
    from ..driver.live.default_source import default_source_url

    return default_source_url(DEFAULT_SIM_URL)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-capture",
        description="Stream raw radar frames from a source, run the DSP and the odometry on every "
                    "frame, publish them over Zenoh, show a live status, and optionally record the frames "
                    "to a capture directory.",
        epilog="Sources: replay://DIR[?rate=1.0|max&loop=N&start=K|Ss&frames=N] plays a capture "
               "directory or TI recorder files (with --cfg); sim://SCENE[?seed=N&rate=1.0|max&duration=S&loop=N] "
               "simulates a scene (corridor, room, lab, calibration, or a .toml/.json file). "
               "dca1000://[BOARD_IP][?cli=PORT&host=IP&delay=US&policy=latest|queue] streams the live "
               "radar. coloradar://RUN_DIR[?velocity=single_chip|single_chip_adc&heatmap=cascade|single_chip|"
               "single_chip_adc&rate=1.0|max&start=S&calib=DIR] plays a ColoRadar run. tidemo://[DATA_PORT][?cli=PORT] "
               "streams the radar alone, its demo firmware's points and heatmap (no DCA1000). Without --source: "
               "the live radar when one is plugged in (dca1000:// where a DCA1000 is attached, else tidemo://), "
               f"else {DEFAULT_SIM_URL}.")
    parser.add_argument("--cfg", metavar="FILE",
                        help="radar configuration (TI .cfg); for replay:// of a capture directory "
                             "it defaults to the directory's radar.cfg")
    parser.add_argument("--source", metavar="URL",
                        help=f"frame source ({', '.join(s + '://' for s in sorted(SCHEMES))}; default: "
                             f"the live radar if one is plugged in, through its DCA1000 or without one over "
                             f"its UART, else {DEFAULT_SIM_URL})")
    parser.add_argument("--record", metavar="DIR", help="record the frames to this new capture directory")
    parser.add_argument("--points-out", metavar="FILE.csv",
                        help="run the DSP and write every frame's point cloud to this new CSV file")
    parser.add_argument("--heatmap-out", metavar="DIR",
                        help="run the DSP and write every frame's range-azimuth heatmaps (.npy) here")
    parser.add_argument("--odom-out", metavar="FILE.tum",
                        help="write the odometry (body frame in the first frame's, one TUM line per frame) "
                             "to this new file")
    parser.add_argument("--no-odom", action="store_true",
                        help="do not run the estimator (capture, record and DSP exports only)")
    parser.add_argument("--estimator-config", metavar="FILE.json",
                        help="estimator settings (JSON, as EstimatorConfig.dump writes; default: the built-in ones, "
                             "or those the source's frames call for: tidemo:// EstimatorConfig.tidemo())")
    parser.add_argument("--wheeled", action="store_true",
                        help="the robot's base cannot slide or skid sideways (differential drive, car-like; not "
                             "mecanum or skid-steered): with --mount off its rotation axis the radar's Doppler "
                             "measures the yaw rate in turns, on the axis the radar's velocity is taken to have no "
                             "sideways part, along the forward axis learnt from straight drives (docs/cli.md)")
    parser.add_argument("--no-wall-map", action="store_true",
                        help="publish the odometry's own heading, not corrected by the walls seen again (the map "
                             "of wall directions, on by default: docs/estimator.md)")
    ros_outputs.add_arguments(parser)
    view_option.add_view_argument(parser)
    cli.add_overwrite(parser)
    parser.add_argument("--no-publish", action="store_true",
                        help="do not publish over Zenoh (offline runs and evaluation)")
    add_zenoh_arguments(parser, ros2=True)
    parser.add_argument("--frames", type=cli.positive_int, metavar="N", help="stop after N frames")
    parser.add_argument("--duration", type=cli.positive_float, metavar="S",
                        help="stop after S seconds of stream time")
    cli.add_verbosity(parser)
    return parser


@contextlib.contextmanager
def _stop_on_signals(pipeline: Pipeline) -> Iterator[None]:
    """First SIGINT/SIGTERM: ask the pipeline to stop after the current frame.
    Second: abort now (KeyboardInterrupt)."""
    received = 0

    def handler(signum, frame):
        nonlocal received
        received += 1
        if received > 1:
            raise KeyboardInterrupt
        pipeline.stop()
        if not pipeline.stats.frames and pipeline.source.starts_radar:
            # a radar being started answers sensorStart first (seconds): say why nothing happens yet
            log.warning("stopping once the radar has started (it answers sensorStart first); Ctrl-C again aborts now")

    with cli.on_stop_signals(handler):
        yield


def _estimator_config(args: argparse.Namespace) -> EstimatorConfig:
    """--estimator-config's settings (or the defaults) with --mount's place of the radar, with
    --wheeled a base that cannot slide sideways (off its rotation axis the radar's Doppler then
    measures the yaw rate; on it, the radar does not slide) and with --no-wall-map the heading
    not corrected by the walls seen again."""
    config = EstimatorConfig.load(args.estimator_config) if args.estimator_config else EstimatorConfig()
    mount = args.mount
    # Only what the options say: --wheeled alone keeps the settings file's mount.
    odometry = {} if mount.is_identity else {"mount_x_m": mount.x, "mount_y_m": mount.y, "mount_yaw_rad": mount.yaw}
    filed = {key: getattr(config.odometry, key) for key in odometry}
    if any(filed.values()) and not all(math.isclose(filed[k], v, abs_tol=1e-9) for k, v in odometry.items()):
        raise UsageError(  # one of the two would be dropped without a word
            f"--mount {mount.x:g},{mount.y:g},{mount.z:g},{math.degrees(mount.yaw):g} and --estimator-config "
            f"{args.estimator_config}'s odometry mount (x {filed['mount_x_m']:g} m, y {filed['mount_y_m']:g} m, yaw "
            f"{math.degrees(filed['mount_yaw_rad']):g} degrees) differ: give the mount once")
    if args.wheeled:
        odometry["base"] = "wheeled"
    if odometry:
        config = config.with_(odometry=odometry)
    if args.no_wall_map:
        config = config.with_(wall_map={"use": False})
    return config


def _main(args: argparse.Namespace, status: StatusLine) -> int:
    status.enabled = not args.quiet
    estimator_options = [option for option, given in (("--odom-out", args.odom_out), ("--estimator-config",
                         args.estimator_config), ("--wheeled", args.wheeled), ("--no-wall-map", args.no_wall_map))
                         if given]
    if args.no_odom and estimator_options:
        raise UsageError(f"--no-odom turns the estimator off: it cannot also take {estimator_options[0]}")
    # --ros2-topic names the bag's odometry topic too: an offline conversion may take it.
    zenoh_given = options_given(args)
    given = [option for option in (zenoh_given if args.no_publish else [])
             if not (option == "--ros2-topic" and args.mcap)]
    if given:
        raise UsageError(f"{given[0]} is about publishing over Zenoh, which --no-publish turns off: drop one")
    if "--ros2-topic" in zenoh_given and not (args.ros2 or args.mcap):
        raise UsageError("--ros2-topic names the ROS 2 odometry topic: add --ros2 (publish it) or --mcap FILE "
                         "(write it to a bag)")
    if "--ros2-domain" in zenoh_given and not args.ros2:
        raise UsageError("--ros2-domain is the ROS 2 domain of --ros2's messages: add --ros2")
    cfg = RadarConfig.from_file(args.cfg) if args.cfg else None
    # Read the estimator's settings before any hardware is touched.
    args.estimator = _estimator_config(args)
    defaulted = not args.source
    if defaulted:
        args.source = _default_source()
    # The Zenoh options are checked here, but the session opens only once the source is open
    # and the outputs are checked: a bad URL, scene, cfg or output is the one error printed.
    zenoh_options = None if args.no_publish else _zenoh_options(args)
    with contextlib.ExitStack() as session:
        source = session.enter_context(open_source(args.source, cfg))
        if defaulted and args.source == DEFAULT_SIM_URL:
            log.warning("%s", _default_sim_note(source))
        _check_source_and_outputs(args, source)
        publisher = None if zenoh_options is None else session.enter_context(_open_publisher(zenoh_options, args.mount))
        summary = _run(args, source, publisher, status)
    print(f"radar-capture: {summary}")
    return 0


def _default_sim_note(source: Source) -> str:
    """When the default simulator stream ends, and how to keep it going."""
    about = source.describe()
    forever = DEFAULT_SIM_URL + "?loop=0"
    return (f"the simulated {about['scene']} runs {about['duration_s']:.1f} s ({about['frames']} frames); "
            f"Ctrl-C stops; --source '{forever}' runs forever")


def _zenoh_options(args: argparse.Namespace):
    from .zenoh_args import options_from_args

    return options_from_args(args)


def _open_publisher(options, mount):
    from ..publish import Publisher

    return Publisher(options, mount=mount)


def _check_source_and_outputs(args: argparse.Namespace, source: Source) -> None:
    if args.record and not (source.carries_raw or source.records_itself):
        raise UsageError(f"{args.source} gives point clouds and heatmaps, not raw ADC frames only: "
                         "--record needs a raw source (for ColoRadar: velocity=single_chip_adc"
                         "&heatmap=single_chip_adc)")
    ros_outputs.check_times(args, source)
    _check_outputs(args)


def _recording_sink(args: argparse.Namespace, source: Source):
    """The --record sink: the source's own recorder (tidemo://: its UART packets), else a capture
    directory of raw ADC frames."""
    if source.records_itself:
        return source.recorder(args.record)
    return CaptureSink(CaptureWriter(args.record, source.config, source=args.source,
                                     extra=source.recording_metadata()), source)


def _outputs(args: argparse.Namespace) -> list[tuple[str, str, str]]:
    """(path, kind, option) of every output asked for; kind as :class:`.replaced_outputs.ReplacedOutputs` takes it."""
    outputs = [(args.record, "capture", "--record"), (args.heatmap_out, "heatmaps", "--heatmap-out"),
               (args.points_out, "file", "--points-out"),
               (None if args.no_odom else args.odom_out, "file", "--odom-out")]
    return [out for out in outputs if out[0]] + ros_outputs.outputs(args) + view_option.outputs(args)


def _inputs(args: argparse.Namespace) -> list[tuple[str, str]]:
    """(option, path) of the files and directories the run reads: its cfg and settings, and a
    recording or ColoRadar run it streams."""
    return cli.read_paths([("--cfg", args.cfg), ("--estimator-config", args.estimator_config),
                           ("--zenoh-config", getattr(args, "zenoh_config", None))], args.source)


def _check_outputs(args: argparse.Namespace) -> None:
    """Every file output is new (or, with --overwrite, replaceable), and none is another output
    or an input: checked before anything is created, so a refusal leaves nothing behind."""
    ros_outputs.check(args)
    # Heatmaps may go beside a recording, the one written or the one replayed: their files'
    # names are their own (NNNNNN_*.npy, index.json), and their writer refuses a heatmap run there.
    outputs = _outputs(args)
    cli.check_distinct([(option, path) for path, kind, option in outputs if kind != "heatmaps"], _inputs(args))
    cli.check_files_in_directories(outputs)
    cli.check_new_outputs(outputs, overwrite=args.overwrite, what=view_option.WHAT)


def _sinks(args: argparse.Namespace, source: Source, publisher) -> list:
    """The outputs asked for (checked by :func:`_check_outputs`)."""
    sinks: list = []
    try:
        if args.record:  # a recording takes the raw frames before anything can fail on them
            sinks.append(_recording_sink(args, source))
        # The heatmap directory next: it may already hold heatmaps, found only when opened.
        if args.heatmap_out:
            sinks.append(HeatmapSink(args.heatmap_out))
        if args.points_out:
            sinks.append(PointsCsvSink(args.points_out))
        if args.odom_out and not args.no_odom:
            sinks.append(TumSink(args.odom_out))
        sinks += ros_outputs.build_sinks(args, source)
        sinks += view_option.build_sinks(args, source)
    except BaseException:
        for sink in reversed(sinks):  # the last opened first: a file in the recording's directory goes before it
            sink.close(PipelineStats())  # no frame yet: a capture directory and the new files are removed
        raise
    if publisher is not None:
        from ..pipeline.zenoh_sink import PublisherSink

        sinks.append(PublisherSink(publisher, source))
    return sinks


def _run(args: argparse.Namespace, source: Source, publisher, status: StatusLine) -> str:
    """Stream the open *source* (its outputs checked) through the pipeline; the summary."""
    # Without --estimator-config, the settings the source's frames call for (tidemo://: its own).
    estimator = args.estimator if args.estimator_config else source_estimator(source, args.estimator)
    if not args.no_odom:  # settings that cannot run on the source's heatmaps fail before outputs are replaced
        try:
            check_features_fit(source, estimator.features)
        except ConfigError as exc:
            raise exc.located(path=args.estimator_config or "the estimator's settings") from None
    # What --overwrite replaces is set aside, each removed once its new output holds data.
    replaced = ReplacedOutputs([(path, kind) for path, kind, _ in _outputs(args)] if args.overwrite else [])
    pipeline = None
    try:
        pipeline = Pipeline(source, estimator=None if args.no_odom else estimator,
                            sinks=_sinks(args, source, publisher), max_frames=args.frames,
                            max_duration_s=args.duration)
        stats = _stream(args, source, pipeline, status, replaced)
    except BaseException:
        replaced.settle_after_error()
        raise
    replaced.settle()
    summary = stream_summary(args, source, stats, pipeline.sinks)
    if publisher is not None:
        counts = publisher.counts
        summary += (f"; published {counts['odom']} odometry, {counts['pointcloud']} point cloud, "
                    f"{counts['heatmap']} heatmap and {counts['status']} status messages under "
                    f"{publisher.options.key_prefix}")
        if publisher.options.ros2:
            summary += (f", and to ROS 2 (domain {publisher.options.ros2_domain}) {counts['ros2']} on "
                        f"{publisher.options.ros2_topic}, {counts['ros2_points']} point clouds and "
                        f"{counts['ros2_tf']} TF")
    summary += _bag_part(args) + view_option.summary(args, pipeline.sinks)
    problem = view_option.saved_problem(args, pipeline.sinks)
    if problem:
        print(f"radar-capture: {summary}")
        raise CaptureError(problem)
    return summary


def _bag_part(args: argparse.Namespace) -> str:
    """The summary's word of the ROS 2 bag, kept whatever ended the run (its sink closes it, or says
    what it kept of it)."""
    return f"; ROS 2 bag {args.mcap}" if args.mcap else ""


def _stream(args: argparse.Namespace, source: Source, pipeline: Pipeline, status: StatusLine,
            replaced: ReplacedOutputs) -> PipelineStats:
    """Run *pipeline*, its status shown, the outputs it replaces removed as the new ones hold data;
    on an error after frames, what was kept is said first."""
    def on_frame(result, stats: PipelineStats) -> None:
        replaced.drop_replaced()
        status.update(status_fields(stats, args.record is not None, source) + odometry_fields(stats))

    with _stop_on_signals(pipeline):
        try:
            return pipeline.run(on_frame)
        except RadarodomError:
            status.clear()
            if pipeline.stats.frames:  # what was kept and lost, then the error (a board that died, a cable)
                print(f"radar-capture: {stream_summary(args, source, pipeline.stats, pipeline.sinks)}{_bag_part(args)}")
            raise
        finally:
            status.clear()


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run_with_status(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
