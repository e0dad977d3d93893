"""The bench's matrix recordings that several test files read, made once for the whole test run."""

from __future__ import annotations

import fcntl
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
import robustness_matrix as rm  # noqa: E402
import sequences  # noqa: E402


def shared_recording(cell: rm.SimCell, tmp_path_factory) -> str:
    """*cell* recorded (rm.record) with its DSP products (sequences.load) once for the whole test run:
    tests/test_heading_diagnosis.py, test_scene_edits.py and test_matrix_recordings.py each recorded
    the same loop (a radar-sim run and the DSP), the same bytes.  Theirs to read only
    (a test that changes a recording copies it first).  Under xdist, in the run's folder that its workers
    share (--dist loadfile may put the three files on either), made by the first under a lock."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the run's own (pytest-N), not one of an earlier run
    with open(root / "shared-recordings.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released as the file closes
        directory = rm.record(cell, str(root / "shared-recordings"))  # as it is when recorded already
        sequences.load(directory)  # its products made here: the tests' loads only read them
    return directory
