"""bench/matrix_recordings.py: the matrix's recordings kept across a change to the simulator's
sources only once the cells it records anew are the same as before, byte for byte."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
import matrix_recordings as mr  # noqa: E402
import robustness_matrix as rm  # noqa: E402
import sequences  # noqa: E402
from bench_recordings import shared_recording  # noqa: E402

#: A short loop (turns at 90 deg/s, straights of 0.5 m): a few seconds to record.
CELL = rm.SimCell(scene="room", turn_rate_dps=90.0, straight_m=0.5)
OTHER = dataclasses.replace(CELL, seed=1)
OLD_FP = "0123456789abcdef"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """CELL recorded by today's simulator, with its DSP products and without its ADC samples, as
    the matrix keeps it."""
    data = str(tmp_path_factory.mktemp("matrix"))
    # The run's one recording of CELL (rm.record's, its products made) copied: its ADC is dropped here.
    shared = shared_recording(CELL, tmp_path_factory)
    directory = rm._sequence_dir(CELL, data)
    rm.copy_recording(shared, directory)
    assert os.path.basename(directory) == os.path.basename(shared)
    rm.drop_adc(directory)
    return directory


def _as_earlier(recording: str, data: str, cell, monkeypatch) -> str:
    """A copy of *recording* as *cell*'s under the key of an earlier simulator (OLD_FP)."""
    with monkeypatch.context() as m:
        m.setattr(rm, "sim_fingerprint", lambda: OLD_FP)
        old = rm._sequence_dir(cell, data)
    shutil.copytree(recording, old)
    with open(old + ".scene.json", "w", encoding="utf-8") as fh:
        json.dump(rm.scene_spec(cell), fh)
    with open(os.path.join(old, "capture.json"), encoding="utf-8") as fh:
        meta = json.load(fh)
    meta["source"] = f"sim://{old}.scene.json?seed={cell.seed}&fidelity=fast"  # as radar-sim wrote it there
    with open(os.path.join(old, "capture.json"), "w", encoding="utf-8") as fh:
        json.dump(meta, fh)
    return old


def test_earlier_recordings_are_kept_once_a_cell_recorded_anew_is_the_same(tmp_path, recorded, monkeypatch):
    data = str(tmp_path)
    old_checked = _as_earlier(recorded, data, CELL, monkeypatch)
    old_other = _as_earlier(recorded, data, OTHER, monkeypatch)
    (tmp_path / old_other / "mark").write_text("kept as it was")
    assert mr.earlier(CELL, data) == old_checked and mr.earlier(OTHER, data) == old_other
    said = []
    assert mr.keep_recordings([CELL, OTHER], data, workers=1, log=said.append) == 0
    assert "1 cells recorded under today's key the same as before; 1 earlier recordings kept" in said[-1]
    # seed 0 was recorded anew (its earlier copy dropped); seed 1's earlier recording moved, not made again
    assert not os.path.exists(old_checked) and not os.path.exists(old_other)
    assert not os.path.exists(old_checked + ".scene.json") and not os.path.exists(old_other + ".scene.json")
    today = rm._sequence_dir(OTHER, data)
    assert rm.record(OTHER, data) == today and (tmp_path / today / "mark").read_text() == "kept as it was"
    with open(os.path.join(today, "capture.json"), encoding="utf-8") as fh:
        source = json.load(fh)["source"]
    assert source == f"sim://{today}.scene.json?seed=1&fidelity=fast"
    assert os.path.exists(today + ".scene.json")
    assert not os.path.exists(os.path.join(rm._sequence_dir(CELL, data), "adc_data.bin"))  # dropped as the matrix does
    said.clear()
    assert mr.keep_recordings([CELL, OTHER], data, workers=1, log=said.append) == 0
    assert "nothing to keep" in said[-1]


def test_a_difference_keeps_every_earlier_recording_out(tmp_path, recorded, monkeypatch):
    data = str(tmp_path)
    shutil.copytree(recorded, rm._sequence_dir(CELL, data))  # today's, already recorded: compared as it is
    old_checked = _as_earlier(recorded, data, CELL, monkeypatch)
    old_other = _as_earlier(recorded, data, OTHER, monkeypatch)
    with open(os.path.join(old_checked, "groundtruth.tum"), "a", encoding="utf-8") as fh:
        fh.write("# one more line\n")
    argv = ["--scenes", "room", "--seeds", "0", "1", "--cfgs", "shipped", "--snr", "0", "--speeds", "0.8",
            "--turn-rates", "90", "--movers", "scene", "--mounts", "0", "--straight", "0.5", "--data", data,
            "--workers", "1"]
    assert mr.main(argv + ["--dry-run"]) == 0 and os.path.exists(old_other)
    said = []
    assert mr.keep_recordings([CELL, OTHER], data, workers=1, log=said.append) == 1
    assert said[-1].startswith(f"{CELL.name}: groundtruth.tum differs from its earlier recording")
    assert os.path.exists(old_other) and not os.path.exists(rm._sequence_dir(OTHER, data))
    # a scene file other than today's is another loop: not a recording of the cell
    with open(old_other + ".scene.json", "w", encoding="utf-8") as fh:
        json.dump({**rm.scene_spec(OTHER), "name": "elsewhere"}, fh)
    assert mr.earlier(OTHER, data) is None


