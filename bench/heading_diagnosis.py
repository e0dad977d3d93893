"""Stage-by-stage heading diagnosis against the ground truth (issue 20).

    python bench/heading_diagnosis.py SEQUENCE_DIR [...] [--estimator-config FILE.json]
                                      [--baselines 1 2 4 8]
                                      [--straights 6 [--min-straight-m 1] [--straight-end-m 1]]
                                      [--trace 100 120]
                                      [--turned-translation 0 0.1 -0.1] [--true-velocity]

For each simulated sequence (a capture directory with groundtruth.tum, such as bench/sequences.py
or bench/robustness_matrix.py record), every step is classified by the truth (standing still,
driving straight, a moving turn left or right, a turn in place) and the yaw increment is
compared with the truth at each stage:

- ``estimate``: the estimator's increment (after the yaw-rate filter, the keyframe and the map of
  wall directions; a settings file with ``{"wall_map": {"use": false}}`` leaves the map out);
- ``field, true translation``: the likelihood-field search of the two frames (the estimator's
  features and fields) moved by the TRUE translation and centred on the true rotation: what the
  registration alone gives when everything before it is right;
- ``field, no translation``: the same without moving the previous frame: how much the
  rectification matters.

Straight drives and standing still report the mean error (bias, deg per frame) and its RMS;
turns the ratio of the summed increments (estimate / truth), each taken in its turn's direction
(a loop's left and right turns would otherwise cancel).  ``--baselines`` also registers
frames 1, 2, 4, 8 steps apart on straight drives with the true motion and reports the forward
term (the earlier frame's points in the later frame's field), the backward term and their sum
separately: a bias that is the same at every baseline is an offset of each registration, one
that grows with the baseline comes from the motion; and, over moving turns and turns in place,
the two-way registration's turn ratio at each baseline (what a keyframe that many frames back
measures, given the true motion) and each of its two terms' alone (in the simulator's turns in
place they err by up to a fifth each way and cancel in their sum: docs/heading.md).

``--straights K`` takes each straight drive apart (at least ``--min-straight-m`` long; a loop's
straights turn opposite ways and cancel in the bias): the estimate's heading error over it, each
blended chain's (the heatmaps' registration's and the points'), and the field search's with the
true motion between frames K apart along it, in degrees a metre (docs/heading.md, "Each straight
apart": the field has the straights' error too, so it is the registration's, not the chain's), and
the estimate's error in degrees over its first metre, its middle and its last metre
(``--straight-end-m``; docs/heading.md, "Longer straights": where along a straight it arises).
bench/scene_edits.py records a matrix cell with objects of its scene left out, to run this on.

``--trace FIRST LAST`` prints the steps into frames FIRST to LAST one by one: the truth's speed
and turn, the estimate's, its error and the error summed from FIRST, the field search's error
given the true motion, and the estimator's flags: where in a run the heading went.

``--turned-translation DEG [DEG ...]`` gives, on straight drives, the field search of
consecutive frames given the true translation turned by each DEG (positive: to the left): how
much a straight's bias moves with the direction of the translation the registration is given,
the Doppler velocity's direction error's share in it (docs/heading.md, item 27).

``--true-velocity`` runs the estimator with each frame's velocity taken from the ground truth
(the radar's, by its poses before and after) instead of its point cloud's fit, the points still
given to the points' yaw and the map of walls: every figure above then says what is left once
the Doppler velocity is right, in the steps' translation, the rectification and the static-cell
tests (the drift part ``translation`` falls to the truth's sampling); against a run without it,
what the velocity's errors make.  For a cloud without elevation (2 TX) the Doppler's elevation
still reads the cells against the level fit's forward speed, as it is made to (given the true
one, every cell reads farther off level and the turns in place of TI's profile_2d came out 1-3 %
long).

Last, what makes the drift (``drift parts``,
:func:`radarodom.estimator.heading_metrics.drift_parts`): the estimate's drift, and the drift that
each kind of frame's yaw errors (straight, the first frames after a turn, moving turns, turns in
place, the rest) and the estimate's translation make alone.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
from collections.abc import Iterator

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import sequences  # noqa: E402  (bench/ is not a package)
from sequences import true_velocities, truth  # noqa: E402,F401  (truth: turn_phases' too)

from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.estimator.heading_metrics import (  # noqa: E402
    MOVING_MPS, STRAIGHT_RATE_DPS, drift_parts, straight_runs, straight_steps)
from radarodom.estimator.icp import _offsets, _peak_at, _scores, field_rotation  # noqa: E402
from radarodom.estimator.odometry import RadarOdometry  # noqa: E402
from radarodom.estimator.velocity import VelocityEstimate  # noqa: E402

STAGES = ("estimate", "field, true translation", "field, no translation")


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def step_motion(poses: np.ndarray, i: int, j: int) -> tuple[np.ndarray, float]:
    """The true translation (2,) m in frame i's axes and rotation (rad) from frame i to j."""
    d = poses[j, :2] - poses[i, :2]
    c, s = math.cos(poses[i, 2]), math.sin(poses[i, 2])
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]), float(_wrap(poses[j, 2] - poses[i, 2]))


