"""A program whose standard output cannot be written (sent to a full disk, or closed) says so in
one line, exit 1, and keeps the outputs it wrote; a closed pipe (``| head``) still ends it quietly."""

from __future__ import annotations

import os
import subprocess

import pytest
from conftest import console_command

pytestmark = pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs Linux's /dev/full (a full disk)")

FULL = "cannot write to the standard output: No space left on device; free some space, or send it elsewhere"
CFG = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "configs", "awr1843_raw.cfg")


def _run(args, stdout):
    return subprocess.run(args, stdout=stdout, stderr=subprocess.PIPE, text=True, timeout=120)


@pytest.fixture
def tum(tmp_path):
    path = tmp_path / "gt.tum"
    path.write_text("".join(f"{1 + i / 10:.1f} {i * 0.2:.1f} 0 0 0 0 0 1\n" for i in range(20)))
    return path


@pytest.mark.parametrize("program, args", [
    ("radar-eval", ["TUM", "TUM"]),  # once "internal error: OSError: [Errno 28] No space left on device"
    ("radar-cfg", [CFG]),
    ("radar-cfg", ["--help"]),  # once exit 0, the help lost without a word
    ("radar-eval", ["--version"]),
])
def test_a_full_disk_on_stdout_is_one_line_and_exit_1(tum, program, args):
    with open("/dev/full", "w") as full:
        proc = _run(console_command(program) + [str(tum) if a == "TUM" else a for a in args], full)
    assert proc.returncode == 1
    lines = [line for line in proc.stderr.splitlines() if ": warning: " not in line]
    assert lines == [f"{program}: {'error: ' + FULL}"], proc.stderr
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr


def test_the_outputs_written_are_kept(tmp_path):
    odom = tmp_path / "odom.tum"
    # Fast fidelity: what is checked is the summary's failed write and the trajectory kept, not the
    # simulator's exact bytes.
    with open("/dev/full", "w") as full:
        proc = _run(console_command("radar-capture") + ["--source", "sim://lab?rate=max&fidelity=fast&duration=0.5",
                                                       "--no-publish", "--odom-out", str(odom)], full)
    assert proc.returncode == 1 and proc.stderr.rstrip().endswith(f"radar-capture: error: {FULL}"), proc.stderr
    assert len(odom.read_text().splitlines()) >= 2


@pytest.mark.parametrize("program, args", [
    ("radar-cfg", [CFG, "--json"]),  # once "internal error: AttributeError: 'NoneType' object has no attribute 'write'"
    ("radar-cfg", ["--list", "--json"]),
    ("radar-eval", ["TUM", "TUM"]),  # once exit 0, its report lost without a word (print to None)
    ("radar-cfg", ["--help"]),
])
def test_a_closed_stdout_is_one_line_and_exit_1(tum, program, args):
    """Started with its standard output closed (``>&-``, where Python's sys.stdout is None)."""
    argv = console_command(program) + [str(tum) if a == "TUM" else a for a in args]
    proc = subprocess.run(["sh", "-c", 'exec "$@" >&-', "sh", *argv], stderr=subprocess.PIPE, text=True, timeout=120)
    assert proc.returncode == 1
    lines = [line for line in proc.stderr.splitlines() if ": warning: " not in line]
    assert lines == [f"{program}: error: cannot write to the standard output: it is closed"], proc.stderr


def test_a_run_with_its_stdout_closed_keeps_its_recording(tmp_path):
    proc = subprocess.run(["sh", "-c", 'exec "$@" >&-', "sh", *console_command("radar-capture"), "--source",
                           "sim://lab?rate=max&fidelity=fast&duration=0.3", "--no-publish", "-q", "--record",
                           str(tmp_path / "rec")], stderr=subprocess.PIPE, text=True, timeout=120)
    assert proc.returncode == 1 and proc.stderr.endswith("it is closed\n"), proc.stderr  # its summary
    assert (tmp_path / "rec" / "capture.json").is_file()  # the recording kept


def test_a_closed_pipe_still_ends_quietly(tum):
    proc = subprocess.Popen(console_command("radar-eval") + [str(tum), str(tum)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    proc.stdout.close()  # the reader gone before a byte is read: '| true'
    _, err = proc.communicate(timeout=120)
    assert proc.returncode in (0, 1) and err == ""


def test_a_program_that_prints_normally_is_unchanged(tum):
    proc = _run(console_command("radar-eval") + [str(tum), str(tum)], subprocess.PIPE)
    assert proc.returncode == 0 and proc.stderr == "" and "yaw" in proc.stdout.lower()


@pytest.mark.parametrize("stderr", ["closed", "full"])
def test_an_error_that_cannot_be_said_still_gets_its_exit_code(tmp_path, stderr):
    """stderr closed (2>&-) or on a full disk (2>/dev/full): a bad cfg's error is lost, but the exit
    code is still the bad input's 2 (a full stderr gave 1, a traceback's), and nothing goes to
    stdout (a closed stderr's error was printed there: print(file=None) writes to stdout)."""
    bad = tmp_path / "bad.cfg"
    bad.write_text("bogus 1 2\n")
    redirect = "2>&-" if stderr == "closed" else "2>/dev/full"
    proc = subprocess.run(["sh", "-c", f'exec "$@" {redirect}', "sh", *console_command("radar-cfg"), str(bad)],
                          stdout=subprocess.PIPE, text=True, timeout=120)
    assert (proc.returncode, proc.stdout) == (2, "")
