"""The numbers of an evaluation as text: the table radar-eval prints, and the lines every
plot carries.  No matplotlib."""

from __future__ import annotations

import math

from ..estimator.consistency import offset_text
from ..estimator.evaluation import EvaluationResult, Stats
from ..estimator.heading_metrics import (AFTER_TURN_FRAMES, DRIFT_PARTS, MIN_STRAIGHT_M, MIN_TURN_DEG,
                                         STRAIGHT_RATE_DPS, HeadingMetrics)
from ..estimator.quality import Flag
from .odometry_log import OdometryLog

_COLUMNS = ("rmse", "mean", "median", "std", "min", "max")


def _fit(value: float, spec: str) -> str:
    """*value* as *spec* formats it, but in exponent form when that would not fit a column of the
    table (coordinates near the float limit), so that the table keeps its columns; NaN "-",
    infinity "inf"."""
    if math.isnan(value):
        return "-"
    text = format(value, spec)
    return format(value, ".3g") if math.isinf(value) or len(text) > 9 else text


def _row(label: str, stats: Stats) -> str:
    cells = "".join(f"{_fit(v, '.4f'):>10}" for v in (getattr(stats, c) for c in _COLUMNS))
    return f"{label:<32}{cells} {stats.n:>6}"  # (a space: a count of millions keeps its column apart)


def format_table(r: EvaluationResult) -> str:
    """The human summary of an evaluation."""
    d = f"{r.delta_m:g} m"
    lines = [
        f"{r.est_source} against {r.ref_source}",
        (f"  {r.matched} poses matched (estimate {r.est_poses}, ground truth {r.ref_poses}, within "
         f"{r.max_diff_s:g} s) over {_fit(r.duration_s, '.1f')} s; path {_fit(r.ref_path_m, '.2f')} m "
         f"(estimate {_fit(r.est_path_m, '.2f')} m)"),
        "",
        f"{'':<32}" + "".join(f"{c:>10}" for c in _COLUMNS) + f" {'n':>6}",
        _row("RPE per frame, translation m", Stats.of(r.rpe_frame.translation_m)),
        _row("RPE per frame, rotation deg", Stats.of(r.rpe_frame.rotation_deg)),
        _row(f"RPE per {d}, translation m", Stats.of(r.rpe_distance.translation_m)),
        _row(f"RPE per {d}, translation %", Stats.of(r.rpe_distance.translation_pct)),
        _row(f"RPE per {d}, rotation deg", Stats.of(r.rpe_distance.rotation_deg)),
        _row("yaw-increment error deg", Stats.of(r.yaw_error_deg)),
        _row("ATE (Umeyama-aligned) m", Stats.of(r.ate_m)),
        "",
    ]
    lines.append(f"final drift (aligned at the first pose): {_fit(r.drift_m, '.3f')} m = "
                 f"{_fit(r.drift_pct, '.2f')} % of the path, yaw {_fit(r.drift_yaw_deg, '+.2f')} deg")
    return "\n".join(lines)


def format_heading(m: HeadingMetrics, parts: dict[str, float]) -> str:
    """The heading figures (docs/heading.md) of :func:`heading_metrics` and :func:`drift_parts` at
    their defaults: the truth told into straight drives and turns, the estimate's heading error on
    each, and the drift each kind of frame's yaw errors make alone."""
    def turns(count: int, true_deg: float, ratio: float, worst: float) -> str:
        if not count:
            return "none"
        text = f"{count}, {true_deg:.1f} deg in all, measured {_num(ratio, '.3f')} of it"
        return text + (f"; each turn's own, farthest from 1: {_num(worst, '.3f')}" if count > 1 else "")

    if m.straight_frames:
        straight = (f"{m.straight_m:.2f} m in {m.straight_s:.1f} s, heading bias "
                    f"{_num(m.straight_bias_deg_per_m, '+.3f')} deg/m = {_num(m.straight_bias_deg_per_min, '+.2f')} "
                    f"deg/min = {_num(m.straight_bias_deg_per_frame, '+.4f')} deg/frame")
        if m.straights:
            straight += (f"\n{'':<20}each of {m.straights} straight(s) of {MIN_STRAIGHT_M:g} m or more: RMS "
                         f"{_num(m.straight_rms_deg_per_m, '.3f')}, "
                         f"worst {_num(m.straight_max_deg_per_m, '.3f')} deg/m")
        if m.straight_after_turn_frames:
            straight += (f"\n{'':<20}in the {AFTER_TURN_FRAMES} frames after each turn "
                         f"{_num(m.straight_after_turn_deg, '+.2f')} deg in all; the rest "
                         f"{_num(m.straight_own_bias_deg_per_frame, '+.4f')} deg/frame")
    else:
        straight = "none"
    kinds = ", ".join(f"{name} {_num(parts[name], '.2f')}" for name in DRIFT_PARTS[1:])
    return "\n".join([
        f"heading (the truth drives straight where it turns under {STRAIGHT_RATE_DPS:g} deg/s and moves; "
        f"a turn turns {MIN_TURN_DEG:g} deg or more):",
        f"  straight drives   {straight}",
        f"  moving turns      "
        f"{turns(m.moving_turns, m.moving_turn_deg, m.moving_turn_ratio, m.moving_turn_worst_ratio)}",
        f"  turns in place    "
        f"{turns(m.inplace_turns, m.inplace_turn_deg, m.inplace_turn_ratio, m.inplace_turn_worst_ratio)}",
        "  drift parts, % of the path (each kind of frame's yaw errors alone, and the translation's):",
        f"{'':<20}{kinds}",
    ])


