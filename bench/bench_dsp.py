"""DSP speed: how long does radarodom take from a raw cube to points and a heatmap?

One frame of 256 samples x 128 loops x 3 TX (masks 1, 4, 2) x 4 RX, made by the
simulator (built-in scene ``corridor``, frame ``--frame``; synthesis is not
timed) and decoded with RawLayout, is processed over and over in this process
after a warm-up; every figure is the median of ``--repeats`` runs (default 30).

1. radarodom, default DspConfig (Hann windows, OS range + CA Doppler CFAR,
   peak grouping, TDM compensation, one FFT thread, FFT backend "auto": FFTW
   when pyFFTW is installed, the ``fftw`` extra, else scipy.fft): the whole
   chain, ``FrameProcessor.process(cube)`` +
   ``HeatmapMaker.range_azimuth(spectrum)``, and each stage on its own
   (range_fft, doppler_fft, power, cfar_peaks, points, heatmap), so one sees
   where the time goes.  The whole chain is also run with
   ``DspConfig(workers=2)`` and, when FFTW is the default, with
   ``DspConfig(fft="scipy")``.
1b. The chain exactly as ``radar-capture`` builds it (radarodom.pipeline,
   ``FrameProducts.for_estimator``): ``FrameProcessor(cfg)`` with the default DspConfig, and
   ``HeatmapMaker(processor, doppler_cells=EstimatorConfig().features.doppler_cells)``
   (the fast heatmap mode, 800 cells with the default k = 200), or
   ``HeatmapMaker(processor)`` (the full map, what ``--heatmap-out`` gets).
   The goal (5 ms) is about the fast one.  Median, min, p10 and p90 of
   ``--repeats`` runs each.  With pyFFTW installed the fast chain is also run
   on scipy.fft (``fast_scipy``), what a plain ``pip install`` gets.
2. OpenRadar (PyPI ``openradar`` 1.0.1, import name ``mmwave``) on the same
   frame, the partial chain of its own demo (demo/visualizer/main.py):
   ``range_processing`` (windowed range FFT), ``doppler_processing``
   (TX separation, windowed Doppler FFT, log2|X| summed over the virtual
   array) and its CFAR (``np.apply_along_axis(dsp.ca_, ...)`` along Doppler and
   along range, the two masks and ``argwhere``).  Same Hann windows as ours,
   clutter removal off as in our default (``--openradar-clutter`` turns it on,
   as the demo has it).  No angles, no heatmap: compare it with our partial
   chain (range_fft + doppler_fft + power + cfar_peaks).
3. Anchors, same run: a bare ``scipy.fft.fft`` of the same sizes on complex64
   (range: 256 points over the samples axis; Doppler: 128 points over the
   loops axis) with workers=2 and workers=1, ``numpy.fft.fft`` of the same,
   and (with pyFFTW) the same two transforms planned by FFTW, one thread.  The
   2-D anchor (range then Doppler) of a backend is the floor of any
   range-Doppler chain on it.  Anchors are measured first
   and again last (the heap, hence page faults on fresh outputs, differs); the
   lower median of the two is the anchor.

Ratios: "x OpenRadar" is OpenRadar's time over ours (above 1: we are faster);
"x anchor" is our time over the matching one-thread FFT anchor of the backend
in use (range and Doppler rows: their own 1-D anchor; every other row: the 2-D
anchor).

OpenRadar is imported for comparison only, with one work-around: its
``mmwave/__init__.py`` imports ``mmwave.clustering`` (needs scikit-learn),
``mmwave.tracking`` and ``mmwave.dataloader``, none of which this benchmark
uses.  We register an empty package module ``mmwave`` whose ``__path__`` is the
installed package directory, so that ``import mmwave.dsp`` loads only
``mmwave/dsp`` and never runs ``mmwave/__init__.py``.  ``mmwave.dsp`` itself
imports cleanly on numpy 2: the removed aliases it uses (``np.complex`` in
angle_estimation, ``np.int`` in ZoomFFT) sit inside functions we do not call,
and it does not use numba, so no numpy alias is patched.

    python bench/bench_dsp.py [--repeats 30] [--frame N] [--json] [--env-sweep]

``--env-sweep`` runs the whole benchmark again in fresh processes: as is, with
``OPENBLAS_NUM_THREADS=1``, and with glibc's malloc told to keep blocks of up to
32 MiB in the heap (``GLIBC_TUNABLES``; a probe of the cost of page faults on
fresh temporaries, not a recommended setting), and reports each.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import os
import platform
import statistics
import subprocess
import sys
import time
import types

import numpy as np
import scipy
import scipy.fft

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.sim.scene import load_scene
from radarodom.driver.sim.simulator import Simulator
from radarodom.dsp.cfar_peaks import cfar_peaks
from radarodom.dsp.config import DspConfig
from radarodom.dsp.fft import fftw_available
from radarodom.dsp.heatmap import HeatmapMaker
from radarodom.dsp.processor import FrameProcessor
from radarodom.estimator.config import EstimatorConfig
from radarodom.rawframe import RawLayout

from dsp_report import print_table, rows_of  # bench/ is not a package: the script's folder is on the path


def bench_config() -> RadarConfig:
    """The shipped profile (77 GHz, idle 100 us, ramp 40 us, 96 MHz/us, 256 samples at
    8 Msps) with 128 loops of TX1, TX3, TX2 instead of 64: 384 chirps x 140 us = 53.8 ms
    of chirping in a 100 ms frame."""
    cfg = RadarConfig.from_file(shipped_config_path())
    return cfg.replace(dataclasses.replace(cfg.frame, num_loops=128))


SCENE = "corridor"
GOAL_MS = 5.0


def capture_doppler_cells() -> int:
    """The heatmap's fast mode as radar-capture sets it: dominant Doppler for the
    doppler_cells strongest cells (FeatureConfig.doppler_cells: 4 k, k the Top-k features)."""
    return EstimatorConfig().features.doppler_cells


def _times_ms(fn, repeats: int, warmup: int = 3) -> list[float]:
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t) * 1e3)
    return times


def _median_ms(fn, repeats: int, warmup: int = 3) -> float:
    return statistics.median(_times_ms(fn, repeats, warmup))


def _summary_ms(times: list[float]) -> dict:
    return {"median": statistics.median(times), "min": min(times),
            "p10": float(np.percentile(times, 10)), "p90": float(np.percentile(times, 90))}


def import_openradar_dsp():
    """``mmwave.dsp`` without running ``mmwave/__init__.py`` (see the module docstring);
    (module, None) or (None, reason)."""
    spec = importlib.util.find_spec("mmwave")
    if spec is None or not spec.submodule_search_locations:
        return None, "openradar is not installed (pip install openradar)"
    if "mmwave" not in sys.modules:
        pkg = types.ModuleType("mmwave")
        pkg.__path__ = list(spec.submodule_search_locations)
        sys.modules["mmwave"] = pkg
    try:
        from mmwave import dsp
    except Exception as exc:  # noqa: BLE001 - report any import failure, do not crash the bench
        return None, f"import mmwave.dsp failed: {exc!r}"
    return dsp, None


def _openradar_version() -> str | None:
    try:
        from importlib.metadata import version

        return version("openradar")
    except Exception:  # noqa: BLE001
        return None


def make_cube(cfg: RadarConfig, frame: int | None) -> tuple[np.ndarray, dict]:
    sim = Simulator(cfg, load_scene(SCENE, seed=0), seed=0)
    i = sim.num_frames // 2 if frame is None else frame
    t = time.perf_counter()
    f = sim.frame(i)
    sim_ms = (time.perf_counter() - t) * 1e3
    cube = RawLayout.from_config(cfg).decode(f.raw)
    return cube, {"source": f"simulator, scene {SCENE!r}, frame {i} of {sim.num_frames}",
                  "paths": f.num_paths, "simulate_ms": sim_ms}


def bench_radarodom(cfg: RadarConfig, cube: np.ndarray, repeats: int, workers: int = 1, fft: str = "auto") -> dict:
    # The simulator's ideal board: its identity line fits (Source.calibrated), as radar-capture on sim:// has it.
    proc = FrameProcessor(cfg, DspConfig(workers=workers, fft=fft), calibrated=True)
    maker = HeatmapMaker(proc)
    prm = proc.params

    def chain():
        res = proc.process(cube)
        maker.range_azimuth(res.spectrum)

    chain_times = _times_ms(chain, repeats)
    out = {"chain": statistics.median(chain_times)}
    spread = {"min": min(chain_times), "p10": float(np.percentile(chain_times, 10)),
              "p90": float(np.percentile(chain_times, 90))}
    res = proc.process(cube)
    n_points = len(res.points)
    rs = proc.range_fft(cube).copy()
    # doppler_fft may overwrite its input (scipy) or copies it into its buffer first (FFTW:
    # ~0.1 ms more than in the chain, where the range FFT's buffer is its input).
    spec = proc.doppler_fft(rs.copy()).copy()
    power = proc.power(spec).copy()
    def cfar(p):  # the processor's detection: the CFAR at the map's peaks in the detection range
        return cfar_peaks(p, prm.range_cfar, prm.doppler_cfar, range_bins=proc._range_ok)

    det = cfar(power)
    keep = proc._range_ok[det.range_idx]
    d_idx, r_idx, snr, noise = det.doppler_idx[keep], det.range_idx[keep], det.snr_db[keep], det.noise[keep]
    out["range_fft"] = _median_ms(lambda: proc.range_fft(cube), repeats)
    out["doppler_fft"] = _median_ms(lambda: proc.doppler_fft(rs), repeats)
    out["power"] = _median_ms(lambda: proc.power(spec), repeats)
    out["cfar"] = _median_ms(lambda: cfar(power), repeats)
    out["points"] = _median_ms(lambda: proc.points(spec, d_idx, r_idx, snr, noise), repeats)
    out["heatmap"] = _median_ms(lambda: maker.range_azimuth(spec), repeats)
    fast_maker = HeatmapMaker(proc, doppler_cells=capture_doppler_cells())
    out["heatmap_fast"] = _median_ms(lambda: fast_maker.range_azimuth(spec), repeats)
    out["chain_fast"] = _median_ms(lambda: fast_maker.range_azimuth(proc.process(cube).spectrum), repeats)
    out["partial_chain"] = _median_ms(lambda: cfar(proc.power(proc.doppler_fft(proc.range_fft(cube)))), repeats)
    return {"ms": out, "chain_spread_ms": spread, "detections": len(det), "points": n_points}


def bench_capture_chain(cfg: RadarConfig, cube: np.ndarray, repeats: int, backends: list[str]) -> dict:
    """The whole chain as radar-capture builds it (module docstring, 1b): fast and full
    heatmap modes, each with its own processor and maker (their buffers), run in turns;
    "fast" and "full" with the default DspConfig, "fast_scipy" etc. forcing another FFT backend."""
    cells = capture_doppler_cells()
    out = {"doppler_cells": cells, "fft": FrameProcessor(cfg).fft_backend}
    runs = [(mode, doppler_cells, "auto") for mode, doppler_cells in (("fast", cells), ("full", None))]
    runs += [(f"fast_{b}", cells, b) for b in backends if b != out["fft"]]
    for mode, doppler_cells, fft in runs:
        proc = FrameProcessor(cfg, DspConfig(fft=fft), calibrated=True)  # the ideal board, as sim:// says
        maker = HeatmapMaker(proc, doppler_cells=doppler_cells)
        out[mode] = _summary_ms(_times_ms(lambda: maker.range_azimuth(proc.process(cube).spectrum), repeats))
        spec = proc.process(cube).spectrum
        out[mode]["heatmap"] = _median_ms(lambda: maker.range_azimuth(spec), repeats)
    return out


def bench_openradar(dsp, cfg: RadarConfig, cube: np.ndarray, repeats: int, clutter: bool) -> dict:
    from mmwave.dsp.utils import Window

    n_tx = cfg.num_tx_slots
    # OpenRadar's frame layout: (chirps in TX order, rx, samples); ours reshapes to it.
    frame = np.ascontiguousarray(cube.reshape(-1, cfg.num_rx, cfg.num_samples))
    win = Window.HANNING

    def range_stage():
        return dsp.range_processing(frame, window_type_1d=win)

    def doppler_stage(radar_cube):
        return dsp.doppler_processing(radar_cube, num_tx_antennas=n_tx, clutter_removal_enabled=clutter,
                                      interleaved=True, window_type_2d=win, accumulate=True)

    def cfar_stage(det_matrix):
        # As demo/visualizer/main.py: CA along Doppler and along range, both masks, argwhere.
        fft2d_sum = det_matrix.astype(np.int64)
        thr_d, _ = np.apply_along_axis(func1d=dsp.ca_, axis=0, arr=fft2d_sum.T, l_bound=1.5,
                                       guard_len=4, noise_len=16)
        thr_r, _ = np.apply_along_axis(func1d=dsp.ca_, axis=0, arr=fft2d_sum, l_bound=2.5,
                                             guard_len=4, noise_len=16)
        mask = (det_matrix > thr_d.T) & (det_matrix > thr_r)
        return np.argwhere(mask)

    def chain():
        cfar_stage(doppler_stage(range_stage())[0])

    rc = range_stage()
    det_matrix, _ = doppler_stage(rc)
    peaks = cfar_stage(det_matrix)
    out = {
        "range": _median_ms(range_stage, repeats),
        "doppler": _median_ms(lambda: doppler_stage(rc), repeats),
        "cfar": _median_ms(lambda: cfar_stage(det_matrix), repeats),
        "partial_chain": _median_ms(chain, repeats),
    }
    return {"ms": out, "detections": len(peaks), "range_cube_dtype": str(rc.dtype),
            "clutter_removal": clutter}


def bench_anchors(cube: np.ndarray, repeats: int) -> dict:
    x = np.ascontiguousarray(cube)  # complex64 (loops, tx, rx, samples)
    out = {}
    for w in (2, 1):
        out[f"scipy_range_w{w}"] = _median_ms(lambda w=w: scipy.fft.fft(x, axis=-1, workers=w), repeats)
        out[f"scipy_doppler_w{w}"] = _median_ms(lambda w=w: scipy.fft.fft(x, axis=0, workers=w), repeats)
        out[f"scipy_2d_w{w}"] = _median_ms(
            lambda w=w: scipy.fft.fft(scipy.fft.fft(x, axis=-1, workers=w), axis=0, workers=w, overwrite_x=True),
            repeats)
    out["numpy_range"] = _median_ms(lambda: np.fft.fft(x, axis=-1), repeats)
    out["numpy_doppler"] = _median_ms(lambda: np.fft.fft(x, axis=0), repeats)
    out["numpy_2d"] = _median_ms(lambda: np.fft.fft(np.fft.fft(x, axis=-1), axis=0), repeats)
    if fftw_available():
        import pyfftw

        # Planned out of place, as the processor plans them (FFTW_ESTIMATE, one thread).
        src, mid, dst = (pyfftw.empty_aligned(x.shape, np.complex64) for _ in range(3))
        src[...] = x
        rng = pyfftw.FFTW(src, mid, axes=(3,), flags=("FFTW_ESTIMATE",), threads=1)
        dop = pyfftw.FFTW(mid, dst, axes=(0,), flags=("FFTW_ESTIMATE",), threads=1)
        out["fftw_range_w1"] = _median_ms(rng.execute, repeats)
        out["fftw_doppler_w1"] = _median_ms(dop.execute, repeats)
        out["fftw_2d_w1"] = _median_ms(lambda: (rng.execute(), dop.execute()), repeats)
    return out


def machine_info() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            cpu = next((ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), cpu)
    except OSError:
        pass
    try:
        deps = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
        blas = deps.get("openblas configuration") or deps.get("name")
    except Exception:  # noqa: BLE001 - older numpy: no dict mode
        blas = None
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "openradar": _openradar_version(), "blas": blas,
            "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS"),
            "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS")}


def run(args) -> dict:
    cfg = bench_config()
    cube, source = make_cube(cfg, args.frame)
    anchors_first = bench_anchors(cube, args.repeats)
    backends = ["scipy", "fftw"] if fftw_available() else ["scipy"]
    ours = bench_radarodom(cfg, cube, args.repeats)
    ours["fft"] = FrameProcessor(cfg).fft_backend
    ours_w2 = bench_radarodom(cfg, cube, args.repeats, workers=2)
    ours_scipy = bench_radarodom(cfg, cube, args.repeats, fft="scipy") if ours["fft"] != "scipy" else None
    capture = bench_capture_chain(cfg, cube, args.repeats, backends)
    dsp, why = import_openradar_dsp()
    theirs = bench_openradar(dsp, cfg, cube, args.repeats, args.openradar_clutter) if dsp else None
    anchors_last = bench_anchors(cube, args.repeats)
    # Measured first and last (the heap differs): a floor is the lower of the two.
    anchors = {k: min(anchors_first[k], anchors_last[k]) for k in anchors_first}
    return {"machine": machine_info(), "cube_shape": list(cube.shape), "frame": source,
            "repeats": args.repeats, "goal_ms": GOAL_MS, "radarodom": ours, "radarodom_workers2": ours_w2,
            "radarodom_scipy": ours_scipy,
            "capture_chain": capture,
            "openradar": theirs, "openradar_unavailable": why, "anchors": anchors,
            "anchors_first": anchors_first, "anchors_last": anchors_last}


#: Environments of --env-sweep.  The glibc one keeps freed blocks of up to 32 MiB in the heap
#: (no mmap/munmap, so no fresh page faults, per temporary array): a probe of how much of the
#: time is the allocator's, not a setting we ship.
SWEEP = (
    ("default", {}),
    ("OPENBLAS_NUM_THREADS=1", {"OPENBLAS_NUM_THREADS": "1"}),
    ("GLIBC_TUNABLES mmap_threshold=32MiB", {
        "GLIBC_TUNABLES": "glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=1073741824"}),
)


def env_sweep(args) -> dict:
    """The benchmark in fresh processes, with and without OPENBLAS_NUM_THREADS=1."""
    out = {}
    for name, extra in SWEEP:
        env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "GLIBC_TUNABLES")}
        env.update(extra)
        cmd = [sys.executable, os.path.abspath(__file__), "--json", "--repeats", str(args.repeats)]
        if args.frame is not None:
            cmd += ["--frame", str(args.frame)]
        if args.openradar_clutter:
            cmd.append("--openradar-clutter")
        out[name] = json.loads(subprocess.run(cmd, env=env, check=True, capture_output=True,
                                             text=True).stdout)["result"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--frame", type=int, default=None, help="simulator frame (default: the middle one)")
    parser.add_argument("--openradar-clutter", action="store_true",
                        help="OpenRadar with its mean-subtraction clutter removal on (its demo's setting)")
    parser.add_argument("--env-sweep", action="store_true",
                        help="run in fresh processes: as is, OPENBLAS_NUM_THREADS=1, glibc malloc tunables")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if args.env_sweep:
        sweep = env_sweep(args)
        if args.json:
            print(json.dumps({k: {"result": v, "rows": rows_of(v)} for k, v in sweep.items()}, indent=2))
            return
        for name, result in sweep.items():
            print(f"=== {name}")
            print_table(result)
            print()
        print("summary, whole chain ms (full map: default / workers=2; as radar-capture builds it: fast / full;"
              " 2-D anchor of the default backend, one thread):")
        for name, result in sweep.items():
            cc = result["capture_chain"]
            print(f"  {name:<40} {result['radarodom']['ms']['chain']:7.2f} / "
                  f"{result['radarodom_workers2']['ms']['chain']:7.2f}; {cc['fast']['median']:7.2f} / "
                  f"{cc['full']['median']:7.2f}; {result['anchors'][result['radarodom']['fft'] + '_2d_w1']:5.2f}")
        return
    result = run(args)
    if args.json:
        print(json.dumps({"result": result, "rows": rows_of(result)}, indent=2))
        return
    print_table(result)


if __name__ == "__main__":
    main()
