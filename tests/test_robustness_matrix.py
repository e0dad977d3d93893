"""bench/robustness_matrix.py (issue 20): its cells as data, the loops it drives in each scene,
its per-cell cache, and a ColoRadar run as a cell (tests/coloradar_synth.py's synthetic run)."""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
import re
import subprocess
import sys
import time
from types import SimpleNamespace

import numpy as np
import pytest
from coloradar_synth import write_moving_run
from radarodom.cfg import RadarConfig
from radarodom.driver.sim.scene import scene_from_dict

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
import robustness_matrix as rm


def test_the_matrix_cfgs_are_valid_and_differ_as_named():
    shapes = {name: RadarConfig.from_file(path) for name, path in rm.CFGS.items()}
    assert shapes["shipped"].cube_shape == (64, 3, 4, 256)
    assert shapes["2tx"].cube_shape == (64, 2, 4, 256)
    assert shapes["128loops"].cube_shape == (128, 3, 4, 256)
    assert shapes["slope60"].slope_hz_per_s == pytest.approx(60e12)
    # TI's SDK demo profiles: 32 loops of 7 us idle, Doppler bins six times the shipped cfg's.
    assert shapes["sdk2d"].cube_shape == (32, 2, 4, 256) and shapes["sdk3d"].cube_shape == (32, 3, 4, 256)
    for name in ("sdk2d", "sdk3d"):
        assert shapes[name].velocity_resolution_mps > 6 * shapes["shipped"].velocity_resolution_mps


@pytest.mark.parametrize("scene", sorted(rm.LAYOUT))
@pytest.mark.parametrize("speed, rate", [(0.8, 45), (0.3, 90), (1.5, 30), (1.5, 90)])
def test_each_scene_drives_a_closed_loop_with_the_cells_speed_turn_rate_snr_and_movers(scene, speed, rate):
    cell = rm.SimCell(scene=scene, speed_mps=speed, turn_rate_dps=rate, snr_db=-10, movers="people")
    built = scene_from_dict(rm.scene_spec(cell))
    traj = built.trajectory
    assert built.snr_db == -10 and len(built.movers) >= 1
    assert math.hypot(traj.x[-1] - traj.x[0], traj.y[-1] - traj.y[0]) < 0.05  # the loop closes
    assert math.degrees(traj.yaw[-1] - traj.yaw[0]) == pytest.approx(180, abs=0.01)  # +90, +180, -90
    vx, vy, w = traj.velocity(traj.times)
    assert np.hypot(vx, vy).max() == pytest.approx(speed, rel=0.01)
    assert math.degrees(np.abs(w).max()) == pytest.approx(rate, rel=0.01)
    assert not scene_from_dict(rm.scene_spec(dataclasses.replace(cell, movers="none"))).movers


@pytest.mark.parametrize("scene", sorted(rm.LAYOUT))
def test_odd_seeds_turn_in_place_to_the_right_over_the_same_loop(scene):
    # Until 2026-12-06 every loop turned in place to the left, and the straights after the turn,
    # which take back part of its error, carried that direction's sign into the straight bias.
    even, odd = rm.SimCell(scene=scene, seed=2), rm.SimCell(scene=scene, seed=3)
    assert (even.turn_in_place_deg, odd.turn_in_place_deg) == (180, -180)
    a, b = (scene_from_dict(rm.scene_spec(c)).trajectory for c in (even, odd))
    assert math.hypot(b.x[-1] - b.x[0], b.y[-1] - b.y[0]) < 0.05  # the loop closes
    assert math.degrees(b.yaw[-1] - b.yaw[0]) == pytest.approx(-180, abs=0.01)  # +90, -180, -90
    assert math.degrees(a.yaw[-1] - a.yaw[0]) == pytest.approx(180, abs=0.01)  # +90, +180, -90
    assert len(a.times) == len(b.times) and np.hypot(a.x - b.x, a.y - b.y).max() < 0.05  # the same path
    with pytest.raises(ValueError, match="180 or -180 degrees, got 90"):
        rm.loop_segments(scene, 0.8, 45.0, 3.0, turn_in_place_deg=90)


@pytest.mark.parametrize("speed, rate, mount", [(0.8, 45, 0.0), (0.3, 45, 0.0), (1.5, 45, 0.0), (0.8, 30, 0.0),
                                               (0.8, 90, 0.0), (0.8, 45, 0.3)])
