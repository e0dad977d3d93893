"""bench/scene_edits.py: a matrix cell named as the matrix names it, its scene's objects listed, and
the cell recorded again with objects left out (the same recording, byte for byte, with none left
out; its first seconds alone with --duration); and heading_diagnosis.py --straights on such
recordings, chain by chain."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import re
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
import heading_diagnosis as hd  # noqa: E402
import matrix_cells as mc  # noqa: E402
import robustness_matrix as rm  # noqa: E402
import scene_edits  # noqa: E402
from bench_recordings import shared_recording  # noqa: E402

#: The short loop of tests/test_heading_diagnosis.py (turns at 90 deg/s, straights of 0.5 m).
CELL = rm.SimCell(scene="room", turn_rate_dps=90.0, straight_m=0.5)


def test_every_cell_of_the_matrix_is_found_again_by_its_name():
    parser = argparse.ArgumentParser()
    rm.add_cell_arguments(parser)
    cells = rm.selected_cells(parser.parse_args([]))
    assert len(cells) == 288  # 252 until TI's SDK profiles became cfgs sdk2d and sdk3d (docs/heading.md item 37)
    assert all(mc.SimCell.from_name(c.name) == c for c in cells)
    for cell in (CELL, mc.SimCell("lab", 3, "2tx", -15.0, 1.5, 30.0, "people", 2.5, 0.3, "exact")):
        assert mc.SimCell.from_name(cell.name) == cell
    for wrong in ("kitchen_s0_shipped_snr0_v0.8_w45_scene_L3", "room_s0_3tx_snr0_v0.8_w45_scene_L3",
                  "room_s0_shipped_snr0_v0.8_w45_cats_L3", "room_s0", ""):
        with pytest.raises(ValueError, match="not a simulated cell's name"):
            mc.SimCell.from_name(wrong)


def test_objects_are_left_out_by_number():
    spec = mc.scene_spec(CELL)
    objects = spec["objects"]
    assert len(objects) == 10
    assert scene_edits.edited(spec)["objects"] == objects
    assert scene_edits.edited(spec, without=[4, 0])["objects"] == [o for i, o in enumerate(objects) if i not in (0, 4)]
    assert scene_edits.edited(spec, only=[4])["objects"] == [objects[4]]
    assert scene_edits.edited(spec, only=[])["objects"] == []
    # Only the objects change: the walls, the loop and the radar stay the cell's.
    assert {k: v for k, v in scene_edits.edited(spec, only=[]).items() if k != "objects"} == \
        {k: v for k, v in spec.items() if k != "objects"}
    with pytest.raises(ValueError, match="no object numbered 10, -1: the scene's objects are 0-9"):
        scene_edits.edited(spec, without=[10, -1])


def test_the_list_numbers_the_objects_and_bad_input_exits_2(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert scene_edits.main([CELL.name, "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [int(line.split()[0]) for line in lines] == list(range(10))
    assert lines[4].split()[1] == "box" and "center [6.4, 3.1]" in lines[4]
    assert re.search(r"; the loop passes (\d\.\d\d) m from it$", lines[4])
    assert "(occludes)" in lines[5]
    assert lines[9].split()[1] == "door" and "passes" not in lines[9]
    path = scene_edits.radar_path(mc.scene_spec(CELL))
    for line, obj in zip(lines, mc.scene_spec(CELL)["objects"]):
        distance = mc.object_distance(obj, path)
        if distance is not None:
            assert line.endswith(f"passes {distance:.2f} m from it")
            assert distance >= mc.CLEARANCE_M  # the matrix's loops keep clear of everything
    for argv, message in (([CELL.name, "--only", "11", "--out", "x"], "no object numbered 11"),
                          (["room_s9", "--list"], "not a simulated cell's name"),
                          ([CELL.name, "--only"], "--out DIR is needed"),
                          ([CELL.name, "--azimuth-hpbw", "0", "--out", "x"],
                           "radar.azimuth_hpbw_deg: must be from 1 to 179 degrees, got 0")):
        with pytest.raises(SystemExit) as exc:
            scene_edits.main(argv)
        assert exc.value.code == 2
        assert message in capsys.readouterr().err
    assert not os.listdir(tmp_path)  # nothing recorded nor written for a refused edit


def test_a_cell_recorded_again_is_its_own_recording_and_edited_differs(tmp_path, tmp_path_factory, capsys):
    own = shared_recording(CELL, tmp_path_factory)  # rm.record's, made once for the run: read only
    whole_adc = pathlib.Path(own, "adc_data.bin").read_bytes()
    whole_frames = len(pathlib.Path(own, "timestamps.txt").read_text().splitlines())
    # Its first second recorded again with nothing left out: the recording's first ten frames.
    same = tmp_path / "same"
    rm.simulate(scene_edits.edited(mc.scene_spec(CELL)), CELL, str(same), duration_s=1.0)
    same_adc = (same / "adc_data.bin").read_bytes()
    assert len(same_adc) * whole_frames == len(whole_adc) * 10 and same_adc == whole_adc[:len(same_adc)]
    walls = tmp_path / "walls"
    walls.mkdir()
    (walls / "stale").write_text("an earlier recording's")  # replaced, not refused
    assert scene_edits.main([CELL.name, "--only", "--duration", "1", "--out", str(walls)]) == 0
    assert capsys.readouterr().out.strip() == f"{walls}: {CELL.name} with 0 object(s), its first 1 s"
    with open(f"{walls}.scene.json", encoding="utf-8") as fh:
        assert json.load(fh)["objects"] == []
    assert not os.path.exists(f"{walls}.tmp") and not (walls / "stale").exists()
    walls_adc = (walls / "adc_data.bin").read_bytes()
    assert len(walls_adc) == len(same_adc) and walls_adc != same_adc

    # Each straight chain by chain: without the map of wall directions the estimate's heading is
    # the two chains' blended half and half, so over each straight its error is their mean.
    settings = tmp_path / "no_wall_map.json"
    settings.write_text(json.dumps({"wall_map": {"use": False}}))
    assert hd.main([own, "--straights", "1", "--min-straight-m", "0.3", "--estimator-config", str(settings)]) == 0
    found = re.findall(r"straight from frame \d+, [\d.]+ m: estimate [-+\d.]+ deg/m \(([-+\d.]+) deg\), heatmaps' "
                       r"chain [-+\d.]+ \(([-+\d.]+) deg\), points' chain [-+\d.]+ \(([-+\d.]+) deg\)",
                       capsys.readouterr().out)
    assert len(found) >= 2
    for estimate, heatmaps, points in found:
        assert float(estimate) == pytest.approx(0.5 * (float(heatmaps) + float(points)), abs=0.011)
    assert any(abs(float(h) - float(p)) > 0.05 for _, h, p in found)


def test_the_radar_is_edited_flat_and_its_beam_widened(tmp_path, capsys):
    from radarodom.driver.sim.scene import scene_from_dict
    spec = mc.scene_spec(CELL)
    flat = scene_edits.edited(spec, flat=True, beam={"azimuth_hpbw_deg": 80.0})
    assert flat["objects"] == spec["objects"] and flat["trajectory"] == spec["trajectory"]
    assert flat["flat"] is True and flat["radar"] == {**spec.get("radar", {}), "azimuth_hpbw_deg": 80.0}
    scene = scene_from_dict(flat)
    assert scene.flat and scene.pattern.azimuth_hpbw_deg == 80.0 and scene.pattern.elevation_hpbw_deg == 40.0
    assert "flat" not in scene_edits.edited(spec) and scene_edits.edited(spec).get("radar") == spec.get("radar")
    out = tmp_path / "flat"
    assert scene_edits.main([CELL.name, "--flat", "--elevation-hpbw", "60", "--duration", "0.2",
                             "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == (f"{out}: {CELL.name} with 10 object(s), flat, its first 0.2 s, "
                                               "elevation_hpbw_deg 60")
    with open(f"{out}.scene.json", encoding="utf-8") as fh:
        written = json.load(fh)
    assert written["flat"] is True and written["radar"]["elevation_hpbw_deg"] == 60.0
    assert os.path.getsize(out / "adc_data.bin") > 0


@pytest.mark.parametrize("scene", ["room", "lab", "corridor"])
def test_the_scene_and_its_loop_are_mirrored_left_to_right(scene):
    from scipy.spatial import cKDTree

    from radarodom.driver.sim.scene import scene_from_dict
    cell = rm.SimCell(scene=scene, turn_rate_dps=90.0, straight_m=0.5)
    spec = mc.scene_spec(cell)
    mirror = scene_edits.mirrored(spec)
    assert scene_edits.mirrored(mirror) == spec and spec == mc.scene_spec(cell)  # an involution; spec untouched
    flip = np.array([1.0, -1.0])
    np.testing.assert_allclose(scene_edits.radar_path(mirror), scene_edits.radar_path(spec) * flip, atol=1e-9)
    a, b = scene_from_dict(spec, seed=3), scene_from_dict(mirror, seed=3)
    # The walls that hide what is behind them mirrored, and every scatterer (a door's recess
    # behind it, a box's faces, the floor's) where the mirror image puts one: within the
    # surfaces' sampling (0.35 m) of one of the scene's own.
    def segments(scene, f):
        return sorted(sorted((round(float(x), 6), round(float(y) * f, 6)) for x, y in ends)
                      for ends in zip(scene.wall_a, scene.wall_b))
    assert segments(b, -1.0) == segments(a, 1.0)
    assert b.num_static == a.num_static
    distance, _ = cKDTree(a.static.pos * [1.0, -1.0, 1.0]).query(b.static.pos)
    assert distance.max() < 0.35
    if a.movers:
        assert [m.path.tolist() for m in b.movers] == [(m.path * flip).tolist() for m in a.movers]


def test_the_turn_in_place_reversed_and_the_noise_drawn_anew(tmp_path, capsys):
    """--turn-in-place-reversed: the loop's turn in place the other way, the radar facing the same way
    after it, twice the same loop again; --noise-seed reaches radar-sim; a loop without such a turn is
    refused by name."""
    from radarodom.driver.sim.trajectory import from_spec
    spec = mc.scene_spec(CELL)
    right = scene_edits.turned_in_place_reversed(spec)
    assert right["objects"] == spec["objects"] and mc.scene_spec(CELL) == spec  # spec untouched
    assert scene_edits.turned_in_place_reversed(right) == spec
    a, b = from_spec(spec["trajectory"]), from_spec(right["trajectory"])
    turning = np.abs(np.angle(np.exp(1j * (a.yaw - b.yaw)))) > 1e-4  # else the same heading
    assert turning.any() and np.abs(a.yaw[-1] - b.yaw[-1]) == pytest.approx(2 * np.pi, abs=1e-6)
    # The same path up to the turn; after it within centimetres (the braking into the turn and the
    # start after it, which the turn overlaps, curve the other way).
    first = np.flatnonzero(turning)[0]
    np.testing.assert_allclose([b.x[:first], b.y[:first]], [a.x[:first], a.y[:first]], atol=1e-9)
    assert np.hypot(a.x - b.x, a.y - b.y).max() < 0.05
    # Within the turn each has turned as far as the other, the other way.
    start = a.yaw[first - 1]
    np.testing.assert_allclose(b.yaw[turning] - start, -(a.yaw[turning] - start), atol=1e-4)
    twice = dict(right, trajectory=dict(right["trajectory"], segments=right["trajectory"]["segments"] * 2))
    with pytest.raises(ValueError, match="no single turn in place of 180 degrees"):
        scene_edits.turned_in_place_reversed(twice)
    out = tmp_path / "right"
    assert scene_edits.main([CELL.name, "--turn-in-place-reversed", "--noise-seed", "5", "--duration", "0.2",
                             "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == (f"{out}: {CELL.name} with 10 object(s), turned in place to the right, "
                                               "noise seed 5, its first 0.2 s")
    with open(out / "capture.json", encoding="utf-8") as fh:
        assert json.load(fh)["simulator"]["noise_seed"] == 5
    # An odd seed's loop turns in place to the right: reversed, to the left; mirrored, to the left
    # too; both, to the right again.
    odd = dataclasses.replace(CELL, seed=1)
    rotate = lambda spec: [seg["rotate"] for seg in spec["trajectory"]["segments"] if "rotate" in seg]  # noqa: E731
    assert rotate(mc.scene_spec(odd)) == [-180] and rotate(mc.scene_spec(CELL)) == [180]
    assert rotate(scene_edits.turned_in_place_reversed(mc.scene_spec(odd))) == [180]
    assert rotate(scene_edits.mirrored(mc.scene_spec(odd))) == [180]
    assert scene_edits.main([odd.name, "--mirror", "--turn-in-place-reversed", "--duration", "0.2",
                             "--out", str(tmp_path / "odd")]) == 0
    assert capsys.readouterr().out.strip().endswith("mirrored, turned in place to the right, its first 0.2 s")
    with open(f"{tmp_path / 'odd'}.scene.json", encoding="utf-8") as fh:
        assert rotate(json.load(fh)) == [-180]
