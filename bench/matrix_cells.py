"""The heading robustness matrix's cells (bench/robustness_matrix.py): the cfgs, where the loop
fits in each built-in scene, a simulated cell (scene, seed, cfg, SNR, speed, turn rate, movers,
mount, fidelity) and its scene file, a ColoRadar run as a cell, and the command-line options
that select cells (robustness_matrix.py's and matrix_recordings.py's)."""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import math
import os
import re
import sys
from dataclasses import dataclass

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = os.path.dirname(HERE)

#: The matrix's cfgs: name -> file (the shipped cfg and the variants in bench/cfgs/).
CFGS = {
    "shipped": os.path.join(PACKAGE, "configs", "awr1843_raw.cfg"),
    "2tx": os.path.join(HERE, "cfgs", "awr1843_2tx.cfg"),
    "128loops": os.path.join(HERE, "cfgs", "awr1843_128loops.cfg"),
    "slope60": os.path.join(HERE, "cfgs", "awr1843_slope60.cfg"),
    # TI's SDK demo profiles' chirps: frames of 3-4 ms, Doppler bins of half a metre a second.
    "sdk2d": os.path.join(HERE, "cfgs", "awr1843_sdk2d.cfg"),
    "sdk3d": os.path.join(HERE, "cfgs", "awr1843_sdk3d.cfg"),
}

#: Where the loop fits in each built-in scene: its first straight runs along y = y0 toward +x and
#: its moving turn ends at x = turn_x, heading +y (the start is placed backwards from there, no
#: further back than x_min); the second straight reaches at most y_max; the path of the person
#: added with movers="people" (the lab has its own). Every loop keeps CLEARANCE_M from the walls
#: and the furniture (:func:`loop_segments` checks it): a radar driven through a pillar or a
#: table sees nothing, which no robot meets.
LAYOUT = {
    "corridor": {"x_min": -0.5, "y0": 0.0, "turn_x": 16.0, "y_max": 11.0, "person": [[2.0, -0.5], [14.0, -0.5]]},
    "room": {"x_min": 1.0, "y0": 0.6, "turn_x": 7.0, "y_max": 5.4, "person": [[2.0, 4.6], [6.0, 4.6]]},
    "lab": {"x_min": 1.0, "y0": 3.0, "turn_x": 6.0, "y_max": 7.0, "person": [[1.0, 4.0], [9.0, 4.0]]},
    "hall": {"x_min": 2.0, "y0": 3.6, "turn_x": 19.0, "y_max": 16.0, "person": [[8.0, 5.2], [18.0, 5.2]]},
}

#: The least distance, m, between the loop and a wall or the footprint of an object of the scene.
CLEARANCE_M = 0.25


_NUMBER = r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?"
#: :attr:`SimCell.name`'s pattern.
_NAME = re.compile(rf"(?P<scene>[a-z]+)_s(?P<seed>\d+)_(?P<cfg>\w+?)_snr(?P<snr>{_NUMBER})_v(?P<speed>{_NUMBER})"
                   rf"_w(?P<turn>{_NUMBER})_(?P<movers>scene|none|people)_L(?P<straight>{_NUMBER})"
                   rf"(?:_m(?P<mount>{_NUMBER}))?(?P<exact>_exact)?")


