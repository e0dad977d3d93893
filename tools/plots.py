"""PNG plots of a trajectory evaluation (matplotlib's Agg renderer, no display).

:func:`evaluation_figures` builds the figures (a test or a notebook may look into them);
:func:`plot_evaluation` writes them.  Each figure carries the run's name and the numbers
radar-eval prints; ``report.png`` puts every panel on one page.

matplotlib is an optional extra (``pip install "radarodom[plot]"``), imported only when a
plot is asked for.
"""

from __future__ import annotations

import io
import logging
import os
from typing import Any, Callable

from ..errors import CaptureError, UsageError, why_not_written
from ..estimator.evaluation import EvaluationResult
from ..whole_files import write_bytes_atomically
from . import plot_panels as panels
from .odometry_log import OdometryLog, read_odometry_log
from .eval_summary import format_table, summary_lines

log = logging.getLogger(__name__)

TRAJECTORIES_PNG = "trajectories.png"
YAW_PNG = "yaw.png"
SPEED_PNG = "speed.png"
POSITION_ERROR_PNG = "position_error.png"
YAW_ERROR_PNG = "yaw_error.png"
YAW_CUMULATIVE_PNG = "yaw_cumulative_error.png"
FLAGS_PNG = "flags.png"
REPORT_PNG = "report.png"

Panel = Callable[[Any, panels.PlotData], None]

#: The figures of one panel each, by file name, with the legend entries they draw.
_SINGLE: dict[str, tuple[Panel, tuple[str, ...]]] = {
    TRAJECTORIES_PNG: (panels.trajectory, panels.TRAJECTORY_KEYS), YAW_PNG: (panels.yaw, panels.TIME_KEYS),
    SPEED_PNG: (panels.speed, panels.TIME_KEYS), POSITION_ERROR_PNG: (panels.position_error, panels.TURN_KEYS),
    YAW_ERROR_PNG: (panels.yaw_error, panels.TURN_KEYS), YAW_CUMULATIVE_PNG: (panels.yaw_cumulative, panels.TURN_KEYS),
    FLAGS_PNG: (panels.flags, panels.TURN_KEYS),
}
#: The report's time panels, top to bottom, sharing the time axis.
_REPORT_TIME: tuple[Panel, ...] = (panels.yaw, panels.speed, panels.position_error, panels.yaw_error,
                                   panels.flags)

__all__ = ["evaluation_figures", "file_names", "plot_evaluation", "require_matplotlib", "OdometryLog",
           "read_odometry_log"]


def file_names(*, flags: bool) -> list[str]:
    """The files :func:`plot_evaluation` writes, ``report.png`` first; ``flags.png`` only when
    the flags are known (*flags*)."""
    return [REPORT_PNG] + [f for f in _SINGLE if flags or f != FLAGS_PNG]


def require_matplotlib() -> None:
    """Raise :class:`UsageError` with the install command when matplotlib is missing."""
    _figure_class()


def _figure_class() -> Any:
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise UsageError('plots need matplotlib: pip install "radarodom[plot]"') from None

    def new_figure(**kw) -> Any:
        # An Agg canvas of its own: no pyplot state, no display needed.
        fig = Figure(**kw)
        FigureCanvasAgg(fig)
        return fig

    return new_figure


def _header(fig: Any, name: str, lines: list[str], *, size: str) -> None:
    """The run's name and the summary numbers across the top of *fig* (a subfigure), as written:
    a name or a file name with ``$`` is no maths (matplotlib's mathtext raised on ``$x^$``), a
    control character is shown as ``?`` (the fonts have no glyph for it)."""
    def shown(text: str) -> str:
        return "".join(c if c.isprintable() else "?" for c in text)

    fig.text(0.005, 0.95, shown(name), ha="left", va="top", fontsize="x-large", weight="bold", parse_math=False)
    fig.text(0.005, 0.95, "\n" + "\n".join(shown(line) for line in lines), ha="left", va="top", fontsize=size,
             linespacing=1.5, family="monospace", parse_math=False)


