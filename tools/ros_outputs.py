"""radar-capture's robot-facing outputs: where the radar sits (``--mount``), the ROS 2 bag
(``--mcap FILE``) and the odometry as JSON lines (``--odom-json FILE``); their options, their
checks and their sinks, so that radar_capture.py only calls in."""

from __future__ import annotations

import argparse

from ..errors import UsageError
from ..mount import Mount
from .cli import mount


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """--mount, --mcap, --odom-json."""
    parser.add_argument("--mount", type=mount, default=Mount(), metavar="X,Y,Z,YAW_DEG",
                        help="where the radar sits on the robot: its position in base_link (m, REP-103: x ahead, "
                             "y left, z up) and its yaw (degrees, counter-clockwise); the ROS 2 outputs' "
                             "base_link -> radar transform (default: the radar is base_link)")
    parser.add_argument("--mcap", metavar="FILE.mcap",
                        help="write a ROS 2 bag (MCAP: odometry, TF, point clouds, heatmaps, diagnostics, ground "
                             'truth) to this new file (needs pip install "radarodom[ros2]")')
    parser.add_argument("--odom-json", metavar="FILE.jsonl",
                        help="write every odometry message (as published, one JSON object per line) to this "
                             "new file")


def check(args: argparse.Namespace) -> None:
    """Refuse what cannot be done as asked, before anything opens."""
    if args.no_odom and args.odom_json:
        raise UsageError("--no-odom turns the estimator off: it cannot also write --odom-json")
    if args.mcap:
        # The libraries are checked before any output opens: a missing extra is an option error.
        from ..ros2 import ros2_typestore
        from ..ros2_bag import _mcap

        ros2_typestore()
        _mcap()


def check_times(args: argparse.Namespace, source) -> None:
    """Refuse, before any output opens, a recording whose frames' times a ROS 2 stamp cannot hold
    (--ros2, --mcap), naming its times' file; found mid-run, the outputs before it were left."""
    asked = [option for option, given in (("--ros2", getattr(args, "ros2", False)), ("--mcap", args.mcap)) if given]
    span = source.time_span() if asked else None
    if span is None:
        return
    from ..ros2_messages import ROS2_TIME_END_S  # (the ROS 2 messages only when asked for)

    first, last, where = span
    if first < 0 or last >= ROS2_TIME_END_S:
        raise UsageError(f"{where}: the frames' times run from {first:.3f} s to {last:.3f} s, and a ROS 2 stamp holds "
                         f"0 to {ROS2_TIME_END_S - 1} s (a node's time is never negative; its seconds are 32-bit): "
                         f"shift the times into that range, or leave out {' and '.join(asked)}")


def outputs(args: argparse.Namespace) -> list[tuple[str, str, str]]:
    """(path, "file", option) of each output asked for, for radar-capture's new-file and --overwrite checks."""
    return [(path, "file", option) for path, option in ((args.mcap, "--mcap"), (args.odom_json, "--odom-json"))
            if path]


def build_sinks(args: argparse.Namespace, source) -> list:
    """The sinks of the outputs asked for (their paths checked by :func:`outputs`' caller)."""
    sinks: list = []
    try:
        if args.odom_json:
            from ..pipeline.sinks import OdometryJsonSink

            sinks.append(OdometryJsonSink(args.odom_json))
        if args.mcap:
            from ..pipeline.mcap_sink import McapSink

            sinks.append(McapSink(args.mcap, source, mount=args.mount, odom_topic=args.ros2_topic))
    except BaseException:
        from ..pipeline.stats import PipelineStats

        for sink in sinks:
            sink.close(PipelineStats())  # no frame: the new files are removed
        raise
    return sinks