def test_the_hall_has_room_for_straights_of_10_m_among_its_furniture(speed, rate, mount):
    # Its reason to be: the other scenes fit the star's loops with 3-5 m straights, the corridor
    # 10 m ones without furniture (docs/heading.md, "Longer straights").
    segments, _ = rm.loop_segments("hall", speed, rate, 10.0, mount)
    assert [s["straight"] for s in segments if "straight" in s] == [10.0] * 4


def test_the_hall_is_furnished():
    import matrix_cells
    table = matrix_cells._scene_table("hall")
    assert sum(o["type"] in ("box", "cylinder") for o in table["objects"]) >= 15


def test_a_loop_through_the_furniture_is_refused(monkeypatch):
    # The room's loop once drove through its pillar at 0.3 m/s and 90 deg/s: a radar inside a
    # pillar sees nothing, which no robot meets.
    import matrix_cells
    from radarodom.driver.sim.trajectory import from_segments
    table = matrix_cells._scene_table("room")
    through = from_segments([{"straight": 3.0, "speed": 0.8}], start=[2.8, 3.0, 0.0])
    clearance, what = matrix_cells.loop_clearance(table, through)
    assert clearance < 0 and what == "the cylinder at [4.3, 3.0]"
    monkeypatch.setitem(matrix_cells.LAYOUT, "room", {**matrix_cells.LAYOUT["room"], "turn_x": 4.5})
    with pytest.raises(ValueError, match="passes -?[0-9.]+ m from the"):
        matrix_cells.loop_segments("room", 0.8, 90.0, 3.0)


def test_a_radar_mounted_ahead_of_its_base_keeps_clear_too(monkeypatch):
    # Until 2026-11-28 only the base's path was checked: the lab's radar, 0.3 m ahead of the axis,
    # turned in place 0.1 m from a 2 m cabinet and saw almost nothing for a second.
    import matrix_cells
    from radarodom.driver.sim.trajectory import from_segments
    table = matrix_cells._scene_table("lab")
    for mount, side in itertools.product((0.0, 0.3), (180, -180)):
        segs, start = matrix_cells.loop_segments("lab", 0.8, 45.0, 3.0, mount, side)
        radar = from_segments(segs, start=start, mount=(mount, 0.0, 0.0))
        assert max(radar.y) == pytest.approx(matrix_cells.LAYOUT["lab"]["y_max"], abs=0.01)  # the radar stops there
        assert matrix_cells.loop_clearance(table, radar)[0] >= matrix_cells.CLEARANCE_M
    monkeypatch.setitem(matrix_cells.LAYOUT, "lab", {**matrix_cells.LAYOUT["lab"], "y_max": 7.25})
    with pytest.raises(ValueError, match="the radar 0.3 m ahead of its base's axis on a loop .* passes 0.15 m from"):
        matrix_cells.loop_segments("lab", 0.8, 45.0, 3.0, 0.3)
    with pytest.raises(ValueError, match="lab: a loop at .* passes 0.15 m from"):
        matrix_cells.loop_segments("lab", 0.8, 45.0, 3.5)


def test_cells_are_selected_by_axis_in_star_and_product_designs():
    args = SimpleNamespace(scenes=["room"], seeds=[0, 1], cfgs=["shipped", "2tx"], snr=[0.0, -10.0],
                           speeds=[0.8], turn_rates=[45.0], movers=["scene"], mounts=[0.0], straight=3.0,
                           design="star", coloradar=None)
    star = rm.cells(args)
    assert len(star) == 2 * 3  # per seed: the base, the 2-TX cfg, -10 dB
    assert {(c.cfg, c.snr_db) for c in star} == {("shipped", 0.0), ("2tx", 0.0), ("shipped", -10.0)}
    assert [c.cfg == "shipped" and c.snr_db == 0.0 for c in star[:2]] == [True, True]  # base cells first
    args.design = "product"
    assert len(rm.cells(args)) == 2 * 4
    args.mounts = [0.0, 0.3]
    assert len(rm.cells(args)) == 2 * 8
    assert {c.mount_m for c in rm.cells(args)} == {0.0, 0.3}


