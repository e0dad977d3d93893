"""The panels of radar-eval's plots, one function each drawing into a matplotlib Axes, and the
numbers they draw (speeds, the truth's turns, runs of flagged steps, the trajectory's limits).

Colours mean the same in every panel: the truth black, the estimate aligned at its first pose
orange (its drift), aligned by Umeyama blue (ATE); the truth's turns are grey bands.
matplotlib is imported by the caller (:mod:`.plots`), never here at import.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..estimator.evaluation import EvaluationResult, Stats, path_steps
from ..estimator.heading_metrics import MIN_TURN_DEG, STRAIGHT_RATE_DPS, segment_turns
from ..estimator.quality import Flag
from .odometry_log import OdometryLog

#: The truth turns where its yaw rate exceeds this (deg/s), over at least TURN_MIN_DEG: as
#: radar-eval's heading figures tell turns.
TURN_RATE_DPS = STRAIGHT_RATE_DPS
TURN_MIN_DEG = MIN_TURN_DEG
#: Margin around the trajectories: this share of the larger extent, and at least PAD_MIN_M.
PAD_SHARE = 0.04
PAD_MIN_M = 0.25


def speed_of(times: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Speed (k,) m/s from consecutive positions of *poses* (n, 3) at *times* (n,) s, at the
    middle of each interval (k,) s."""
    dt = np.diff(times)
    return times[:-1] + dt / 2.0, path_steps(poses[:, :2]) / dt


def unwrapped_yaw_deg(poses: np.ndarray) -> np.ndarray:
    """Yaw (n,) deg of *poses* (n, 3), continuous (no jump at +-180)."""
    return np.degrees(np.unwrap(poses[:, 2]))


@dataclass(frozen=True)
class Turn:
    """A turn of the truth: from *start* to *end* (s, the evaluation's clock), the true angle
    and the estimate's over the same frames (deg, signed)."""

    start: float
    end: float
    true_deg: float
    est_deg: float


def turns(r: EvaluationResult) -> list[Turn]:
    """The truth's turns (|yaw rate| > TURN_RATE_DPS, turning at least TURN_MIN_DEG), each with
    what the estimate turned over it."""
    d_ref = np.degrees(np.diff(np.unwrap(r.ref[:, 2])))
    d_est = np.degrees(np.diff(np.unwrap(r.est[:, 2])))
    return [Turn(float(r.times[i]), float(r.times[j]), float(d_ref[i:j].sum()), float(d_est[i:j].sum()))
            for i, j, _ in segment_turns(r.times, r.ref, straight_rate_dps=TURN_RATE_DPS, min_turn_deg=TURN_MIN_DEG)]


def flag_runs(timeline: OdometryLog, name: str) -> list[tuple[float, float]]:
    """(start, width) s of each run of consecutive steps flagged *name*: a step lasts until the
    next one (the last one, the median step)."""
    t = timeline.times
    if not len(t):
        return []
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.1
    ends = np.append(t[1:], t[-1] + step)
    runs: list[tuple[float, float]] = []
    for i, flags in enumerate(timeline.flags):
        if name not in flags:
            continue
        if i and name in timeline.flags[i - 1]:
            runs[-1] = (runs[-1][0], float(ends[i] - runs[-1][0]))
        else:
            runs.append((float(t[i]), float(ends[i] - t[i])))
    return runs


def tight_limits(*xys: np.ndarray) -> tuple[tuple[float, float], tuple[float, float]]:
    """x and y limits (m) around every position of *xys* (each (n, 2)), with a margin of
    PAD_SHARE of the larger extent and at least PAD_MIN_M, so no point sits on the frame."""
    xy = np.concatenate([np.asarray(a, dtype=float).reshape(-1, 2) for a in xys])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = max(PAD_SHARE * float((hi - lo).max()), PAD_MIN_M)
    return (float(lo[0] - pad), float(hi[0] + pad)), (float(lo[1] - pad), float(hi[1] + pad))


# ------------------------------------------------------------------ panels
TRUTH, ESTIMATE, UMEYAMA = "black", "tab:orange", "tab:blue"
TURN_SHADE = "0.86"
#: Labels of the trajectory plot's markers, which tests look for.
START, END_TRUTH, END_ESTIMATE = "start", "end, truth", "end, estimate"


