"""Issue 18: the simulator's bytes depended on the BLAS thread count (``radar-sim`` and
``sim://...&rate=max`` with the same seed differed by one ADC count in some frames).  With
``fidelity="exact"`` every frame is the same bytes whatever the threads, the program or the
order frames are made in."""

from __future__ import annotations

import hashlib
import json
import os
import sys

import numpy as np
import pytest
from conftest import console_command, run_together

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.recordings.capture_dir import ADC_DATA
from radarodom.driver.sim.physics import EXACT_PRODUCT_COLUMNS, exact_product
from radarodom.driver.sim.scene import load_scene
from radarodom.driver.sim.simulator import Simulator
from radarodom.driver.sources import open_source

#: Frames of the corridor (moving at walking speed among about a thousand paths) that came out
#: one ADC count apart with one and two OpenBLAS threads before the fix.
FRAMES = range(8, 15)

_HASH_FRAMES = """
import hashlib, json, sys
from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.sim.scene import load_scene
from radarodom.driver.sim.simulator import Simulator
sim = Simulator(RadarConfig.from_file(shipped_config_path()), load_scene("corridor", seed=2), seed=2)
print(json.dumps([hashlib.sha256(sim.frame(i).raw).hexdigest() for i in json.loads(sys.argv[1])]))
"""


def _blas_env(threads: int) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    env.update(OPENBLAS_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads), MKL_NUM_THREADS=str(threads))
    return env


@pytest.fixture(scope="module")
def subprocess_hashes() -> dict[int, list[str]]:
    """{BLAS threads: the FRAMES' hashes made in a process of their own with that many}, the three
    processes run at the same time (a process's BLAS threads are its own whatever runs beside
    it); the tests below read them."""
    calls = [dict(args=[sys.executable, "-c", _HASH_FRAMES, json.dumps(list(FRAMES))], env=_blas_env(threads),
                  capture_output=True, text=True, timeout=300, check=True) for threads in (1, 2, 4)]
    return {threads: json.loads(proc.stdout) for threads, proc in zip((1, 2, 4), run_together(*calls))}


def test_frames_are_the_same_bytes_with_one_two_and_four_blas_threads(subprocess_hashes):
    one = subprocess_hashes[1]
    assert subprocess_hashes[2] == one
    assert subprocess_hashes[4] == one


def test_frames_do_not_depend_on_the_order_they_are_made_in(subprocess_hashes):
    cfg = RadarConfig.from_file(shipped_config_path())
    in_order = Simulator(cfg, load_scene("corridor", seed=2), seed=2)
    expected = [in_order.frame(i).raw for i in FRAMES]
    backwards = Simulator(cfg, load_scene("corridor", seed=2), seed=2)
    got = {i: backwards.frame(i).raw for i in reversed(FRAMES)}
    assert [got[i] for i in FRAMES] == expected
    assert subprocess_hashes[2] == [hashlib.sha256(raw).hexdigest() for raw in expected]


def test_radar_sim_and_sim_rate_max_record_the_same_bytes(tmp_path):
    """radar-sim (BLAS threads as the environment says, here two) and radar-capture (which runs
    OpenBLAS on one thread) with sim://...&rate=max, run at the same time."""
    sim_out, cap_out = tmp_path / "radar_sim", tmp_path / "capture"
    procs = run_together(
        dict(args=console_command("radar-sim") + ["corridor", "--seed", "2", "--duration", "1.5", "--out", str(sim_out),
                                                  "-q"], env=_blas_env(2), capture_output=True, text=True, timeout=300),
        dict(args=console_command("radar-capture") + ["--source", "sim://corridor?seed=2&rate=max&duration=1.5",
                                                      "--record", str(cap_out), "--no-publish", "--no-odom", "-q"],
             env=_blas_env(1), capture_output=True, text=True, timeout=300))
    for proc in procs:
        assert proc.returncode == 0, proc.stderr
    a, b = (sim_out / ADC_DATA).read_bytes(), (cap_out / ADC_DATA).read_bytes()
    assert len(a) == len(b) > 0
    frame = len(a) // 15
    differing = [k for k in range(15) if a[k * frame:(k + 1) * frame] != b[k * frame:(k + 1) * frame]]
    assert differing == []


