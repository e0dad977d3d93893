"""Detection: does radarodom miss any reflector OpenRadar's CA-CFAR finds, and do
noise-only frames give no more false points than the configured Pfa?

1. Scenes.  Four still scenes made by the simulator (shipped cfg: 256 samples, 64 loops,
   3 TX x 4 RX, 4.88 cm range bins; sensor at the origin, 0.4 m up, ``pause`` only, so
   every reflector sits in the zero-Doppler bin), seven corner reflectors each (2-8 m,
   +/-60 deg): in each, pairs 3-6 range bins apart at different azimuths and 6-20 dB
   apart in strength (the weak one inside the strong one's CFAR training window), and a
   pair at the same range 40-50 deg apart; scene "wall" adds a wall 8.3 m ahead behind
   them.  Each seed gives other reflector phases and noise (frame 0 of
   ``Simulator(seed=s)``; scene k takes seeds 1000 k ...).
2. Truth per reflector in the TI frame: range, azimuth atan2(x, y), elevation, range bin
   (range / resolution), and strength: the expected map SNR (the scene's per-sample SNR,
   RCS, R^-4, the simulator's antenna pattern, samples x loops integration, the windows'
   processing losses) and that relative to the scene's strongest reflector.
3. radarodom, only through its public API: ``FrameProcessor(cfg, dsp).process(cube).points``
   with the DspConfig of ``--dsp-config FILE.json`` (default: ``DspConfig()``).  Found: a
   point within one range bin and 4 deg azimuth.  False: a point not within 2 bins and
   8 deg of any reflector (in scene "wall", points from 2 bins before the wall on are
   counted as wall clutter instead).
4. OpenRadar 1.0.1 (``mmwave.dsp``, imported without its ``__init__``, which needs
   scikit-learn for code we do not use) on the same cube, its AWR1843 demo path
   (demo/visualizer/main.py): ``range_processing`` on (chirps in TX-slot order, rx,
   samples), ``doppler_processing(num_tx_antennas=3, clutter_removal_enabled=False,
   accumulate=True)`` (sum over the virtual array of log2|X|, (range, doppler), Doppler not
   fftshifted), the demo's int64 cast, ``ca_`` along Doppler (l_bound 1.5) and along range
   (l_bound 2.5), guard 4, noise 16, mode 'wrap', ANDed, then ``prune_to_peaks(...,
   reserve_neighbor=True)``.  ``ca_`` is called once on the 2-D matrix (scipy's
   convolve1d runs along the last axis: the same numbers as the demo's apply_along_axis).
   Windows: ours where OpenRadar has them (hann, hamming, blackman, bartlett, rect).
   The demo's later ``range_based_pruning`` is left out: its peakVal limits are absolute
   sums of log2 counts, tuned on mis-read (uint16) ADC data.  Found: a detection in the
   zero-Doppler bin within one range bin of the reflector's; a detection counts for one
   reflector only (a maximum matching, stronger reflectors first), so two reflectors in
   one range bin are one found unless two cells are detected.  OpenRadar has no peak
   grouping in range: a reflector lights 3-4 contiguous cells, so it is credited with
   both of a same-range pair (marked "within a bin of" in the tables).  radarodom is
   matched the same one-to-one way.
5. Noise-only: ``--noise-frames`` cubes of complex Gaussian noise: radarodom's points and
   detected cells per frame against the bound range_cfar.pfa x the map cells in the
   detection range (the range pass alone; the Doppler pass and peak grouping only remove
   cells), with the Poisson probability of seeing that many at the bound; OpenRadar's
   detections per frame, and how often a 3-bin zero-Doppler window 2-8 m holds one by
   chance (what "found by OpenRadar" is worth on a reflector too weak to see).

    python bench/detection_vs_openradar.py [--dsp-config FILE.json] [--seeds 16]
        [--noise-frames 200] [--json FILE]
"""

from __future__ import annotations

import argparse
import datetime
import importlib.metadata
import importlib.util
import json
import math
import os
import platform
import subprocess
import sys
import time

import numpy as np
import scipy
import scipy.optimize
import scipy.signal
import scipy.stats

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_dsp import import_openradar_dsp  # noqa: E402  (bench/ is not a package)