@dataclass(frozen=True)
class PlotData:
    """What every panel may draw: the evaluation, the truth's turns, and the flags on the
    evaluation's clock (None: not given)."""

    result: EvaluationResult
    turns: list[Turn]
    flags: OdometryLog | None


def trajectory(ax: Any, d: PlotData) -> None:
    r = d.result
    styles = _styles(d)
    ax.plot(r.ref[:, 0], r.ref[:, 1], **styles["truth"])
    ax.plot(r.est_umeyama[:, 0], r.est_umeyama[:, 1], **styles["umeyama"])
    ax.plot(r.est_first_pose[:, 0], r.est_first_pose[:, 1], **styles["estimate"])
    ax.plot(r.ref[0, 0], r.ref[0, 1], **styles["start"], zorder=5)
    ax.plot(r.ref[-1, 0], r.ref[-1, 1], **styles["end_truth"], zorder=5)
    ax.plot(r.est_first_pose[-1, 0], r.est_first_pose[-1, 1], **styles["end_estimate"], zorder=5)
    xlim, ylim = tight_limits(r.ref[:, :2], r.est_umeyama[:, :2], r.est_first_pose[:, :2])
    if np.isfinite(xlim + ylim).all():  # coordinates that overflow are left to matplotlib
        ax.set_xlim(*xlim)
        ax.set_ylim(*ylim)
    # Equal scale by shrinking the box, never by widening the limits around the data.
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("Trajectory")
    ax.grid(True, alpha=0.3)


def _styles(d: PlotData) -> dict[str, dict[str, Any]]:
    """How the truth, the estimate and the markers are drawn, with their labels."""
    r = d.result
    return {
        "truth": {"color": TRUTH, "lw": 1.8, "label": "ground truth"},
        "estimate": {"color": ESTIMATE, "lw": 1.3, "ls": "--",
                     "label": f"estimate, aligned at the first pose (drift {r.drift_m:.2f} m)"},
        "umeyama": {"color": UMEYAMA, "lw": 1.1,
                    "label": f"estimate, Umeyama-aligned (ATE RMSE {Stats.of(r.ate_m).rmse:.3f} m)"},
        "start": {"marker": "o", "ls": "", "color": "tab:green", "ms": 8, "mec": "black", "label": START},
        "end_truth": {"marker": "s", "ls": "", "color": TRUTH, "ms": 7, "label": END_TRUTH},
        "end_estimate": {"marker": "X", "ls": "", "color": ESTIMATE, "ms": 8, "mec": "black", "label": END_ESTIMATE},
    }


#: The legend entries each panel draws (the report shows them all).
TRAJECTORY_KEYS = ("truth", "estimate", "umeyama", "start", "end_truth", "end_estimate")
TIME_KEYS = ("truth", "estimate", "turn")
TURN_KEYS = ("turn",)
ALL_KEYS = (*TRAJECTORY_KEYS, "turn")


