"""radar-capture with the estimator, from the command line: --odom-out, --no-odom,
--estimator-config, the odometry part of the summary, and radar-eval on what it wrote.

The programs run on real files: in this process (``capture_main``, conftest's run_main) when
the subject is their answer, as subprocesses where the process matters (Ctrl-C, two runs at
once) and in test_missing_estimator_config_file (the installed script, end to end).  One short
simulation of the ``corridor`` scene (1 s standing still, then 2 s driving straight ahead and
speeding up to 1.2 m/s) is streamed once per session through ``sim://`` with ``--record`` and
``--odom-out`` (conftest's ``corridor_run``, shared with other modules); the other runs replay
that recording.
"""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import time

import numpy as np
import pytest
from conftest import CORRIDOR_URL, console_command, run_together
from test_cli_capture import one_error_line, popen_capture, run_capture_cli, summary_re

from radarodom.estimator.config import EstimatorConfig

DURATION_S = 3
FRAMES = 30  # 10 Hz (configs/awr1843_raw.cfg)
STANDING_S = 1.0  # the corridor's trajectory starts with a 1 s pause
SIM_URL = f"sim://corridor?rate=max&fidelity=fast&duration={DURATION_S}"
assert SIM_URL == CORRIDOR_URL  # the run is conftest's corridor_run

#: The odometry part radar-capture adds to its summary when the estimator runs.
ODOM_PART = (r"; odometry: x (?P<x>-?\d+\.\d\d) m, y (?P<y>-?\d+\.\d\d) m, yaw (?P<yaw>-?\d+\.\d) deg, "
             r"estimator median (?P<ms>\d+\.\d) ms/frame, latency p50 (?P<p50>\d+\.\d) ms, "
             r"p99 (?P<p99>\d+\.\d) ms(?:, trajectory in (?P<path>.+?))?"
             r"(?:; (?:point clouds|heatmaps|odometry messages) in .+?)?"
             r"(?:; published \d+ odometry, \d+ point cloud, \d+ heatmap and \d+ status messages under \S+)?$")


def tum_rows(path) -> list[list[str]]:
    """The fields of every line of a TUM file; every line must be complete."""
    text = open(path, encoding="ascii").read()
    assert text.endswith("\n"), text[-80:]
    return [line.split() for line in text.splitlines()]


def poses(path) -> np.ndarray:
    """(n, 8) t x y z qx qy qz qw."""
    return np.array([[float(v) for v in row] for row in tum_rows(path)])


def yaw_of(q: np.ndarray) -> np.ndarray:
    return 2.0 * np.arctan2(q[..., 2], q[..., 3])


def snapshot(path) -> tuple[bytes, int]:
    return open(path, "rb").read(), os.stat(path).st_mtime_ns


@pytest.fixture(scope="module")
def sim_run(corridor_run):
    """radar-capture streaming the simulator (SIM_URL), recording it and writing the odometry:
    conftest's session-wide run of it (read only)."""
    return corridor_run


def replay_url(sim_run) -> str:
    return f"replay://{sim_run.rec}?rate=max"


@pytest.fixture(scope="module")
def default_replay(sim_run, tmp_path_factory):
    """The recording replayed with the default settings, not publishing, its trajectory (tum) and
    its messages (odom) written: the plain run that the heatmap export's and the wall map's tests
    hold theirs against (read only; one replay for both)."""
    from types import SimpleNamespace

    base = tmp_path_factory.mktemp("default_replay")
    tum, odom = base / "plain.tum", base / "plain.jsonl"
    proc = run_capture_cli("--source", replay_url(sim_run), "--no-publish", "--odom-out", tum, "--odom-json", odom)
    assert proc.returncode == 0, proc.stderr
    return SimpleNamespace(tum=tum, odom=odom)


# ------------------------------------------------------------------ the run itself
def test_summary_has_the_odometry_part(sim_run):
    proc = sim_run.proc
    # Nothing but, on a loaded machine, the status line a log gets every 10 s.
    assert [ln for ln in proc.stderr.splitlines() if not ln.startswith("frames ")] == []
    line = proc.stdout.rstrip("\n")
    assert proc.stdout.count("\n") == 1, proc.stdout
    assert re.fullmatch(summary_re(FRAMES, 0, 0, "2.90", "end of source", sim_run.rec), line), line
    m = re.search(ODOM_PART, line)
    assert m, line
    assert m["path"] == str(sim_run.tum)
    assert 0.0 < float(m["ms"]) < 1000.0
    # The summary's pose is the last line of the trajectory.
    last = poses(sim_run.tum)[-1]
    assert m["x"] == f"{last[1]:.2f}" and m["y"] == f"{last[2]:.2f}"
    assert float(m["yaw"]) == pytest.approx(math.degrees(yaw_of(last[4:])), abs=0.051)


