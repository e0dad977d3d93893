"""Solved CFAR scales kept on disk (radarodom.dsp.kept_scales): a program after the first reads
them, the same to the last bit, without importing scipy's integration and root finding; a damaged
or unwritable cache only means solving again.  And pyFFTW imported without its Dask interface."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys

import pytest

from radarodom.dsp import kept_scales

#: Builds the frame processor of the shipped cfg with the estimator's DSP settings, as
#: radar-capture does, and prints its CFARs' scales and what it imported.
BUILD = """
import json, sys
from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.estimator.config import EstimatorConfig
from radarodom.pipeline.products import FrameProducts
products = FrameProducts.for_estimator(RadarConfig.from_file(shipped_config_path()), EstimatorConfig().features)
params = products.processor.params
print(json.dumps({"scales": [params.range_cfar.scale.hex(), params.range_cfar.edge_scale.hex(),
                             params.doppler_cfar.scale.hex(), params.range_cfar.noise_factor.hex()],
                  "imported": sorted(m for m in ("scipy.integrate", "scipy.optimize", "dask") if m in sys.modules)}))
"""


def _build(cache: str) -> dict:
    env = dict(os.environ, RADARODOM_CACHE_DIR=str(cache))
    proc = subprocess.run([sys.executable, "-c", BUILD], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""  # nothing said about the cache at the default log level
    return json.loads(proc.stdout)


def _kept_files(cache) -> list[str]:
    return sorted(name for name in os.listdir(cache) if name.startswith("cfar-scales-"))


def test_the_second_program_reads_the_scales_the_first_solved(tmp_path):
    cache = tmp_path / "cache"
    first = _build(cache)
    assert "scipy.integrate" in first["imported"]  # solved here
    [name] = _kept_files(cache)
    kept = json.loads((cache / name).read_text())
    assert any(key.startswith("summed_scale('os'") for key in kept), kept
    second = _build(cache)
    assert second["scales"] == first["scales"]  # to the last bit
    assert "scipy.integrate" not in second["imported"] and "scipy.optimize" not in second["imported"]
    assert json.loads((cache / name).read_text()) == kept  # nothing new to keep


def test_a_damaged_or_unwritable_cache_only_means_solving_again(tmp_path):
    reference = _build(tmp_path / "fresh")["scales"]
    cache = tmp_path / "damaged"
    cache.mkdir()
    [name] = _kept_files(tmp_path / "fresh")
    (cache / name).write_text('{"summed_scale(\'os\'": [1, 2')  # cut short
    assert _build(cache)["scales"] == reference
    assert json.loads((cache / name).read_text()).keys() == json.loads((tmp_path / "fresh" / name).read_text()).keys()
    blocked = tmp_path / "a-file"
    blocked.write_text("not a directory")
    assert _build(blocked / "cache")["scales"] == reference
    assert blocked.read_text() == "not a directory"
    assert not [p for p in tmp_path.rglob(".cfar-scales-*")]  # no temporary file left


@pytest.mark.parametrize("text", [
    "[" * 200_000 + "]" * 200_000,  # was "internal error: RecursionError" in every program with a DSP
    '{"k": NaN}', '{"k": Infinity}', '{"k": 1e400}',  # were used: no point in any frame
    '{"k": -5.0}', '{"k": 0}',  # were used: every cell a point
    '{"k": "7"}', '{"k": true}', '{"k": [7]}', "[7]", '{"k": 7, "k": 8}',
])
def test_a_file_of_impossible_scales_is_not_read(tmp_path, text):
    path = tmp_path / "kept.json"
    path.write_text(text)
    assert kept_scales._read(str(path)) == {}


def test_only_a_regular_file_is_read(tmp_path):
    """A pipe where the file goes hung every program that builds a DSP (its open waited for a writer)."""
    path = tmp_path / "kept.json"
    os.mkfifo(path)
    assert kept_scales._read(str(path)) == {}
    path.unlink()
    path.mkdir()
    assert kept_scales._read(str(path)) == {}
    path.rmdir()
    path.write_text('{"summed_scale(\'os\', 8)": 12.5, "noise_factor(\'ca\')": 1}')
    assert kept_scales._read(str(path)) == {"summed_scale('os', 8)": 12.5, "noise_factor('ca')": 1.0}


def test_where_the_cache_is(monkeypatch, tmp_path):
    monkeypatch.delenv("RADARODOM_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert kept_scales.cache_dir() == str(tmp_path / "xdg" / "radarodom")
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert kept_scales.cache_dir() == str(tmp_path / "home" / ".cache" / "radarodom")
    monkeypatch.setenv("RADARODOM_CACHE_DIR", str(tmp_path / "given"))
    assert kept_scales.kept_path().startswith(str(tmp_path / "given" / "cfar-scales-"))


def test_a_kept_function_takes_numbers_and_strings_only():
    with pytest.raises(TypeError, match="a number, a string or None"):
        kept_scales.kept(lambda x: 1.0)([1.0])


@pytest.mark.skipif(importlib.util.find_spec("pyfftw") is None or importlib.util.find_spec("dask") is None,
                    reason="needs both pyFFTW and Dask installed")
def test_pyfftw_comes_without_dask_and_dask_still_imports_after():
    code = ("import sys\nfrom radarodom.dsp.fft import fftw_available\nassert fftw_available()\n"
            "assert 'dask' not in sys.modules, sorted(m for m in sys.modules if m.startswith('dask'))\n"
            "import dask.array\nprint(dask.array.ones(3).sum().compute())")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "3.0", proc.stderr