@dataclass(frozen=True)
class SimCell:
    """One simulated sequence of the matrix."""

    scene: str
    seed: int = 0
    cfg: str = "shipped"
    snr_db: float = 0.0
    speed_mps: float = 0.8
    turn_rate_dps: float = 45.0
    #: "scene" (as the built-in scene has them), "none" or "people" (the scene's and one more).
    movers: str = "scene"
    straight_m: float = 3.0
    #: The radar's lever arm ahead of the base's rotation axis, m (the scene's trajectory mount).
    mount_m: float = 0.0
    #: The simulator's fidelity (radar-sim --fidelity): "fast" records the matrix's hundreds of
    #: sequences several times quicker; docs/benchmarks.md compares it with "exact" on cells.
    fidelity: str = "fast"
    kind: str = "sim"

    @property
    def turn_in_place_deg(self) -> int:
        """The loop's turn in place, degrees: to the left (+180) on even seeds, to the right (-180)
        on odd ones, so that a row's six seeds turn half each way (since 2026-12-06: a matrix whose
        turns in place all went left put their direction's sign into the straight drives after them)."""
        return 180 if self.seed % 2 == 0 else -180

    @property
    def name(self) -> str:
        return (f"{self.scene}_s{self.seed}_{self.cfg}_snr{self.snr_db:g}_v{self.speed_mps:g}"
                f"_w{self.turn_rate_dps:g}_{self.movers}_L{self.straight_m:g}"
                + (f"_m{self.mount_m:g}" if self.mount_m else "") + ("_exact" if self.fidelity == "exact" else ""))

    @classmethod
    def from_name(cls, name: str) -> "SimCell":
        """The cell :attr:`name` names (``room_s0_shipped_snr0_v0.8_w45_scene_L3``); ValueError
        when *name* is not one."""
        m = _NAME.fullmatch(name)
        if m is None or m["scene"] not in LAYOUT or m["cfg"] not in CFGS:
            raise ValueError(f"{name!r} is not a simulated cell's name: SCENE_sSEED_CFG_snrDB_vMPS_wDPS_MOVERS_LM"
                             f"[_mM][_exact], SCENE one of {', '.join(LAYOUT)}, CFG one of {', '.join(CFGS)}")
        return cls(scene=m["scene"], seed=int(m["seed"]), cfg=m["cfg"], snr_db=float(m["snr"]),
                   speed_mps=float(m["speed"]), turn_rate_dps=float(m["turn"]), movers=m["movers"],
                   straight_m=float(m["straight"]), mount_m=float(m["mount"] or 0.0),
                   fidelity="exact" if m["exact"] else "fast")


@dataclass(frozen=True)
class ColoradarCell:
    """A ColoRadar run (``coloradar://``) through radar-capture's pipeline and the default estimator."""

    run: str
    options: str = "rate=max"
    kind: str = "coloradar"

    @property
    def name(self) -> str:
        return "coloradar_" + os.path.basename(os.path.normpath(self.run))

    @property
    def url(self) -> str:
        return f"coloradar://{os.path.abspath(self.run)}?{self.options}"


Cell = SimCell | ColoradarCell


# ------------------------------------------------------------------ scenes and trajectories
def loop_segments(scene: str, speed: float, turn_rate_dps: float, straight_m: float,
                  mount_m: float = 0.0, turn_in_place_deg: int = 180) -> tuple[list, list]:
    """(segments, start [x, y, yaw deg]) of the matrix's closed loop in *scene* (module text) for
    a radar *mount_m* ahead of the base's axis (the base's second straight is shortened by it, so
    that the radar, not the base, stops at y_max before turning in place), turning in place by
    *turn_in_place_deg* (180 to the left, -180 to the right); ValueError when it does not fit, or
    when the base or the radar passes nearer than CLEARANCE_M to a wall or an object."""
    if turn_in_place_deg not in (180, -180):
        raise ValueError(f"the loop's turn in place is 180 or -180 degrees, got {turn_in_place_deg:g}")
    lay = LAYOUT[scene]
    r = speed / math.radians(turn_rate_dps)
    l1 = min(straight_m, lay["turn_x"] - r - lay["x_min"])
    x0, y0 = lay["turn_x"] - r - l1, lay["y0"]
    l2 = min(straight_m, lay["y_max"] - y0 - r - max(mount_m, 0.0))
    if min(l1, l2) < 0.5:
        raise ValueError(f"{scene}: a loop at {speed} m/s and {turn_rate_dps} deg/s (radius {r:.2f} m) does not fit")
    segs = [{"pause": 1.0}, {"straight": l1, "speed": speed}, {"turn": 90, "radius": r, "speed": speed},
            {"straight": l2, "speed": speed}, {"rotate": turn_in_place_deg, "rate": turn_rate_dps},
            {"straight": l2, "speed": speed}, {"turn": -90, "radius": r, "speed": speed},
            {"straight": l1, "speed": speed}, {"pause": 1.0}]
    start = [x0, y0, 0.0]
    from radarodom.driver.sim.trajectory import from_segments
    table = _scene_table(scene)
    paths = [(0.0, "a loop")]
    if mount_m:
        paths.append((mount_m, f"the radar {mount_m:g} m ahead of its base's axis on a loop"))
    for mount, who in paths:
        clearance, what = loop_clearance(table, from_segments(segs, start=start, mount=(mount, 0.0, 0.0)))
        if clearance < CLEARANCE_M:
            raise ValueError(f"{scene}: {who} at {speed} m/s and {turn_rate_dps} deg/s passes {clearance:.2f} m from "
                             f"{what} (at least {CLEARANCE_M} m)")
    return segs, start


def _scene_table(scene: str) -> dict:
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    from importlib import resources
    return tomllib.loads(resources.files("radarodom.driver.sim").joinpath("scenes", f"{scene}.toml").read_text("utf-8"))


