"""The Python examples of the docs run as written (docs/estimator.md's used a `frames` it never
made).  The subscriber of the README and docs/messages.md runs in tests/test_publish.py."""

from __future__ import annotations

import re
import subprocess
import sys

from conftest import REPO


def _python_block(page: str, heading: str) -> str:
    text = (REPO / page).read_text()
    section = text[text.index(heading):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_estimators_python_example_runs_and_drives_forward(tmp_path):
    code = _python_block("docs/estimator.md", "## Settings and use from Python")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 30, len(lines)  # three seconds at the shipped cfg's 10 frames a second
    assert lines[0].startswith("0.00 0.00 0.000 0.00 ['first_frame'] ")
    x = [float(line.split()[0]) for line in lines]
    assert x == sorted(x) and 1.5 < x[-1] < 2.5, x[-1]  # the corridor's path: forward, about 1.9 m by then
    assert list(tmp_path.iterdir()) == []  # it writes nothing
