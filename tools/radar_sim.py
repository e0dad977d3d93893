"""radar-sim: simulate a scene and write a capture directory with ground truth.

    radar-sim SCENE [--cfg CFG] [--duration S] [--seed N] [--noise-seed N] [--board NAME|FILE] --out DIR
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Sequence
from urllib.parse import quote

from ..cfg import RadarConfig, shipped_config_path
from ..driver.recordings.capture_dir import ADC_DATA, CaptureWriter
from ..driver.sim.board import BUILTIN_BOARDS, load_board
from ..driver.sim.scene import BUILTIN_SCENES, load_scene
from ..driver.sim.physics import FIDELITIES
from ..driver.sim.simulator import Simulator
from ..driver.sim.source import SimSource
from ..errors import UsageError
from . import cli
from .replaced_outputs import ReplacedOutputs
from .status import StatusLine, format_duration


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-sim",
        description="Simulate the AWR1843BOOST in a scene along its trajectory and write a capture "
                    "directory (raw DCA1000 bytes, timestamps, groundtruth.tum).")
    parser.add_argument("scene", metavar="SCENE",
                        help=f"a built-in scene ({', '.join(BUILTIN_SCENES)}) or a .toml/.json scene file")
    parser.add_argument("--cfg", metavar="FILE", help="radar configuration (default: the shipped "
                                                       "configs/awr1843_raw.cfg)")
    parser.add_argument("--duration", type=cli.positive_float, metavar="S",
                        help="seconds to simulate (default: the whole trajectory)")
    parser.add_argument("--seed", type=cli.non_negative_int, default=0, metavar="N", help="random seed (default 0)")
    parser.add_argument("--noise-seed", type=cli.non_negative_int, metavar="N",
                        help="the thermal noise's own seed (default: --seed's): another draw of the noise over the "
                             "same scatterers and path")
    parser.add_argument("--board", default="ideal", metavar="NAME|FILE",
                        help=f"the board's imperfections: {', '.join(BUILTIN_BOARDS)} or a board .toml file "
                             "(default: ideal)")
    parser.add_argument("--fidelity", choices=FIDELITIES, default="exact",
                        help="exact (default): every chirp's delay drift, the same bytes for a seed whatever the "
                             "BLAS thread count; fast: several times quicker, spurious Doppler lines 20-30 dB "
                             "below fast-moving strong targets, the same bytes at the same BLAS thread count")
    parser.add_argument("--out", required=True, metavar="DIR", help="new capture directory to write (--overwrite: or one radarodom wrote, replaced)")
    cli.add_overwrite(parser)
    cli.add_verbosity(parser)
    return parser


def _bar(done: int, total: int, width: int = 24) -> str:
    filled = round(width * done / total) if total else width
    return "[" + "#" * filled + "." * (width - filled) + "]"


def _frames_bytes(directory: str) -> int:
    """The size of the frame data of the recording in *directory* that --overwrite replaces, bytes."""
    try:
        return os.path.getsize(os.path.join(directory, ADC_DATA))
    except OSError:
        return 0


def _main(args: argparse.Namespace, status: StatusLine) -> int:
    status.enabled = not args.quiet
    if args.scene.startswith("sim:") and not os.path.exists(args.scene):  # radar-capture's --source, given here
        name = args.scene.removeprefix("sim:").removeprefix("//").partition("?")[0] or "corridor"
        raise UsageError(f"{args.scene}: radar-sim takes a scene's name or file, not a sim:// URL: "
                         f"radar-sim {name} --out DIR (the URL's options are radar-sim's: --seed, --duration, "
                         "--board, --fidelity, --noise-seed)")
    cfg = RadarConfig.from_file(args.cfg or shipped_config_path())
    scene = load_scene(args.scene, seed=args.seed)
    board = load_board(args.board)
    sim = Simulator(cfg, scene, seed=args.seed, duration_s=args.duration, board=board, fidelity=args.fidelity,
                    noise_seed=args.noise_seed)
    replaced = 0  # the bytes --overwrite frees
    if os.path.exists(args.out):  # else CaptureWriter checks (and makes its parents)
        cli.check_new_path(args.out, is_dir=True, overwrite=args.overwrite)
        if args.overwrite:
            replaced = _frames_bytes(args.out)
    else:
        cli.check_writable_directory(args.out, "--out")
    # Before anything is replaced: a --duration off by a few zeros would fill the disk.
    cli.check_room(args.out, sim.num_frames * cfg.frame_bytes, "--out",
                   f"{sim.num_frames} frames of {cfg.frame_bytes} bytes ({sim.num_frames * sim.period:,.1f} s)",
                   replaced)
    aside = ReplacedOutputs([(args.out, "capture")] if args.overwrite else [])  # removed once a frame is in it
    start = time.monotonic()
    # Quoted, so that a board file's path with '&', '?' or spaces reads back as the same option.
    url = (f"sim://{args.scene}?seed={args.seed}" + ("" if board.is_ideal else f"&board={quote(args.board, safe='/')}")
           + ("" if args.fidelity == "exact" else f"&fidelity={args.fidelity}")
           + ("" if args.noise_seed is None else f"&noise_seed={args.noise_seed}"))
    # Ctrl-C and SIGTERM stop between frames, so that the recording closes on a whole frame.
    stopped: list[int] = []
    written = 0
    try:
        with cli.on_stop_signals(lambda signum, _: stopped.append(signum)):
            with CaptureWriter(args.out, cfg, source=url, extra=SimSource(sim).recording_metadata()) as writer:
                for i in range(sim.num_frames):
                    if stopped:
                        break
                    f = sim.frame(i)
                    writer.write(f.raw, f.timestamp, 0, f.pose)
                    written = i + 1
                    aside.drop_replaced()  # the old recording's room, once this one holds a frame
                    elapsed = time.monotonic() - start
                    eta = elapsed / (i + 1) * (sim.num_frames - i - 1)
                    status.update(f"{_bar(i + 1, sim.num_frames)} {i + 1}/{sim.num_frames} frames  "
                                  f"{f.num_paths} paths  elapsed {format_duration(elapsed)}  "
                                  f"left {format_duration(eta)}", force=(i + 1 == sim.num_frames))
    except BaseException:
        aside.settle_after_error()
        raise
    aside.settle()
    if stopped and written < sim.num_frames:
        status.clear()
        kept = f"the {written} frames before it are kept in {args.out}" if written else "nothing was recorded"
        print(f"radar-sim: interrupted at frame {written} of {sim.num_frames}; {kept}", file=sys.stderr)
        return 130
    status.clear()
    frames = f"{sim.num_frames} frame{'' if sim.num_frames == 1 else 's'}"
    print(f"radar-sim: {frames} of {scene.name} ({sim.num_frames * sim.period:.1f} s, "
          f"seed {args.seed}{'' if args.noise_seed is None else f', noise seed {args.noise_seed}'}) in "
          f"{time.monotonic() - start:.1f} s -> {args.out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run_with_status(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