def test_products_that_differ_are_named(tmp_path, recorded):
    import numpy as np
    other = tmp_path / "other"
    shutil.copytree(recorded, other)
    assert mr.difference(recorded, str(other)) is None
    path = sequences.cache_path(str(other))
    with np.load(path) as products:
        arrays = {k: products[k] for k in products.files}
    arrays["intensity"] = arrays["intensity"] * 1.0001
    np.savez(path, **arrays)
    assert mr.difference(recorded, str(other)) == "the DSP products' 'intensity' differ"


OLD_PRODUCTS = "dsp-0123456789abcdef.npz"


def _under_an_earlier_dsp(recording: str, data: str, cell) -> str:
    """A copy of *recording* as *cell*'s today, its DSP products as an earlier DSP's (OLD_PRODUCTS)."""
    directory = rm._sequence_dir(cell, data)
    shutil.copytree(recording, directory)
    os.replace(sequences.cache_path(directory), os.path.join(directory, OLD_PRODUCTS))
    return directory


def test_earlier_dsp_products_are_linked_once_a_cell_made_anew_gives_the_same(tmp_path, recorded):
    """The check seed's cell is recorded anew and its products under today's DSP compared; the same,
    so the other cell's earlier products become today's (a link: the earlier name stays)."""
    data = str(tmp_path)
    checked, other = _under_an_earlier_dsp(recorded, data, CELL), _under_an_earlier_dsp(recorded, data, OTHER)
    said = []
    assert mr.keep_products([CELL, OTHER], data, workers=1, dry_run=True, log=said.append) == 0
    assert not os.path.exists(sequences.cache_path(other))
    assert mr.keep_products([CELL, OTHER], data, workers=1, log=said.append) == 0
    assert said[-1] == "1 cells' DSP products the same under today's DSP; 1 cells' earlier products linked as today's"
    linked, earlier = sequences.cache_path(other), os.path.join(other, OLD_PRODUCTS)
    assert os.path.samefile(linked, earlier)
    # The checked cell: recorded anew, today's products made, its ADC dropped, its earlier products kept.
    assert os.path.exists(sequences.cache_path(checked)) and os.path.exists(os.path.join(checked, OLD_PRODUCTS))
    assert not os.path.exists(os.path.join(checked, "adc_data.bin"))
    assert mr.keep_products([CELL, OTHER], data, workers=1, log=said.append) == 0
    assert "nothing to keep" in said[-1]


def test_earlier_dsp_products_that_differ_keep_every_cells_out(tmp_path, recorded):
    import numpy as np
    data = str(tmp_path)
    checked, other = _under_an_earlier_dsp(recorded, data, CELL), _under_an_earlier_dsp(recorded, data, OTHER)
    made = sequences.cache_path(checked)
    shutil.copyfile(os.path.join(checked, OLD_PRODUCTS), made)  # made by today's DSP already: compared as it is
    with np.load(made) as products:
        arrays = {k: products[k] for k in products.files}
    arrays["doppler"] = arrays["doppler"] + 1e-3
    np.savez(made, **arrays)
    said = []
    assert mr.keep_products([CELL, OTHER], data, workers=1, log=said.append) == 1
    assert said[-1].startswith(f"{CELL.name}: the DSP products' 'doppler' differ from the earlier DSP's")
    assert not os.path.exists(sequences.cache_path(other))


def test_damaged_dsp_products_are_said_and_made_again(tmp_path, capsys):
    """A products file cut short (a run killed as it wrote) was a BadZipFile traceback naming no file."""
    path = tmp_path / "dsp-x.npz"
    np.savez(path, counts=np.arange(3), times=np.zeros(3))
    assert list(sequences._cached(str(path))["counts"]) == [0, 1, 2]
    path.write_bytes(path.read_bytes()[:100])
    assert sequences._cached(str(path)) is None
    assert capsys.readouterr().err.startswith(f"{path}: damaged (BadZipFile: ")
    assert sequences._cached(str(tmp_path / "none.npz")) is None
