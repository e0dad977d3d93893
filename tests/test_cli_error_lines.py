"""An error or a warning is one line on the terminal whatever the user's input held: a path's or a
URL's newline, tab or escape sequence (``\\x1b[2J`` clears the screen) is written as its Python
escape, never sent raw to the terminal.  And an option that takes one value, given twice, is
refused rather than one of them dropped without a word."""

from __future__ import annotations

import subprocess

from conftest import console_command
from hypothesis import given
from hypothesis import strategies as st

from radarodom.errors import one_line

HOSTILE = "a\nb\x1b[2J\tc\r\x7f\x85\u202e"


@given(st.text())
def test_one_line_has_no_control_character_and_keeps_printable_text(text):
    shown = one_line(text)
    assert all(ch.isprintable() or ch == " " for ch in shown)
    if text.isprintable():
        assert shown == text
    assert one_line(shown) == shown  # what it shows is shown as it is


def test_one_line_writes_each_control_as_its_escape():
    assert one_line(HOSTILE) == "a\\nb\\x1b[2J\\tc\\r\\x7f\\x85\\u202e"
    assert one_line("né 中 x") == "né 中 x"


def test_a_path_and_a_url_with_controls_give_one_error_line(tmp_path):
    bad = str(tmp_path / f"no{HOSTILE}.tum")
    for argv, what in ((["radar-eval", bad, bad], "no such file"),
                       (["radar-cfg", bad], "cannot read the file"),
                       (["radar-capture", "--no-publish", "--source", f"sim://corr{HOSTILE}idor"], "no such scene")):
        proc = subprocess.run(console_command(argv[0]) + argv[1:], stdin=subprocess.DEVNULL, capture_output=True,
                              text=True, timeout=60)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(f"{argv[0]}: error: "), repr(proc.stderr)
        assert "\x1b" not in proc.stderr and "\r" not in proc.stderr and "\\x1b[2J" in proc.stderr
        assert what in proc.stderr


def test_an_unknown_option_with_controls_is_shown_escaped():
    proc = subprocess.run(console_command("radar-eval") + ["a.tum", "b.tum", f"--bogus{HOSTILE}"],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and proc.stderr.splitlines()[-1] == f"radar-eval: error: unrecognized arguments: " \
        f"--bogus{one_line(HOSTILE)}", proc.stderr
    assert "\x1b" not in proc.stderr


def test_an_option_given_twice_is_refused_naming_both(tmp_path, capsys):
    """``--odom-out a --odom-out b`` wrote b alone, ``--view save:`` twice one view: refused, exit 2,
    before any output is written; flags and list options still repeat."""
    from radarodom.tools import cli, radar_capture

    base = ["--source", "sim://lab?rate=max&fidelity=fast&duration=0.2", "--no-publish", "-q"]
    a, b = tmp_path / "a.tum", tmp_path / "b.tum"
    for twice, message in (
            (["--odom-out", str(a), "--odom-out", str(b)],
             f"argument --odom-out: given twice (--odom-out {str(a)!r}, then {str(b)!r}): give it once"),
            (["--frames", "2", "--frames=3"], "argument --frames: given twice (--frames 2, then 3): give it once"),
            (["--view", f"save:{a}.rrd", "--view", f"save:{b}.rrd"], "argument --view: given twice")):
        rc = radar_capture.main(base + twice)
        stderr = capsys.readouterr().err
        assert rc == 2 and stderr.startswith(f"radar-capture: error: {message}"), stderr
        assert stderr.count("\n") == 1, stderr
        assert list(tmp_path.iterdir()) == []
    # Flags and lists repeat as before; made so twice and parsing twice, a parser refuses nothing more.
    parser = radar_capture.build_parser()
    for _ in range(2):
        cli._refuse_repeats(parser)
        args = parser.parse_args(["-v", "-v", "--connect", "tcp/127.0.0.1:1", "--connect", "tcp/127.0.0.1:2"])
        assert args.connect == ["tcp/127.0.0.1:1", "tcp/127.0.0.1:2"]
