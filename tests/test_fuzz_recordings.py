"""Property-based tests of what a capture directory can hold (issue 18): any capture.json, any
timestamps.txt text and any data-file size either plays as a consistent recording or is refused
with the package's own error; radar-capture replaying it never ends in "internal error".

Every example writes a small SMALL_CFG directory (3072-byte frames) into a fresh temporary
directory; example counts are modest to keep the suite fast.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import shutil
import tempfile

import numpy as np
import pytest
from conftest import SMALL_CFG, make_capture
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from radarodom.cfg import RadarConfig
from radarodom.driver.recordings.capture_dir import CaptureDirectory
from radarodom.driver.sources import open_source
from radarodom.errors import RadarodomError
from radarodom.tools import radar_capture

FRAME_BYTES = 3072
N_FRAMES = 6
INCOMPLETE = {2: 100, 4: 3072}

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A closed 6-frame capture with two incomplete frames, copied by each example."""
    cfg = RadarConfig.from_text(SMALL_CFG, "small.cfg")
    d = tmp_path_factory.mktemp("fuzz") / "base"
    make_capture(d, cfg, N_FRAMES, incomplete=INCOMPLETE)
    return d


@contextlib.contextmanager
def copy_of(base):
    with tempfile.TemporaryDirectory() as tmp:
        d = os.path.join(tmp, "cap")
        shutil.copytree(base, d)
        yield d


def check_read(d) -> CaptureDirectory | None:
    """Open *d*: a package error with a one-line message that shows bad input readably (no
    replacement characters, nothing a terminal would act on) (None), or a recording whose
    frames, times and loss figures are consistent with its files."""
    try:
        cap = CaptureDirectory(d)
    except RadarodomError as exc:
        message = str(exc)
        assert message and message.isprintable() and "\ufffd" not in message, message
        return None
    size = os.path.getsize(os.path.join(d, "adc_data.bin"))
    fb = cap.config.frame_bytes
    assert 0 <= cap.num_frames <= size // fb
    assert len(cap.timestamps) == cap.num_frames
    assert np.all(np.isfinite(cap.timestamps))
    assert np.all(np.diff(cap.timestamps) > 0)
    for i in range(cap.num_frames):
        assert 0 <= cap.cut_bytes(i) <= cap.missing_bytes(i) <= fb
        assert len(cap.raw(i)) == fb
    if cap.metadata.get("closed"):
        assert size == cap.num_frames * fb == cap.metadata["frame_count"] * fb
    if cap.num_frames:
        with open_source(f"replay://{d}?rate=max") as src:
            frames = list(src)
        assert [f.index for f in frames] == list(range(cap.num_frames))
        assert all(f.missing_bytes <= fb for f in frames)
    return cap


# ------------------------------------------------------------------- capture.json

json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-2**70, 2**70) | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=12,
)
META_KEYS = ["format", "format_version", "frame_bytes", "frame_count", "closed", "incomplete_frames",
             "lost_bytes", "cut_bytes", "first_timestamp", "last_timestamp", "start_time_unix", "source",
             "software", "dropped_frames", "simulator", "other"]
ENTRY_KEYS = ["frame", "missing_bytes", "cut_bytes", "other"]


@st.composite
def metadata_texts(draw, meta: dict) -> str | bytes:
    kind = draw(st.sampled_from(["field", "entry", "delete", "text", "bytes", "nesting"]))
    meta = json.loads(json.dumps(meta))
    if kind == "field":
        meta[draw(st.sampled_from(META_KEYS))] = draw(json_values | st.integers(-10, 10**12))
    elif kind == "entry":
        entries = meta["incomplete_frames"]
        entry = entries[draw(st.integers(0, len(entries) - 1))]
        entry[draw(st.sampled_from(ENTRY_KEYS))] = draw(json_values | st.integers(-10, 10**12))
    elif kind == "delete":
        meta.pop(draw(st.sampled_from(META_KEYS)), None)
    elif kind == "text":
        return draw(st.text(max_size=60))
    elif kind == "bytes":
        return draw(st.binary(max_size=60))
    else:
        depth = draw(st.integers(1, 5000))
        return draw(st.sampled_from(["[", "{\"a\":"])) * depth
    return json.dumps(meta, allow_nan=True)