def test_smoke_presets_only_the_axes_not_given():
    import argparse
    parser = argparse.ArgumentParser()
    rm.add_cell_arguments(parser)
    names = lambda argv: [c.name for c in rm.selected_cells(parser.parse_args(argv))]  # noqa: E731
    assert names(["--smoke"]) == [f"{s}_s0_shipped_snr0_v0.8_w45_scene_L2" for s in ("corridor", "room", "lab")]
    assert names(["--smoke", "--scenes", "room", "--seeds", "3"]) == ["room_s3_shipped_snr0_v0.8_w45_scene_L2"]
    assert len(names([])) == 288 and len(names(["--scenes", "lab"])) == 96  # the whole star, and its lab


def test_a_cells_cache_key_follows_its_parameters_and_the_sources():
    a = rm.SimCell(scene="lab")
    assert rm.cell_key(a, "fp1") == rm.cell_key(rm.SimCell(scene="lab"), "fp1")
    assert rm.cell_key(a, "fp1") != rm.cell_key(dataclasses.replace(a, seed=1), "fp1")
    assert rm.cell_key(a, "fp1") != rm.cell_key(a, "fp2")
    assert len(rm.fingerprint()) == 16


def test_a_coloradar_run_is_a_cell_and_its_result_is_cached(tmp_path):
    run = write_moving_run(tmp_path / "runs")
    cell = rm.ColoradarCell(str(run))
    first = rm.run_all([cell], str(tmp_path / "data"), workers=1, log=lambda msg: None)[0]
    assert not first["cached"] and first["frames"] > 10
    assert first["path_m"] > 1.0 and first["moving_turns"] >= 1  # the synthetic run drives a left arc
    assert first["yaw_rmse_deg"] < 2.0 and first["moving_turn_ratio"] == pytest.approx(1.0, abs=0.2)
    assert first["drift_parts"]["all"] == pytest.approx(first["drift_pct"])  # and what made it, by kind of frame
    assert first["covariance"] is None  # a TUM file holds no covariance
    again = rm.run_all([cell], str(tmp_path / "data"), workers=1, log=lambda msg: None)[0]
    assert again["cached"] and again["yaw_rmse_deg"] == first["yaw_rmse_deg"]
    assert "coloradar_" in rm.table([again])
    # a result cached before a column was added shows "-" there, as one without straights does
    assert again["straights"] == 0 and again["straight_rms_deg_per_m"] is None
    older = {k: v for k, v in again.items() if k not in ("straight_rms_deg_per_m", "straight_max_deg_per_m")}
    assert rm.table([older]) == rm.table([again])
    # A result cut short (a run killed as it wrote): said, naming the file, and computed again (it was
    # a JSONDecodeError traceback, naming no file, on every rerun until the file was found).
    [kept] = (tmp_path / "data" / "results").iterdir()
    kept.write_text(kept.read_text()[:100])
    anew = rm.run_all([cell], str(tmp_path / "data"), workers=1, log=lambda msg: None)[0]
    assert not anew["cached"] and anew["yaw_rmse_deg"] == first["yaw_rmse_deg"]
    assert rm._cached_result(str(kept))["yaw_rmse_deg"] == first["yaw_rmse_deg"]


@pytest.mark.parametrize("args, words", [
    (["--workers", "0"], "argument --workers: '0': a whole number above 0"),
    (["--turn-rates", "0"], "argument --turn-rates: '0': a turn rate above 0 deg/s"),  # a ZeroDivisionError
    (["--speeds", "nan"], "argument --speeds: 'nan': a speed above 0 m/s"),
    (["--snr", "1e400"], "argument --snr: '1e400': a finite number of dB"),  # a cell named snrinf
    (["--seeds", "-3"], "argument --seeds: '-3': a whole number >= 0"),
    (["--coloradar", "/nonexistent"], "argument --coloradar: '/nonexistent': no such directory"),
])
def test_bad_arguments_are_refused_before_any_cell(capsys, args, words):
    with pytest.raises(SystemExit) as info:
        rm.main(["--smoke", "--list", *args])
    assert info.value.code == 2 and words in capsys.readouterr().err


def test_an_out_that_cannot_be_written_is_refused_before_any_cell(tmp_path, capsys):
    """It was a FileExistsError after every cell had run."""
    (tmp_path / "out").write_text("")
    with pytest.raises(SystemExit) as info:
        rm.main(["--smoke", "--scenes", "room", "--out", str(tmp_path / "out"), "--data", str(tmp_path / "data")])
    assert info.value.code == 2 and f"--out {tmp_path / 'out'}: File exists" in capsys.readouterr().err
    assert not (tmp_path / "data").exists()