#: The kinds of step, by the truth: a moving turn left and right apart (a bias that turns both the
#: same way, as the straights' does, lengthens one and shortens the other).
KINDS = ("still", "straight", "moving turn, left", "moving turn, right", "turn in place")


def kind(translation: np.ndarray, dyaw: float, dt: float) -> str:
    """One of KINDS, by the truth."""
    turning = math.degrees(abs(dyaw)) / dt > STRAIGHT_RATE_DPS
    moving = float(np.hypot(*translation)) / dt > MOVING_MPS
    if not turning:
        return "straight" if moving else "still"
    return ("moving turn, left" if dyaw > 0 else "moving turn, right") if moving else "turn in place"


@dataclasses.dataclass
class Step:
    """One step into frame *frame* (*t* s after the first): the truth's speed (m/s) and turn
    (rad), the estimate's turn and the field's given the true motion (None: no field)."""

    frame: int
    t: float
    speed_mps: float
    true_rad: float
    estimate_rad: float
    field_rad: float | None
    flags: tuple[str, ...]


def run(seq: sequences.Sequence, config: EstimatorConfig, velocities: list[VelocityEstimate] | None = None
        ) -> Iterator[tuple[int, object, object, np.ndarray]]:
    """Each frame of *seq* through the estimator of *config* (given *velocities*, each frame's
    kept instead of its points' fit): its index, the published state, what the estimator keeps of
    the frame (features, field) and the two blended chains' headings, the heatmaps' and the
    points' (2,) rad (NaN without the blend)."""
    odom = RadarOdometry(config)
    for i in range(len(seq)):
        odom.add_points(seq.times[i], seq.points[i], velocity=None if velocities is None else velocities[i])
        state = odom.add_heatmap(seq.times[i], seq.heatmap(i))
        chains = np.full(2, np.nan)
        if odom.blend is not None and odom.blend.chains is not None:
            chains = np.array([chain.yaw for chain in odom.blend.chains])
        yield i, state, odom._previous, chains


def diagnose(seq: sequences.Sequence, config: EstimatorConfig, velocities: list[VelocityEstimate] | None = None
             ) -> tuple[dict, list, np.ndarray, list, np.ndarray]:
    """Per kind of step, per stage: lists of (estimated, true) increments; the kept frames; the
    estimated poses (n, 3); each step's (into frame i >= 1) :class:`Step`; and the two blended
    chains' headings, the heatmaps' and the points' (n, 2) rad (NaN without the blend).
    *velocities*: as :func:`run`."""
    poses = truth(seq)
    icp = config.icp
    common = icp.score_support == "common"
    out: dict[str, dict[str, list]] = {}
    kept, previous, steps = [], None, []
    estimated = np.zeros((len(seq), 3))
    chains = np.full((len(seq), 2), np.nan)
    for i, state, current, headings in run(seq, config, velocities):
        estimated[i], chains[i] = state.pose, headings
        kept.append(current)
        if i > 0:
            t, dyaw = step_motion(poses, i - 1, i)
            rows = out.setdefault(kind(t, dyaw, seq.times[i] - seq.times[i - 1]), {s: [] for s in STAGES})
            rows["estimate"].append((state.yaw_increment, dyaw))
            field = None
            if previous.field is not None and current.field is not None:
                for stage, move in (("field, true translation", t), ("field, no translation", np.zeros(2))):
                    r = field_rotation(previous.field.points, current.field.points, previous.field.smoothed,
                                       current.field.smoothed, move, -dyaw, icp.field_search_rad, icp.field_step_rad,
                                       common)
                    if r is not None:
                        rows[stage].append((-r, dyaw))
                        if stage == "field, true translation":
                            field = -r
            steps.append(Step(i, seq.times[i] - seq.times[0], float(np.hypot(*t)) / (seq.times[i] - seq.times[i - 1]),
                              dyaw, state.yaw_increment, field, tuple(str(f) for f in state.flags)))
        previous = current
    return out, kept, estimated, steps, chains


