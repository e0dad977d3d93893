"""Heading robustness matrix (issue 20): the default estimator on many simulated sequences.

    python bench/robustness_matrix.py [--smoke] [--design star|product] [--scenes corridor room lab]
        [--seeds 0 1 2 3 4 5] [--cfgs shipped 2tx 128loops slope60 sdk2d sdk3d] [--snr 0 -5 -10 -15]
        [--speeds 0.3 0.8 1.5] [--turn-rates 30 60 90] [--movers none people] [--mounts 0 0.3] [--straight 3]
        [--coloradar RUN_DIR ...] [--workers N | --cluster ADDRESS] [--data DIR] [--out DIR]

A cell is one sequence: a scene, a seed, a cfg, an SNR, a speed, a turn rate, with or without
walking people, the radar on the base's rotation axis or ahead of it (:class:`SimCell`), or a ColoRadar run read through ``coloradar://``
(:class:`ColoradarCell`). Simulated cells drive a closed loop made for the matrix inside the
scene: pause, straight, a moving left turn of 90 degrees (radius speed / turn rate), straight, a
turn in place of 180 degrees at the turn rate (to the left on even seeds, to the right on odd
ones), straight back, a moving right turn, straight back, pause (:func:`loop_segments`). The SNR
is the scene's ``[radar] snr_db`` (per-sample SNR of a 1 m^2 target 5 m away on boresight; the
built-in scenes have 0 dB).

``--design star`` (default) varies one axis at a time around the base cell (shipped cfg, 0 dB,
0.8 m/s, 45 deg/s, the scene's own movers), for every scene and seed; ``--design product``
takes every combination of the values given. ``--smoke`` is a small preset (three scenes, one
seed, short loops) for the axes not given (``--smoke --scenes room``: the room alone).

Each cell runs in a worker: the sequence is recorded with ``radar-sim`` (once), put through the
DSP (once, cached beside it by bench/sequences.py; then the recording's ADC samples are dropped
unless ``--keep-adc``, and recorded again if a changed DSP needs them), the default estimator runs on it and the
heading metrics (:mod:`radarodom.estimator.heading_metrics`) compare it with the ground truth,
and its drift parts say what made the drift (``drift_parts``: each kind of frame's yaw errors
alone, and the translation's).
A cell's result is cached in ``DATA/results/`` under a key of its parameters and a fingerprint
of the simulator's, the DSP's and the estimator's sources: a rerun computes only what changed.
Workers: a local process pool (``--workers``, default the CPU count), or with ``--cluster
ADDRESS`` a running Dask distributed scheduler (matrix_cluster.py: the scheduler and the workers
started with this clone's bench/ on their path, the workers with radarodom installed and --data
at the same path).

Writes OUT/robustness.md (a table per cell) and OUT/robustness.json.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import hashlib
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from matrix_cells import (CFGS, LAYOUT, Cell, ColoradarCell, SimCell, positive_int,  # noqa: E402,F401
                          add_cell_arguments, cells, loop_segments, scene_spec, selected_cells)


# ------------------------------------------------------------------ fingerprints and caching
def _digest_tree(digest, folder: str) -> None:
    for root, dirs, files in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith((".py", ".toml")):
                path = os.path.join(root, name)
                with open(path, "rb") as fh:
                    digest.update(os.path.relpath(path, folder).encode() + b"\0" + fh.read())


def sim_fingerprint() -> str:
    """The simulator's sources (with its scenes and boards) and radar-sim's."""
    import radarodom
    digest = hashlib.sha256()
    root = os.path.dirname(radarodom.__file__)
    _digest_tree(digest, os.path.join(root, "driver", "sim"))
    with open(os.path.join(root, "tools", "radar_sim.py"), "rb") as fh:
        digest.update(fh.read())
    return digest.hexdigest()[:16]


def fingerprint() -> str:
    """What makes a cell's result: simulator, DSP (bench/sequences.py's fingerprint), estimator, this file."""
    import radarodom
    import sequences
    digest = hashlib.sha256((sim_fingerprint() + sequences.dsp_fingerprint()).encode())
    _digest_tree(digest, os.path.join(os.path.dirname(radarodom.__file__), "estimator"))
    with open(os.path.abspath(__file__), "rb") as fh:
        digest.update(fh.read())
    return digest.hexdigest()[:16]


def cell_key(cell: Cell, fp: str) -> str:
    """A cell's key under *fp*: its parameters and, for a simulated cell, the scene file the
    simulator is given (its loop included: a changed layout records anew)."""
    body = json.dumps(dataclasses.asdict(cell), sort_keys=True)
    if isinstance(cell, SimCell):
        body += json.dumps(scene_spec(cell), sort_keys=True)
        with open(CFGS[cell.cfg], "rb") as fh:
            body += hashlib.sha256(fh.read()).hexdigest()
    return hashlib.sha256((body + fp).encode()).hexdigest()[:16]


# ------------------------------------------------------------------ one cell
def _sequence_dir(cell: SimCell, data: str) -> str:
    """The recording's folder: keyed by what makes the bytes (cell, cfg, simulator), not the estimator."""
    return os.path.join(data, "seq", f"{cell.name}-{cell_key(cell, sim_fingerprint())}")