def test_a_dask_cluster_runs_the_cells_as_the_local_pool_does(tmp_path):
    # A real Dask scheduler and worker process on loopback (free ports, no dashboard), given by
    # address as --cluster takes it; the worker imports the bench modules from the path it inherits.
    distributed = pytest.importorskip("dask.distributed")
    run = write_moving_run(tmp_path / "runs")
    cells = [rm.ColoradarCell(str(run))]
    logged: list[str] = []
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        remote = rm.run_all(cells, str(tmp_path / "dask"), cluster=cluster.scheduler_address, log=logged.append)
        again = rm.run_all(cells, str(tmp_path / "dask"), cluster=cluster.scheduler_address, log=logged.append)
    local = rm.run_all(cells, str(tmp_path / "local"), workers=1, log=lambda msg: None)
    assert [m.startswith("[1/1] coloradar_ec_hallways_run0: yaw ") for m in logged] == [True, True]
    assert [m.endswith(" (cached)") for m in logged] == [False, True]
    assert not remote[0]["cached"] and again[0]["cached"]  # the worker wrote the cell's result to the cache
    assert os.listdir(tmp_path / "dask" / "results")
    same = {k: v for k, v in remote[0].items() if k != "compute_s"}
    assert same == {k: v for k, v in local[0].items() if k != "compute_s"}


def test_a_scheduler_without_the_bench_modules_is_refused_before_any_cell(tmp_path):
    # Dask's scheduler unpickles each task: started without bench/ on its path, every cell would
    # fail with "Error during deserialization of the task graph". A scheduler of its own on a free
    # port, started outside the clone.
    pytest.importorskip("dask.distributed")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    log = tmp_path / "scheduler.log"
    with open(log, "w") as err:
        scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                      "--port", "0", "--no-dashboard"], cwd=tmp_path, env=env,
                                     stdout=subprocess.DEVNULL, stderr=err)
    try:
        deadline = time.monotonic() + 120  # a bound on a hung start, not a speed check
        while not (found := re.search(r"Scheduler at:\s*(\S+)", log.read_text())):
            assert scheduler.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.1)
        with pytest.raises(SystemExit, match=r"the scheduler cannot import bench/'s modules \(matrix_cells, "
                                             r"robustness_matrix, sequences\): start the scheduler and the workers "
                                             r"with this clone's bench/ on their path, e\.g\. PYTHONPATH="):
            rm.run_all([rm.SimCell(scene="room")], str(tmp_path / "data"), cluster=found.group(1))
        assert not (tmp_path / "data").exists()  # nothing was recorded
    finally:
        scheduler.terminate()
        scheduler.wait(timeout=30)


def test_cluster_without_dask_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask", None)  # as if not installed, whether it is or not
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    with pytest.raises(SystemExit, match="dask\\[distributed\\]"):
        rm.run_all([rm.SimCell(scene="room")], str(tmp_path), cluster="tcp://127.0.0.1:1")


def test_a_cell_keeps_its_dsp_products_and_drops_the_adc_samples(tmp_path):
    import sequences
    cell = rm.SimCell(scene="room")
    directory = rm._sequence_dir(cell, str(tmp_path))
    os.makedirs(directory)
    current = sequences.cache_path(directory)
    stale = os.path.join(directory, "dsp-0000000000000000.npz")
    for name in ("capture.json", "adc_data.bin", "timestamps.txt", os.path.basename(stale)):
        (tmp_path / directory / name).write_bytes(b"x")
    rm.drop_adc(directory)  # no products of today's DSP yet: nothing goes
    assert sorted(os.listdir(directory)) == sorted(["capture.json", "adc_data.bin", "timestamps.txt",
                                                    os.path.basename(stale)])
    open(current, "wb").close()
    rm.drop_adc(directory)
    assert sorted(os.listdir(directory)) == sorted(["capture.json", "timestamps.txt", os.path.basename(current)])
    assert rm.record(cell, str(tmp_path)) == directory  # its products are there: not recorded again
    assert sorted(os.listdir(directory)) == sorted(["capture.json", "timestamps.txt", os.path.basename(current)])


