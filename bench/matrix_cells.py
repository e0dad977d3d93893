"""The heading robustness matrix's cells (bench/robustness_matrix.py): the cfgs, where the loop
fits in each built-in scene, a simulated cell (scene, seed, cfg, SNR, speed, turn rate, movers,
mount, fidelity) and its scene file, and a ColoRadar run as a cell."""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = os.path.dirname(HERE)

#: The matrix's cfgs: name -> file (the shipped cfg and the variants in bench/cfgs/).
CFGS = {
    "shipped": os.path.join(PACKAGE, "configs", "awr1843_raw.cfg"),
    "2tx": os.path.join(HERE, "cfgs", "awr1843_2tx.cfg"),
    "128loops": os.path.join(HERE, "cfgs", "awr1843_128loops.cfg"),
    "slope60": os.path.join(HERE, "cfgs", "awr1843_slope60.cfg"),
}

#: Where the loop fits in each built-in scene: start (x, y) heading +x, the largest x the first
#: straight and moving turn may reach, the largest y the second straight may reach, and the path of
#: the person added with movers="people" (the lab has its own). The corridor's loop ends its
#: moving turn at x = 16 (the middle of its north branch): its start is placed backwards from there.
LAYOUT = {
    "corridor": {"start": None, "turn_x": 16.0, "y_max": 11.0, "person": [[2.0, -0.5], [14.0, -0.5]]},
    "room": {"start": (1.0, 0.8), "x_max": 7.2, "y_max": 5.2, "person": [[2.0, 4.6], [6.0, 4.6]]},
    "lab": {"start": (1.0, 3.0), "x_max": 9.0, "y_max": 7.2, "person": [[1.0, 4.0], [9.0, 4.0]]},
}


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
    def name(self) -> str:
        return (f"{self.scene}_s{self.seed}_{self.cfg}_snr{self.snr_db:g}_v{self.speed_mps:g}"
                f"_w{self.turn_rate_dps:g}_{self.movers}_L{self.straight_m:g}"
                + (f"_m{self.mount_m:g}" if self.mount_m else "") + ("_exact" if self.fidelity == "exact" else ""))


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
def loop_segments(scene: str, speed: float, turn_rate_dps: float, straight_m: float) -> tuple[list, list]:
    """(segments, start [x, y, yaw deg]) of the matrix's closed loop in *scene* (module text)."""
    lay = LAYOUT[scene]
    r = speed / math.radians(turn_rate_dps)
    if lay["start"] is None:
        l1 = min(straight_m, lay["turn_x"] - r + 0.5)
        x0, y0 = lay["turn_x"] - r - l1, 0.0
    else:
        (x0, y0) = lay["start"]
        l1 = min(straight_m, lay["x_max"] - x0 - r)
    l2 = min(straight_m, lay["y_max"] - y0 - r)
    if min(l1, l2) < 0.5:
        raise ValueError(f"{scene}: a loop at {speed} m/s and {turn_rate_dps} deg/s (radius {r:.2f} m) does not fit")
    segs = [{"pause": 1.0}, {"straight": l1, "speed": speed}, {"turn": 90, "radius": r, "speed": speed},
            {"straight": l2, "speed": speed}, {"rotate": 180, "rate": turn_rate_dps},
            {"straight": l2, "speed": speed}, {"turn": -90, "radius": r, "speed": speed},
            {"straight": l1, "speed": speed}, {"pause": 1.0}]
    return segs, [x0, y0, 0.0]


def scene_spec(cell: SimCell) -> dict:
    """The built-in scene's table with the cell's trajectory, SNR and movers."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    from importlib import resources
    text = resources.files("radarodom.driver.sim").joinpath("scenes", f"{cell.scene}.toml").read_text("utf-8")
    spec = tomllib.loads(text)
    segs, start = loop_segments(cell.scene, cell.speed_mps, cell.turn_rate_dps, cell.straight_m)
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
