"""radar-cfg, the command-line program: exit codes, output, error lines.

Most cases call ``radarodom.tools.radar_cfg.main`` in-process (conftest's run_main, or with capsys);
the installed console script runs in a subprocess (what a user runs) once end to end, and to read
/dev/zero (a regression would fill the memory of the process that reads).
"""

from __future__ import annotations

import json
import pathlib
import os
import re
import subprocess

import pytest
from conftest import REPO, SMALL_CFG, console_command

from radarodom.cfg import RAW_LVDS_LINE, RadarConfig, shipped_config_path
from radarodom.tools import radar_cfg

SHIPPED = REPO / "configs" / "awr1843_raw.cfg"

STABLE_KEYS = ("range_resolution_m", "max_range_m", "velocity_resolution_mps", "max_velocity_mps",
               "frame_bytes", "frame_period_s", "data_rate_mbps", "num_tx", "num_rx", "num_samples",
               "num_loops", "tx_order")


def run_cfg_script(*args) -> subprocess.CompletedProcess:
    return subprocess.run(console_command("radar-cfg") + [str(a) for a in args],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)


@pytest.fixture
def run_cfg(run_main, monkeypatch):
    """radar-cfg in this process (conftest's run_main), in the directory
    *cwd* when given (it resolves the relative paths it is given there)."""
    def run(*args, cwd=None) -> subprocess.CompletedProcess:
        with monkeypatch.context() as patch:
            if cwd is not None:
                patch.chdir(cwd)
            return run_main("radar-cfg", *args)
    return run


def write_cfg(tmp_path, old: str | None = None, new: str | None = None, name: str = "test.cfg"):
    """SMALL_CFG with line *old* replaced by *new*; returns (path, 1-based line number)."""
    lines = SMALL_CFG.splitlines()
    lineno = None
    if old is not None:
        lineno = lines.index(old) + 1
        lines[lineno - 1] = new
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path, lineno


def _table(stdout: str) -> dict[str, tuple[float, str]]:
    """The '  label   value unit' rows of the human output."""
    rows = {}
    for line in stdout.splitlines():
        m = re.match(r"^  (\S.*?)\s{2,}(-?\d+(?:\.\d+)?) (\S+)$", line)
        if m:
            rows[m.group(1)] = (float(m.group(2)), m.group(3))
    return rows