def test_odom_out_has_one_line_per_frame_at_the_frame_times(sim_run):
    rows = tum_rows(sim_run.tum)
    stamps = (sim_run.rec / "timestamps.txt").read_text().split()
    assert len(stamps) == FRAMES
    assert len(rows) == FRAMES
    assert all(len(r) == 8 for r in rows)
    # The same times, to the nanosecond, as the recorded frames (and their ground truth).
    assert [r[0] for r in rows] == stamps
    gt = tum_rows(sim_run.rec / "groundtruth.tum")
    assert [r[0] for r in gt] == stamps
    p = poses(sim_run.tum)
    assert np.all(np.isfinite(p))
    assert np.all(np.diff(p[:, 0]) > 0)
    # Planar: z = 0, a unit quaternion about z only.
    assert np.all(p[:, 3] == 0.0)
    assert np.all(p[:, 4] == 0.0) and np.all(p[:, 5] == 0.0)
    np.testing.assert_allclose(np.linalg.norm(p[:, 4:], axis=1), 1.0, atol=1e-8)
    # The world is the first body frame: the first pose is the identity.
    assert rows[0][1:] == ["0", "0", "0", "0", "0", "0", "1"], rows[0]


def test_the_estimate_follows_the_corridor(sim_run):
    p = poses(sim_run.tum)
    gt = poses(sim_run.rec / "groundtruth.tum")
    standing = p[:, 0] < STANDING_S - 1e-6
    assert standing.sum() == 10
    # Standing still: zero Doppler everywhere, no motion at all; the yaw barely moves.
    assert np.all(p[standing, 1:3] == 0.0)
    assert np.all(np.abs(np.degrees(yaw_of(p[standing, 4:]))) < 0.5)
    # Then forward along x; the run ends about 1.9 m ahead.
    travelled = gt[-1, 1]
    assert travelled == pytest.approx(1.92, abs=0.05)
    assert np.all(np.diff(p[:, 1]) >= -1e-9)
    assert p[-1, 1] == pytest.approx(travelled, rel=0.05)
    assert abs(p[-1, 2]) < 0.05 * travelled
    assert np.all(np.abs(np.degrees(yaw_of(p[:, 4:]))) < 2.0)


def test_radar_eval_on_the_run(sim_run, tmp_path, run_main):
    out = tmp_path / "eval.json"
    proc = run_main("radar-eval", sim_run.tum, sim_run.rec / "groundtruth.tum", "--json", out)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert f"{FRAMES} poses matched" in proc.stdout
    data = json.loads(out.read_text())
    assert data["poses"] == {"estimate": FRAMES, "reference": FRAMES, "matched": FRAMES}
    path = data["reference_path_length_m"]
    assert path == pytest.approx(1.92, abs=0.05)
    assert data["estimate_path_length_m"] == pytest.approx(path, rel=0.05)
    # Measured (default estimator): 0.6 % drift, 0.05 deg yaw-increment RMSE, 7 mm ATE.
    assert 0 <= data["final_drift"]["percent_of_path"] < 5.0
    assert abs(data["final_drift"]["yaw_deg"]) < 1.5
    assert data["yaw_increment_error_deg"]["rmse"] < 0.3
    assert data["ate_m"]["rmse"] < 0.05
    assert data["rpe_per_frame"]["translation_m"]["max"] < 0.03


def test_replay_with_a_dumped_default_config_gives_the_same_trajectory(sim_run, tmp_path, capture_main):
    # The recording replayed, with the default settings as EstimatorConfig.dump writes them:
    # the file is accepted and changes nothing.
    cfg = tmp_path / "estimator.json"
    EstimatorConfig().dump(cfg)
    tum = tmp_path / "replay.tum"
    proc = capture_main("--source", replay_url(sim_run), "--estimator-config", cfg, "--odom-out", tum)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert re.search(ODOM_PART, proc.stdout.rstrip("\n")), proc.stdout
    live, replay = tum_rows(sim_run.tum), tum_rows(tum)
    assert [r[0] for r in replay] == [r[0] for r in live]
    np.testing.assert_allclose(poses(tum), poses(sim_run.tum), rtol=0, atol=1e-6)