def trace(steps: list[Step], first: int, last: int) -> list[str]:
    """The steps into frames *first* to *last*, one line each, degrees (see the module docstring)."""
    lines = ["  frame      t  speed   true  estimate   error  summed   field  flags"]
    summed = 0.0
    for st in steps:
        if not first <= st.frame <= last:
            continue
        error = math.degrees(float(_wrap(st.estimate_rad - st.true_rad)))
        summed += error
        field = "-" if st.field_rad is None else f"{math.degrees(float(_wrap(st.field_rad - st.true_rad))):+.2f}"
        lines.append(f"  {st.frame:5d} {st.t:6.2f} {st.speed_mps:6.2f} {math.degrees(st.true_rad):+6.2f} "
                     f"{math.degrees(st.estimate_rad):+9.2f} {error:+7.2f} {summed:+7.2f} {field:>7}  "
                     f"{' '.join(st.flags)}")
    return lines


def _terms(a, b, translation: np.ndarray, dyaw: float, deltas: np.ndarray, common: bool) -> dict[str, float | None]:
    """The field search of kept frames *a* and *b* given the true motion (*translation* (2,) m in
    a's axes, *dyaw* rad), centred on the true rotation: the peak's offset from it (rad; None where
    no score is finite) on the grid *deltas* of its forward term (a's points in b's field), its
    backward term (b's points in a's field) and their sum (the two-way search)."""
    forward = _scores(a.points.shifted(translation), b.smoothed, -dyaw + deltas, common)
    backward = _scores(b.points.turned(dyaw).shifted(-translation), a.smoothed, -deltas, common)
    return {name: _peak_at(scores, deltas)
            for name, scores in (("forward", forward), ("backward", backward), ("two-way", forward + backward))}


def baselines(seq: sequences.Sequence, kept: list, config: EstimatorConfig, steps: list[int]) -> list[str]:
    """Forward, backward and two-way field registration of straight-drive frames *steps* apart,
    and over frames *steps* apart within a turn the two-way registration's turn ratio and each
    of its two terms' alone."""
    poses = truth(seq)
    kinds = [""] + [kind(*step_motion(poses, m - 1, m), seq.times[m] - seq.times[m - 1]) for m in range(1, len(seq))]
    icp = config.icp
    common = icp.score_support == "common"
    deltas = _offsets(math.radians(3.0), math.radians(0.25))
    lines = []
    for k in steps:
        errors: dict[str, list] = {"forward": [], "backward": [], "two-way": []}
        turns: dict[str, dict[str, list]] = {name: {"two-way": [], "forward": [], "backward": []}
                                             for name in KINDS[2:]}
        for j in range(k, len(seq)):
            between = set(kinds[j - k + 1:j + 1])
            a, b = kept[j - k].field, kept[j].field
            if len(between) != 1 or a is None or b is None:
                continue
            t, dyaw = step_motion(poses, j - k, j)
            if between <= set(turns):
                found = turns[between.pop()]
                r = field_rotation(a.points, b.points, a.smoothed, b.smoothed, t, -dyaw, icp.field_search_rad,
                                   icp.field_step_rad, common)
                if r is not None:
                    found["two-way"].append((-r, dyaw))
                terms = _terms(a, b, t, dyaw, deltas, common)
                for name in ("forward", "backward"):
                    if terms[name] is not None:
                        found[name].append((dyaw - terms[name], dyaw))
                continue
            if between != {"straight"}:
                continue
            for name, peak in _terms(a, b, t, dyaw, deltas, common).items():
                if peak is not None:
                    errors[name].append(-math.degrees(peak))
        ratios = [f"{name} ratio {_ratio(np.array(v['two-way'])):.3f} (forward {_shown_ratio(v['forward'])}, "
                  f"backward {_shown_ratio(v['backward'])}; n={len(v['two-way'])})"
                  for name, v in turns.items() if v["two-way"]]
        lines.append(f"  {k} frame(s) apart, n={len(errors['two-way'])}: " + ", ".join(
            f"{name} {np.mean(v):+.3f}" for name, v in errors.items() if v) + " deg"
            + "".join("; " + r for r in ratios))
    return lines


