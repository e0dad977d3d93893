"""The Zenoh session options every publishing or subscribing program takes
(``radar-capture``, ``radar-echo``), in one place."""

from __future__ import annotations

import argparse

from ..publish import DEFAULT_ENDPOINT, DEFAULT_KEY_PREFIX, DEFAULT_ROS2_TOPIC, MODES, ZenohOptions
from . import cli


def add_zenoh_arguments(parser: argparse.ArgumentParser, *, ros2: bool = False) -> None:
    """--key-prefix, --connect, --listen, --mode, --zenoh-config; with *ros2* also
    --ros2, --ros2-domain, --ros2-topic (for a publisher)."""
    group = parser.add_argument_group(
        "Zenoh session",
        f"Without options: a peer without multicast scouting; publishers listen on {DEFAULT_ENDPOINT}, "
        "subscribers connect there (one machine, no router, no network). A config file replaces these "
        "defaults; the options below override it.")
    group.add_argument("--key-prefix", default=DEFAULT_KEY_PREFIX, metavar="P",
                       help=f"keys are P/odom, P/pointcloud, P/heatmap, P/status (default {DEFAULT_KEY_PREFIX})")
    group.add_argument("--connect", action="append", metavar="EP",
                       help="a Zenoh endpoint to connect to, e.g. tcp/192.168.1.10:7447 (repeat for more); "
                            "retried until it answers")
    group.add_argument("--listen", action="append", metavar="EP",
                       help="a Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7448 to be reachable from the "
                            "network (repeat for more)")
    group.add_argument("--mode", choices=MODES, help="peer (the default) or client (needs --connect ROUTER)")
    group.add_argument("--zenoh-config", metavar="FILE", help="a Zenoh config file (JSON5)")
    if ros2:
        group.add_argument("--ros2", action="store_true",
                           help="also publish nav_msgs/msg/Odometry for ROS 2 nodes using rmw_zenoh "
                                '(needs pip install "radarodom[ros2]"; connects to tcp/localhost:7447 '
                                "unless --connect is given)")
        group.add_argument("--ros2-domain", type=cli.ros2_domain, default=0, metavar="N",
                           help="ROS_DOMAIN_ID (default 0)")
        group.add_argument("--ros2-topic", type=_ros2_topic, default=DEFAULT_ROS2_TOPIC, metavar="TOPIC",
                           help=f"ROS 2 odometry topic, published and in --mcap's bag (default {DEFAULT_ROS2_TOPIC})")


def options_from_args(args: argparse.Namespace) -> ZenohOptions:
    """The :class:`ZenohOptions` of parsed arguments (raises PublishConfigError, exit 2)."""
    return ZenohOptions(mode=args.mode, connect=args.connect, listen=args.listen, config_file=args.zenoh_config,
                        key_prefix=args.key_prefix, ros2=getattr(args, "ros2", False),
                        ros2_domain=getattr(args, "ros2_domain", 0),
                        ros2_topic=getattr(args, "ros2_topic", DEFAULT_ROS2_TOPIC))


def options_given(args: argparse.Namespace) -> list[str]:
    """The Zenoh options of :func:`add_zenoh_arguments` given a value of their own (for a run
    that publishes nothing, which would ignore them)."""
    given = [option for option, value in (("--ros2", getattr(args, "ros2", False)), ("--connect", args.connect),
                                          ("--listen", args.listen), ("--mode", args.mode),
                                          ("--zenoh-config", args.zenoh_config)) if value]
    return given + [option for option, value, default in (
        ("--key-prefix", args.key_prefix, DEFAULT_KEY_PREFIX),
        ("--ros2-topic", getattr(args, "ros2_topic", DEFAULT_ROS2_TOPIC), DEFAULT_ROS2_TOPIC),
        ("--ros2-domain", getattr(args, "ros2_domain", 0), 0)) if value != default]


def _ros2_topic(text: str) -> str:
    """argparse type: an absolute ROS name (checked here too, as --mcap takes it without a publisher)."""
    from ..errors import PublishConfigError
    from ..ros2 import check_odometry_topic
    from ..zenoh_session import check_ros2_topic

    try:
        return check_odometry_topic(check_ros2_topic(text))
    except PublishConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


#: A name, not a number: the numeric options' fuzz test (tests/test_fuzz_cli_options.py) leaves it
#: to the topic's own tests.
_ros2_topic.not_a_number = True  # type: ignore[attr-defined]