def legend(fig: Any, d: PlotData, keys: tuple[str, ...] = ALL_KEYS, **kw) -> None:
    """The legend of the entries *keys* (the colours, the markers, the turns) on *fig*."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    styles = _styles(d)
    handles = [Patch(color=TURN_SHADE, label=f"turn of the truth (> {TURN_RATE_DPS:g} deg/s)") if key == "turn"
               else Line2D([], [], **styles[key]) for key in keys]
    fig.legend(handles=handles, frameon=False, **kw)


def _turn_bands(ax: Any, d: PlotData, *, angles: bool = False) -> None:
    for turn in d.turns:
        ax.axvspan(turn.start, turn.end, color=TURN_SHADE, lw=0, zorder=0)
        if angles:
            # The turned angles, where a user looks for a turn measured too small or too large.
            ax.annotate(f"{turn.true_deg:+.0f}\N{DEGREE SIGN}\nest {turn.est_deg:+.1f}\N{DEGREE SIGN}",
                        xy=((turn.start + turn.end) / 2, 1.0), xycoords=("data", "axes fraction"),
                        xytext=(0, -3), textcoords="offset points", ha="center", va="top", fontsize="small")


def _time_axis(ax: Any, d: PlotData, ylabel: str, title: str) -> None:
    ax.set_xlim(0.0, max(d.result.duration_s, 1e-3))
    ax.set_xlabel("time (s)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize="medium")
    ax.grid(True, alpha=0.3)


def yaw(ax: Any, d: PlotData) -> None:
    r = d.result
    _turn_bands(ax, d)
    styles = _styles(d)
    ax.plot(r.times, unwrapped_yaw_deg(r.ref), **styles["truth"])
    ax.plot(r.times, unwrapped_yaw_deg(r.est_first_pose), **styles["estimate"])
    _time_axis(ax, d, "yaw (deg)", f"Yaw, aligned at the first pose (final error {r.drift_yaw_deg:+.2f} deg)")


def speed(ax: Any, d: PlotData) -> None:
    r = d.result
    _turn_bands(ax, d)
    t, v_ref = speed_of(r.times, r.ref)
    _, v_est = speed_of(r.times, r.est)
    styles = _styles(d)
    ax.plot(t, v_ref, **styles["truth"])
    ax.plot(t, v_est, **styles["estimate"])
    _time_axis(ax, d, "speed (m/s)", f"Speed, from consecutive poses (path {r.ref_path_m:.2f} m, "
                                     f"estimate {r.est_path_m:.2f} m)")


def position_error(ax: Any, d: PlotData) -> None:
    r = d.result
    _turn_bands(ax, d)
    err = r.est_first_pose[:, :2] - r.ref[:, :2]
    ax.plot(r.times, err[:, 0], color="tab:red", lw=1.1, label="x")
    ax.plot(r.times, err[:, 1], color="tab:purple", lw=1.1, label="y")
    ax.plot(r.times, np.hypot(err[:, 0], err[:, 1]), color="0.35", lw=0.9, ls=":", label="distance")
    ax.axhline(0.0, color="black", lw=0.6)
    _time_axis(ax, d, "error (m)", f"Position error, aligned at the first pose (final {r.drift_m:.3f} m)")
    ax.legend(fontsize="small", loc="best", ncols=3)


def yaw_error(ax: Any, d: PlotData) -> None:
    r = d.result
    _turn_bands(ax, d, angles=True)
    ax.plot(r.times[1:], r.yaw_error_deg, color="tab:blue", lw=0.8)
    ax.axhline(0.0, color="black", lw=0.6)
    _time_axis(ax, d, "error (deg)", f"Yaw-increment error per frame (RMSE {r.yaw_rmse_deg:.3f} deg)")
    # Room above the curve for the turns' angles.
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + 0.25 * (hi - lo))


def yaw_cumulative(ax: Any, d: PlotData) -> None:
    r = d.result
    _turn_bands(ax, d)
    ax.plot(r.times[1:], r.yaw_cumulative_sq_deg2, color="tab:blue", lw=1.2)
    _time_axis(ax, d, "deg$^2$", "Cumulative squared yaw-increment error")


def flags(ax: Any, d: PlotData) -> None:
    """One row per flag that occurs, a bar over each run of steps that carry it."""
    _time_axis(ax, d, "", "Estimator quality flags")
    if d.flags is None:
        ax.text(0.5, 0.5, "not given: radar-eval --odom ODOM.jsonl", transform=ax.transAxes,
                ha="center", va="center", color="0.4")
        ax.set_yticks([])
        return
    names = d.flags.names()
    _turn_bands(ax, d)
    for row, name in enumerate(names):
        ax.broken_barh(flag_runs(d.flags, name), (row - 0.35, 0.7),
                       color="0.5" if name == Flag.FIRST_FRAME else "tab:red")
    ax.set_yticks(range(len(names)), [f"{n} ({d.flags.count(n)})" for n in names], fontsize="small")
    ax.set_ylim(len(names) - 0.5 if names else 0.5, -0.5)
    if not names:
        ax.text(0.5, 0.5, f"no flag in {len(d.flags)} steps", transform=ax.transAxes, ha="center", va="center")
    ax.grid(True, axis="x", alpha=0.3)
    ax.grid(False, axis="y")