def test_estimator_config_is_used(sim_run, tmp_path, capture_main):
    # A partial file: a velocity fit that needs more points than any frame has never
    # succeeds, so the estimate never moves (while the default one moved 1.9 m).
    cfg = tmp_path / "strict.json"
    cfg.write_text(json.dumps({"velocity": {"min_points": 100000}}))
    tum = tmp_path / "strict.tum"
    proc = capture_main("--source", replay_url(sim_run), "--estimator-config", cfg, "--odom-out", tum)
    assert proc.returncode == 0, proc.stderr
    m = re.search(ODOM_PART, proc.stdout.rstrip("\n"))
    assert m and (m["x"], m["y"]) == ("0.00", "0.00"), proc.stdout
    p = poses(tum)
    assert len(p) == FRAMES
    assert np.all(p[:, 1:3] == 0.0)
    assert poses(sim_run.tum)[-1, 1] > 1.5


def test_no_odom_runs_without_the_estimator(sim_run, tmp_path, capture_main):
    before = sorted(os.listdir(tmp_path))
    proc = capture_main("--source", replay_url(sim_run), "--no-odom")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    line = proc.stdout.rstrip("\n")
    assert re.fullmatch(summary_re(FRAMES, 0, 0, "2.90", "end of source"), line), line
    assert "; odometry:" not in line and "estimator" not in line
    assert sorted(os.listdir(tmp_path)) == before