def test_the_summary_gives_a_row_per_axis_and_the_goals_before_and_after():
    import matrix_summary
    def result(name, drift, **cell):
        return {"name": name, "cell": {**dataclasses.asdict(rm.SimCell(scene="room")), **cell}, "yaw_rmse_deg": 0.3,
                "straight_bias_deg_per_frame": -0.004, "moving_turn_ratio": 1.01, "inplace_turn_ratio": None,
                "drift_pct": drift, "final_heading_error_deg": -2.0}
    before = [result("a", 3.0), result("b", 9.0, speed_mps=1.5), result("only-before", 1.0)]
    after = [result("a", 1.0), result("b", 4.0, speed_mps=1.5)]
    text = matrix_summary.summary([before, after])
    lines = text.splitlines()
    assert lines[2].startswith("| base (") and "| 3.0 / 3.0 -> 1.0 / 1.0 |" in lines[2]
    assert lines[3].startswith("| 1.5 m/s (1) |") and "9.0 / 9.0 -> 4.0 / 4.0" in lines[3]
    assert "cells 2 -> 2" in text and "drift <= 2 % 0 -> 1" in text and "straight bias <= 0.005 2 -> 2" in text
    assert "What makes the drift" not in text  # results without drift parts (before 2026-11-29)
    assert "each straight's heading error, RMS / worst deg/m - -> -" in text  # nor straights (2026-11-30)
    # nor the frames after the turns apart (2026-12-06)
    assert "the straights' own bias <= 0.005 - -> -" in text
    assert "signed straight bias, all / after turns' frames deg/frame -0.0040 / - -> -0.0040 / -" in text


def test_the_summary_names_the_cells_that_miss_or_cross_each_goal():
    import matrix_summary
    def result(name, drift, bias, inplace):
        return {"name": name, "cell": dataclasses.asdict(rm.SimCell(scene="lab")), "yaw_rmse_deg": 0.3,
                "straight_bias_deg_per_frame": bias, "moving_turn_ratio": 1.0, "moving_turn_worst_ratio": 1.0,
                "inplace_turn_ratio": inplace, "drift_pct": drift, "final_heading_error_deg": 0.5}
    before = [result("a", 2.5, 0.004, 1.01), result("b", 1.0, -0.007, None), result("c", 1.5, 0.001, 0.97)]
    after = [result("a", 1.5, 0.006, 1.01), result("b", 2.2, 0.002, None), result("c", 1.5, 0.001, 0.97)]
    text = matrix_summary.summary([before, after])
    assert "The cells that crossed a goal (BEFORE -> AFTER):" in text
    assert "- straight bias at most 0.005 deg/frame, gained 1: b -0.007 -> 0.002" in text
    assert "- straight bias at most 0.005 deg/frame, lost 1: a 0.004 -> 0.006" in text
    assert "- drift at most 2 %, gained 1: a 2.5 -> 1.5" in text and "- drift at most 2 %, lost 1: b 1 -> 2.2" in text
    assert "turns in place" not in text.split("crossed a goal")[1]  # c misses it in both runs: no crossing
    alone = matrix_summary.summary([after])
    assert "- turns in place within 2 %, missed by 1: c 0.97" in alone  # b turns in place nowhere
    assert "- drift at most 2 %, missed by 1: b 2.2" in alone
    assert "each moving turn within 2 %, missed" not in alone  # every cell meets it
    many = [result(f"cell{i:02d}", 3.0, 0.0, 1.0) for i in range(15)]
    listed = matrix_summary.summary([many])
    assert "missed by 15: cell00 3, " in listed and "cell11 3, and 3 more" in listed  # twelve named


