"""How far the map of wall directions' lines lie from the scene's walls (issue 20; docs/heading.md,
"Measured and not adopted": the map told where a step's turn is in doubt).

    python bench/wall_lines.py SEQUENCE_DIR [...] [--estimator-config FILE.json] [--near DEG]

For each simulated sequence (a capture directory recorded by ``radar-sim``, whose capture.json
names its scene, with groundtruth.tum: bench/robustness_matrix.py records them) the estimator runs
once. Each frame's static points, taken as the wall map takes them (estimator/point_yaw.py's
``static_points`` at the published velocity), are placed over the map's window of frames by the
true poses and, apart, by the estimator's own; wherever the heading turned by at most the map's
``match_span_rad`` over that window, lines are searched as the map does
(``wall_map.wall_lines``) and each line's direction in the world is held against the nearest
direction of the scene's walls (its occluding segments: walls, doors, the occluding boxes).
Placed by the true poses, that is each line's own error (the points' places, the fit); placed by
the estimator's, it adds the heading's error and the window's, as the map sees it.

Printed per sequence, then over all: the lines found; of those within ``--near`` degrees of a
wall direction (the others are furniture, clutter or corners, which the map's gates must keep
out), the median and RMS of the error and its mean, and the median of what each line states as
its standard deviation; and the share of all lines beyond 5 degrees. With ``--by-stated``, the
lines within ``--near`` degrees over all the sequences again, grouped by what each states: how
far they lie off their wall against what they state (docs/heading.md, "Measured and not adopted":
what a line states and how far it lies).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import urllib.parse

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import sequences  # noqa: E402  (bench/ is not a package)
from heading_diagnosis import run  # noqa: E402

from radarodom.driver.sim.scene import load_scene  # noqa: E402
from radarodom.driver.sources import split_url  # noqa: E402
from radarodom.estimator.angles import wrap_line  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.estimator.config_wall_map import WallMapConfig  # noqa: E402
from radarodom.estimator.point_yaw import static_points  # noqa: E402
from radarodom.estimator.wall_map import placed_points, wall_lines, window_points  # noqa: E402

#: A scene segment shorter than this (m) gives no wall direction (a pillar's cross).
MIN_SEGMENT_M = 0.3
#: The share of lines reported as far off a wall: beyond this, degrees.
FAR_DEG = 5.0
#: ``--by-stated``'s groups: the standard deviation a line states, degrees, between these.
STATED_EDGES_DEG = (0.0, 0.2, 0.3, 0.5, 0.8, math.inf)


def scene_directions(capture_dir: str) -> np.ndarray:
    """The directions (rad in [0, pi)) of the occluding segments of the scene *capture_dir* was
    recorded in (capture.json's ``sim://`` source, its seed), each once."""
    with open(os.path.join(capture_dir, "capture.json"), encoding="utf-8") as fh:
        source = json.load(fh).get("source", "")
    scheme, scene_name, query = split_url(source) if "://" in source else ("", "", "")
    if scheme != "sim":
        raise SystemExit(f"{capture_dir}: not a simulated recording (its source is {source!r})")
    seed = int(urllib.parse.parse_qs(query).get("seed", ["0"])[0])
    scene = load_scene(scene_name, seed=seed)
    d = scene.wall_b - scene.wall_a
    keep = np.hypot(d[:, 0], d[:, 1]) >= MIN_SEGMENT_M
    return np.unique(np.round(np.arctan2(d[keep, 1], d[keep, 0]) % math.pi, 9))


def direction_errors(directions: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """Each of *directions* (rad, world; a line has no sense) minus the nearest of *walls* (rad),
    in [-pi/2, pi/2)."""
    diff = wrap_line(np.asarray(directions, float)[:, None] - walls[None, :])
    return diff[np.arange(len(diff)), np.argmin(np.abs(diff), axis=1)] if len(diff) else np.zeros(0)


def window_lines(poses: np.ndarray, statics: list[np.ndarray], config: WallMapConfig) -> list[tuple[float, float]]:
    """(world direction, stated std) rad of the lines in each window of ``window_frames`` frames of
    *statics* ((n, 2) m each, radar axes) placed by *poses* ((N, 3) x, y, yaw), over which the
    heading turned by at most ``match_span_rad``."""
    out = []
    frames = config.window_frames
    for k in range(frames - 1, len(statics)):
        span = poses[k - frames + 1:k + 1, 2]
        if span.max() - span.min() > config.match_span_rad:
            continue
        here = window_points([placed_points(statics[j], poses[j]) for j in range(k - frames + 1, k + 1)],
                             poses[k], config.max_range_m)
        if here is None:
            continue
        out += [(line.direction + poses[k, 2], line.std) for line in wall_lines(here, config)]
    return out


def sequence_lines(directory: str, config: EstimatorConfig) -> dict[str, np.ndarray]:
    """For the two placings ("true poses", "own poses"): (L, 2) each line's error against the
    scene's walls and its stated std, rad."""
    seq = sequences.load(directory)
    walls = scene_directions(directory)
    threshold = config.wall_map.static_threshold_mps
    statics, own = [], []
    for i, state, _, _ in run(seq, config):
        points = seq.points[i]
        statics.append(np.zeros((0, 2)) if points is None or not len(points) else
                       static_points(points, np.array([state.vx, state.vy]), threshold))
        own.append((state.x, state.y, state.yaw))
    out = {}
    for name, poses in (("true poses", sequences.truth(seq)), ("own poses", np.array(own))):
        lines = np.array(window_lines(poses, statics, config.wall_map)).reshape(-1, 2)
        out[name] = np.column_stack([direction_errors(lines[:, 0], walls), lines[:, 1]])
    return out


def summary(name: str, placing: str, lines: np.ndarray, near_deg: float) -> str:
    """One line of the table for *lines* ((L, 2) error, stated std rad)."""
    err, stated = np.degrees(lines[:, 0]), np.degrees(lines[:, 1])
    near = np.abs(err) < near_deg
    head = f"{name}  {placing:<10}  {len(err):5d} lines"
    if not near.any():
        return head + f", none within {near_deg:g} degrees of a wall"
    e = err[near]
    return (head + f", {near.sum():5d} within {near_deg:g} degrees: median |error| {np.median(np.abs(e)):.2f}, "
            f"RMS {math.sqrt(float(np.mean(e ** 2))):.2f}, mean {e.mean():+.2f}, stated {np.median(stated[near]):.2f}; "
            f"beyond {FAR_DEG:g}: {100.0 * np.mean(np.abs(err) > FAR_DEG):.1f} %")


def by_stated(lines: np.ndarray, near_deg: float, edges_deg=STATED_EDGES_DEG) -> list[str]:
    """For *lines* ((L, 2) error, stated std rad) within *near_deg* of a wall, one row per group of
    what they state (*edges_deg*): how many, their median and RMS error, the share off by more than
    a degree, and the RMS over the group's median stated std."""
    err, stated = np.degrees(np.abs(lines[:, 0])), np.degrees(lines[:, 1])
    near = err < near_deg
    err, stated = err[near], stated[near]
    rows = []
    for lo, hi in zip(edges_deg[:-1], edges_deg[1:]):
        k = (stated >= lo) & (stated < hi)
        if not k.any():
            continue
        rms = math.sqrt(float(np.mean(err[k] ** 2)))
        rows.append(f"  stating {lo:.1f}-{hi:.1f} degrees: {k.sum():5d} lines, median |error| "
                    f"{np.median(err[k]):.2f}, RMS {rms:.2f} ({rms / np.median(stated[k]):.1f} times the "
                    f"stated), beyond 1 degree {100.0 * np.mean(err[k] > 1.0):.0f} %")
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("sequences", nargs="+", metavar="SEQUENCE_DIR")
    parser.add_argument("--estimator-config", metavar="FILE.json", help="estimator settings over the defaults")
    parser.add_argument("--near", type=float, default=10.0, metavar="DEG",
                        help="a line this close to a wall direction is the wall's (default 10)")
    parser.add_argument("--by-stated", action="store_true",
                        help="the lines near a wall grouped by the standard deviation they state")
    args = parser.parse_args(argv)
    config = EstimatorConfig.load(args.estimator_config) if args.estimator_config else EstimatorConfig()
    every: dict[str, list[np.ndarray]] = {}
    for directory in args.sequences:
        name = os.path.basename(os.path.normpath(directory))
        for placing, lines in sequence_lines(directory, config).items():
            print(summary(name, placing, lines, args.near))
            every.setdefault(placing, []).append(lines)
    pooled = {placing: np.concatenate(parts) for placing, parts in every.items()}
    if len(args.sequences) > 1:
        for placing, lines in pooled.items():
            print(summary(f"all {len(args.sequences)}", placing, lines, args.near))
    if args.by_stated:
        for placing, lines in pooled.items():
            print(f"{placing}, by what each line states:")
            print("\n".join(by_stated(lines, args.near)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