def test_a_stopped_run_leaves_whole_lines_one_per_frame(tmp_path):
    # Streaming in real time, stopped with Ctrl-C after a few frames: the trajectory holds
    # one complete line for every frame the summary counts.
    tum = tmp_path / "stopped.tum"
    proc = popen_capture("--source", "sim://corridor?rate=1", "--odom-out", tum, text=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if tum.exists() and tum.read_text().count("\n") >= 3:
                break
            if proc.poll() is not None:
                pytest.fail(f"radar-capture ended early: {proc.communicate()}")
            time.sleep(0.02)
        else:
            pytest.fail("fewer than 3 odometry lines after 60 s")
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, stderr
    line = stdout.rstrip("\n")
    frames = int(re.match(r"radar-capture: (\d+) frames? ", line).group(1))
    assert re.fullmatch(summary_re(frames, 0, 0, r"\d+\.\d\d", "stopped"), line), line
    assert re.search(ODOM_PART, line), line
    rows = tum_rows(tum)
    assert len(rows) == frames >= 3
    np.testing.assert_allclose([float(r[0]) for r in rows], 0.1 * np.arange(frames), atol=1e-9)


# ------------------------------------------------------------------------ refusals
def test_odom_out_onto_an_existing_file_is_refused(sim_run, tmp_path, capture_main):
    existing = tmp_path / "old.tum"
    existing.write_text("0.000000000 1 2 0 0 0 0 1\n")
    os.utime(existing, ns=(1_000_000_000, 1_000_000_000))
    before = snapshot(existing)
    points, out = tmp_path / "points.csv", tmp_path / "out"
    proc = capture_main("--source", replay_url(sim_run), "--odom-out", existing,
                        "--points-out", points, "--record", out)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert len(proc.stderr.splitlines()) == 1, proc.stderr
    line = one_error_line(proc)
    assert str(existing) in line and "already exists" in line
    assert snapshot(existing) == before
    # Refused before anything was written.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.tum"]


@pytest.mark.parametrize("extra", [["--odom-out", "x.tum"], ["--estimator-config", "e.json"], ["--wheeled"],
                                   ["--no-wall-map"]], ids=["odom-out", "estimator-config", "wheeled", "no-wall-map"])
def test_no_odom_with_an_estimator_option_is_a_usage_error(sim_run, tmp_path, extra, capture_main, monkeypatch):
    (tmp_path / "e.json").write_text("{}")
    before = sorted(os.listdir(tmp_path))
    monkeypatch.chdir(tmp_path)  # the relative x.tum and e.json are there, as for a run started there
    proc = capture_main("--source", replay_url(sim_run), "--no-odom", *extra)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert len(proc.stderr.splitlines()) == 1, proc.stderr
    line = one_error_line(proc)
    assert "--no-odom" in line and extra[0] in line
    assert sorted(os.listdir(tmp_path)) == before


BAD_CONFIGS = {
    # case: (file text, what the message must name besides the file)
    "malformed-json": ("{ not json", ["cannot read", "line 1"]),
    "not-an-object": ("[1, 2]", ["JSON object"]),
    "unknown-key": ('{"bogus": 1}', ["bogus"]),
    "unknown-nested-key": ('{"icp": {"bogus": 1}}', ["icp.bogus"]),
    "wrong-type": ('{"features": {"k": "many"}}', ["k:", "'many'", "integer"]),
    "wrong-type-section": ('{"features": 5}', ["features:", "5"]),
    "wrong-type-bool": ('{"icp": {"two_way": "yes"}}', ["two_way:", "'yes'", "boolean"]),
    "bad-value": ('{"icp": {"iterations": 0}}', ["icp.iterations:", "must be in [1, 1000], got 0"]),
    "bad-choice": ('{"features": {"method": "sift"}}', ["method:", "sift", "topk"]),
}


@pytest.mark.parametrize("case", list(BAD_CONFIGS))
def test_bad_estimator_config_is_one_clear_line(sim_run, tmp_path, case, capture_main):
    text, words = BAD_CONFIGS[case]
    cfg = tmp_path / "estimator.json"
    cfg.write_text(text)
    tum = tmp_path / "x.tum"
    proc = capture_main("--source", replay_url(sim_run), "--estimator-config", cfg, "--odom-out", tum)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert len(proc.stderr.splitlines()) == 1, proc.stderr
    line = one_error_line(proc)  # also: no traceback
    assert line.startswith(f"radar-capture: error: {cfg}: "), line
    for word in words:
        assert word in line, (word, line)
    assert not tum.exists()


def test_missing_estimator_config_file(sim_run, tmp_path):
    missing = tmp_path / "nope.json"
    # A subprocess on purpose: the file's end-to-end check of the installed console script.
    proc = run_capture_cli("--source", replay_url(sim_run), "--estimator-config", missing)
    assert proc.returncode == 2
    line = one_error_line(proc)
    assert line.startswith(f"radar-capture: error: {missing}: ") and "No such file" in line, line


def test_a_bad_value_in_a_section_is_named_by_its_path(sim_run, tmp_path, capture_main):
    cfg = tmp_path / "estimator.json"
    cfg.write_text('{"icp": {"iterations": "many"}}')
    proc = capture_main("--source", replay_url(sim_run), "--estimator-config", cfg)
    assert proc.returncode == 2
    assert "icp.iterations" in one_error_line(proc)


def test_settings_that_cannot_run_on_the_cfg_fail_before_overwrite_replaces_anything(sim_run, tmp_path, capture_main):
    """A CFAR window longer than the cfg's heatmap, found when the first frame came, had already
    let --overwrite replace the recording; a nested CFAR field was named without its section."""
    defaults = EstimatorConfig().to_dict()
    record = tmp_path / "run"
    # The recording to be kept is made recording only: no estimator nor publisher to load.
    proc = capture_main("--source", replay_url(sim_run) + "&frames=3", "--record", record, "--no-odom",
                        "--no-publish")
    assert proc.returncode == 0, proc.stderr
    before = {p.name: p.read_bytes() for p in record.iterdir()}
    cases = [({"features": {**defaults["features"], "method": "cfar",
                            "cfar": {**defaults["features"]["cfar"], "guard": 100}}},
              "features.cfar: a window of guard 100 and train 8 spans 217 range cells, more than the heatmap's"),
             ({"features": {"cfar": {**defaults["features"]["cfar"], "channels": 0}}},
              "features.cfar.channels: must be at least 1, got 0")]
    for settings, message in cases:
        path = tmp_path / "estimator.json"
        path.write_text(json.dumps(settings))
        proc = capture_main("--source", replay_url(sim_run), "--record", record, "--overwrite",
                            "--estimator-config", path)
        assert proc.returncode == 2
        assert one_error_line(proc).startswith(f"radar-capture: error: {path}: {message}"), proc.stderr
        assert {p.name: p.read_bytes() for p in record.iterdir()} == before


def test_wheeled_alone_keeps_the_settings_files_mount(sim_run, tmp_path, capture_main):
    # --wheeled without --mount replaced the file's mount_x_m with the axis, then refused it.
    path = tmp_path / "mounted.json"
    path.write_text(json.dumps({"odometry": {"mount_x_m": 0.3}}))
    proc = capture_main("--source", replay_url(sim_run) + "&frames=3", "--estimator-config", path, "--wheeled")
    assert proc.returncode == 0, proc.stderr
    # The same mount given by both is one (its height is the TF's alone); two mounts were the
    # option's without a word (hunt 4), now refused.
    proc = capture_main("--source", replay_url(sim_run) + "&frames=3", "--estimator-config", path,
                        "--mount", "0.3,0,0.2,0")
    assert proc.returncode == 0, proc.stderr
    proc = capture_main("--source", replay_url(sim_run) + "&frames=3", "--estimator-config", path,
                        "--mount", "0.3,0,0,10")
    assert proc.returncode == 2 and one_error_line(proc) == (
        f"radar-capture: error: --mount 0.3,0,0,10 and --estimator-config {path}'s odometry mount (x 0.3 m, y 0 m, "
        "yaw 0 degrees) differ: give the mount once"), proc.stderr


def test_the_wall_map_corrects_the_heading_unless_turned_off(sim_run, default_replay, tmp_path):
    """The map of wall directions (``wall_map.use``, on by default; docs/estimator.md): the
    corridor's walls, seen while it drives straight, move the heading by their points' noise;
    --no-wall-map and a settings file's ``"use": false`` publish the odometry's own."""
    config = tmp_path / "no-walls.json"
    config.write_text(json.dumps({"wall_map": {"use": False}}))
    # With the walls: the default settings' replay (default_replay's messages).
    outputs = {"walls": default_replay.odom, **{name: tmp_path / f"{name}.jsonl" for name in ("flag", "file")}}
    procs = run_together(*(dict(args=console_command("radar-capture") + [
        "--source", replay_url(sim_run), "--no-publish", "--odom-json", outputs[name], *extra],
        stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120) for name, extra in
        (("flag", ["--no-wall-map"]), ("file", ["--estimator-config", config]))))
    for proc in procs:
        assert proc.returncode == 0, proc.stderr
    states = {name: [{k: v for k, v in json.loads(line).items() if k != "compute_ms"}
                     for line in path.read_text().splitlines()] for name, path in outputs.items()}
    plain = states["flag"]
    assert states["file"] == plain
    assert len(states["walls"]) == len(plain) >= 20
    changed = [a["yaw"] != b["yaw"] for a, b in zip(states["walls"], plain)]
    assert any(changed) and not any(changed[:10])  # not before a window of frames has seen a wall
    assert [a["yaw"] for a in states["walls"]] == pytest.approx([b["yaw"] for b in plain], abs=math.radians(0.5))


def test_exporting_full_heatmaps_does_not_change_the_odometry(sim_run, default_replay, tmp_path, capture_main):
    """--heatmap-out writes every cell's dominant Doppler, the estimator takes its strongest
    cells' only: the export is made apart, and the odometry is the same to the last digit."""
    # The run without the export is default_replay's: the same options but --heatmap-out.
    plain, exported, heatmaps = default_replay.tum, tmp_path / "exported.tum", tmp_path / "heatmaps"
    proc = capture_main("--source", replay_url(sim_run), "--no-publish", "--odom-out", exported,
                        "--odom-json", tmp_path / "exported.jsonl", "--heatmap-out", heatmaps)
    assert proc.returncode == 0, proc.stderr
    assert plain.read_bytes() == exported.read_bytes()
    index = json.loads((heatmaps / "index.json").read_text())
    assert len(index["frames"]) == len(plain.read_text().splitlines()) >= 20
    doppler = np.load(heatmaps / f"{index['frames'][-1]['frame']:06d}_doppler.npy")
    assert np.isfinite(doppler).all()  # the full map, not the estimator's strongest cells


def test_a_recording_of_a_replayed_simulation_keeps_its_simulated_board(sim_run, tmp_path, capture_main):
    """The simulator block (scene, seed, board and its calibration) goes into a recording of the
    replay, which replay:// then checks a cfg's calibration line against, as the original's."""
    copy = tmp_path / "copy"
    proc = capture_main("--source", replay_url(sim_run) + "&frames=3", "--record", copy, "--no-odom",
                        "--no-publish")
    assert proc.returncode == 0, proc.stderr
    original = json.loads((sim_run.rec / "capture.json").read_text())["simulator"]
    assert json.loads((copy / "capture.json").read_text())["simulator"] == original
    from radarodom.driver.sources import open_source

    with open_source(f"replay://{sim_run.rec}") as a, open_source(f"replay://{copy}") as b:
        assert a.calibrated is b.calibrated is not None


def test_an_uncreatable_odom_out_leaves_nothing_behind(sim_run, tmp_path, capture_main):
    points, heatmaps = tmp_path / "points.csv", tmp_path / "heatmaps"
    proc = capture_main("--source", replay_url(sim_run), "--points-out", points, "--heatmap-out", heatmaps,
                        "--odom-out", tmp_path / "no-such-dir" / "x.tum")
    assert proc.returncode != 0
    assert "no-such-dir" in one_error_line(proc)
    assert sorted(os.listdir(tmp_path)) == []


# ------------------------------------------------------------------ a radar on a wheeled base
def test_a_radar_on_a_wheeled_bases_axis_does_not_slide_sideways(sim_run, tmp_path):
    """--wheeled without --mount (the radar on the axis; it was refused: its Doppler sees no yaw
    rate there) takes the velocity along the base's forward axis, once learnt from the straight
    frames (5 here), from the settings file as from the flag."""
    # The three runs replay the module's recording of the corridor (SIM_URL) rather than each
    # simulating it.
    learn, wheeled = tmp_path / "learn.json", tmp_path / "wheeled.json"
    learn.write_text(json.dumps({"odometry": {"axis_learn_frames": 5}}))
    wheeled.write_text(json.dumps({"odometry": {"base": "wheeled", "axis_learn_frames": 5}}))
    outputs = {name: tmp_path / f"{name}.jsonl" for name in ("flag", "file", "any")}
    extras = {"flag": ["--wheeled", "--estimator-config", learn], "file": ["--estimator-config", wheeled],
              "any": ["--estimator-config", learn]}
    procs = run_together(*(dict(args=console_command("radar-capture") + [
        "--source", replay_url(sim_run), "--no-publish", "--odom-json", outputs[name], *extra],
        stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120) for name, extra in extras.items()))
    for proc in procs:
        assert proc.returncode == 0, proc.stderr
    states = {name: [{k: v for k, v in json.loads(line).items() if k != "compute_ms"}
                     for line in path.read_text().splitlines()] for name, path in outputs.items()}
    assert len(states["flag"]) == len(states["any"]) >= 15
    assert states["flag"] == states["file"]
    learnt = next(k for k, (a, b) in enumerate(zip(states["flag"], states["any"])) if a != b)
    assert 5 <= learnt < len(states["any"]) - 5  # the fit's velocity until five frames drove straight
    moving = [s for s in states["flag"][learnt:] if abs(s["vx"]) > 0.1]
    assert moving and all(abs(s["vy"]) <= math.tan(math.radians(2.0)) * abs(s["vx"]) for s in moving)


def test_a_mounted_radar_on_a_wheeled_base_measures_its_turn_in_place(tmp_path, capture_main):
    """The radar 0.3 m ahead of a wheeled base's axis, turning in place among reflectors: with
    --mount and --wheeled the odometry turns as the base did (its Doppler sees the turn)."""
    rng = np.random.default_rng(4)
    angles, ranges = rng.uniform(-np.pi, np.pi, 40), rng.uniform(2.0, 7.0, 40)
    scene = {"name": "spin", "radar": {"snr_db": 10.0},
             "objects": [{"type": "corner_reflector", "rcs_dbsm": 5.0,
                          "position": [float(r * np.cos(a)), float(r * np.sin(a)), 0.6]} for a, r in zip(angles, ranges)],
             "trajectory": {"start": [0, 0, 0], "mount": [0.3, 0.0, 0.0],
                            "segments": [{"pause": 0.5}, {"rotate": 90, "rate": 45}, {"pause": 0.5}]}}
    path = tmp_path / "spin.json"
    path.write_text(json.dumps(scene))
    tum = tmp_path / "spin.tum"
    proc = capture_main("--source", f"sim://{path}?rate=max&fidelity=fast", "--no-publish", "--odom-out", tum,
                        "--mount", "0.3,0,0.4,0", "--wheeled")
    assert proc.returncode == 0, proc.stderr
    yaw = np.degrees(yaw_of(poses(tum)[:, 4:]))
    assert yaw[-1] == pytest.approx(90.0, abs=3.0)