def straights(seq: sequences.Sequence, kept: list, estimated: np.ndarray, config: EstimatorConfig,
              steps: int, chains: np.ndarray | None = None, min_m: float = 1.0, end_m: float = 1.0) -> list[str]:
    """Each straight drive at least *min_m* long apart (heading_metrics.straight_runs): its length
    and the estimate's heading error over it (in degrees a metre and in all), each blended chain's
    (*chains*, :func:`diagnose`'s) beside it, the field search's with the true motion between
    frames *steps* apart along it (mean error a hop over the mean hop, degrees a metre), and the
    estimate's error in its first *end_m* metres, its middle and its last *end_m* (degrees; the
    first wins where they overlap)."""
    poses = truth(seq)
    dt = np.diff(seq.times)
    steps_m = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    d_ref = _wrap(np.diff(poses[:, 2]))
    straight = straight_steps(dt, d_ref, poses, STRAIGHT_RATE_DPS, MOVING_MPS)
    err = _wrap(_wrap(np.diff(estimated[:, 2])) - d_ref)
    chain_err = None if chains is None else np.degrees(_wrap(_wrap(np.diff(chains, axis=0)) - d_ref[:, None]))
    icp = config.icp
    lines = []
    for i, j, length, error in straight_runs(straight, steps_m, err, min_m):
        hops = []
        for a in range(i, j + 1 - steps):  # frames i..j: the run's steps i..j-1
            t, dyaw = step_motion(poses, a, a + steps)
            fa, fb = kept[a].field, kept[a + steps].field
            if fa is None or fb is None:
                continue
            r = field_rotation(fa.points, fb.points, fa.smoothed, fb.smoothed, t, -dyaw, icp.field_search_rad,
                               icp.field_step_rad, icp.score_support == "common")
            if r is not None:
                hops.append((math.degrees(-r - dyaw), float(np.hypot(*t))))
        field = f"{np.mean([h[0] for h in hops]) / np.mean([h[1] for h in hops]):+.2f}" if hops else "-"
        own = f"estimate {math.degrees(error) / length:+.2f} deg/m ({math.degrees(error):+.2f} deg)"
        if chain_err is not None and not np.isnan(chains[i:j + 1]).any():
            errors = chain_err[i:j].sum(axis=0)
            own += (f", heatmaps' chain {errors[0] / length:+.2f} ({errors[0]:+.2f} deg), points' chain "
                    f"{errors[1] / length:+.2f} ({errors[1]:+.2f} deg)")
        along = np.cumsum(steps_m[i:j])  # m driven at each step's end
        first = along <= end_m
        last = (along > length - end_m) & ~first
        ends = " / ".join(f"{math.degrees(err[i:j][m].sum()):+.2f}" for m in (first, ~first & ~last, last))
        lines.append(f"  straight from frame {i}, {length:.1f} m: {own}, "
                     f"field with the true motion ({steps} frames apart) {field} deg/m; "
                     f"first {end_m:g} m / middle / last {end_m:g} m {ends} deg")
    return lines


