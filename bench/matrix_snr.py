"""What the robustness matrix's SNR axis means to the detections: per scene and scene SNR (the
scene's ``[radar] snr_db``), over the cached DSP products of the cells that differ from the base
cell by their SNR only (the shipped cfg, 0.8 m/s, 45 deg/s, the scene's movers, the radar on the
axis), the detected points a frame, their ``snr_db`` (median, 10th and 90th percentile over all
points) and each frame's strongest heatmap cell over its median cell (the median over the frames),
as docs/benchmarks.md gives them.

    python bench/matrix_snr.py [--data ~/.cache/radarodom/robustness]

The products are those ``bench/robustness_matrix.py`` cached (the newest of a cell's, where a
changed DSP left several); run it first, with ``--snr`` for the rows wanted.
"""

from __future__ import annotations

import argparse
import collections
import glob
import os
import re

import numpy as np

#: A cell's directory name (matrix_cells.SimCell.name) with its scene's key and the base's other axes.
CELL = re.compile(r"(?P<scene>[a-z]+)_s\d+_shipped_snr(?P<snr>-?[\d.]+)_v0\.8_w45_scene_L[\d.]+-[0-9a-f]+")


def rows(data: str) -> dict[tuple[str, float], dict[str, list[np.ndarray]]]:
    """(scene, SNR dB) -> the arrays of its cells: point SNRs, points a frame, peak over median (dB)."""
    out: dict = collections.defaultdict(lambda: collections.defaultdict(list))
    for cell in sorted(glob.glob(os.path.join(data, "seq", "*", ""))):
        m = CELL.fullmatch(os.path.basename(os.path.dirname(cell)))
        products = sorted(glob.glob(os.path.join(cell, "dsp-*.npz")), key=os.path.getmtime)
        if m is None or not products:
            continue
        with np.load(products[-1]) as z:
            power = z["intensity"].reshape(len(z["intensity"]), -1)  # (frames, cells), linear
            row = out[(m["scene"], float(m["snr"]))]
            row["snr_db"].append(z["points"]["snr_db"])
            row["points"].append(z["counts"])
            row["peak_db"].append(10 * np.log10(power.max(axis=1) / np.median(power, axis=1)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default=os.path.expanduser("~/.cache/radarodom/robustness"),
                        help="the matrix's cache (robustness_matrix.py --data)")
    data = parser.parse_args().data
    found = rows(data)
    if not found:
        raise SystemExit(f"matrix_snr.py: no DSP products of base or SNR cells under {data}/seq: run "
                         "bench/robustness_matrix.py first (--data for another cache)")
    print("| scene | scene SNR dB | cells | points a frame, median | point SNR dB, median (p10-p90) "
          "| peak over median, dB |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for (scene, snr) in sorted(found, key=lambda k: (k[0], -k[1])):
        r = {key: np.concatenate(v) for key, v in found[(scene, snr)].items()}
        snrs = "-" if not len(r["snr_db"]) else "{1:.1f} ({0:.1f}-{2:.1f})".format(
            *np.percentile(r["snr_db"], [10, 50, 90]))  # (no detection in the whole row: none to show)
        print(f"| {scene} | {snr:g} | {len(found[(scene, snr)]['points'])} | {np.median(r['points']):.0f} | "
              f"{snrs} | {np.median(r['peak_db']):.1f} |")


if __name__ == "__main__":
    main()