# --------------------------------------------------------------------- valid cfg
def test_shipped_cfg_prints_derived_quantities_with_units(shipped_cfg, run_cfg):
    proc = run_cfg("configs/awr1843_raw.cfg", cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    # The shipped cfg carries the identity calibration line: one warning, naming the line and the fix.
    line = next(n for n, text in enumerate(SHIPPED.read_text().splitlines(), start=1)
                if text.startswith("compRangeBiasAndRxChanPhase"))
    assert proc.stderr.startswith(f"radar-cfg: warning: configs/awr1843_raw.cfg:{line}: "
                                  "compRangeBiasAndRxChanPhase is the identity")
    assert "radar-calibrate" in proc.stderr and len(proc.stderr.splitlines()) == 1
    assert "channel calibration      identity" in proc.stdout
    lines = proc.stdout.splitlines()
    assert lines[0] == "configs/awr1843_raw.cfg: valid xWR18xx configuration"
    assert "note:" not in proc.stdout  # the shipped cfg streams raw ADC and fits the DCA1000
    # ... and not TI's demo's UART (tidemo://, without a DCA1000): what that needs is said.
    assert "  demo UART load           141.5 %  (tidemo://, without a DCA1000: 64 points a frame at 921600 " \
           "baud)\n                           over 100 %: tidemo:// refuses it; it needs a frameCfg period of at " \
           "least 130 ms; or fewer range bins (profileCfg's numAdcSamples 128 or less)\n" in proc.stdout, proc.stdout
    rows = _table(proc.stdout)
    cfg = shipped_cfg
    # (label, value in the printed unit, unit, tolerance: half the last printed digit)
    expected = [
        ("range resolution", cfg.range_resolution_m, "m", 5e-5),
        ("max range (80% IF)", cfg.max_range_m, "m", 5e-3),
        ("velocity resolution", cfg.velocity_resolution_mps, "m/s", 5e-5),
        ("max velocity (+/-)", cfg.max_velocity_mps, "m/s", 5e-4),
        ("carrier (ADC centre)", cfg.carrier_frequency_hz * 1e-9, "GHz", 5e-4),
        ("sampled bandwidth", cfg.bandwidth_hz * 1e-6, "MHz", 5e-2),
        ("chirp time", cfg.chirp_time_s * 1e6, "us", 5e-3),
        ("frame period", cfg.frame_period_s * 1e3, "ms", 5e-4),
        ("frame size", cfg.frame_bytes, "bytes", 0),
        ("raw data rate", cfg.data_rate_mbps, "Mbit/s", 5e-3),
    ]
    for label, value, unit, tol in expected:
        assert label in rows, f"no row {label!r} in:\n{proc.stdout}"
        got, got_unit = rows[label]
        assert got_unit == unit, label
        assert got == pytest.approx(value, abs=tol + 1e-12), label
    # Independent of cfg.py: the figures the shipped cfg's own header comments state.
    assert rows["range resolution"][0] == pytest.approx(0.049, abs=0.001)
    assert rows["max range (80% IF)"][0] == pytest.approx(10.0, abs=0.05)
    assert rows["max velocity (+/-)"][0] == pytest.approx(2.3, abs=0.05)
    assert rows["velocity resolution"][0] == pytest.approx(0.07, abs=0.001)
    assert rows["frame size"][0] == 786432
    assert rows["frame period"][0] == 100.0
    assert rows["raw data rate"][0] == pytest.approx(63, abs=0.5)
    assert "TX1 TX3 TX2" in proc.stdout and "12 virtual antennas" in proc.stdout
    assert "64 loops x 3 chirps x 256 samples" in proc.stdout


def test_a_tx_that_fires_twice_a_frame_is_counted_as_one_antenna(tmp_path, capsys):
    """TX1, TX3, TX3 (the third chirp on TX3 again): two TX, eight virtual antennas, twelve
    channels; "2 TX, 12 virtual antennas" contradicted itself."""
    text = SHIPPED.read_text()
    twice = re.sub(r"^chirpCfg 2 2 0 0 0 0 0 2\b", "chirpCfg 2 2 0 0 0 0 0 4", text, flags=re.M)
    assert twice != text
    path = tmp_path / "twice.cfg"
    path.write_text(twice)
    assert radar_cfg.main([str(path)]) == 0
    assert "TX1 TX3 TX3  (2 TX in 3 chirps, 4 RX, 8 virtual antennas in 12 channels)" in capsys.readouterr().out


def _check_stable_keys(data: dict, cfg: RadarConfig) -> None:
    for key in STABLE_KEYS:
        assert key in data, key
    assert data["range_resolution_m"] == cfg.range_resolution_m
    assert data["max_range_m"] == cfg.max_range_m
    assert data["velocity_resolution_mps"] == cfg.velocity_resolution_mps
    assert data["max_velocity_mps"] == cfg.max_velocity_mps
    assert data["frame_bytes"] == cfg.frame_bytes
    assert data["frame_period_s"] == cfg.frame_period_s
    assert data["data_rate_mbps"] == cfg.data_rate_mbps
    assert data["num_tx"] == cfg.num_tx
    assert data["num_rx"] == cfg.num_rx
    assert data["num_samples"] == cfg.num_samples
    assert data["num_loops"] == cfg.num_loops
    assert data["tx_order"] == list(cfg.tx_order)


def test_json_subprocess_has_stable_keys(shipped_cfg):
    proc = run_cfg_script(SHIPPED, "--json")  # the console script itself, end to end
    assert proc.returncode == 0, proc.stderr
    assert "compRangeBiasAndRxChanPhase is the identity" in proc.stderr  # the warning, on stderr only
    data = json.loads(proc.stdout)  # nothing but JSON on stdout
    _check_stable_keys(data, shipped_cfg)
    assert data["frame_bytes"] == 786432 and data["tx_order"] == [1, 3, 2]
    assert data["num_tx"] == 3 and data["num_rx"] == 4
    assert data["num_samples"] == 256 and data["num_loops"] == 64
    assert data["streams_raw_adc"] is True
    calibration = data["calibration"]
    assert calibration["identity"] is True and calibration["range_bias_m"] == 0.0
    assert calibration["coefficients"] == [[1.0, 0.0]] * 12
    assert calibration["gain_db"] == [0.0] * 12 and calibration["phase_deg"] == [0.0] * 12


def test_json_in_process(tmp_path, small_cfg, capsys):
    path, _ = write_cfg(tmp_path)
    assert radar_cfg.main([str(path), "--json"]) == 0
    out, err = capsys.readouterr()
    # The small cfg streams raw ADC (meant for a board) and has no calibration line: one warning.
    assert err.startswith(f"radar-cfg: warning: {path}: compRangeBiasAndRxChanPhase is missing")
    assert len(err.splitlines()) == 1
    data = json.loads(out)
    _check_stable_keys(data, small_cfg)
    load = data.pop("demo_uart_load")  # what tidemo:// would ask of the demo's UART
    assert data == json.loads(json.dumps(small_cfg.summary()))
    assert data["frame_bytes"] == 3072 and data["frame_period_s"] == 0.05
    assert 0 < load < 1


def test_packet_delay_changes_capacity(tmp_path, capsys):
    path, _ = write_cfg(tmp_path)
    assert radar_cfg.main([str(path), "--json", "--packet-delay-us", "5"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["packet_delay_us"] == 5.0
    assert data["dca1000_capacity_mbps"] == pytest.approx(706.0)  # UG Table 19


# ------------------------------------------------------------------- invalid cfg
BAD_LINES = [
    # (line in SMALL_CFG, replacement, command, field)
    ("profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30",
     "profileCfg 0 77 100 6 40 0 0 96 1 15 8000 0 0 30", "profileCfg", "numAdcSamples"),
    ("profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30",
     "profileCfg 0 77 abc 6 40 0 0 96 1 16 8000 0 0 30", "profileCfg", "idleTime"),
    ("adcCfg 2 1", "adcCfg 1 1", "adcCfg", "numADCBits"),
    ("frameCfg 0 2 4 0 50 1 0", "frameCfg 0 2 4 0 1 1 0", "frameCfg", "framePeriodicity"),
]


@pytest.mark.parametrize("old,new,command,field", BAD_LINES,
                         ids=["odd-samples", "not-a-number", "14-bit", "period-too-short"])
def test_invalid_cfg_one_line_with_location(tmp_path, old, new, command, field, run_cfg):
    path, lineno = write_cfg(tmp_path, old, new, "bad.cfg")
    proc = run_cfg(path)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert re.fullmatch(rf"radar-cfg: error: {re.escape(str(path))}:{lineno}: {command}: {field}: \S.*",
                        lines[0]), lines[0]
    assert "Traceback" not in proc.stderr


def test_invalid_cfg_verbose_shows_traceback(tmp_path, run_cfg):
    old, new, command, field = BAD_LINES[0]
    path, lineno = write_cfg(tmp_path, old, new, "bad.cfg")
    proc = run_cfg("--verbose", path)
    assert proc.returncode == 2
    assert f"radar-cfg: error: {path}:{lineno}: {command}: {field}: " in proc.stderr
    assert "Traceback (most recent call last)" in proc.stderr
    assert "ConfigError" in proc.stderr


def test_invalid_cfg_in_process(tmp_path, capsys):
    old, new, command, field = BAD_LINES[0]
    path, lineno = write_cfg(tmp_path, old, new, "bad.cfg")
    assert radar_cfg.main([str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.splitlines() == [err.rstrip("\n")]
    assert err.startswith(f"radar-cfg: error: {path}:{lineno}: {command}: {field}: ")
    assert "Traceback" not in err


def test_missing_file_exits_2(tmp_path, run_cfg):
    path = tmp_path / "nope.cfg"
    proc = run_cfg(path)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"radar-cfg: error: {path}: ")
    assert "Traceback" not in proc.stderr


def test_no_argument_is_a_usage_error(run_cfg):
    proc = run_cfg()
    assert proc.returncode == 2
    assert "usage: radar-cfg" in proc.stderr
    assert "Traceback" not in proc.stderr


# ----------------------------------------------------------- lvdsStreamCfg note
def test_non_raw_lvds_is_valid_with_a_note(tmp_path, run_cfg):
    path, lineno = write_cfg(tmp_path, "lvdsStreamCfg -1 0 1 0", "lvdsStreamCfg -1 0 0 0", "ti.cfg")
    proc = run_cfg(path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0] == f"{path}: valid xWR18xx configuration"
    notes = [ln for ln in proc.stdout.splitlines() if "note:" in ln]
    assert len(notes) == 1, proc.stdout
    assert f"line {lineno}" in notes[0]
    assert "'lvdsStreamCfg -1 0 0 0'" in notes[0]
    assert f"'{RAW_LVDS_LINE}'" in notes[0] and RAW_LVDS_LINE == "lvdsStreamCfg -1 0 1 0"

    proc = run_cfg(path, "--json")
    assert proc.returncode == 0
    assert json.loads(proc.stdout)["streams_raw_adc"] is False


def test_missing_lvds_line_is_noted(tmp_path, capsys):
    path = tmp_path / "nolvds.cfg"
    path.write_text("".join(ln + "\n" for ln in SMALL_CFG.splitlines()
                            if not ln.startswith("lvdsStreamCfg")))
    assert radar_cfg.main([str(path)]) == 0
    out = capsys.readouterr().out
    notes = [ln for ln in out.splitlines() if "note:" in ln]
    assert len(notes) == 1 and "no lvdsStreamCfg line" in notes[0]
    assert "'lvdsStreamCfg -1 0 1 0'" in notes[0]


def test_help_exits_0(run_cfg):
    proc = run_cfg("--help")
    assert proc.returncode == 0
    assert proc.stdout.startswith("usage: radar-cfg")
    assert "--json" in proc.stdout and "--verbose" in proc.stdout
    assert proc.stderr == ""


def test_a_boards_line_is_shown_and_not_warned_about(tmp_path, shipped_cfg, run_cfg):
    """A cfg carrying a board's compRangeBiasAndRxChanPhase: the range bias and each path's gain
    and phase relative to TX1 RX1, as the line corrects them; no warning."""
    from radarodom.driver.sim.board import load_board

    board = load_board("uncalibrated")
    path = tmp_path / "board.cfg"
    shipped_cfg.replace(board.calibration().to_command()).write(path)
    proc = run_cfg(path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    lines = proc.stdout.splitlines()
    at = next(i for i, line in enumerate(lines) if "channel calibration" in line)
    assert lines[at + 1].strip() == "range bias +6.50 cm"
    rows = {line.split()[0]: line for line in lines[at + 2:at + 5]}
    assert set(rows) == {"TX1", "TX2", "TX3"}
    # TX2 RX3: the board's -0.8 - 1.0 dB and 28 + 22 degrees.
    assert "RX3 -1.80 dB   +50.0 deg" in rows["TX2"], rows["TX2"]
    data = json.loads(run_cfg(path, "--json").stdout)["calibration"]
    assert data["identity"] is False and data["range_bias_m"] == pytest.approx(0.065)
    assert data["gain_db"][6] == pytest.approx(-1.8, abs=0.01) and data["phase_deg"][6] == pytest.approx(50.0, abs=0.1)


# -------------------------------------------------- hostile options and files (issue 18)
@pytest.mark.parametrize("value", ["inf", "1e308", "nan", "-5", "0", "4.99", "500.5", "1_0", "\u0665", " 25"])
def test_packet_delay_outside_its_range_exits_2_naming_the_option(tmp_path, capsys, value):
    path, _ = write_cfg(tmp_path)
    assert radar_cfg.main([str(path), "--json", f"--packet-delay-us={value}"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert "argument --packet-delay-us: expected a number in 5..500 us" in err
    assert "internal error" not in err and "Traceback" not in err


@pytest.mark.parametrize("value", ["5", "25", "500", "1e2", "77.5"])
def test_packet_delay_inside_its_range_prints_strict_json(tmp_path, capsys, value):
    path, _ = write_cfg(tmp_path)
    assert radar_cfg.main([str(path), "--json", "--packet-delay-us", value]) == 0
    data = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(f"{c} in --json"))
    assert data["packet_delay_us"] == float(value) and data["dca1000_capacity_mbps"] > 0


def test_dev_zero_exits_2_with_the_size_limit():
    proc = run_cfg_script("/dev/zero")  # a subprocess: a regression would fill its memory, not the tests'
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("radar-cfg: error: /dev/zero: larger than 1 MiB")
    assert len(proc.stderr.splitlines()) == 1 and "MemoryError" not in proc.stderr


def test_a_cfg_with_a_huge_token_is_not_echoed(tmp_path, run_cfg):
    path, _ = write_cfg(tmp_path, "lowPower 0 0", "lowPower 0 " + "7" * 900_000)
    proc = run_cfg(path)
    assert proc.returncode == 2
    assert len(proc.stderr) < 400 and "900000 characters" in proc.stderr


# ------------------------------------------------- several files, --list, --copy (issue 19)
def test_several_files_are_each_reported_and_the_exit_status_is_the_worst(tmp_path, capsys, shipped_cfg):
    good, _ = write_cfg(tmp_path, name="good.cfg")
    bad, lineno = write_cfg(tmp_path, "frameCfg 0 2 4 0 50 1 0", "frameCfg 0 2 4 0 0.001 1 0", name="bad.cfg")
    missing = tmp_path / "missing.cfg"
    assert radar_cfg.main([str(good), str(bad), str(missing), str(SHIPPED)]) == 2
    out, err = capsys.readouterr()
    assert out.count(": valid xWR18xx configuration") == 2
    assert f"{good}: valid" in out and f"{SHIPPED}: valid" in out
    errors = [line for line in err.splitlines() if ": error: " in line]
    assert len(errors) == 2 and errors[0].startswith(f"radar-cfg: error: {bad}:{lineno}: frameCfg")
    assert errors[1].startswith(f"radar-cfg: error: {missing}: ")
    assert radar_cfg.main([str(good), str(SHIPPED)]) == 0
    capsys.readouterr()
    assert radar_cfg.main([str(good), str(bad), "--json"]) == 2
    out, err = capsys.readouterr()
    data = json.loads(out)
    assert list(data) == [str(good), str(bad)]
    assert data[str(good)]["frame_bytes"] == RadarConfig.from_file(good).frame_bytes
    assert set(data[str(bad)]) == {"error"} and data[str(bad)]["error"].startswith(f"{bad}:{lineno}: ")


def test_list_names_the_shipped_cfgs_with_a_description(run_cfg):
    proc = run_cfg("--list")
    assert proc.returncode == 0 and proc.stderr == ""
    shipped = sorted(p.name for p in (REPO / "configs").glob("*.cfg"))
    lines = proc.stdout.splitlines()
    assert [line.split()[0] for line in lines] == shipped
    assert lines[0].split(None, 1)[1] == ("raw ADC capture on the AWR1843BOOST with a DCA1000EVM "
                                          "(mmWave SDK 3.x demo firmware)")
    proc = run_cfg("--list", "--json")
    assert proc.returncode == 0 and proc.stderr == ""
    listed = json.loads(proc.stdout)
    assert list(listed) == shipped and listed["awr1843_raw.cfg"] == lines[0].split(None, 1)[1]
    proc = run_cfg("--copy", "awr1843_raw", "--json")
    assert proc.returncode == 2 and "--json goes with FILEs or --list, not --copy" in proc.stderr


def test_overwrite_without_copy_is_refused(tmp_path, run_cfg):
    """'radar-cfg FILE --overwrite' was taken and ignored: nothing but --copy writes."""
    proc = run_cfg(str(shipped_config_path()), "--overwrite")
    assert proc.returncode == 2 and "--overwrite goes with --copy" in proc.stderr, proc.stderr


def test_copy_onto_the_shipped_cfg_itself_is_refused(run_cfg):
    """'--copy awr1843_raw <the shipped file> --overwrite' rewrote the install's own file (exit 0)."""
    shipped = pathlib.Path(shipped_config_path())
    for dest in (shipped, shipped.parent):
        proc = run_cfg("--copy", "awr1843_raw", str(dest), "--overwrite")
        assert proc.returncode == 2 and "would write over the input the shipped cfg" in proc.stderr, proc.stderr


def test_copy_writes_a_shipped_cfg_and_never_overwrites_without_asking(tmp_path, run_cfg):
    proc = run_cfg("--copy", "awr1843_raw", cwd=tmp_path)  # default: NAME here
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "awr1843_raw.cfg").read_bytes() == SHIPPED.read_bytes()
    assert proc.stdout == "radar-cfg: copied awr1843_raw.cfg to awr1843_raw.cfg\n"
    mine = tmp_path / "mine.cfg"
    mine.write_text("% my edits\n")
    proc = run_cfg("--copy", "awr1843_raw.cfg", mine)
    assert proc.returncode == 2 and "already exists" in proc.stderr and "--overwrite" in proc.stderr
    assert mine.read_text() == "% my edits\n"
    proc = run_cfg("--copy", "awr1843_raw.cfg", mine, "--overwrite")
    assert proc.returncode == 0 and mine.read_bytes() == SHIPPED.read_bytes()
    sub = tmp_path / "sub"
    sub.mkdir()
    assert run_cfg("--copy", "awr1843_raw", sub).returncode == 0  # a directory: NAME in it
    assert (sub / "awr1843_raw.cfg").read_bytes() == SHIPPED.read_bytes()
    proc = run_cfg("--copy", "nosuch")
    assert proc.returncode == 2 and "no shipped cfg 'nosuch'" in proc.stderr and "awr1843_raw.cfg" in proc.stderr
    proc = run_cfg("--copy", "a", "b", "c")
    assert proc.returncode == 2 and "usage: radar-cfg" in proc.stderr
    proc = run_cfg("--list", SHIPPED)
    assert proc.returncode == 2 and "usage: radar-cfg" in proc.stderr


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc, where no file can be made")
def test_copy_to_a_directory_that_takes_no_files_says_what_where_why_and_the_fix(tmp_path, run_cfg):
    """Once only the kernel's "cannot write /proc/awr1843_raw.cfg: No such file or directory"."""
    proc = run_cfg("--copy", "awr1843_raw", "/proc")
    assert proc.returncode == 1 and proc.stdout == ""
    assert proc.stderr == ("radar-cfg: error: cannot write the copy of awr1843_raw.cfg to /proc/awr1843_raw.cfg: the "
                           "directory /proc takes no new files (the system says: No such file or directory); choose "
                           "a writable destination\n")


def test_copy_under_a_file_or_into_a_read_only_directory_is_refused_before_writing(tmp_path, capsys, monkeypatch):
    afile = tmp_path / "afile"
    afile.write_text("mine\n")
    for dest in (afile / "x.cfg", afile / "sub" / "x.cfg"):  # once "no directory .../afile/sub"
        assert radar_cfg.main(["--copy", "awr1843_raw", str(dest)]) == 2
        assert capsys.readouterr().err == (f"radar-cfg: error: cannot write the copy of awr1843_raw.cfg to {dest}: "
                                           f"{afile} is a file, not a directory; choose a writable destination\n")
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    # Root writes anywhere, so the directory is read-only as os.access tells it (the check asks it).
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: os.fspath(path) != str(locked)
                        and real_access(path, mode, **kw))
    assert radar_cfg.main(["--copy", "awr1843_raw", str(locked)]) == 2
    assert capsys.readouterr().err == (f"radar-cfg: error: cannot write the copy of awr1843_raw.cfg to "
                                       f"{locked / 'awr1843_raw.cfg'}: the directory {locked} is not writable; "
                                       "choose a writable destination\n")
    locked.chmod(0o755)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "locked"] and not any(locked.iterdir())


def test_the_usage_says_copy_takes_at_most_one_dest(tmp_path, run_cfg):
    usage = radar_cfg.build_parser().format_help()
    assert "--copy NAME [DEST]" in usage and "[DEST ...]" not in usage, usage
    proc = run_cfg("--copy", "awr1843_raw", tmp_path / "a", tmp_path / "b", cwd=tmp_path)
    assert proc.returncode == 2 and "--copy takes NAME and at most one DEST" in proc.stderr, proc.stderr


@pytest.mark.parametrize("argv, words", [
    (["--list", "FILE"], "FILEs and --list do not go together"),
    (["--copy", "awr1843_raw.cfg", "--list"], "--list and --copy do not go together"),
    ([], "give one or more FILEs, or --list, or --copy NAME [DEST]"),
])
def test_commands_given_together_or_none_are_named(tmp_path, capsys, argv, words):
    cfg = tmp_path / "my.cfg"
    cfg.write_text(SMALL_CFG)
    assert radar_cfg.main([str(cfg) if a == "FILE" else a for a in argv]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"radar-cfg: error: {words}" + (
        ": give one or more FILEs to check, or --list, or --copy NAME [DEST]" if "together" in words else "")


def test_a_sensor_start_before_the_radars_configuration_is_warned_of(tmp_path, capsys):
    # It validated without a word: radarodom sends its own sensorStart last, TI's tools do not.
    lines = SHIPPED.read_text().splitlines()
    moved = tmp_path / "early.cfg"
    moved.write_text("\n".join(["sensorStart"] + [ln for ln in lines if ln.strip() != "sensorStart"]) + "\n")
    assert radar_cfg.main([str(moved)]) == 0
    err = capsys.readouterr().err
    assert re.search(rf"warning: {re.escape(str(moved))}:1: sensorStart comes before \w+ \(line \d+\): .*put "
                     r"sensorStart last", err), err
    assert RadarConfig.from_file(moved).commands_to_send() == RadarConfig.from_file(SHIPPED).commands_to_send()
    assert radar_cfg.main([str(SHIPPED)]) == 0
    assert "sensorStart comes" not in capsys.readouterr().err
