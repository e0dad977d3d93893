"""A robustness-matrix cell's scene with some of its objects left out, recorded with the cell's own
seed, cfg, loop and fidelity: which object of a scene turns a straight or a turn (issue 20;
docs/heading.md, "Driving close past furniture").

    python bench/scene_edits.py room_s0_shipped_snr0_v0.8_w45_scene_L3 --list
    python bench/scene_edits.py CELL --without 4 --out DIR   # every object but number 4
    python bench/scene_edits.py CELL --only 4 --out DIR      # the walls and number 4 alone
    python bench/scene_edits.py CELL --only --out DIR        # the walls alone
    python bench/scene_edits.py CELL --flat --out DIR        # every scatterer at the radar's height
    python bench/scene_edits.py CELL --azimuth-hpbw 130 --out DIR   # a wider beam in azimuth
    python bench/scene_edits.py CELL --mirror --out DIR     # the scene and its loop mirrored left to right
    python bench/scene_edits.py CELL --mirror --noise-seed 1000 --out DIR   # ... with the noise drawn anew
    python bench/scene_edits.py CELL --turn-in-place-reversed --out DIR   # the loop's turn in place the other way
    python bench/heading_diagnosis.py DIR --straights 1      # then each straight, chain by chain

CELL is a simulated cell's name as bench/robustness_matrix.py writes it. The edited scene file is
written beside the recording (DIR.scene.json). Nothing is left out but what is named: the
recording is the cell's own, value for value, when no object is left out (radar-sim is
deterministic for a seed), so the differences are the objects'. ``--flat`` and the beam widths
edit the scene's radar instead (docs/heading.md, "The turns in place's length"): the scene file's
``flat`` and ``[radar]`` ``azimuth_hpbw_deg`` / ``elevation_hpbw_deg``. ``--mirror`` takes the scene
and its loop's turns to their mirror image (y -> -y; the walls' scatterers mirror one for one, the
objects', floor's and ceiling's are drawn anew in their mirrored places): a bias of the scene's
geometry changes sign with it, a handedness of the simulator, the DSP or the estimator does not
(docs/heading.md, "Straight drives still turn"). The mirrored cell's thermal noise is the cell's own
draw, frame for frame, unless ``--noise-seed`` draws it anew: the same noise in both is a part of
their errors that the mirror does not flip. ``--turn-in-place-reversed`` turns the loop's turn in
place the other way (the matrix's loops turn left on even seeds, right on odd ones; with ``--mirror``,
the mirrored loop's turn): the same scene, scatterers and noise, the same path up to the turn and after
it within 2-4 cm (the braking into the turn and the start after it, which
the turn overlaps, curve the other way), the radar facing the same way after it.
"""

from __future__ import annotations

import argparse
import copy
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402

from matrix_cells import SimCell, object_distance, scene_spec  # noqa: E402  (bench/ is not a package)
from robustness_matrix import simulate  # noqa: E402

from radarodom.driver.sim.scene import scene_from_dict  # noqa: E402
from radarodom.errors import ConfigError  # noqa: E402
from radarodom.tools import cli  # noqa: E402


def describe(index: int, obj: dict, path: np.ndarray | None = None) -> str:
    """One line naming a scene object: its number, its type, where it stands (m) and, given the
    radar's *path* (k, 2) m, how near the path passes it."""
    where = ", ".join(f"{key} {obj[key]}" for key in ("center", "a", "b", "size", "radius", "height", "yaw")
                      if key in obj)
    line = f"{index:3d}  {obj.get('type', '?'):9s} {where}" + ("  (occludes)" if obj.get("occludes") else "")
    distance = None if path is None else object_distance(obj, path)
    return line if distance is None else f"{line}; the loop passes {distance:.2f} m from it"


def radar_path(spec: dict) -> np.ndarray:
    """The radar's positions (k, 2) m along the scene table *spec*'s trajectory, as radar-sim drives it."""
    from radarodom.driver.sim.trajectory import from_spec
    trajectory = from_spec(spec["trajectory"])
    return np.column_stack([trajectory.x, trajectory.y])[::10]


def edited(spec: dict, without: list[int] | None = None, only: list[int] | None = None, *, flat: bool = False,
           beam: dict[str, float] | None = None) -> dict:
    """*spec* (a scene table) with the objects numbered in *without* left out, or all but those in
    *only* (an empty list: the walls alone); *flat*: every scatterer at the radar's height; *beam*:
    the ``[radar]`` table's beam widths to set (azimuth_hpbw_deg, elevation_hpbw_deg). ValueError
    naming a number the scene has no object for."""
    objects = spec.get("objects", [])
    named = (without or []) + (only or [])
    wrong = [i for i in named if not 0 <= i < len(objects)]
    if wrong:
        raise ValueError(f"no object numbered {', '.join(map(str, wrong))}: the scene's objects are "
                         f"0-{len(objects) - 1} (--list shows them)")
    if only is not None:
        keep = set(only)
    else:
        keep = set(range(len(objects))) - set(without or [])
    out = {**spec, "objects": [obj for i, obj in enumerate(objects) if i in keep]}
    if flat:
        out["flat"] = True
    if beam:
        out["radar"] = {**spec.get("radar", {}), **beam}
    return out


def _mirror_xy(p) -> list:
    return [p[0], -p[1], *p[2:]]