from radarodom.cfg import RadarConfig, shipped_config_path  # noqa: E402
from radarodom.driver.sim.physics import AntennaPattern  # noqa: E402
from radarodom.driver.sim.scene import scene_from_dict  # noqa: E402
from radarodom.driver.sim.simulator import Simulator  # noqa: E402
from radarodom.dsp.config import DspConfig  # noqa: E402
from radarodom.dsp.processor import FrameProcessor  # noqa: E402

HEIGHT = 0.4  # sensor height, m
SNR_DB = -20.0  # scene per-sample SNR of 1 m^2 at 5 m: the weakest reflectors end 15-20 dB over the noise
NOISE_COUNTS = 5.0  # ADC counts RMS per I and Q (the simulator's default)
FOUND_BINS, FOUND_DEG = 1.0, 4.0
FALSE_BINS, FALSE_DEG = 2.0, 8.0
#: name -> (wall's forward distance in m or None, reflectors (range m, + range bins, azimuth deg
#: (positive right, TI), height m, RCS dBsm)).  "+ bins" places a pair's partner exactly k bins off.
SCENES = {
    "near": (None, [(2.50, 0, -10, 0.40, 15), (2.50, 4, 20, 0.50, 3), (3.60, 0, -35, 0.40, 10),
                    (3.60, 0, 15, 0.30, 10), (4.60, 0, 0, 0.40, 20), (4.60, -5, -40, 0.60, 4),
                    (5.80, 0, 30, 0.40, 6)]),
    "mid": (None, [(3.00, 0, 25, 0.40, 12), (3.00, 3, -5, 0.40, 5), (4.20, 0, -50, 0.50, 6),
                   (4.20, 6, 10, 0.40, 20), (5.50, 0, -20, 0.40, 10), (5.50, 0, 20, 0.40, 6),
                   (7.00, 0, 45, 0.40, 14)]),
    "far": (None, [(4.00, 0, 0, 0.40, 18), (4.00, 5, 30, 0.40, 4), (5.20, 0, -30, 0.40, 16),
                   (5.20, 4, 5, 0.30, 2), (6.50, 0, -55, 0.40, 12), (6.50, 0, -15, 0.50, 12),
                   (7.80, 0, 20, 0.40, 10)]),
    "wall": (8.3, [(2.20, 0, 5, 0.40, 12), (2.20, 3, -25, 0.40, 2), (3.40, 0, 40, 0.40, 10),
                   (3.40, 0, -10, 0.40, 8), (5.00, 0, -15, 0.40, 18), (5.00, 6, 25, 0.40, 0),
                   (7.90, 0, 10, 0.40, 10)]),
}
#: DspConfig window names -> OpenRadar's Window member (None: no window).
OR_WINDOWS = {"hann": "HANNING", "hanning": "HANNING", "hamming": "HAMMING", "blackman": "BLACKMAN",
              "bartlett": "BARTLETT", "rect": None, "boxcar": None, "none": None}


def window_loss_db(name: str, n: int) -> float:
    """SNR loss of a window (its coherent gain squared over its noise gain), dB."""
    w = np.ones(n) if name in ("rect", "boxcar", "none") else scipy.signal.get_window(name, n, fftbins=False)
    return 10 * math.log10(w.sum() ** 2 / (n * (w * w).sum()))


