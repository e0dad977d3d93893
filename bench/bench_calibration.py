"""What the channel calibration costs the DSP: the chain with a board's line against the
identity line, on the same frame.

    python bench/bench_calibration.py [--rounds 5] [--repeats 60] [--json]

The chain is the one radar-capture builds (``FrameProcessor(cfg)`` and
``HeatmapMaker(processor, doppler_cells=features.doppler_cells)``: points and the range-azimuth heatmap) on a
frame of the shipped cfg (256 samples x 64 loops x 3 TX x 4 RX) from the simulator's
corridor, once with the shipped cfg's identity ``compRangeBiasAndRxChanPhase`` (which
multiplies nothing) and once with a line (every virtual antenna times its coefficient: the
detections' samples and their Doppler neighbours, the heatmap's whole azimuth row, where the
TDM phases alone leave the first TX slot untouched).  Two cases:

- ``same work``: a perfect board's frame, the line one common phase on every antenna: the same
  detections and angles, so the difference is the calibration's arithmetic alone;
- ``a board``: the uncalibrated simulated board's frame, uncorrected against corrected by its
  own line (the detections differ too, and uncorrected it keeps one azimuth a cell).

The chains are timed alternately, run by run, so that both see the same machine; each round
gives the two medians and their ratio, the summary the ratios' median over the rounds (the
goal: within 5 %, a ratio of at most 1.05).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as radar-capture runs

import numpy as np  # noqa: E402

from radarodom.calibration import ChannelCalibration  # noqa: E402
from radarodom.cfg import RadarConfig, shipped_config_path  # noqa: E402
from radarodom.driver.sim.board import Board, load_board  # noqa: E402
from radarodom.driver.sim.scene import load_scene  # noqa: E402
from radarodom.driver.sim.simulator import Simulator  # noqa: E402
from radarodom.dsp.heatmap import HeatmapMaker  # noqa: E402
from radarodom.dsp.processor import FrameProcessor  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402


def chain(cfg: RadarConfig, calibrated: bool | None):
    proc = FrameProcessor(cfg, calibrated=calibrated)
    maker = HeatmapMaker(proc, doppler_cells=EstimatorConfig().features.doppler_cells)

    def run(cube):
        result = proc.process(cube)
        maker.range_azimuth(result.spectrum)
        return len(result.points)
    return run


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=60, help="runs of each chain a round")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    cfg = RadarConfig.from_file(shipped_config_path())
    board = load_board("uncalibrated")
    common = ChannelCalibration(0.0, np.full((3, 4), np.exp(0.5j)))
    cases = {}
    # What the source would say: the perfect board's identity line fits it (so both chains look
    # for two azimuths a cell); the uncalibrated board's does not (one azimuth, against two).
    for name, frame_board, line, fits in (("same work", Board(), common, True),
                                          ("a board", board, board.calibration(), None)):
        sim = Simulator(cfg, load_scene("corridor"), board=frame_board, fidelity="fast")
        cube = sim.layout.decode(sim.frame(sim.num_frames // 2).raw)
        cases[name] = _rounds(chain(cfg, fits), chain(cfg.replace(line.to_command()), fits), cube, args.rounds,
                              args.repeats)
    result = {"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
                         f"Python {platform.python_version()}", "date": time.strftime("%Y-%m-%d"),
              "fft": FrameProcessor(cfg).fft_backend, "cases": cases}
    if args.json:
        print(json.dumps(result, indent=1))
        return 0
    print(f"{result['machine']}, FFT {result['fft']}, {result['date']}\n")
    print("| case | identity line, ms | the line, ms | ratio, median of rounds (range) |\n| --- | ---: | ---: | ---: |")
    for name, rounds in cases.items():
        ratios = [r["ratio"] for r in rounds]
        print(f"| {name} | {statistics.median(r['identity_ms'] for r in rounds):.2f} | "
              f"{statistics.median(r['line_ms'] for r in rounds):.2f} | {statistics.median(ratios):.3f} "
              f"({min(ratios):.3f}-{max(ratios):.3f}) |")
    return 0


def _rounds(identity, calibrated, cube, rounds: int, repeats: int) -> list[dict]:
    for _ in range(5):  # warm-up: plans, caches, page faults
        identity(cube), calibrated(cube)
    out = []
    for _ in range(rounds):
        times = {"identity": [], "line": []}
        for _ in range(repeats):
            for name, fn in (("identity", identity), ("line", calibrated)):
                t0 = time.perf_counter()
                fn(cube)
                times[name].append(1e3 * (time.perf_counter() - t0))
        a, b = statistics.median(times["identity"]), statistics.median(times["line"])
        out.append({"identity_ms": a, "line_ms": b, "ratio": b / a})
    return out


if __name__ == "__main__":
    raise SystemExit(main())
