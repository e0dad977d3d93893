"""PNG plots of a trajectory evaluation (matplotlib's Agg renderer, no display).

matplotlib is an optional extra (``pip install "radarodom[plot]"``), imported
only when a plot is asked for.
"""

from __future__ import annotations

import logging
import os
from typing import Any

import numpy as np

from ..errors import CaptureError, UsageError
from ..estimator.evaluation import EvaluationResult

log = logging.getLogger(__name__)

TRAJECTORIES_PNG = "trajectories.png"
YAW_ERROR_PNG = "yaw_error.png"
YAW_CUMULATIVE_PNG = "yaw_cumulative_error.png"


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


def plot_evaluation(result: EvaluationResult, directory: str | os.PathLike) -> list[str]:
    """Write the evaluation's plots into *directory* (created if needed; PNGs of
    the same names are replaced); returns their paths."""
    new_figure = _figure_class()
    directory = os.fspath(directory)
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError as exc:
        raise CaptureError(f"cannot create {directory}: {exc.strerror or exc}") from None
    written = []
    for name, draw in ((TRAJECTORIES_PNG, _trajectories), (YAW_ERROR_PNG, _yaw_error),
                       (YAW_CUMULATIVE_PNG, _yaw_cumulative)):
        fig = new_figure(figsize=(7.0, 5.0), dpi=110, layout="constrained")
        draw(fig.add_subplot(), result)
        path = os.path.join(directory, name)
        try:
            fig.savefig(path)
        except OSError as exc:
            raise CaptureError(f"cannot write {path}: {exc.strerror or exc}") from None
        log.debug("wrote %s", path)
        written.append(path)
    return written


def _trajectories(ax, r: EvaluationResult) -> None:
    ax.plot(r.ref[:, 0], r.ref[:, 1], color="black", lw=1.6, label="ground truth")
    ax.plot(r.est_umeyama[:, 0], r.est_umeyama[:, 1], color="tab:blue", lw=1.2,
            label=f"estimate, Umeyama-aligned (ATE RMSE {np.sqrt(np.mean(r.ate_m ** 2)):.3f} m)")
    ax.plot(r.est_first_pose[:, 0], r.est_first_pose[:, 1], color="tab:orange", lw=1.2, ls="--",
            label=f"estimate, aligned at the first pose (drift {r.drift_m:.2f} m)")
    ax.plot(r.ref[0, 0], r.ref[0, 1], "o", color="black", ms=5, label="start")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("Trajectories")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")


def _yaw_error(ax, r: EvaluationResult) -> None:
    ax.plot(r.times[1:], r.yaw_error_deg, color="tab:blue", lw=0.8)
    ax.axhline(0.0, color="black", lw=0.6)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("yaw-increment error (deg)")
    ax.set_title(f"Yaw-increment error per frame (RMSE {r.yaw_rmse_deg:.3f} deg)")
    ax.grid(True, alpha=0.3)


def _yaw_cumulative(ax, r: EvaluationResult) -> None:
    ax.plot(r.times[1:], r.yaw_cumulative_sq_deg2, color="tab:blue", lw=1.2)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("cumulative squared yaw error (deg$^2$)")
    ax.set_title("Cumulative squared yaw-increment error")
    ax.grid(True, alpha=0.3)