def build_scene(name: str, cfg: RadarConfig, dsp: DspConfig) -> tuple[dict, np.ndarray]:
    """The scene's spec (for scene_from_dict) and its truth (structured, one row per reflector)."""
    wall, refl = SCENES[name]
    res = cfg.range_resolution_m
    objects, rows = [], []
    for r0, k, az_deg, z, rcs in refl:
        r, az = r0 + k * res, math.radians(az_deg)
        rho = math.sqrt(r * r - (z - HEIGHT) ** 2)  # horizontal distance
        fwd, left = rho * math.cos(az), -rho * math.sin(az)  # world: x forward, y left
        objects.append({"type": "corner_reflector", "position": [fwd, left, z], "rcs_dbsm": rcs})
        x_ti, y_ti, z_ti = -left, fwd, z - HEIGHT  # TI frame: x right, y boresight, z up
        rows.append((x_ti, y_ti, z_ti, rcs))
    t = np.array(rows)
    rng = np.linalg.norm(t[:, :3], axis=1)
    truth = np.empty(len(t), [("range", "f8"), ("azimuth", "f8"), ("elevation", "f8"), ("bin", "f8"),
                              ("snr_db", "f8"), ("rel_db", "f8")])
    truth["range"], truth["bin"] = rng, rng / res
    truth["azimuth"], truth["elevation"] = np.arctan2(t[:, 0], t[:, 1]), np.arcsin(t[:, 2] / rng)
    gain = AntennaPattern().amplitude(truth["azimuth"], truth["elevation"])
    loss = window_loss_db(dsp.range_window, cfg.num_samples) + window_loss_db(dsp.doppler_window, cfg.num_loops)
    truth["snr_db"] = (SNR_DB + t[:, 3] - 40 * np.log10(rng / 5.0) + 20 * np.log10(gain)
                       + 10 * math.log10(cfg.num_samples * cfg.num_loops) + loss)
    truth["rel_db"] = truth["snr_db"] - truth["snr_db"].max()
    spec = {"name": name, "radar": {"snr_db": SNR_DB, "noise_counts": NOISE_COUNTS}, "objects": objects,
            "trajectory": {"height": HEIGHT, "segments": [{"pause": 3.0}]}}
    if wall is not None:
        # sigma0 1, ten times the built-in scenes' walls, so that at this SNR its returns stand
        # 5-15 dB over the noise (8.3-9.7 m), the last reflector 8-11 bins in front of it.
        spec["walls"] = [{"points": [[wall, -5.0], [wall, 5.0]], "sigma0": 1.0}]
    return spec, truth


def matched(allowed: np.ndarray, rel_db: np.ndarray) -> np.ndarray:
    """Which reflectors (rows of *allowed*, reflectors x detections) get a detection of their
    own: a maximum one-to-one matching, ties going to the stronger reflectors."""
    found = np.zeros(allowed.shape[0], bool)
    if allowed.shape[1]:
        weight = np.where(allowed, 1000.0 + rel_db[:, None], 0.0)  # count first, then strength
        rows, cols = scipy.optimize.linear_sum_assignment(weight, maximize=True)
        found[rows[allowed[rows, cols]]] = True
    return found


class OpenRadar:
    """OpenRadar's demo detection (module docstring, 4) on our cubes."""

    def __init__(self, dsp_module, cfg: RadarConfig, dsp: DspConfig) -> None:
        from mmwave.dsp.utils import Window

        self.m, self.cfg = dsp_module, cfg
        self.windows, names = {}, []
        for what, name in (("range", dsp.range_window), ("doppler", dsp.doppler_window)):
            member = OR_WINDOWS.get(name, "HANNING")  # a window OpenRadar lacks: Hann, reported
            self.windows[what] = None if member is None else getattr(Window, member)
            names.append(f"{what} {member or 'none'}" + ("" if name in OR_WINDOWS else f" (it has no {name})"))
        self.window_names = ", ".join(names)
        self.prune_error = None

    def detect(self, cube: np.ndarray) -> np.ndarray:
        """(range bin, Doppler bin) per detection, (n, 2); Doppler bin 0 is zero velocity."""
        dsp = self.m
        frame = cube.reshape(-1, self.cfg.num_rx, self.cfg.num_samples)  # chirps in TX-slot order
        rc = dsp.range_processing(frame, window_type_1d=self.windows["range"])
        det, _ = dsp.doppler_processing(rc, num_tx_antennas=self.cfg.num_tx_slots, clutter_removal_enabled=False,
                                        window_type_2d=self.windows["doppler"], accumulate=True)
        s = det.astype(np.int64)  # the demo's cast: its noise floors are truncated integers
        thr_doppler, _ = dsp.ca_(s, l_bound=1.5, guard_len=4, noise_len=16, mode="wrap")
        thr_range, _ = dsp.ca_(s.T, l_bound=2.5, guard_len=4, noise_len=16, mode="wrap")
        cells = np.argwhere((det > thr_doppler) & (det > thr_range.T))
        if self.prune_error is None:
            obj = np.zeros(len(cells), [("rangeIdx", "<i4"), ("dopplerIdx", "<i4"), ("peakVal", "<f4")])
            obj["rangeIdx"], obj["dopplerIdx"] = cells[:, 0], cells[:, 1]
            obj["peakVal"] = s[cells[:, 0], cells[:, 1]]
            try:
                kept = dsp.prune_to_peaks(obj, det, det.shape[1], reserve_neighbor=True)
                return np.column_stack([kept["rangeIdx"], kept["dopplerIdx"]])
            except Exception as exc:  # noqa: BLE001 - numpy 2 breakage: report, keep the raw cells
                self.prune_error = repr(exc)
        return cells