def format_covariance(c: dict, source: str, used: int, total: int) -> str:
    """The lines radar-eval prints for the reported covariances against the truth
    (``odometry_consistency``'s dict *c*, over *used* of the *total* messages of *source*)."""
    def line(label: str, part: dict | None, normal: str, more: str = "") -> str:
        if part is None or part["z_rms"] is None:
            what = ("frame" if label in ("heading", "position") else
                    "single estimator step (frames that follow, whose yaw rate times time is their turn)")
            return f"  {label:<18}not compared: no {what} with a variance"
        return (f"  {label:<18}RMS {_fit(part['z_rms'], '.2f')}, within 1 sd {100 * part['within_1sigma']:.0f} %, "
                f"within 2 sd {100 * part['within_2sigma']:.0f} % ({normal}){more}")
    return "\n".join([
        f"reported covariance ({_short(source)}: {used} of {total} odometry messages compared with the truth "
        f"{offset_text(c.get('measured_at_s', 0.0))}; each error since the first over its standard deviation",
        "  (RMS below 1: the covariance is wide, above 1: narrow; a normal error's shares in brackets)):",
        line("heading", c["yaw"], "68 / 95 %",
             f"; after the run: error {_fit(c['final_yaw_error_deg'], '+.2f')} deg, "
             f"sd {_fit(c['final_yaw_sigma_deg'], '.2f')} deg"),
        line("position", c["position"], "63 / 98 %"),
        line("yaw rate", c["yaw_rate"], "68 / 95 %", ", each single step"),
        line("forward speed", c.get("forward_speed"), "68 / 95 %", ", each single step"),
        line("sideways speed", c.get("sideways_speed"), "68 / 95 %", ", each single step"),
    ])


def _num(value: float, spec: str) -> str:
    return "-" if not math.isfinite(value) else format(value, spec)


def _short(text: str, limit: int = 48) -> str:
    return text if len(text) <= limit else "..." + text[-(limit - 3):]


def summary_lines(r: EvaluationResult, flags: OdometryLog | None = None) -> list[str]:
    """The numbers radar-eval prints, in four lines: what was compared, the main errors, the
    relative errors, the flags."""
    rpe_d, rpe_f = r.rpe_distance, r.rpe_frame
    lines = [
        f"{_short(r.est_source)} against {_short(r.ref_source)}: {r.matched} poses over {r.duration_s:.1f} s, "
        f"path {_num(r.ref_path_m, '.2f')} m (estimate {_num(r.est_path_m, '.2f')} m)",
        f"yaw-increment RMSE {_num(r.yaw_rmse_deg, '.3f')} deg    drift {_num(r.drift_m, '.3f')} m = "
        f"{_num(r.drift_pct, '.2f')} % of the path, yaw {r.drift_yaw_deg:+.2f} deg    "
        f"ATE RMSE {_num(Stats.of(r.ate_m).rmse, '.3f')} m",
        f"RPE per {r.delta_m:g} m: {_num(Stats.of(rpe_d.translation_pct).rmse, '.2f')} %, "
        f"{_num(Stats.of(rpe_d.rotation_deg).rmse, '.3f')} deg    "
        f"RPE per frame: {_num(Stats.of(rpe_f.translation_m).rmse, '.4f')} m, "
        f"{_num(Stats.of(rpe_f.rotation_deg).rmse, '.3f')} deg (RMSE)",
    ]
    if flags is None:
        lines.append("quality flags: not given (radar-eval --odom ODOM.jsonl)")
    else:
        # "ok" as the odometry message has it: no flag but first_frame.
        not_ok = sum(bool(set(f) - {Flag.FIRST_FRAME}) for f in flags.flags)
        counts = ", ".join(f"{name} {flags.count(name)}" for name in flags.names())
        lines.append(f"quality flags: {not_ok} of {len(flags)} steps not ok" + (f" ({counts})" if counts else ""))
    return lines
