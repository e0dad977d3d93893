"""Two trajectories' poses paired by time, as evo pairs them, each pose used once; and the
checks both must pass first (trajectories, with times that increase, two poses at least).
Split off :mod:`radarodom.estimator.evaluation`, which re-exports it.  Pure numpy.
"""

from __future__ import annotations

import logging
import math
import os

import numpy as np

from ..errors import EvaluationError
from ..plain_numbers import is_number, time_text
from ..tum import TumTrajectory

log = logging.getLogger(__name__)


def _span(traj: TumTrajectory) -> str:
    name = traj.source or "<trajectory>"
    return f"{name} ({len(traj)} poses, t {time_text(traj.times[0])} .. {time_text(traj.times[-1])} s)"


def _unit_hint(est: TumTrajectory, ref: TumTrajectory) -> str | None:
    """Where one trajectory's times span a thousand, a million or a billion times the other's:
    that it was written in milli-, micro- or nanoseconds (TUM's are seconds)."""
    spans = [float(traj.times[-1] - traj.times[0]) for traj in (est, ref)]
    if min(spans) <= 0:
        return None
    longer, shorter = (est, ref) if spans[0] > spans[1] else (ref, est)
    ratio = max(spans) / min(spans)
    for factor, times, unit in ((1e9, "a billion", "nanoseconds"), (1e6, "a million", "microseconds"),
                                (1e3, "a thousand", "milliseconds")):
        if factor / 2 <= ratio <= factor * 2:
            return (f"{longer.source or 'a trajectory'}'s times span about {times} times "
                    f"{shorter.source or 'the other'}'s: written in {unit}? TUM times are seconds")
    return None


def check_increasing(traj: TumTrajectory) -> None:
    bad = np.flatnonzero(np.diff(traj.times) <= 0)
    if len(bad):
        i = int(bad[0]) + 1
        raise EvaluationError(f"{traj.where(i)}: time {time_text(traj.times[i], 9)} s is not after the previous "
                              f"pose's {time_text(traj.times[i - 1], 9)} s; timestamps must increase")


#: The least share of the shorter trajectory's time span the matched poses are expected to cover.
PARTLY = 0.8


def check_finite(traj: TumTrajectory) -> None:
    """:class:`EvaluationError` naming the first pose with a NaN or inf: read_tum refuses them, but
    a trajectory built in Python made every figure NaN (a NaN time its pose left out unsaid)."""
    bad = ~(np.isfinite(traj.times) & np.isfinite(traj.positions).all(axis=1)
            & np.isfinite(traj.quaternions).all(axis=1))
    if bad.any():
        i = int(np.argmax(bad))
        raise EvaluationError(f"{traj.where(i)}: pose {i} (t {traj.times[i]:g} s) holds NaN or inf; a pose's "
                              "time, position and orientation must be finite numbers")


def check_trajectory(name: str, traj) -> None:
    """:class:`EvaluationError` unless *traj* is a trajectory (a path is read by ``read_tum``)."""
    if not isinstance(traj, TumTrajectory):
        how = " (radarodom.tum.read_tum reads a TUM file)" if isinstance(traj, (str, bytes, os.PathLike)) else ""
        raise EvaluationError(f"{name}: a TumTrajectory{how}, got {type(traj).__name__}")


def associate(est: TumTrajectory, ref: TumTrajectory, max_diff: float = 0.01
              ) -> tuple[TumTrajectory, TumTrajectory]:
    """The poses of *est* and *ref* that match in time, as two trajectories of
    equal length (est, ref).

    Like evo's ``associate_trajectories``: each pose of the trajectory with
    fewer poses takes the nearest pose in time of the other, within *max_diff*
    seconds.  Unlike evo, a pose is never used twice: where two poses would take
    the same partner, the nearer keeps it.  Timestamps must increase.
    Raises :class:`EvaluationError`, naming both files' time spans, when fewer
    than two poses match.
    """
    if not (is_number(max_diff) and max_diff >= 0 and math.isfinite(max_diff)):
        raise EvaluationError(f"max_diff must be a time >= 0 s, got {max_diff!r}")
    for name, traj in (("est", est), ("ref", ref)):
        check_trajectory(name, traj)
    for traj in (est, ref):
        check_finite(traj)
        check_increasing(traj)
        if len(traj) < 2:
            raise EvaluationError(f"{traj.source or '<trajectory>'} holds "
                                  + ("no poses (an empty file, or only comments)" if not len(traj) else "1 pose")
                                  + ": at least 2 are needed")
    # evo iterates over the shorter trajectory (the estimate when they are equally long).
    est_short = len(est) <= len(ref)
    short, long_ = (est, ref) if est_short else (ref, est)
    ts, tl = short.times, long_.times
    upper = np.minimum(np.searchsorted(tl, ts, side="right"), len(tl) - 1)
    diff_ub = tl[upper] - ts
    diff_lb = np.where(upper > 0, ts - tl[np.maximum(upper - 1, 0)], np.inf)
    inside = (ts >= tl[0] - max_diff) & (ts <= tl[-1] + max_diff)
    take_ub = inside & (diff_ub <= max_diff) & (diff_ub < diff_lb)
    take_lb = inside & ~take_ub & (diff_lb <= max_diff) & (diff_lb <= diff_ub)
    partner = np.where(take_ub, upper, upper - 1)
    dt = np.where(take_ub, np.abs(diff_ub), diff_lb)
    hit = np.flatnonzero(take_ub | take_lb)
    # A pose of the longer trajectory serves one pose only, the nearest in time.
    order = np.lexsort((dt[hit], partner[hit]))
    hit = hit[order]
    first = np.ones(len(hit), dtype=bool)
    first[1:] = partner[hit][1:] != partner[hit][:-1]
    idx_short = np.sort(hit[first])
    idx_long = partner[idx_short]
    if len(idx_short) < 2:
        raise EvaluationError(
            f"only {len(idx_short)} pose(s) of {_span(est)} and {_span(ref)} match in time within "
            f"{max_diff:g} s; at least 2 are needed ({_unit_hint(est, ref) or 'same clock? --max-diff?'})")
    if len(idx_short) < len(short):
        log.info("%d of %d poses of %s matched", len(idx_short), len(short), short.source or "the shorter trajectory")
    matched_s = ts[idx_short[-1]] - ts[idx_short[0]]
    if matched_s < PARTLY * min(est.times[-1] - est.times[0], ref.times[-1] - ref.times[0]):
        # Each covers a stretch the other does not: another run's truth, or a clock offset.
        log.warning("the poses matched span %.3g s, less than %d %% of %s and %s: the two overlap in time only "
                    "in part (same run, same clock?)", matched_s, round(PARTLY * 100), _span(est), _span(ref))
    pair = (short.take(idx_short), long_.take(idx_long))
    return pair if est_short else (pair[1], pair[0])
