"""``radar-capture --view web:PORT``: the page is served while the radar runs, a real headless
Chromium renders the view from it (the heatmap's colours on screen), and Ctrl-C ends the run
with the view's frames accounted for.  Skips the browser part when Chromium or the screenshot
tool (a developer's, in ../shared/tools) is absent."""

from __future__ import annotations

import os
import re
import pathlib
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

from conftest import REPO, make_capture

pytest.importorskip("rerun", reason='the view needs rerun-sdk (pip install "radarodom[view]")')
from test_view import GUARD_S, rerun_analytics_off  # noqa: E402,F401  (the fixture: analytics off here too)

from radarodom.view.target import ViewTarget, free_web_port, web_page_url  # noqa: E402

SHOT_TOOL = pathlib.Path(os.environ.get("RADARODOM_SHARED", REPO.parent / "shared")) / "tools" / "browser_shot.py"
#: viridis's darkest colour: the heatmap's noise floor, in the texture under the points and
#: in the polar image.
DARK_VIRIDIS = np.array([68, 1, 84])


def wait_for_page(url: str, proc: subprocess.Popen) -> str:
    deadline = time.monotonic() + GUARD_S
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        try:
            with urllib.request.urlopen(url, timeout=5) as reply:
                return reply.read().decode("utf-8", "replace")
        except OSError:
            time.sleep(0.5)
    pytest.fail(f"nothing served at {url}")


def test_the_web_viewer_is_served_and_renders_the_view(tmp_path, small_cfg):
    make_capture(tmp_path / "src", small_cfg, 40, poses=True, seed=2)
    port = free_web_port()
    # The 40 frames (2 s) over and over, in real time, until Ctrl-C.
    argv = [sys.executable, "-m", "radarodom.tools.radar_capture", "--source",
            f"replay://{tmp_path / 'src'}?rate=1&loop=0", "--no-publish", "--view", f"web:{port}"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        page = wait_for_page(f"http://127.0.0.1:{port}/", proc)
        assert "Rerun" in page
        shot = tmp_path / "view_web.png"
        if shutil.which("chromium") and SHOT_TOOL.is_file():
            url = web_page_url("127.0.0.1", ViewTarget("web", port=port))
            subprocess.run([sys.executable, str(SHOT_TOOL), url, str(shot), "--wait", "25", "--size", "1200x800"],
                           check=True, capture_output=True, timeout=GUARD_S)
        time.sleep(1.0)
    finally:
        proc.send_signal(signal.SIGINT)  # stops after the current frame; the view drains and closes
        out, err = proc.communicate(timeout=GUARD_S)
    assert proc.returncode == 0, err
    assert f"radar-capture: view: the web viewer: open http://{socket.gethostname()}:{port}/?url=" in err
    assert "Warning" not in err, err  # the view's process started without runpy's RuntimeWarning
    # As many frames as the replay made in real time before the Ctrl-C: one on a busy machine.
    assert "; stopped; " in out and re.search(r"; view: [1-9]\d* frames? drawn, ", out), out
    if not shot.exists():
        pytest.skip("Chromium (apt-get install chromium) or ../shared/tools/browser_shot.py is absent: "
                    "the page was served, not rendered")
    import matplotlib.image

    pixels = (matplotlib.image.imread(shot)[..., :3] * 255).round()
    dark = np.all(np.abs(pixels - DARK_VIRIDIS) <= 12, axis=-1)
    assert dark.sum() > 2000, "no heatmap on the screenshot: the viewer did not draw the view"