def run_scenes(args, cfg, dsp, proc, orad) -> list[dict]:
    res = cfg.range_resolution_m
    out = []
    for index, name in enumerate(SCENES):
        spec, truth = build_scene(name, cfg, dsp)
        wall = SCENES[name][0]
        n = len(truth)
        hits = {k: np.zeros(n, int) for k in ("radarodom", "openradar", "or_only", "neither")}
        false_pts = clutter_pts = or_dets = or_zero = 0
        for seed in range(1000 * index, 1000 * index + args.seeds):  # no two scenes share a noise draw
            sim = Simulator(cfg, scene_from_dict(spec, seed=seed, where=name), seed=seed)
            cube = sim.layout.decode(sim.frame(0).raw)
            pts = proc.process(cube).points
            dr = np.abs(pts["range"][None, :] - truth["range"][:, None]) / res  # (reflectors, points)
            da = np.degrees(np.abs(pts["azimuth"][None, :] - truth["azimuth"][:, None]))
            ours = matched((dr <= FOUND_BINS) & (da <= FOUND_DEG), truth["rel_db"])
            near = ((dr <= FALSE_BINS) & (da <= FALSE_DEG)).any(axis=0)
            is_clutter = pts["range"] >= wall - FALSE_BINS * res if wall else np.zeros(len(pts), bool)
            false_pts += int((~near & ~is_clutter).sum())
            clutter_pts += int((~near & is_clutter).sum())
            theirs = np.zeros(n, bool)
            if orad is not None:
                det = orad.detect(cube)
                zero = det[det[:, 1] == 0, 0]  # range bins of zero-Doppler detections
                or_dets, or_zero = or_dets + len(det), or_zero + len(zero)
                theirs = matched(np.abs(zero[None, :] - truth["bin"][:, None]) <= FOUND_BINS, truth["rel_db"])
            hits["radarodom"] += ours
            hits["openradar"] += theirs
            hits["or_only"] += theirs & ~ours
            hits["neither"] += ~theirs & ~ours
        reflectors = [{"id": f"{name}{i + 1}", **{k: float(truth[k][i]) for k in truth.dtype.names},
                       **{k: int(v[i]) for k, v in hits.items()},
                       "same_cell_as": [f"{name}{j + 1}" for j in range(n)
                                        if j != i and abs(truth["bin"][j] - truth["bin"][i]) <= 1.0]}
                      for i in range(n)]
        out.append({"scene": name, "wall_m": wall, "frames": args.seeds, "reflectors": reflectors,
                    "false_points": false_pts, "clutter_points": clutter_pts,
                    "openradar_detections": or_dets, "openradar_zero_doppler": or_zero})
    return out


def run_noise(args, cfg, dsp, proc, orad) -> dict:
    rng = np.random.default_rng(12345)
    points, cells, or_dets, or_chance = [], [], [], []
    lo, hi = np.searchsorted(np.arange(cfg.num_samples) * cfg.range_resolution_m, [2.0, 8.0])
    for _ in range(args.noise_frames):
        cube = (rng.standard_normal(cfg.cube_shape, np.float32)
                + 1j * rng.standard_normal(cfg.cube_shape, np.float32)) * np.float32(NOISE_COUNTS)
        pts = proc.process(cube).points
        points.append(len(pts))
        cells.append(len(np.unique(np.column_stack([pts["range_bin"], pts["doppler_bin"]]), axis=0)))
        if orad is not None:
            det = orad.detect(cube)
            or_dets.append(len(det))
            row = np.zeros(cfg.num_samples + 2, bool)
            row[det[det[:, 1] == 0, 0] + 1] = True  # padded by one bin each side
            window_hit = row[:-2] | row[1:-1] | row[2:]  # any detection within one bin of each bin
            or_chance.append(window_hit[lo:hi].mean())
    # The bound: the range pass's Pfa over every map cell a point can come from.
    lo_m, hi_m = getattr(proc, "detection_range_m", (dsp.min_range_m, dsp.max_range_m or cfg.max_range_m))
    n_cells = int(((proc.range_m >= lo_m) & (proc.range_m <= hi_m)).sum()) * proc.n_doppler
    pfa = None if dsp.ti_like else dsp.range_cfar.pfa
    out = {"frames": args.noise_frames, "points_per_frame": float(np.mean(points)),
           "cells_per_frame": float(np.mean(cells)), "max_points": int(np.max(points)), "map_cells": n_cells,
           "pfa": pfa, "bound_per_frame": None, "p_at_bound": None,
           "openradar_per_frame": float(np.mean(or_dets)) if or_dets else None,
           "openradar_chance_hit": float(np.mean(or_chance)) if or_chance else None}
    if pfa is not None:
        out["bound_per_frame"] = pfa * n_cells
        # P(at least this many cells in all frames | Poisson at the bound): small means "above the bound".
        out["p_at_bound"] = float(scipy.stats.poisson.sf(sum(cells) - 1, pfa * n_cells * args.noise_frames))
    return out