def recorded(directory: str) -> bool:
    """Whether *directory* holds a recording :func:`record` uses as it is: its ADC file, or without
    it (dropped by :func:`drop_adc`) the DSP products of today's DSP."""
    import sequences
    return os.path.exists(os.path.join(directory, "capture.json")) and (
        os.path.exists(os.path.join(directory, "adc_data.bin")) or os.path.exists(sequences.cache_path(directory)))


def record(cell: SimCell, data: str) -> str:
    """The cell's recording, made with radar-sim unless it is there (:func:`recorded`)."""
    directory = _sequence_dir(cell, data)
    if recorded(directory):
        return directory
    shutil.rmtree(directory, ignore_errors=True)
    os.makedirs(os.path.join(data, "seq"), exist_ok=True)
    simulate(scene_spec(cell), cell, directory)
    return directory


def scene_file(directory: str) -> str:
    """The scene file radar-sim recorded *directory* from: beside it, as DIRECTORY.scene.json."""
    return directory + ".scene.json"


def copy_recording(source: str, directory: str) -> None:
    """The recording *source* and its scene file copied to *directory* (which must not exist yet)."""
    shutil.copytree(source, directory)
    shutil.copyfile(scene_file(source), scene_file(directory))


def simulate(spec: dict, cell: SimCell, directory: str, noise_seed: int | None = None,
             duration_s: float | None = None) -> None:
    """Record the scene table *spec* with radar-sim at the cell's seed, cfg and fidelity into
    *directory* (replaced), its scene file beside it as DIRECTORY.scene.json; through a temporary
    directory first, so that a recording cut short never passes for a whole one. *noise_seed*:
    radar-sim's --noise-seed (None: the cell's seed draws the noise too); *duration_s*: its
    --duration (None: the whole loop)."""
    scene = scene_file(directory)
    with open(scene, "w", encoding="utf-8") as fh:
        json.dump(spec, fh, indent=1)
    tmp = directory + ".tmp"
    subprocess.run([sys.executable, "-m", "radarodom.tools.radar_sim", scene, "--seed", str(cell.seed),
                    "--cfg", CFGS[cell.cfg], "--fidelity", cell.fidelity, "--out", tmp, "--overwrite", "-q"]
                   + ([] if noise_seed is None else ["--noise-seed", str(noise_seed)])
                   + ([] if duration_s is None else ["--duration", repr(duration_s)]), check=True,
                   env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    shutil.rmtree(directory, ignore_errors=True)
    os.replace(tmp, directory)


def drop_adc(directory: str) -> None:
    """Keep only what the estimator reads: the DSP products of today's DSP (tens of MB) without the
    recording's ADC samples (hundreds of MB a cell; the 252 cells' together filled a 250 GB disk).
    :func:`record` records the cell again when a changed DSP needs them."""
    import sequences
    kept = os.path.basename(sequences.cache_path(directory))  # hashes the DSP's sources: once
    if os.path.exists(os.path.join(directory, kept)):
        for name in os.listdir(directory):
            if name == "adc_data.bin" or (name.startswith("dsp-") and name.endswith(".npz") and name != kept):
                os.remove(os.path.join(directory, name))


def estimator_config(cell: Cell, settings: dict | None = None):
    """The estimator a cell runs: *settings* (EstimatorConfig.to_dict(), None: the defaults), and
    for a radar mounted off the rotation axis, the mounting on a wheeled base, as a user gives it
    (radar-capture --mount --wheeled)."""
    from radarodom.estimator.config import EstimatorConfig
    config = EstimatorConfig() if settings is None else EstimatorConfig.from_dict(settings)
    if isinstance(cell, SimCell) and cell.mount_m:
        config = config.with_(odometry={"mount_x_m": cell.mount_m, "base": "wheeled"})
    return config


def _estimate_sim(cell: SimCell, data: str, settings: dict | None = None):
    import sequences
    from radarodom.estimator.odometry import RadarOdometry
    from radarodom.tum import TumTrajectory
    seq = sequences.load(record(cell, data), cell.name)
    odom = RadarOdometry(estimator_config(cell, settings))
    poses = np.zeros((len(seq), 3))
    covariances = np.zeros((len(seq), 2, 3, 3))
    rates, frames = np.zeros(len(seq)), np.zeros(len(seq), np.int64)
    flagged = 0
    for i in range(len(seq)):
        st = odom.step(seq.times[i], seq.points[i], seq.heatmap(i))
        poses[i] = st.x, st.y, st.yaw
        covariances[i] = st.pose_covariance, st.twist_covariance
        rates[i], frames[i] = st.yaw_rate, st.frame
        flagged += not st.ok
    states = (seq.times, poses, covariances[:, 0], covariances[:, 1], rates, frames)
    return TumTrajectory.from_se2(seq.times, poses, source=cell.name), seq.groundtruth, flagged, states


def _estimate_coloradar(cell: ColoradarCell, data: str, settings: dict | None = None):
    from radarodom.driver.sources import open_source
    from radarodom.tum import read_tum
    out = os.path.join(data, "coloradar", f"{cell.name}-{hashlib.sha256(cell.url.encode()).hexdigest()[:8]}.tum")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    extra = []
    if settings is not None:
        config_file = out + ".estimator.json"
        estimator_config(cell, settings).dump(config_file)
        extra = ["--estimator-config", config_file]
    subprocess.run([sys.executable, "-m", "radarodom.tools.radar_capture", "--source", cell.url, "--no-publish",
                    "--odom-out", out, "--overwrite", "-q", *extra], check=True,
                   env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    with open_source(cell.url) as source:
        truth = source.groundtruth()
    return read_tum(out), truth, None, None


def run_cell(cell: Cell, data: str, fp: str, settings: dict | None = None, keep_adc: bool = False) -> dict:
    """The cell's metrics with the estimator *settings* (None: the defaults), from its cache or
    computed (and cached); the recording's ADC samples kept only with *keep_adc*."""
    key_fp = fp if settings is None else fp + json.dumps(settings, sort_keys=True)
    path = os.path.join(data, "results", f"{cell.name}-{cell_key(cell, key_fp)}.json")
    cached = _cached_result(path)
    if cached is not None:
        return {**cached, "cached": True}
    from radarodom.estimator.evaluation import associate
    from radarodom.estimator.consistency import odometry_consistency
    from radarodom.cfg import RadarConfig
    from radarodom.estimator.heading_metrics import drift_parts, heading_metrics
    from radarodom.strict_json import finite
    started = time.monotonic()
    est, truth, flagged, states = (_estimate_sim if isinstance(cell, SimCell) else _estimate_coloradar)(
        cell, data, settings)
    if isinstance(cell, SimCell) and not keep_adc:
        drop_adc(_sequence_dir(cell, data))
    est_m, ref_m = associate(est, truth, 0.01)
    mount = (cell.mount_m if isinstance(cell, SimCell) else 0.0, 0.0, 0.0)
    metrics = heading_metrics(ref_m.times, ref_m.se2(), est_m.se2(), radar_on_base=mount)
    parts = drift_parts(ref_m.times, ref_m.se2(), est_m.se2(), radar_on_base=mount)
    result = {"cell": dataclasses.asdict(cell), "name": cell.name, "frames": len(est_m), "flagged": flagged,
              "duration_s": float(ref_m.times[-1] - ref_m.times[0]), **metrics.to_dict(),
              "drift_parts": finite(parts),
              "covariance": None if states is None else finite(odometry_consistency(
                  *states, truth, measured_at_s=RadarConfig.from_file(CFGS[cell.cfg]).measured_at_s)[0]),
              "compute_s": time.monotonic() - started, "fingerprint": fp}
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = f"{path}.{os.getpid()}.tmp"  # two matrices on one --data each write their own
    with open(tmp, "w", encoding="utf-8") as fh:
        json.dump(result, fh, indent=1)
    os.replace(tmp, path)
    return {**result, "cached": False}


def _cached_result(path: str) -> dict | None:
    """The result kept in *path*, None when there is none; a damaged one (a run killed as it wrote,
    an edit) is said, naming the file, and computed again."""
    try:
        with open(path, encoding="utf-8") as fh:
            result = json.load(fh)
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        print(f"{path}: damaged ({exc}): the cell is computed again", file=sys.stderr)
        return None
    if not isinstance(result, dict) or not all(isinstance(result.get(k), (int, float))
                                               for k in ("yaw_rmse_deg", "frames")):
        print(f"{path}: damaged (no cell's result): the cell is computed again", file=sys.stderr)
        return None
    return result


# ------------------------------------------------------------------ the matrix
def run_all(todo: list[Cell], data: str, *, workers: int | None = None, cluster: str | None = None,
            settings: dict | None = None, keep_adc: bool = False, log=lambda msg: print(msg, file=sys.stderr)) -> list[dict]:
    """Every cell's result, in *todo*'s order, with the estimator *settings* (None: the
    defaults): on a local process pool, or on a Dask cluster."""
    fp = fingerprint()
    results: dict[int, dict] = {}

    def done(i: int, r: dict) -> None:
        results[i] = r
        log(f"[{len(results)}/{len(todo)}] {todo[i].name}: yaw {r['yaw_rmse_deg']:.2f} deg, "
            f"drift {_f(r['drift_pct'], '.1f')} %{' (cached)' if r['cached'] else ''}")

    calls = [(c, data, fp, settings, keep_adc) for c in todo]
    if cluster:
        from matrix_cluster import run_on_cluster
        for i, r in run_on_cluster(cluster, run_cell, calls):
            done(i, r)
    else:
        with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
            futures = {pool.submit(run_cell, *args): i for i, args in enumerate(calls)}
            for fut in concurrent.futures.as_completed(futures):
                done(futures[fut], fut.result())
    return [results[i] for i in range(len(todo))]


def _f(v, fmt: str) -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


COLUMNS = [("yaw RMSE deg", "yaw_rmse_deg", ".2f"), ("straight bias deg/m", "straight_bias_deg_per_m", "+.3f"),
           ("deg/min", "straight_bias_deg_per_min", "+.1f"), ("deg/frame", "straight_bias_deg_per_frame", "+.4f"),
           ("after turns deg", "straight_after_turn_deg", "+.2f"),
           ("own deg/frame", "straight_own_bias_deg_per_frame", "+.4f"),
           ("each straight RMS deg/m", "straight_rms_deg_per_m", ".2f"),
           ("worst straight deg/m", "straight_max_deg_per_m", ".2f"),
           ("moving-turn ratio", "moving_turn_ratio", ".3f"),
           ("each moving turn, farthest from 1", "moving_turn_worst_ratio", ".3f"),
           ("in-place ratio", "inplace_turn_ratio", ".3f"),
           ("drift %", "drift_pct", ".2f"), ("final heading deg", "final_heading_error_deg", "+.1f"),
           ("path m", "path_m", ".1f"), ("path ratio", "path_ratio", ".3f"), ("frames", "frames", "d")]


def table(results: list[dict]) -> str:
    head = "| cell | " + " | ".join(c[0] for c in COLUMNS) + " |\n| --- |" + " ---: |" * len(COLUMNS) + "\n"
    # (.get: results cached before a column was added have none)
    return head + "".join(f"| {r['name']} | " + " | ".join(_f(r.get(k), fmt) for _, k, fmt in COLUMNS) + " |\n"
                          for r in results)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_cell_arguments(parser)
    parser.add_argument("--workers", type=positive_int, default=None, help="local processes (default: the CPU count)")
    parser.add_argument("--cluster", metavar="ADDRESS", help="a Dask distributed scheduler, e.g. tcp://host:8786")
    parser.add_argument("--out", default="robustness-out")
    parser.add_argument("--estimator-config", metavar="FILE.json",
                        help="estimator settings to run (EstimatorConfig.dump; default: the defaults)")
    parser.add_argument("--keep-adc", action="store_true",
                        help="keep each recording's ADC samples (default: only its DSP products; see drop_adc)")
    parser.add_argument("--list", action="store_true", help="print the cells and stop")
    args = parser.parse_args(argv)
    todo = selected_cells(args)
    if args.list:
        print("\n".join(c.name for c in todo))
        return 0
    started = time.monotonic()
    settings = None
    if args.estimator_config:
        from radarodom.errors import RadarodomError
        from radarodom.estimator.config import EstimatorConfig
        try:
            settings = EstimatorConfig.load(args.estimator_config).to_dict()
        except RadarodomError as exc:
            parser.error(f"--estimator-config: {exc}")
    try:  # before the hours of work, not after
        os.makedirs(args.out, exist_ok=True)
    except OSError as exc:
        parser.error(f"--out {args.out}: {exc.strerror or exc}")
    results = run_all(todo, args.data, workers=args.workers, cluster=args.cluster, settings=settings,
                      keep_adc=args.keep_adc)
    header = (f"{len(results)} cells ({sum(r['cached'] for r in results)} from the cache); "
              f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
              f"{time.strftime('%Y-%m-%d')}; {time.monotonic() - started:.0f} s.\n\n")
    text = header + table(results)
    print(text)
    with open(os.path.join(args.out, "robustness.md"), "w", encoding="utf-8") as fh:
        fh.write(text)
    with open(os.path.join(args.out, "robustness.json"), "w", encoding="utf-8") as fh:
        json.dump(results, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