def turned_translation(seq: sequences.Sequence, kept: list, config: EstimatorConfig,
                       angles_deg: list[float]) -> str:
    """The field search of consecutive straight-drive frames given the true translation turned
    by each of *angles_deg* (degrees, counter-clockwise): its mean error, degrees a frame."""
    poses = truth(seq)
    icp = config.icp
    errors: dict[float, list] = {a: [] for a in angles_deg}
    for j in range(1, len(seq)):
        t, dyaw = step_motion(poses, j - 1, j)
        a, b = kept[j - 1].field, kept[j].field
        if kind(t, dyaw, seq.times[j] - seq.times[j - 1]) != "straight" or a is None or b is None:
            continue
        for angle in angles_deg:
            c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
            turned = np.array([c * t[0] - s * t[1], s * t[0] + c * t[1]])
            r = field_rotation(a.points, b.points, a.smoothed, b.smoothed, turned, -dyaw, icp.field_search_rad,
                               icp.field_step_rad, icp.score_support == "common")
            if r is not None:
                errors[angle].append(math.degrees(-r - dyaw))
    return "  straight, field with the true translation turned by: " + ", ".join(
        f"{a:+g} deg {np.mean(v):+.4f}" for a, v in errors.items() if v) + " deg a frame"


def _ratio(pairs: np.ndarray) -> float:
    """Estimated over true turned angle of (estimated, true) increments (n, 2), each taken in
    its turn's direction (a loop's left and right turns would otherwise cancel)."""
    return float((pairs[:, 0] * np.sign(pairs[:, 1])).sum() / np.abs(pairs[:, 1]).sum())


def _shown_ratio(pairs: list) -> str:
    """:func:`_ratio` of (estimated, true) increments to three decimals, "-" without any."""
    return f"{_ratio(np.array(pairs)):.3f}" if pairs else "-"


def report(name: str, found: dict) -> list[str]:
    lines = [name]
    for k in KINDS:
        if k not in found:
            continue
        parts = []
        for stage in STAGES:
            pairs = np.array(found[k][stage], float).reshape(-1, 2)
            if not len(pairs):
                continue
            if k in ("still", "straight"):
                err = np.degrees(pairs[:, 0] - pairs[:, 1])
                parts.append(f"{stage}: bias {err.mean():+.4f} rms {math.sqrt(float(np.mean(err ** 2))):.3f}")
            else:
                parts.append(f"{stage}: ratio {_ratio(pairs):.4f}")
        lines.append(f"  {k:18s} n={len(found[k]['estimate']):4d} | " + " | ".join(parts))
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("sequences", nargs="+", metavar="SEQUENCE_DIR")
    parser.add_argument("--estimator-config", metavar="FILE.json", help="default: the defaults")
    parser.add_argument("--baselines", nargs="*", type=int, default=[], metavar="K")
    parser.add_argument("--straights", type=int, default=None, metavar="K",
                        help="each straight apart, the field's hops K frames long")
    parser.add_argument("--min-straight-m", type=float, default=1.0, metavar="M",
                        help="--straights: the shortest straight taken apart (default 1 m)")
    parser.add_argument("--straight-end-m", type=float, default=1.0, metavar="M",
                        help="--straights: each straight's error also in its first M m, middle and last M m")
    parser.add_argument("--trace", nargs=2, type=int, default=None, metavar=("FIRST", "LAST"),
                        help="the steps into frames FIRST to LAST, one by one")
    parser.add_argument("--turned-translation", nargs="+", type=float, default=None, metavar="DEG",
                        help="straight drives: the field given the true translation turned by each DEG")
    parser.add_argument("--true-velocity", action="store_true",
                        help="the estimator given each frame's true velocity instead of its points' fit")
    args = parser.parse_args(argv)
    config = EstimatorConfig.load(args.estimator_config) if args.estimator_config else EstimatorConfig()
    for directory in args.sequences:
        seq = sequences.load(directory)
        velocities = true_velocities(seq, config) if args.true_velocity else None
        found, kept, estimated, steps, chains = diagnose(seq, config, velocities)
        print("\n".join(report(seq.name + (" (the estimator given the true velocity)" if velocities else ""), found)))
        if args.trace:
            print("\n".join(trace(steps, *args.trace)))
        if args.baselines:
            print("\n".join(baselines(seq, kept, config, args.baselines)))
        if args.straights:
            print("\n".join(straights(seq, kept, estimated, config, args.straights, chains, args.min_straight_m,
                                       args.straight_end_m)))
        if args.turned_translation:
            print(turned_translation(seq, kept, config, args.turned_translation))
        parts = drift_parts(seq.times, truth(seq), estimated)
        print("  drift parts (% of the path): " + ", ".join(f"{k} {v:.2f}" for k, v in parts.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
