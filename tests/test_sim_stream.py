"""sim:// makes each frame while the one before it is processed, as a radar makes its frames while
the host processes the last (in one thread of its own, one frame ahead): every frame once, in
order, the same bytes; an error making one reaches the reader at that frame; a stream left early
or stopped leaves no thread behind."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from radarodom.driver.sources import open_source

URL = "sim://room?rate=max&duration=0.5&fidelity=fast"


def _watch(source, fail_at: int | None = None):
    """What the source's simulator is asked to make, in order: (frame, thread name); *fail_at*: a
    frame whose making fails."""
    made, events, make = [], {}, source.sim.frame

    def frame(i):
        if i == fail_at:
            raise RuntimeError(f"frame {i} could not be made")
        f = make(i)
        made.append((i, threading.current_thread().name))
        events.setdefault(i, threading.Event()).set()
        return f

    source.sim.frame = frame
    return made, lambda i: events.setdefault(i, threading.Event())


def _makers() -> set[threading.Thread]:
    """The simulator's frame-making threads alive (another test's stream, left suspended and not
    yet collected, may keep one of its own)."""
    return {t for t in threading.enumerate() if t.name.startswith("sim-frames")}


def test_the_next_frame_is_made_while_this_one_is_processed():
    before = _makers()
    with open_source(URL) as plain:
        expected = [(f.index, f.timestamp, f.raw.tobytes(), f.pose) for f in plain]
    with open_source(URL) as source:
        made, event = _watch(source)
        got = []
        for frame in source:
            # Held here, as a slow DSP holds it: the next frame is made meanwhile, not on asking.
            if frame.index + 1 < len(expected):
                assert event(frame.index + 1).wait(60), made
            got.append((frame.index, frame.timestamp, frame.raw.tobytes(), frame.pose))
    assert len(expected) == 5 and got == expected
    assert [i for i, _ in made] == list(range(5))
    assert {name.split("_")[0] for _, name in made} == {"sim-frames"}
    assert _makers() <= before


def test_an_error_making_a_frame_reaches_the_reader_at_that_frame():
    before = _makers()
    with open_source(URL) as source:
        _watch(source, fail_at=2)
        got = []
        with pytest.raises(RuntimeError, match="frame 2 could not be made"):
            for frame in source:
                got.append(frame.index)
    assert got == [0, 1] and _makers() <= before


@pytest.mark.parametrize("how", ["left", "stopped"])
def test_a_stream_left_or_stopped_early_finishes_its_frame_and_leaves_no_thread(how):
    before = _makers()
    with open_source(URL) as source:
        made, _ = _watch(source)
        frames = iter(source)
        first = next(frames)
        if how == "stopped":
            source.stop()
            assert list(frames) == []
        else:
            frames.close()
        assert _makers() <= before
        # The frame being made when it ended was finished, and no other begun.
        assert first.index == 0 and [i for i, _ in made] == [0, 1]
        again = list(source)  # a stopped one stays stopped; one left streams anew from its start
    assert [f.index for f in again] == ([] if how == "stopped" else list(range(5)))
    assert np.array_equal(again[0].raw, first.raw) if again else True