def mirrored(spec: dict) -> dict:
    """*spec* (a scene table) mirrored left to right about its x axis: walls, objects (a door's posts
    swapped, so that its recess stays behind it), movers' paths, the surfaces, and the trajectory's
    start, turns and mounting."""
    out = copy.deepcopy(spec)
    for wall in out.get("walls", []):
        wall["points"] = [_mirror_xy(p) for p in wall["points"]]
    for obj in out.get("objects", []):
        for key in ("center", "position"):
            if key in obj:
                obj[key] = _mirror_xy(obj[key])
        if "yaw" in obj:
            obj["yaw"] = -obj["yaw"]
        if obj.get("type") == "door":
            obj["a"], obj["b"] = _mirror_xy(obj["b"]), _mirror_xy(obj["a"])
    for mover in out.get("movers", []):
        mover["path"] = [_mirror_xy(p) for p in mover["path"]]
    if "surfaces" in out:
        lo, hi = out["surfaces"]["min"], out["surfaces"]["max"]
        out["surfaces"]["min"], out["surfaces"]["max"] = [lo[0], -hi[1]], [hi[0], -lo[1]]
    trajectory = out["trajectory"]
    for key in ("start", "mount"):
        if key in trajectory:
            x, y, yaw = trajectory[key]
            trajectory[key] = [x, -y, -yaw]
    for segment in trajectory.get("segments", []):
        for key in ("turn", "rotate"):
            if key in segment:
                segment[key] = -segment[key]
    if "waypoints" in trajectory:
        trajectory["waypoints"] = [_mirror_xy(p) for p in trajectory["waypoints"]]
    return out


def turned_in_place_reversed(spec: dict) -> dict:
    """*spec* with its loop's one turn in place (a matrix loop's ``rotate`` of 180 or -180 degrees)
    turned the other way: the radar faces the same way after it, and the rest of the path is the same
    within centimetres.
    ValueError for a trajectory without exactly one turn in place of 180 degrees either way."""
    out = copy.deepcopy(spec)
    turns = [seg for seg in out["trajectory"].get("segments", []) if "rotate" in seg]
    if len(turns) != 1 or abs(turns[0]["rotate"]) != 180:
        raise ValueError("--turn-in-place-reversed: the scene's trajectory has no single turn in place of 180 "
                         "degrees (a matrix loop has one)")
    turns[0]["rotate"] = -turns[0]["rotate"]
    return out


def _turn_in_place(spec: dict) -> str:
    rotate = next(seg["rotate"] for seg in spec["trajectory"]["segments"] if "rotate" in seg)
    return f", turned in place to the {'left' if rotate > 0 else 'right'}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("cell", metavar="CELL",
                        help="a simulated cell's name, e.g. room_s0_shipped_snr0_v0.8_w45_scene_L3")
    parser.add_argument("--list", action="store_true", help="list the scene's objects with their numbers")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--without", nargs="+", type=int, default=None, metavar="N", help="leave these objects out")
    group.add_argument("--only", nargs="*", type=int, default=None, metavar="N",
                       help="keep only these objects (none named: the walls alone)")
    parser.add_argument("--flat", action="store_true",
                        help="every scatterer at the radar's height: no elevation anywhere")
    parser.add_argument("--azimuth-hpbw", type=float, metavar="DEG",
                        help="the antennas' half-power beam width in azimuth (the simulator's: 100)")
    parser.add_argument("--elevation-hpbw", type=float, metavar="DEG",
                        help="the same in elevation (the simulator's: 40)")
    parser.add_argument("--mirror", action="store_true",
                        help="the scene and its loop mirrored left to right (y -> -y)")
    parser.add_argument("--turn-in-place-reversed", action="store_true",
                        help="the loop's turn in place the other way (to the right on even seeds, the left on odd)")
    parser.add_argument("--noise-seed", type=cli.non_negative_int, metavar="N",
                        help="radar-sim's --noise-seed: the thermal noise drawn anew (default: the cell's seed's)")
    parser.add_argument("--duration", type=cli.positive_float, metavar="S",
                        help="record the loop's first S seconds only (default: the whole loop)")
    parser.add_argument("--out", metavar="DIR", help="the recording's directory (replaced)")
    args = parser.parse_args(argv)
    try:
        cell = SimCell.from_name(args.cell)
    except ValueError as exc:
        parser.error(str(exc))
    spec = scene_spec(cell)
    if args.list:
        path = radar_path(spec)
        print("\n".join(describe(i, obj, path) for i, obj in enumerate(spec.get("objects", []))))
        return 0
    if not args.out:
        parser.error("--out DIR is needed to record (or --list to see the objects)")
    beam = {key: value for key, value in (("azimuth_hpbw_deg", args.azimuth_hpbw),
                                          ("elevation_hpbw_deg", args.elevation_hpbw)) if value is not None}
    try:
        spec = edited(spec, args.without, args.only, flat=args.flat, beam=beam)
        if args.mirror:
            spec = mirrored(spec)
        if args.turn_in_place_reversed:
            spec = turned_in_place_reversed(spec)
    except ValueError as exc:
        parser.error(str(exc))
    try:  # radar-sim's own check, before it runs: a beam width out of range, named
        scene_from_dict(spec, where=f"the edited scene of {cell.name}")
    except ConfigError as exc:
        parser.error(str(exc))
    simulate(spec, cell, os.path.abspath(args.out), noise_seed=args.noise_seed, duration_s=args.duration)
    radar = "".join([", flat" if args.flat else "", ", mirrored" if args.mirror else "",
                     _turn_in_place(spec) if args.turn_in_place_reversed else "",
                     "" if args.noise_seed is None else f", noise seed {args.noise_seed}",
                     "" if args.duration is None else f", its first {args.duration:g} s"]
                    + [f", {key} {value:g}" for key, value in beam.items()])
    print(f"{args.out}: {cell.name} with {len(spec['objects'])} object(s){radar}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