def machine() -> dict:
    cpu = platform.machine()
    if os.path.exists("/proc/cpuinfo"):
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            cpu = next((ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), cpu)
    try:  # the code measured (the detection is being changed): its commit, "-dirty" if edited
        git = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True, text=True, check=False,
                             cwd=os.path.dirname(sys.modules["radarodom"].__file__), timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        git = None
    try:
        openradar = importlib.metadata.version("openradar")
    except importlib.metadata.PackageNotFoundError:
        openradar = None
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "openradar": openradar, "radarodom_git": git}


def _row(*cells) -> str:
    return "| " + " | ".join(map(str, cells)) + " |"


def print_report(r: dict) -> None:
    m, o, nz = r["machine"], r["openradar"], r["noise"]
    print(f"# Detection: radarodom vs OpenRadar CA-CFAR\n\n{r['date']}; {m['cpu']}, {m['cores']} cores; Python "
          f"{m['python']}, numpy {m['numpy']}, scipy {m['scipy']}, openradar {m['openradar']}; radarodom git "
          f"{m['radarodom_git']}; {r['runtime_s']:.0f} s\ncfg: {r['cfg']['path']}, cube {tuple(r['cfg']['cube_shape'])}, "
          f"range bin {r['cfg']['range_bin_m'] * 100:.2f} cm\nDspConfig ({r['dsp_source']}; FFT backend "
          f"{r['fft_backend']}): `{json.dumps(r['dsp_config'])}`")
    print(f"OpenRadar: {o['unavailable'] or 'windows: ' + o['windows'] + '; ' + o['pipeline']}"
          + (f"; prune_to_peaks FAILED ({o['prune_error']}), raw CFAR cells used" if o.get("prune_error") else ""))
    print(f"Scenes: {r['seeds']} seeds each, per-sample SNR {SNR_DB:g} dB for 1 m^2 at 5 m\n")
    keys = ("radarodom", "openradar", "or_only", "neither")
    print(_row("scene", "reflectors x seeds", "radarodom found", "OpenRadar found", "OpenRadar only", "neither",
               "radarodom false pts/frame", "wall clutter pts/frame", "OpenRadar dets/frame (zero-Doppler)"))
    print("|---" * 9 + "|")
    total = np.zeros(5, int)
    for s in r["scenes"]:
        f, c = s["frames"], [sum(x[k] for x in s["reflectors"]) for k in keys]
        total += [len(s["reflectors"]) * f, *c]
        print(_row(s["scene"], len(s["reflectors"]) * f, *c, f"{s['false_points'] / f:.2f}",
                   f"{s['clutter_points'] / f:.1f}" if s["wall_m"] else "-",
                   f"{s['openradar_detections'] / f:.0f} ({s['openradar_zero_doppler'] / f:.0f})"))
    print(_row("**all**", *total[:3], f"**{total[3]}**", total[4], "", "", "") + "\n")
    print(_row("reflector", "range m", "bin", "azimuth deg", "elev. deg", "exp. SNR dB", "rel. dB", "radarodom",
               "OpenRadar", "OpenRadar only", "within a bin of"))
    print("|---" * 11 + "|")
    for s in r["scenes"]:
        for x in s["reflectors"]:
            print(_row(x["id"], f"{x['range']:.3f}", f"{x['bin']:.1f}", f"{math.degrees(x['azimuth']):+.0f}",
                       f"{math.degrees(x['elevation']):+.1f}", f"{x['snr_db']:.1f}", f"{x['rel_db']:+.1f}",
                       f"{x['radarodom']}/{s['frames']}", f"{x['openradar']}/{s['frames']}", x["or_only"],
                       ", ".join(x["same_cell_as"]) or "-"))
    refl = [x for s in r["scenes"] for x in s["reflectors"]]
    only = [x for x in refl if x["or_only"]]
    print(f"\n**Reflectors OpenRadar finds and radarodom misses: {len(only)} reflectors, {total[3]} reflector-frames**")
    for x in only:
        print(f"- {x['id']}: {x['range']:.3f} m (bin {x['bin']:.1f}), {math.degrees(x['azimuth']):+.0f} deg, "
              f"{x['rel_db']:+.1f} dB rel. (exp. SNR {x['snr_db']:.1f} dB): in {x['or_only']} of {r['seeds']} frames"
              + (f"; within a range bin of {', '.join(x['same_cell_as'])}" if x["same_cell_as"] else ""))
    print("\nMissed by both: " + ("; ".join(f"{x['id']} ({x['range']:.3f} m, {math.degrees(x['azimuth']):+.0f} deg, "
                                            f"{x['rel_db']:+.1f} dB) in {x['neither']} frames"
                                            for x in refl if x["neither"]) or "none"))
    bound = (f"{nz['bound_per_frame']:.3f} ({nz['pfa']:g} x {nz['map_cells']}); measured "
             f"{nz['cells_per_frame'] / nz['bound_per_frame']:.2f}x" if nz["bound_per_frame"] else "n/a (no pfa)")
    oc, od = nz["openradar_chance_hit"], nz["openradar_per_frame"]
    print(f"\n**Noise-only, {nz['frames']} frames** (complex Gaussian, {NOISE_COUNTS:g} counts RMS per I and Q)\n")
    print(_row("radarodom points/frame", "cells/frame", "max points", "bound/frame (pfa x cells)",
               "P(cells >= seen at bound)", "OpenRadar dets/frame", "OpenRadar chance hit, 3-bin zero-Doppler window"))
    print("|---" * 7 + "|")
    print(_row(f"{nz['points_per_frame']:.3f}", f"{nz['cells_per_frame']:.3f}", nz["max_points"], bound,
               "-" if nz["p_at_bound"] is None else f"{nz['p_at_bound']:.3g}", "-" if od is None else f"{od:.0f}",
               "-" if oc is None else f"{oc:.0%}"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dsp-config", help="DspConfig JSON (DspConfig.load); default: DspConfig()")
    parser.add_argument("--seeds", type=int, default=16, help="frames (seeds) per scene")
    parser.add_argument("--noise-frames", type=int, default=200)
    parser.add_argument("--json", help="also write the results to this file")
    args = parser.parse_args()
    t0 = time.perf_counter()
    cfg_path = shipped_config_path()
    cfg = RadarConfig.from_file(cfg_path)
    dsp = DspConfig.load(args.dsp_config) if args.dsp_config else DspConfig()
    proc = FrameProcessor(cfg, dsp, calibrated=True)  # the simulator's ideal board: the identity line fits it
    module, why = import_openradar_dsp()
    orad = OpenRadar(module, cfg, dsp) if module else None
    result = {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"), "machine": machine(),
        "cfg": {"path": cfg_path, "cube_shape": list(cfg.cube_shape), "range_bin_m": cfg.range_resolution_m},
        "dsp_source": args.dsp_config or "default DspConfig()", "dsp_config": dsp.to_dict(),
        "fft_backend": getattr(proc, "fft_backend", None), "seeds": args.seeds,
        "openradar": {"unavailable": why, "windows": orad.window_names if orad else None,
                      "pipeline": "range_processing, doppler_processing(3 TX, no clutter removal, accumulate), "
                                  "int64 cast, ca_ Doppler l_bound 1.5 & range l_bound 2.5 (guard 4, noise 16, "
                                  "wrap), prune_to_peaks(reserve_neighbor=True)"},
    }
    result["scenes"] = run_scenes(args, cfg, dsp, proc, orad)
    result["noise"] = run_noise(args, cfg, dsp, proc, orad)
    result["openradar"]["prune_error"] = orad.prune_error if orad else None
    result["runtime_s"] = time.perf_counter() - t0
    print_report(result)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=2)
            fh.write("\n")


if __name__ == "__main__":
    main()
