"""``sim://`` : the simulator as a frame source.

``sim://SCENE?seed=0&rate=1.0&duration=S&loop=1&noise_seed=N``

- SCENE: a built-in scene (``corridor``, ``room``, ``lab``, ``calibration``;
  default ``corridor``) or a scene file (``sim:///path/to/scene.toml``).
- ``seed``: everything random (scatterers, phases, noise); same seed, same bytes (with
  ``fidelity=exact`` whatever the BLAS thread count; with ``fast`` at the same BLAS thread
  count, as radar-capture runs it: one).
- ``noise_seed``: the thermal noise's alone (default: ``seed``): another draw of the noise over
  the same scatterers and path.
- ``rate``: 1.0 streams in real time (default), 2 twice as fast, ``max`` as
  fast as frames can be made.
- ``duration``: seconds of stream; default the scene's trajectory.
- ``loop``: how many times to play the trajectory (0: until stopped; default 1), as
  ``replay://`` does: later passes continue the clock and the frame numbers (both keep
  increasing), the frames are the first pass's again, and the ground-truth pose restarts
  with the scene (the sensor is back at the trajectory's start, relative to the first frame).
- ``board``: the board's imperfections, ``ideal`` (default), ``uncalibrated`` (TX
  and RX paths tens of degrees and about a dB apart, a range bias, TX-to-RX
  leakage) or a board file (``board=/path/board.toml``; see :mod:`.board`).
- ``fidelity``: ``exact`` models every chirp's delay drift to 1e-3 rad (the
  default with ``rate=max``, and what ``radar-sim`` writes); ``fast`` holds
  each path's delay over chunks of loops, which leaves spurious Doppler lines
  20-30 dB below fast-moving targets but keeps real time on two cores (the
  default when streaming at a finite rate).

The radar configuration is ``--cfg`` when given, else the shipped
``configs/awr1843_raw.cfg``.  Frames carry their ground-truth pose.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Iterator

import numpy as np

from ...cfg import RadarConfig, shipped_config_path
from ...errors import SourceError
from ...tum import TumTrajectory
from ..sources import Frame, Pacer, Source
from ..url_options import RATE_EXPECTED, UrlOptions, at_least, one_of, parse_rate, positive_number
from .board import BUILTIN_BOARDS, load_board
from .physics import FIDELITIES
from .scene import BUILTIN_SCENES, load_scene
from .scene_values import builtin_or_there
from .simulator import Simulator

DEFAULT_SCENE = "corridor"


class SimSource(Source):
    """Streams a :class:`Simulator`'s frames."""

    def __init__(self, sim: Simulator, *, rate: float = 1.0, loop: int = 1) -> None:
        super().__init__()
        self.sim = sim
        self.config: RadarConfig = sim.cfg
        self.rate = rate
        self.loop = loop
        self.calibrated = sim.board.fits(sim.cfg)

    def _frames(self) -> Iterator[Frame]:
        # The next frame is made while this one is processed, as a radar makes its frames while the
        # host processes the last: made after the one before (in one thread, the simulator's
        # buffers being its own), it keeps real time where making and processing a frame take
        # more than a period together but each less (docs/simulator.md, "Fidelity").
        if self.stop_requested:
            return
        pacer = Pacer(self.rate, self)
        n = self.sim.num_frames
        span = n * self.sim.period  # a pass, so that the next one's first frame is a period on
        order = self._order()
        with ThreadPoolExecutor(1, thread_name_prefix="sim-frames") as maker:
            ahead = next(order, None)
            made = maker.submit(self.sim.frame, ahead[1]) if ahead else None
            while made is not None and not self.stop_requested:
                k, i = ahead
                offset = (k // n) * span  # later passes continue the clock, like replay's
                pacer.wait(self.sim.frame_time(i) + offset)
                if self.stop_requested:
                    break
                f = made.result()
                ahead = next(order, None)
                made = maker.submit(self.sim.frame, ahead[1]) if ahead else None
                yield Frame(index=k, timestamp=f.timestamp + offset,
                            raw=np.frombuffer(f.raw, np.uint8), layout=self.sim.layout, pose=f.pose)
            # A frame still being made is finished, not abandoned: the simulator's buffers are
            # not to be shared with another iteration.

    def _order(self) -> Iterator[tuple[int, int]]:
        """(index in the stream, frame of the pass) of each frame to stream, every pass's."""
        n, passes = self.sim.num_frames, 0
        while self.loop == 0 or passes < self.loop:
            for i in range(n):
                yield passes * n + i, i
            passes += 1

    def groundtruth(self) -> TumTrajectory:
        """The true poses of one pass's frames, at their times: what ``radar-eval EST.tum
        sim://...`` compares an estimate of the same stream with (a looped stream's later passes
        repeat them a pass later)."""
        times = np.array([self.sim.frame_time(i) for i in range(self.sim.num_frames)], float)
        poses = np.array([self.sim.groundtruth(t) for t in times], float).reshape(-1, 7)
        return TumTrajectory(times, poses[:, :3], poses[:, 3:], self.url or "sim://")

    def recording_metadata(self) -> dict:
        board = self.sim.board
        out = {"scene": self.sim.scene.name, "seed": self.sim.seed, "board": board.name,
               "board_calibration": board.calibration().describe()}
        if self.sim.noise_seed is not None:
            out["noise_seed"] = self.sim.noise_seed
        return {"simulator": out}

    def describe(self) -> dict:
        return {"url": self.url, "scene": self.sim.scene.name, "frames": self.sim.num_frames,
                "seed": self.sim.seed, "noise_seed": self.sim.noise_seed, "board": self.sim.board.name,
                "rate": "max" if self.rate == float("inf") else self.rate, "loop": self.loop,
                "duration_s": pass_duration_s(self.sim)}


def pass_duration_s(sim: Simulator) -> float:
    """Seconds of stream of one pass of *sim*'s frames."""
    return sim.num_frames * sim.period


def _board_name(text: str) -> str:
    """``board=``'s value: a built-in board's name or a file that is there (``board=`` named no
    file, and no URL; a name that is neither was a ConfigError naming neither the URL nor the option)."""
    if not text.strip() or not builtin_or_there(text, BUILTIN_BOARDS):
        raise ValueError("no such board")
    return text


_board_name.words = True  # type: ignore[attr-defined]  # a word, not a number


def open_sim(path: str, options: UrlOptions, config: RadarConfig | None) -> SimSource:
    seed = options.take("seed", at_least(0), 0, "an integer >= 0")
    rate = options.take("rate", parse_rate, 1.0, RATE_EXPECTED)
    duration = options.take("duration", positive_number, None, "seconds > 0")
    fidelity = options.take("fidelity", one_of(*FIDELITIES), None, " or ".join(FIDELITIES))
    board = options.take("board", _board_name, "ideal", "ideal, uncalibrated or a board .toml file")
    loop = options.take("loop", at_least(0), 1, "a number of passes (0: forever)")
    noise_seed = options.take("noise_seed", at_least(0), None, "an integer >= 0")
    options.finish()
    if fidelity is None:
        fidelity = "exact" if rate == float("inf") else "fast"
    name = path or DEFAULT_SCENE
    if not builtin_or_there(name, BUILTIN_SCENES):
        raise SourceError(f"{options.url}: no such scene {name}: use one of {', '.join(BUILTIN_SCENES)} or a "
                          ".toml/.json scene file")
    cfg = config if config is not None else RadarConfig.from_file(shipped_config_path())
    scene = load_scene(name, seed=seed)
    sim = Simulator(cfg, scene, seed=seed, duration_s=duration, fidelity=fidelity, board=load_board(board),
                    noise_seed=noise_seed)
    return SimSource(sim, rate=rate, loop=loop)
