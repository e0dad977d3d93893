"""Where a turn in place's error lies (issue 20; docs/heading.md, "The turns in place's length").

    python bench/turn_phases.py SEQUENCE_DIR [...] [--estimator-config FILE.json]

A matrix loop's turn in place (a turn of the truth's whose median speed is below 0.05 m/s, as the
matrix's metrics take it) is three phases by the truth's speed: braking into it while the turn
starts (the radar still moving), at rest (below 0.02 m/s), and starting off while the turn ends.
For each turn in place of each simulated sequence (a capture directory with groundtruth.tum:
bench/robustness_matrix.py or bench/scene_edits.py records them), each phase's heading error is
summed, in degrees and taken in the turn's direction (positive: the turn measured too long), for
the published estimate and each blended chain (the heatmaps' registration's and the points'),
beside the degrees the truth turned in it; then each sequence's sums, the whole turn's ratio
(estimated / true) per estimate and chain, and with several sequences their mean. A cause in
what both chains are given shows in both; one of a registration's own, in its chain alone.
Last, the same sum over the AFTER_STEPS steps after the turn ("after it"; outside the ratio, as
the matrix's metrics put them in the straight drive after): what the estimate takes back of the
turn's error, or gives, once it has ended (docs/heading.md, "The straight after a turn in place
pays for the turn's error").
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import sequences  # noqa: E402  (bench/ is not a package)
from heading_diagnosis import _wrap, run, truth  # noqa: E402

from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.estimator.heading_metrics import segment_turns  # noqa: E402

PHASES = ("braking in", "at rest", "starting off")
#: The steps after a turn in place summed as "after it" (a second at 10 frames/s).
AFTER_STEPS = 10
#: Below this speed (m/s) the radar stands.
REST_MPS = 0.02
ESTIMATES = ("published", "heatmaps' chain", "points' chain")


def phase_errors(times: np.ndarray, ref: np.ndarray, estimates: np.ndarray, *, after_steps: int = 0
                 ) -> np.ndarray:
    """Summed over every turn in place of the truth *ref* ((n, 3) x, y, yaw at *times* (n,); the
    matrix's turns, heading_metrics.segment_turns), per phase (PHASES) and estimate (the columns
    of *estimates*, (n - 1, E) rad a step): the error in the turn's direction (rad) and, last
    column, the truth's turn (rad); (3, E + 1). With *after_steps*, a fourth row: the same over
    that many steps after each turn (fewer where the sequence ends)."""
    dt = np.diff(times)
    true_rad = _wrap(np.diff(ref[:, 2]))
    speed = np.hypot(*np.diff(ref[:, :2], axis=0).T) / dt
    out = np.zeros((len(PHASES) + (after_steps > 0), estimates.shape[1] + 1))
    for i, j, in_place in segment_turns(times, ref):
        turn = np.arange(i, j)
        rest = turn[speed[turn] < REST_MPS]
        if not in_place or len(rest) == 0:
            continue
        sign = np.sign(true_rad[turn].sum())
        parts = [turn[turn < rest[0]], turn[(turn >= rest[0]) & (turn <= rest[-1])], turn[turn > rest[-1]]]
        if after_steps:
            parts.append(np.arange(j, min(j + after_steps, len(true_rad))))
        for k, steps in enumerate(parts):
            out[k, :-1] += sign * (estimates[steps] - true_rad[steps, None]).sum(axis=0)
            out[k, -1] += abs(true_rad[steps].sum())
    return out


def sequence_phases(directory: str, config: EstimatorConfig) -> np.ndarray:
    """:func:`phase_errors` of the recording in *directory* with the estimator *config*: the
    published increments and each blended chain's (NaN where the estimator has no blend)."""
    seq = sequences.load(directory)
    headings = np.array([(state.yaw, *chains) for _, state, _, chains in run(seq, config)])
    return phase_errors(seq.times, truth(seq), _wrap(np.diff(headings, axis=0)), after_steps=AFTER_STEPS)


def _shown(value: float, spec: str) -> str:
    """*value* formatted by *spec*, or "-" where it is undefined (an estimator without a blend)."""
    return "-" if math.isnan(value) else format(value, spec)


def lines(name: str, table: np.ndarray) -> list[str]:
    """*table* (:func:`phase_errors`' shape) as text, degrees."""
    deg = np.degrees(table)
    phases, after = deg[:len(PHASES)], deg[len(PHASES):]
    out = [f"{name}: turns in place, error summed in the turn's direction, degrees ("
           + " / ".join(ESTIMATES) + ")"]
    for phase, row in zip(PHASES, phases):
        out.append(f"  {phase:13s} " + " / ".join(_shown(v, "+.2f") for v in row[:-1]) + f"  of {row[-1]:.0f} turned")
    turned = phases[:, -1].sum()
    if turned > 0:
        ratios = 1.0 + phases[:, :-1].sum(axis=0) / turned
        out.append("  whole turn ratio " + " / ".join(_shown(r, ".4f") for r in ratios))
    for row in after:
        out.append(f"  {'after it':13s} " + " / ".join(_shown(v, "+.2f") for v in row[:-1])
                   + f"  over the {AFTER_STEPS} steps after each turn")
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("sequences", nargs="+", metavar="SEQUENCE_DIR")
    parser.add_argument("--estimator-config", metavar="FILE.json", help="default: the defaults")
    args = parser.parse_args(argv)
    config = EstimatorConfig.load(args.estimator_config) if args.estimator_config else EstimatorConfig()
    tables = []
    for directory in args.sequences:
        tables.append(sequence_phases(directory, config))
        print("\n".join(lines(os.path.basename(os.path.normpath(directory)), tables[-1])), flush=True)
    if len(tables) > 1:
        print("\n".join(lines(f"mean of {len(tables)}", np.mean(tables, axis=0))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
