"""The robustness matrix's summary, as docs/benchmarks.md gives it: one row per axis of the star
design (the base cells, then each value changed), means and ranges over its cells, and the whole
matrix against issue 20's goals; given two runs, each figure as BEFORE -> AFTER. Then, per row,
what makes the drift (the cells' drift parts, means: the drift each kind of frame's yaw errors
make alone, and the translation's; heading_metrics.drift_parts), and how the reported pose
covariance covers the errors (estimator/consistency.py), of the last run; before them, per goal,
the cells that miss it (given two runs: that came within it, and that fell out of it).

    python bench/matrix_summary.py [BEFORE/robustness.json] AFTER/robustness.json

Only the cells both runs hold are compared.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics

BASE = {"cfg": "shipped", "snr_db": 0.0, "speed_mps": 0.8, "turn_rate_dps": 45.0, "movers": "scene", "mount_m": 0.0}
LABELS = {"cfg": "cfg {}", "snr_db": "SNR {:g} dB", "speed_mps": "{:g} m/s", "turn_rate_dps": "{:g} deg/s",
          "movers": "movers: {}", "mount_m": "radar {:g} m ahead, wheeled"}


def row_of(cell: dict) -> str:
    """The star design's row of a simulated cell (the first axis off the base), or its scene for
    other cells."""
    for axis, base in BASE.items():
        if cell.get(axis, base) != base:
            return LABELS[axis].format(cell[axis])
    return "base (shipped cfg, scene SNR, 0.8 m/s, 45 deg/s)" if cell.get("kind") == "sim" else cell.get("run", "?")


def _stats(results: list[dict]) -> dict:
    def ratio_range(key: str) -> str:
        values = [r[key] for r in results if r.get(key) is not None]
        return f"{min(values):.3f}-{max(values):.3f}" if values else "-"
    bias = [abs(r["straight_bias_deg_per_frame"]) for r in results]
    drift = [r["drift_pct"] for r in results]
    return {"yaw": f"{statistics.mean(r['yaw_rmse_deg'] for r in results):.2f}",
            "bias": f"{statistics.mean(bias):.3f} / {max(bias):.3f}",
            "moving": ratio_range("moving_turn_ratio"), "each": ratio_range("moving_turn_worst_ratio"),
            "inplace": ratio_range("inplace_turn_ratio"),
            "drift": f"{statistics.mean(drift):.1f} / {max(drift):.1f}"}


# Issue 20's per-cell goals, each a test of one result's value.
def _bias_ok(deg_per_frame: float) -> bool:
    return abs(deg_per_frame) <= 0.005


def _turn_ok(ratio: float | None) -> bool:
    return ratio is None or abs(ratio - 1.0) <= 0.02  # None: no such turn


def _drift_ok(pct: float) -> bool:
    return pct <= 2.0


def _within(results: list[dict], key: str) -> int | str:
    """The cells whose *key* ratio is within 2 % of 1 (or undefined: no such turn); "-" for
    results without it (each turn's own: runs before 2026-11-30)."""
    if not all(key in r for r in results):
        return "-"
    return sum(_turn_ok(r[key]) for r in results)


def totals(results: list[dict]) -> dict:
    """Issue 20's goals over the whole run."""
    bias = [abs(r["straight_bias_deg_per_frame"]) for r in results]
    drift = [r["drift_pct"] for r in results]
    return {"cells": len(results), "yaw RMSE deg": f"{statistics.mean(r['yaw_rmse_deg'] for r in results):.2f}",
            "mean |straight bias| deg/frame": f"{statistics.mean(bias):.3f}",
            "straight bias <= 0.005": sum(map(_bias_ok, bias)),
            "the straights' own bias <= 0.005": _own_within(results),
            "signed straight bias, all / after turns' frames deg/frame": _signed(results),
            "each straight's heading error, RMS / worst deg/m": _straights(results),
            "moving turns within 2 %": _within(results, "moving_turn_ratio"),
            "each moving turn within 2 %": _within(results, "moving_turn_worst_ratio"),
            "turns in place within 2 %": _within(results, "inplace_turn_ratio"),
            "drift % mean": f"{statistics.mean(drift):.2f}", "drift % median": f"{statistics.median(drift):.2f}",
            "drift <= 2 %": sum(map(_drift_ok, drift)), "drift % worst": f"{max(drift):.1f}",
            "|final heading| deg": f"{statistics.mean(abs(r['final_heading_error_deg']) for r in results):.1f}"}


def _own_within(results: list[dict]) -> int | str:
    """The cells whose straight frames but the first after each turn keep the straight goal; "-"
    for results without the split (runs before 2026-12-06)."""
    if not all("straight_own_bias_deg_per_frame" in r for r in results):
        return "-"
    return sum(r["straight_own_bias_deg_per_frame"] is not None and _bias_ok(r["straight_own_bias_deg_per_frame"])
               for r in results)


def _signed(results: list[dict]) -> str:
    """The straight bias's signed mean over the cells, and the part of it made in the frames after
    the turns (each cell's summed error there over its straight frames); "-" for the second without
    the split (runs before 2026-12-06)."""
    signed = statistics.mean(r["straight_bias_deg_per_frame"] for r in results)
    if not all("straight_after_turn_deg" in r for r in results):
        return f"{signed:+.4f} / -"
    after = statistics.mean(r["straight_after_turn_deg"] / r["straight_frames"] for r in results)
    return f"{signed:+.4f} / {after:+.4f}"


def _straights(results: list[dict]) -> str:
    """The RMS over the cells' straight drives of their heading error per metre, and the
    worst; "-" for results without them (runs before 2026-11-30)."""
    rms = [r["straight_rms_deg_per_m"] for r in results if r.get("straight_rms_deg_per_m") is not None]
    worst = [r["straight_max_deg_per_m"] for r in results if r.get("straight_max_deg_per_m") is not None]
    if not rms:
        return "-"
    return f"{statistics.mean(x * x for x in rms) ** 0.5:.2f} / {max(worst):.2f}"


def parts_table(results: list[dict]) -> list[str]:
    """Per row of the star, the means of the cells' drift parts (% of the path); none when the
    results have none (runs before 2026-11-29)."""
    from radarodom.estimator.heading_metrics import DRIFT_PARTS
    rows: dict[str, list[dict]] = {}
    for r in sorted(results, key=lambda r: r["name"]):
        if r.get("drift_parts"):
            rows.setdefault(row_of(r["cell"]), []).append(r["drift_parts"])
    if not rows:
        return []
    lines = ["| cells | " + " | ".join(DRIFT_PARTS) + " |", "| --- |" + " ---: |" * len(DRIFT_PARTS)]
    for label, parts in sorted(rows.items(), key=lambda item: not item[0].startswith("base")):
        values = [[p[k] for p in parts if p.get(k) is not None] for k in DRIFT_PARTS]
        lines.append(f"| {label} ({len(parts)}) | " + " | ".join(f"{statistics.mean(v):.2f}" if v else "-"
                                                                 for v in values) + " |")
    return lines


def covariance_table(results: list[dict]) -> list[str]:
    """Per row of the star, how the reported pose covariance covers the errors (each frame's error
    since the start over its standard deviation: RMS, and the share within two; the final heading's
    standard deviation against its error, RMS over the cells), and the twist's yaw rate and speeds
    (each step's); none when the results have none (runs before 2026-12-01)."""
    rows: dict[str, list[dict]] = {}
    for r in sorted(results, key=lambda r: r["name"]):
        if r.get("covariance"):
            rows.setdefault(row_of(r["cell"]), []).append(r)
    if not rows:
        return []
    lines = ["| cells | heading error / sd, RMS | within 2 sd | final heading sd / error RMS, deg "
             "| position error / sd, RMS | within 2 sd | yaw rate error / sd, RMS | within 2 sd "
             "| speed error / sd, RMS, forward / sideways |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    everything = [r for cells in rows.values() for r in cells]
    for label, cells in [*sorted(rows.items(), key=lambda item: not item[0].startswith("base")), ("all", everything)]:
        def mean(part: str, key: str) -> str:
            values = [r["covariance"][part][key] for r in cells
                      if r["covariance"].get(part) and r["covariance"][part][key] is not None]
            return f"{statistics.mean(values):.2f}" if values else "-"
        finals = [(r["covariance"]["final_yaw_sigma_deg"], r["covariance"]["final_yaw_error_deg"]) for r in cells]
        finals = [(sd, err) for sd, err in finals if sd is not None and err is not None]  # (null: it overflowed)
        sd = statistics.mean(sd for sd, _ in finals) if finals else math.nan
        err = statistics.mean(err ** 2 for _, err in finals) ** 0.5 if finals else math.nan
        lines.append(f"| {label} ({len(cells)}) | {mean('yaw', 'z_rms')} | {mean('yaw', 'within_2sigma')} "
                     f"| {sd:.1f} / {err:.1f} | {mean('position', 'z_rms')} | {mean('position', 'within_2sigma')} "
                     f"| {mean('yaw_rate', 'z_rms')} | {mean('yaw_rate', 'within_2sigma')} "
                     f"| {mean('forward_speed', 'z_rms')} / {mean('sideways_speed', 'z_rms')} |")
    return lines


#: Issue 20's per-cell goals: (name, the result's key, its test).
GOALS = (("straight bias at most 0.005 deg/frame", "straight_bias_deg_per_frame", _bias_ok),
         ("each moving turn within 2 %", "moving_turn_worst_ratio", _turn_ok),
         ("turns in place within 2 %", "inplace_turn_ratio", _turn_ok),
         ("drift at most 2 %", "drift_pct", _drift_ok))
#: The cells named per goal and way; the rest counted.
NAMED = 12


def _value(v) -> str:
    return "-" if v is None else f"{v:.4g}"


def goal_changes(runs: list[list[dict]]) -> list[str]:
    """Per goal (:data:`GOALS`), the cells that miss it in the last run, or with two runs the cells
    that came within it and those that fell out of it, each with its value(s): which cells a
    change moved, where the counts alone net them out."""
    by_name = [{r["name"]: r for r in run} for run in runs]  # one run, or before and after
    lines = []
    for goal, key, meets in GOALS:
        if not all(key in r for run in runs for r in run):
            continue  # results from before the key existed
        met = {n: [meets(run[n][key]) for run in by_name] for n in sorted(by_name[-1])}
        if len(runs) == 1:
            groups = [("missed by", [n for n, (now,) in met.items() if not now])]
        else:
            groups = [("gained", [n for n, (was, now) in met.items() if now and not was]),
                      ("lost", [n for n, (was, now) in met.items() if was and not now])]
        for way, names in groups:
            if not names:
                continue
            shown = ", ".join(f"{n} {' -> '.join(_value(run[n][key]) for run in by_name)}" for n in names[:NAMED])
            more = f", and {len(names) - NAMED} more" if len(names) > NAMED else ""
            lines.append(f"- {goal}, {way} {len(names)}: {shown}{more}")
    return lines


def summary(runs: list[list[dict]]) -> str:
    names = set.intersection(*({r["name"] for r in run} for run in runs))
    runs = [[r for r in run if r["name"] in names] for run in runs]
    rows: dict[str, list[list[dict]]] = {}
    for i, run in enumerate(runs):
        for r in sorted(run, key=lambda r: r["name"]):
            rows.setdefault(row_of(r["cell"]), [[] for _ in runs])[i].append(r)
    joined = lambda values: " -> ".join(values)  # noqa: E731
    lines = ["| cells | yaw RMSE deg | straight bias deg/frame, mean / max abs | moving-turn ratio "
             "| each moving turn, farthest from 1 | in-place ratio | drift %, mean / max |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for label, per_run in sorted(rows.items(), key=lambda item: not item[0].startswith("base")):
        stats = [_stats(results) for results in per_run]
        lines.append(f"| {label} ({len(per_run[0])}) | " + " | ".join(
            joined([s[key] for s in stats]) for key in ("yaw", "bias", "moving", "each", "inplace", "drift")) + " |")
    all_totals = [totals(run) for run in runs]
    lines.append("")
    lines.append("; ".join(f"{key} {joined([str(t[key]) for t in all_totals])}" for key in all_totals[0]))
    changes = goal_changes(runs)
    if changes:
        lines += ["", "The cells " + ("that crossed a goal (BEFORE -> AFTER):" if len(runs) > 1
                                      else "that miss a goal:"), ""] + changes
    parts = parts_table(runs[-1])
    if parts:
        lines += ["", "What makes the drift (% of the path, means; each kind of frame's yaw errors alone, "
                      "and the translation's):", ""] + parts
    covariance = covariance_table(runs[-1])
    if covariance:
        lines += ["", "The reported pose covariance against the errors (estimator/consistency.py; means over "
                      "the cells):", ""] + covariance
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", metavar="ROBUSTNESS.json", help="one run, or BEFORE then AFTER")
    args = parser.parse_args(argv)
    if len(args.runs) > 2:
        parser.error("give one run, or two (before and after)")
    runs = []
    for path in args.runs:
        with open(path, encoding="utf-8") as fh:
            runs.append(json.load(fh))
    print(summary(runs))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