def evaluation_figures(result: EvaluationResult, *, name: str,
                       flags: OdometryLog | None = None) -> dict[str, Any]:
    """The evaluation's figures by file name: one per panel and ``report.png`` with them all.

    *name* titles every figure; *flags* are the estimator's flags on the evaluation's clock
    (``timeline.since(t0)``, t0 the first matched pose's time), None when not known (then
    there is no ``flags.png``).
    """
    new_figure = _figure_class()
    data = panels.PlotData(result, panels.turns(result), flags)
    lines = summary_lines(result, flags)
    figures = {}
    for filename, (draw, keys) in _SINGLE.items():
        if draw is panels.flags and flags is None:
            continue
        fig = new_figure(figsize=(10.0, 7.2), dpi=100, layout="constrained")
        top, body, foot = fig.subfigures(3, 1, height_ratios=(1.2, 5.3, 0.7))
        _header(top, name, lines, size="small")
        draw(body.add_subplot(), data)
        panels.legend(foot, data, keys, loc="center", ncols=3, fontsize="small")
        figures[filename] = fig
    figures[REPORT_PNG] = _report(new_figure, data, name, lines)
    return figures


def _report(new_figure: Callable[..., Any], data: panels.PlotData, name: str, lines: list[str]) -> Any:
    fig = new_figure(figsize=(17.0, 11.0), dpi=100, layout="constrained")
    top, body = fig.subfigures(2, 1, height_ratios=(0.9, 10.1))
    _header(top, name, lines, size="medium")
    panels.legend(top, data, loc="center right", ncols=2)
    left, right = body.subfigures(1, 2, width_ratios=(1.0, 1.0))
    trajectory, table, cumulative = left.subplots(3, 1, height_ratios=(5.6, 1.9, 2.2))
    panels.trajectory(trajectory, data)
    # The whole table radar-eval printed, below its headline numbers' trajectory.
    table.axis("off")
    table.text(0.0, 1.0, "\n".join(format_table(data.result).splitlines()[3:]), transform=table.transAxes,
               ha="left", va="top", family="monospace", fontsize="small")
    panels.yaw_cumulative(cumulative, data)
    axes = right.subplots(len(_REPORT_TIME), 1, sharex=True,
                          height_ratios=[1.0] * (len(_REPORT_TIME) - 1) + [0.8])
    for ax, draw in zip(axes, _REPORT_TIME):
        draw(ax, data)
    for ax in axes[:-1]:
        ax.set_xlabel("")
    return fig


def make_directory(directory: str | os.PathLike) -> str:
    """*directory* (and its parents) made if it is not there; its path."""
    directory = os.fspath(directory)
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError as exc:
        raise CaptureError(f"cannot create the plot directory {directory}: {why_not_written(exc, directory)}") from None
    return directory


def plot_evaluation(result: EvaluationResult, directory: str | os.PathLike, *, name: str,
                    flags: OdometryLog | None = None) -> list[str]:
    """Write the evaluation's figures into *directory* (created if needed; PNGs of the same
    names are replaced); returns their paths, ``report.png`` first."""
    figures = evaluation_figures(result, name=name, flags=flags)
    directory = make_directory(directory)
    written = []
    for filename in file_names(flags=flags is not None):
        path = os.path.join(directory, filename)
        png = io.BytesIO()
        figures[filename].savefig(png, format="png")
        try:  # a write that fails (a full disk) leaves no cut PNG, nor replaces a whole one
            write_bytes_atomically(path, png.getvalue())
        except OSError as exc:
            kept = (f"the figures before it are written ({', '.join(os.path.basename(p) for p in written)})"
                    if written else "no figure was written")
            raise CaptureError(f"cannot write {path}: {why_not_written(exc, path)}; {kept}") from None
        log.debug("wrote %s", path)
        written.append(path)
    return written