@FUZZ
@given(data=st.data())
def test_any_capture_json_is_read_or_refused(base, data):
    meta = json.loads((base / "capture.json").read_text())
    text = data.draw(metadata_texts(meta))
    with copy_of(base) as d:
        path = os.path.join(d, "capture.json")
        with open(path, "wb") as fh:
            fh.write(text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass"))
        check_read(d)


# ------------------------------------------------------------------- timestamps.txt

timestamp_lines = st.one_of(
    st.sampled_from(["nan", "inf", "-inf", "0_5", "0x10", "1e300", "1e999", "", " ", "1,5", "\uff11",
                     "1.5 2.5", "+1", ".5", "5.", "1e-3", "-0.0", "1e10", "10000000001"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-10**12, 10**12).map(str),
    st.text(max_size=12),
)


@FUZZ
@given(lines=st.lists(timestamp_lines, min_size=1, max_size=8), ending=st.sampled_from(["\n", "", "\r\n"]),
       with_metadata=st.booleans())
def test_any_timestamps_text_is_read_or_refused(base, lines, ending, with_metadata):
    with copy_of(base) as d:
        text = ending.join(lines) + ending
        with open(os.path.join(d, "timestamps.txt"), "w", encoding="utf-8", errors="surrogatepass") as fh:
            fh.write(text)
        if not with_metadata:
            os.remove(os.path.join(d, "capture.json"))
        cap = check_read(d)
        if cap is not None and with_metadata:  # a closed capture takes its six lines only
            assert cap.num_frames == N_FRAMES


@FUZZ
@given(frames=st.lists(st.floats(0.0, 2e9, allow_nan=False).map(lambda t: round(t, 6)),
                       min_size=1, max_size=8),
       trailing=st.lists(st.sampled_from(["", " ", "\t", "\r", " \t "]), max_size=4).map(
           lambda blanks: "".join(b + "\n" for b in blanks)))
def test_plain_timestamps_play_exactly_when_they_increase(base, frames, trailing):
    """Blank lines at the end (an editor's) change nothing."""
    with copy_of(base) as d:
        os.remove(os.path.join(d, "capture.json"))
        with open(os.path.join(d, "adc_data.bin"), "wb") as fh:
            fh.write(bytes(FRAME_BYTES * len(frames)))
        with open(os.path.join(d, "timestamps.txt"), "w", newline="") as fh:
            fh.write("".join(f"{t:.6f}\n" for t in frames) + trailing)
        cap = check_read(d)
        increasing = all(b > a for a, b in zip(frames, frames[1:]))
        assert (cap is not None) == increasing
        if cap is not None:
            np.testing.assert_allclose(cap.timestamps, frames, rtol=0, atol=1e-6)


# ------------------------------------------------------------------- data-file sizes

@FUZZ
@given(size=st.integers(0, 8 * FRAME_BYTES + FRAME_BYTES - 1), lines=st.integers(0, 9),
       frame_count=st.integers(0, 9), closed=st.booleans(), with_metadata=st.booleans())
def test_any_data_size_plays_whole_frames_or_is_refused(base, size, lines, frame_count, closed, with_metadata):
    with copy_of(base) as d:
        with open(os.path.join(d, "adc_data.bin"), "wb") as fh:
            fh.write(bytes(size))
        with open(os.path.join(d, "timestamps.txt"), "w") as fh:
            fh.write("".join(f"{1000 + 0.05 * i:.9f}\n" for i in range(lines)))
        meta_path = os.path.join(d, "capture.json")
        if with_metadata:
            meta = json.loads(open(meta_path).read())
            meta.update(frame_count=frame_count, closed=closed,
                        incomplete_frames=[e for e in meta["incomplete_frames"] if e["frame"] < frame_count])
            meta["lost_bytes"] = sum(e["missing_bytes"] for e in meta["incomplete_frames"])
            with open(meta_path, "w") as fh:
                json.dump(meta, fh)
        else:
            os.remove(meta_path)
        cap = check_read(d)
        whole = size // FRAME_BYTES
        crash_like = whole - 1 <= lines <= whole
        if with_metadata and closed:
            assert (cap is not None) == (size == frame_count * FRAME_BYTES and lines == frame_count)
        elif with_metadata:
            assert (cap is not None) == (crash_like and frame_count <= min(whole, lines))
        else:
            assert (cap is not None) == crash_like
        if cap is not None:
            assert cap.num_frames == whole


# ------------------------------------------------------------------- the command line

def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """radar-capture in this process; (exit code, stdout, stderr).  The logger it sets up is
    put back after each run."""
    logger = logging.getLogger("radarodom")
    handlers, level = list(logger.handlers), logger.level
    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = radar_capture.main(argv)
    finally:
        logger.handlers[:] = handlers
        logger.setLevel(level)
    return code, out.getvalue(), err.getvalue()


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), target=st.sampled_from(["capture.json", "timestamps.txt", "adc_data.bin"]))
def test_radar_capture_never_ends_in_an_internal_error(base, data, target):
    with copy_of(base) as d:
        path = os.path.join(d, target)
        if target == "capture.json":
            text = data.draw(metadata_texts(json.loads((base / "capture.json").read_text())))
            payload = text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass")
        elif target == "timestamps.txt":
            lines = data.draw(st.lists(timestamp_lines, min_size=1, max_size=8))
            payload = ("\n".join(lines) + "\n").encode("utf-8", "surrogatepass")
        else:
            payload = bytes(data.draw(st.integers(0, 8 * FRAME_BYTES)))
        with open(path, "wb") as fh:
            fh.write(payload)
        out = os.path.join(os.path.dirname(d), "out")
        code, stdout, stderr = run_cli(["--source", f"replay://{d}?rate=max", "--no-publish", "--no-odom",
                                        "--record", out, "-q"])
        assert "internal error" not in stderr and "Traceback" not in stderr, stderr
        if code == 0:
            assert stdout.startswith("radar-capture: ") and stdout.count("\n") == 1, stdout
            check_read(out)
        else:
            assert code == 2, stderr
            assert stdout == ""
            errors = [ln for ln in stderr.splitlines() if ln.startswith("radar-capture: error: ")]
            assert len(errors) == 1, stderr
            assert not os.path.exists(out)
