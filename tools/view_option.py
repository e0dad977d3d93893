"""radar-capture's ``--view [spawn[:PORT]|web[:PORT]|connect:ADDR|save:FILE.rrd]``: the option, its
checks and its sink, so that radar_capture.py only calls in.  The view is radarodom.view's."""

from __future__ import annotations

import argparse
import os
import sys

from ..errors import UsageError

MISSING = 'the view needs rerun-sdk: pip install "radarodom[view]"'
#: Rerun's log filter for ``--view save:`` unless RUST_LOG is set (:func:`parse_view`).
SAVE_RUST_LOG = "warn,re_log_encoding=off,re_sdk::recording_stream=off"


def parse_view(text: str):
    """argparse type: the ``--view`` value as a :class:`radarodom.view.ViewTarget`, checked
    before anything opens: Rerun installed, a display for ``spawn``, free ports for ``web``."""
    kind, _, rest = text.partition(":")
    try:
        from ..view.target import ViewTarget, check

        if kind in ("web", "spawn"):
            if rest and not rest.isdigit():
                raise UsageError(f"{kind}:PORT takes a port number, got {rest!r}")
            target = ViewTarget(kind, port=int(rest)) if rest else ViewTarget(kind)
        elif kind in ("connect", "save"):
            if not rest:
                raise UsageError(f"{kind}: needs {_NEEDS[kind]}")
            target = ViewTarget(kind, address=rest) if kind == "connect" else ViewTarget(kind, path=rest)
            if kind == "connect":
                from ..view.target import grpc_url

                grpc_url(rest)
        else:
            raise UsageError(f"expected spawn[:PORT], web[:PORT], connect:HOST:PORT or save:FILE.rrd, got {text!r}")
        check(target)  # a display to spawn on, free ports: before anything opens
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if target.kind == "save" and "RUST_LOG" not in os.environ:
        # Before Rerun is imported (below), which reads it once: without its file writer's own
        # console lines (ANSI-coloured ERRORs, one more at exit) for a file it could not write,
        # which the view says in a line of its own (the run's summary and error).
        os.environ["RUST_LOG"] = SAVE_RUST_LOG
    try:
        import rerun  # noqa: F401
    except ImportError:
        raise argparse.ArgumentTypeError(MISSING) from None
    return target


_NEEDS = {"connect": "the viewer's HOST:PORT (or a rerun+http:// URL)", "save": "a file name (FILE.rrd)"}


class _ViewAction(argparse.Action):
    """``--view`` alone means spawn; every value goes through :func:`parse_view` (argparse does
    not convert an option's const)."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        try:
            setattr(namespace, self.dest, parse_view("spawn" if values is None else values))
        except argparse.ArgumentTypeError as exc:
            parser.error(f"argument {option_string}: {exc}")


def add_view_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--view", action=_ViewAction, nargs="?", metavar="MODE",
                        help="draw the point clouds, heatmaps, features, trajectory and time series live with Rerun "
                             "(docs/view.md): spawn[:PORT] (the default: a viewer window, listening on PORT, "
                             "default 9876), web[:PORT] (serve the web viewer on PORT, default 9090, its data on "
                             "PORT+1, for a browser elsewhere), "
                             "connect:HOST:PORT (a viewer elsewhere) or save:FILE.rrd; a slow view drops its "
                             'own frames, never the pipeline\'s (needs pip install "radarodom[view]")')


#: What ``--view save:`` writes, for radar-capture's output checks' messages (as the view's own, when it opens).
WHAT = {"--view save:": "the view"}


def outputs(args: argparse.Namespace) -> list[tuple[str, str, str]]:
    """The .rrd file of ``--view save:`` (path, "file", option), for radar-capture's new-file and
    --overwrite checks."""
    target = args.view
    return [(target.path, "file", "--view save:")] if target is not None and target.kind == "save" else []


def build_sinks(args: argparse.Namespace, source) -> list:
    """The view's sink when ``--view`` is given."""
    if args.view is None:
        return []
    from ..view import open_view

    sink = open_view(args.view, estimator=None if args.no_odom else args.estimator, config=source.config,
                     mount=getattr(args, "mount", None))
    if not args.quiet:
        print(f"radar-capture: view: {sink.where}", file=sys.stderr)
    return [sink]


def summary(args: argparse.Namespace, sinks: list) -> str:
    """"; view: 300 frames drawn, 0 dropped" for the run summary, or "" without ``--view``."""
    if args.view is None:
        return ""
    from ..view import ViewSink

    return "".join(f"; view: {s.summary}" for s in sinks if isinstance(s, ViewSink))


def saved_problem(args: argparse.Namespace, sinks: list) -> str | None:
    """Why ``--view save:FILE.rrd`` is not the whole view (a write that failed, a drawing that
    did not finish), or None: a file the run meant to keep is an output like the others, whose
    loss fails the run (a viewer that went away does not)."""
    if args.view is None or args.view.kind != "save":
        return None
    from ..view import ViewSink

    for sink in sinks:
        if isinstance(sink, ViewSink) and (sink.problem or not sink.finished):
            return (f"--view save:{args.view.path}: the file is incomplete ({sink.problem or 'the view did not finish'})"
                    + _full_disk(args.view.path))
    return None


def _full_disk(path: str) -> str:
    """"; ... full: free some space ..." when *path*'s file system has no room left (Rerun's
    writer says only that it stopped), else ""."""
    try:
        st = os.statvfs(os.path.dirname(os.path.abspath(path)))
    except OSError:
        return ""
    if st.f_bavail * st.f_frsize >= 64 * 1024:  # less than a few of the file's chunks left: full
        return ""
    return "; the disk it is on is full: free some space, or choose another disk"