def test_the_exact_product_is_far_finer_than_an_adc_count_and_sums_every_block():
    rng = np.random.default_rng(5)
    k = 2 * EXACT_PRODUCT_COLUMNS + 37  # three blocks, the last one short
    a = (rng.standard_normal((48, k)) + 1j * rng.standard_normal((48, k))).astype(np.complex64) * 30
    b = np.exp(1j * rng.uniform(0, 2 * np.pi, (k, 64))).astype(np.complex64)
    a[:, EXACT_PRODUCT_COLUMNS:2 * EXACT_PRODUCT_COLUMNS] = 0  # an all-zero block adds nothing
    out = np.empty((48, 64), np.complex64)
    exact_product(a, b, out)
    reference = a.astype(np.complex128) @ b.astype(np.complex128)
    assert np.abs(out - reference).max() < 1e-2  # ADC counts, on sums of about 2000 counts
    empty = np.ones((3, 4), np.complex64)
    exact_product(np.zeros((3, 0), np.complex64), np.zeros((0, 4), np.complex64), empty)
    assert not empty.any()


def test_radar_sim_fast_fidelity_records_what_sim_fast_streams(tmp_path):
    """radar-sim --fidelity fast (one BLAS thread, as radar-capture runs it) writes the bytes
    sim://...&fidelity=fast makes, and says the fidelity in the recording's source."""
    sim_out, cap_out = tmp_path / "radar_sim", tmp_path / "capture"
    procs = run_together(
        dict(args=console_command("radar-sim") + ["corridor", "--seed", "2", "--duration", "0.5", "--fidelity", "fast",
                                                  "--out", str(sim_out), "-q"],
             env=_blas_env(1), capture_output=True, text=True, timeout=300),
        dict(args=console_command("radar-capture") + ["--source", "sim://corridor?seed=2&rate=max&duration=0.5&fidelity=fast",
                                                      "--record", str(cap_out), "--no-publish", "--no-odom", "-q"],
             env=_blas_env(1), capture_output=True, text=True, timeout=300))
    for proc in procs:
        assert proc.returncode == 0, proc.stderr
    assert (sim_out / ADC_DATA).read_bytes() == (cap_out / ADC_DATA).read_bytes()
    assert "fidelity=fast" in (sim_out / "capture.json").read_text()


def test_a_noise_seed_draws_other_noise_over_the_same_scene():
    """The same scene, scatterers and path with the noise drawn again: each frame differs from the
    seed's by the two draws of thermal noise alone, and the seed's own number as noise seed changes
    nothing."""
    cfg = RadarConfig.from_file(shipped_config_path())
    scene = load_scene("corridor", seed=2)

    def cube(sim: Simulator, i: int) -> np.ndarray:
        return sim.layout.decode(sim.frame(i).raw).astype(np.complex128)

    plain, again, other = (Simulator(cfg, scene, seed=2, noise_seed=n) for n in (None, 2, 7))
    assert plain.frame(3).raw == again.frame(3).raw
    a, b = cube(plain, 3), cube(other, 3)
    assert not np.array_equal(a, b)
    # The difference is two draws of the noise: its power is twice the noise's, within a few percent
    # (the cube holds some 10^5 samples), and the scene's echo is in both.
    noise_power = 2.0 * scene.noise_counts ** 2
    diff = a - b
    assert abs(np.mean(np.abs(diff) ** 2) / (2.0 * noise_power) - 1.0) < 0.05
    assert np.mean(np.abs(a) ** 2) > 3.0 * noise_power


def test_radar_sim_and_sim_record_their_noise_seed(tmp_path):
    """radar-sim --noise-seed records the frames the Simulator makes with it and says the noise seed
    in its output, capture.json and source URL; sim://...&noise_seed= streams the same frames."""
    out = tmp_path / "noise7"
    proc = run_together(dict(args=console_command("radar-sim") + [
        "corridor", "--seed", "2", "--noise-seed", "7", "--duration", "0.2", "--out", str(out)],
        capture_output=True, text=True, timeout=300))[0]
    assert proc.returncode == 0, proc.stderr
    assert "seed 2, noise seed 7" in proc.stdout
    meta = json.loads((out / "capture.json").read_text())
    assert meta["simulator"]["noise_seed"] == 7 and meta["simulator"]["seed"] == 2
    assert "noise_seed=7" in meta["source"]
    cfg = RadarConfig.from_file(shipped_config_path())
    expected = Simulator(cfg, load_scene("corridor", seed=2), seed=2, noise_seed=7, fidelity="exact")
    assert (out / ADC_DATA).read_bytes()[:expected.layout.frame_bytes] == expected.frame(0).raw
    with open_source("sim://corridor?seed=2&noise_seed=7&rate=max&duration=0.2") as source:
        assert source.describe()["noise_seed"] == 7
        assert bytes(next(iter(source)).raw) == expected.frame(0).raw