def test_the_summary_says_what_makes_the_drift_per_row():
    import matrix_summary
    from radarodom.estimator.heading_metrics import DRIFT_PARTS
    def result(name, turn_in_place, **cell):
        parts = dict.fromkeys(DRIFT_PARTS, 0.5) | {"turn in place": turn_in_place, "other": None}
        return {"name": name, "cell": {**dataclasses.asdict(rm.SimCell(scene="room")), **cell}, "yaw_rmse_deg": 0.3,
                "straight_bias_deg_per_frame": 0.0, "moving_turn_ratio": 1.0, "inplace_turn_ratio": 1.0,
                "drift_pct": 1.0, "final_heading_error_deg": 0.0, "drift_parts": parts,
                "straight_rms_deg_per_m": turn_in_place / 10, "straight_max_deg_per_m": turn_in_place / 5,
                "straight_frames": 100, "straight_after_turn_deg": -turn_in_place,
                "straight_own_bias_deg_per_frame": 0.002 * turn_in_place}
    text = matrix_summary.summary([[result("a", 1.0), result("b", 3.0, seed=1), result("c", 2.0, speed_mps=1.5)]])
    # own biases 0.002, 0.006, 0.004: two within the goal; the after-turn frames' -0.01, -0.03, -0.02
    assert "the straights' own bias <= 0.005 2" in text
    assert "signed straight bias, all / after turns' frames deg/frame +0.0000 / -0.0200" in text
    # the RMS over the cells of 0.1, 0.3, 0.2 deg/m, and the worst straight of all
    assert "each straight's heading error, RMS / worst deg/m 0.22 / 0.60" in text
    lines = text.split("What makes the drift")[1].splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("| cells |"))
    assert lines[head] == "| cells | " + " | ".join(DRIFT_PARTS) + " |"
    assert lines[head + 2] == "| base (shipped cfg, scene SNR, 0.8 m/s, 45 deg/s) (2) | 0.50 | 0.50 | 0.50 | 0.50 | 2.00 | - | 0.50 |"
    assert lines[head + 3] == "| 1.5 m/s (1) | 0.50 | 0.50 | 0.50 | 0.50 | 2.00 | - | 0.50 |"


def test_the_summary_says_how_the_covariance_covers_the_errors():
    import matrix_summary
    def result(name, z, final_sd, final_error, position=True, **cell):  # (position False: a result without one)
        cov = {"yaw": {"z_rms": z, "within_1sigma": 0.7, "within_2sigma": 0.8 + z / 5},
               "position": {"z_rms": 2 * z, "within_1sigma": 0.5, "within_2sigma": 0.8} if position else None,
               "final_yaw_error_deg": final_error, "final_yaw_sigma_deg": final_sd,
               "yaw_rate": {"z_rms": z / 2, "within_1sigma": 0.9, "within_2sigma": 1.0},
               "forward_speed": {"z_rms": 1.0, "within_1sigma": 0.7, "within_2sigma": 0.95},
               "sideways_speed": {"z_rms": z, "within_1sigma": 0.7, "within_2sigma": 0.95}}
        return {"name": name, "cell": {**dataclasses.asdict(rm.SimCell(scene="room")), **cell}, "yaw_rmse_deg": 0.3,
                "straight_bias_deg_per_frame": 0.0, "moving_turn_ratio": 1.0, "inplace_turn_ratio": 1.0,
                "drift_pct": 1.0, "final_heading_error_deg": 0.0, "covariance": cov}
    older = {**result("d", 1.0, 1.0, 1.0, seed=2), "covariance": None}  # a cached result from before 2026-12-01
    text = matrix_summary.summary([[result("a", 0.5, 4.0, 3.0), result("b", 1.0, 6.0, -4.0, seed=1),
                                    result("c", 0.8, 5.0, 0.0, position=False, mount_m=0.3), older]])
    lines = text.split("The reported pose covariance")[1].splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("| cells |"))
    assert lines[head + 2] == "| base (shipped cfg, scene SNR, 0.8 m/s, 45 deg/s) (2) | 0.75 | 0.95 | 5.0 / 3.5 | 1.50 | 0.80 | 0.38 | 1.00 | 1.00 / 0.75 |"
    assert lines[head + 3] == "| radar 0.3 m ahead, wheeled (1) | 0.80 | 0.96 | 5.0 / 0.0 | - | - | 0.40 | 1.00 | 1.00 / 0.80 |"
    assert lines[head + 4] == "| all (3) | 0.77 | 0.95 | 5.0 / 2.9 | 1.50 | 0.80 | 0.38 | 1.00 | 1.00 / 0.77 |"


@pytest.mark.parametrize("scene", sorted(rm.LAYOUT))
def test_the_built_in_scenes_own_paths_keep_clear_of_their_furniture(scene):
    # The lab's own path crossed a bench until 2026-11-28, as the matrix's loops crossed tables.
    # The room's passes 0.15 m from a chair: near, not through.
    import matrix_cells
    from radarodom.driver.sim.trajectory import from_spec
    table = matrix_cells._scene_table(scene)
    clearance, what = matrix_cells.loop_clearance(table, from_spec(table["trajectory"]))
    assert clearance >= 0.1, f"{scene}'s own path passes {clearance:.2f} m from {what}"