def loop_clearance(table: dict, trajectory) -> tuple[float, str]:
    """The least distance (m; negative: inside) from the *trajectory* (the simulator's, as it
    drives it) to the scene *table*'s walls and the footprints of its boxes and cylinders, and
    what it is."""
    path = np.column_stack([trajectory.x, trajectory.y])[::10]  # every 10 ms: under 2 cm apart
    found = [(math.inf, "nothing")]
    for wall in table.get("walls", []):
        corners = np.asarray(wall["points"], float)
        for a, b in zip(corners[:-1], corners[1:]):
            ab = b - a
            f = np.clip((path - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0)
            found.append((float(np.min(np.hypot(*(path - a - f[:, None] * ab).T))), f"the wall {a.tolist()}-{b.tolist()}"))
    for obj in table.get("objects", []):
        distance = object_distance(obj, path)
        if distance is not None:
            found.append((distance, f"the {obj['type']} at {np.asarray(obj['center'], float).tolist()}"))
    return min(found, key=lambda item: item[0])


def object_distance(obj: dict, path: np.ndarray) -> float | None:
    """The least distance (m; negative: inside) from the points *path* (k, 2) m to the footprint
    of the scene object *obj* (a box's or a cylinder's; None for other objects)."""
    centre = np.asarray(obj.get("center", (math.nan, math.nan)), float)
    if obj.get("type") == "cylinder":
        distance = np.hypot(*(path - centre).T) - obj.get("radius", 0.2)
    elif obj.get("type") == "box":
        yaw = math.radians(obj.get("yaw", 0.0))
        c, s = math.cos(yaw), math.sin(yaw)
        rel = path - centre
        along, across = np.abs(c * rel[:, 0] + s * rel[:, 1]), np.abs(-s * rel[:, 0] + c * rel[:, 1])
        half = np.asarray(obj["size"][:2], float) / 2
        outside = np.hypot(np.maximum(along - half[0], 0.0), np.maximum(across - half[1], 0.0))
        distance = np.where((along < half[0]) & (across < half[1]),
                            -np.minimum(half[0] - along, half[1] - across), outside)
    else:
        return None
    return float(np.min(distance))


def scene_spec(cell: SimCell) -> dict:
    """The built-in scene's table with the cell's trajectory, SNR and movers."""
    spec = _scene_table(cell.scene)
    segs, start = loop_segments(cell.scene, cell.speed_mps, cell.turn_rate_dps, cell.straight_m, cell.mount_m,
                                cell.turn_in_place_deg)
    spec["trajectory"] = {"start": start, "height": spec.get("trajectory", {}).get("height", 0.4), "segments": segs,
                          "mount": [float(cell.mount_m), 0.0, 0.0]}
    spec.setdefault("radar", {})["snr_db"] = float(cell.snr_db)
    if cell.movers == "none":
        spec["movers"] = []
    elif cell.movers == "people":
        extra = {"type": "person", "path": LAYOUT[cell.scene]["person"], "speed": 1.2, "rcs": 0.5}
        if extra["path"] not in [m.get("path") for m in spec.get("movers", [])]:
            spec["movers"] = spec.get("movers", []) + [extra]
    elif cell.movers != "scene":
        raise ValueError(f"movers must be scene, none or people, got {cell.movers!r}")
    spec["name"] = cell.name
    return spec


# ------------------------------------------------------------------ selecting cells
BASE = SimCell(scene="corridor")


def cells(args) -> list[Cell]:
    out: list[Cell] = []
    axes = {"cfg": args.cfgs, "snr_db": args.snr, "speed_mps": args.speeds, "turn_rate_dps": args.turn_rates,
            "movers": args.movers, "mount_m": args.mounts}
    for scene, seed in itertools.product(args.scenes, args.seeds):
        base = dataclasses.replace(BASE, scene=scene, seed=seed, straight_m=args.straight,
                                   fidelity=getattr(args, "fidelity", "fast"))
        if args.design == "product":
            variants = [dataclasses.replace(base, **dict(zip(axes, combo)))
                        for combo in itertools.product(*axes.values())]
        else:
            first = {k: v[0] for k, v in axes.items()}
            variants = [dataclasses.replace(base, **first)]
            for axis, values in axes.items():
                variants += [dataclasses.replace(variants[0], **{axis: v}) for v in values[1:]]
        for v in variants:
            try:
                loop_segments(v.scene, v.speed_mps, v.turn_rate_dps, v.straight_m, v.mount_m, v.turn_in_place_deg)
            except ValueError as exc:
                print(f"skipped {v.name}: {exc}", file=sys.stderr)
                continue
            if v not in out:
                out.append(v)
    # Base cells first: a partial run already covers every scene and seed.
    out.sort(key=lambda c: sum(getattr(c, axis) != values[0] for axis, values in axes.items()))
    out += [ColoradarCell(run) for run in args.coloradar or []]
    return out


#: The axes' values where not given on the command line, and --smoke's preset in their place.
AXES = {"scenes": ["corridor", "room", "lab"], "seeds": list(range(6)), "cfgs": list(CFGS),
        "snr": [0.0, -5.0, -10.0, -15.0], "speeds": [0.8, 0.3, 1.5], "turn_rates": [45.0, 30.0, 90.0],
        "movers": ["scene", "none", "people"], "mounts": [0.0, 0.3], "straight": 3.0}
SMOKE = {"scenes": ["corridor", "room", "lab"], "seeds": [0], "cfgs": ["shipped"], "snr": [0.0], "speeds": [0.8],
         "turn_rates": [45.0], "movers": ["scene"], "mounts": [0.0], "straight": 2.0}


def _number(low: float | None, what: str, *, whole: bool = False, above: bool = True):
    """An argparse type: a finite number (a whole one with *whole*) above *low* (at least it
    without *above*; None: any); argparse names the option before the value it refuses."""
    def parse(text: str):
        try:
            value = int(text) if whole else float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or low is not None and (value <= low if above else value < low):
            raise argparse.ArgumentTypeError(f"{text!r}: {what}")
        return value
    return parse


positive_int = _number(0, "a whole number above 0", whole=True)


def _run_directory(text: str) -> str:
    if not os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text!r}: no such directory (a ColoRadar run's)")
    return text


def add_cell_arguments(parser: argparse.ArgumentParser) -> None:
    """The options that select the cells (and --data, where their recordings are), as
    :func:`selected_cells` reads them; bench/matrix_recordings.py takes them too.  The axes' options
    default to None: :func:`selected_cells` fills what was not given (:data:`AXES`, or with --smoke
    :data:`SMOKE`), so that --smoke --scenes room runs the room alone."""
    preset = ", ".join(f"{k}={v}" for k, v in SMOKE.items())
    parser.add_argument("--smoke", action="store_true", help=f"the small preset, for the axes not given: {preset}")
    parser.add_argument("--design", choices=["star", "product"], default="star")

    def axis(name: str, **kw) -> None:
        text = f"{kw.pop('help', '')} (default: {AXES[name[2:].replace('-', '_')]})".strip()
        parser.add_argument(name, default=None, **kw, help=text)

    axis("--scenes", nargs="+", choices=sorted(LAYOUT))
    axis("--seeds", nargs="+", type=_number(0, "a whole number >= 0", whole=True, above=False))
    axis("--cfgs", nargs="+", choices=list(CFGS))
    axis("--snr", nargs="+", type=_number(None, "a finite number of dB"), metavar="DB")
    axis("--speeds", nargs="+", type=_number(0, "a speed above 0 m/s"), metavar="M/S")
    axis("--turn-rates", nargs="+", type=_number(0, "a turn rate above 0 deg/s"), metavar="DEG/S")
    axis("--movers", nargs="+", choices=["scene", "none", "people"])
    axis("--mounts", nargs="+", type=_number(None, "a finite lever arm in m"), metavar="M",
         help="the radar's lever arm ahead of the rotation axis")
    parser.add_argument("--fidelity", choices=["fast", "exact"], default="fast", help="the simulator's (radar-sim)")
    axis("--straight", type=_number(0, "a length above 0 m"), metavar="M", help="the loop's straights (at most)")
    parser.add_argument("--coloradar", nargs="+", type=_run_directory, metavar="RUN_DIR",
                        help="ColoRadar runs as more cells")
    parser.add_argument("--no-sim", action="store_true", help="only the --coloradar cells")
    parser.add_argument("--data", default=os.path.expanduser("~/.cache/radarodom/robustness"))


def selected_cells(args) -> list[Cell]:
    """The cells :func:`add_cell_arguments`' options select: the axes not given filled in on
    *args* from --smoke's preset or the defaults."""
    for k, v in (SMOKE if args.smoke else AXES).items():
        if getattr(args, k) is None:
            setattr(args, k, v)
    todo = cells(args)
    return [c for c in todo if isinstance(c, ColoradarCell)] if args.no_sim else todo
