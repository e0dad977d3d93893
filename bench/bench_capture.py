"""Capture throughput on loopback: how fast can radarodom take DCA1000 data with zero loss?

The fake DCA1000 runs in its own process (as the board is its own device) and
streams real UDP packets of 1456 data bytes at a set rate: frames of
256 samples x 128 loops x 3 TX x 4 RX (1.5 MiB) at shorter and shorter frame
periods, and with the packet delay of 5 us, at which the real board moves
about 706 Mbit/s (UG Table 19).  This process runs radarodom's receiver (its
own thread, frames assembled by byte count into the ring) and a consumer that
decodes every frame into a complex cube.  A rate passes when every frame
arrives complete and none is dropped.

    python bench/bench_capture.py [--seconds 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import platform
import time

import numpy as np

from radarodom.driver.live.dca1000 import Dca1000Client, Dca1000Settings
from radarodom.driver.live.dca1000_receiver import Dca1000Receiver
from radarodom.driver.live.dca1000_wire import MAX_DATA_BYTES
from radarodom.driver.emulators.rig import BOARD_IP, HOST_IP, free_udp_port
from radarodom.driver.live.frame_ring import FrameRing
from radarodom.rawframe import RawLayout
from radarodom.cfg import dca1000_capacity_mbps

LAYOUT = RawLayout(128, 3, 4, 256)
DCA1000_MAX_MBPS = 706.0  # at 5 us packet delay, UG Table 19


def _board(data_port: int, frame_period_s: float, rate: str, ready, stop, command_port) -> None:
    from radarodom.driver.emulators.fake_dca1000 import FakeDca1000

    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 256, LAYOUT.frame_bytes, dtype=np.uint8).tobytes() for _ in range(4)]
    board = FakeDca1000(host_data_port=data_port, frames=lambda: iter(frames), frame_period_s=frame_period_s,
                        board_ip=BOARD_IP, host_ip=HOST_IP, rate=rate)
    with board:
        board.start()
        command_port.value = board.command_port
        board.lvds_start()  # the "radar" streams whenever the board records
        ready.set()
        stop.wait()


def run_rate(frame_period_s: float | None, seconds: float, delay_us: float, dsp=None) -> dict:
    """Stream for *seconds*; None = as fast as the sender can.  *dsp*: a callable run on
    every decoded cube by the consumer (the DSP chain), or None."""
    ctx = mp.get_context("spawn")
    data_port = free_udp_port(HOST_IP)
    ready, stop, command_port = ctx.Event(), ctx.Event(), ctx.Value("i", 0)
    proc = ctx.Process(target=_board, args=(data_port, frame_period_s or 0.001,
                                            "max" if frame_period_s is None else "paced", ready, stop,
                                            command_port), daemon=True)
    proc.start()
    try:
        if not ready.wait(30):
            raise RuntimeError("the fake board did not start")
        settings = Dca1000Settings(host_ip=HOST_IP, board_ip=BOARD_IP, config_port=0,
                                   board_port=command_port.value, data_port=data_port,
                                   packet_delay_us=delay_us)
        ring = FrameRing(LAYOUT.frame_bytes, 8, "queue")
        receiver = Dca1000Receiver(settings, LAYOUT.frame_bytes, ring)
        receiver.open()
        cube = np.empty(LAYOUT.shape, np.complex64)
        with Dca1000Client(settings) as board:
            board.connect()
            board.configure_fpga()
            board.configure_packets()
            receiver.start()
            board.start_recording()
            start = None
            frames = complete = 0
            deadline = time.monotonic() + seconds + 1.0
            while time.monotonic() < deadline:
                frame = ring.get(timeout=0.2)
                if frame is None:
                    continue
                if start is None:
                    start, deadline = time.monotonic(), time.monotonic() + seconds
                LAYOUT.decode(frame.data, out=cube)  # the consumer decodes every frame
                if dsp is not None:
                    dsp(cube)
                frames += 1
                complete += frame.missing_bytes == 0
                ring.release(frame.slot)
            elapsed = time.monotonic() - start if start else 0.0
            board.stop_recording()
        receiver.close()
        st, asm = receiver.stats, receiver.assembler.stats
        mbps = frames * LAYOUT.frame_bytes * 8 / elapsed / 1e6 if elapsed else 0.0
        return {
            "target_mbps": None if frame_period_s is None else LAYOUT.frame_bytes * 8 / frame_period_s / 1e6,
            "frames": frames, "complete": complete, "dropped_by_ring": ring.dropped_frames,
            "seq_gaps": receiver.gaps.lost, "missing_bytes": asm.missing_bytes,
            "mbps": mbps, "packets_per_s": mbps * 1e6 / 8 / MAX_DATA_BYTES,
            "zero_loss": frames > 0 and complete == frames and ring.dropped_frames == 0 and receiver.gaps.lost == 0,
            "rcvbuf_bytes": st.rcvbuf_bytes,
        }
    finally:
        stop.set()
        proc.join(10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--dsp", action="store_true",
                        help="only the 30 Hz rate, with the consumer also running the DSP chain "
                             "(point cloud and range-azimuth heatmap) on every frame")
    args = parser.parse_args()
    frame_bits = LAYOUT.frame_bytes * 8
    if args.dsp:
        for cells in (None, 256):
            _bench_with_dsp(args.seconds, frame_bits, cells)
        return
    link = dca1000_capacity_mbps(5.0)
    rates = [30 * frame_bits / 1e6, 200.0, 400.0, 600.0, link]  # Mbit/s; 30 Hz frames first
    rows = [run_rate(frame_bits / (r * 1e6), args.seconds, 5.0) for r in rates]
    # Beyond the board: the fake sends unpaced, as fast as its process can.
    rows.append(run_rate(None, args.seconds, 5.0))
    machine = {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
               "python": platform.python_version(), "numpy": np.__version__}
    best = max((r["mbps"] for r in rows if r["zero_loss"]), default=0.0)
    if args.json:
        print(json.dumps({"machine": machine, "rows": rows, "best_zero_loss_mbps": best,
                          "dca1000_max_mbps": DCA1000_MAX_MBPS}, indent=2))
        return
    print(f"machine: {machine}; frame {LAYOUT.shape} = {LAYOUT.frame_bytes} bytes; rcvbuf "
          f"{rows[0]['rcvbuf_bytes'] // 1024} KiB")
    print(f"{'target Mbit/s':>13} {'got Mbit/s':>10} {'packets/s':>10} {'frames':>7} {'complete':>8} "
          f"{'ring drops':>10} {'seq gaps':>8} {'zero loss':>9}")
    for r in rows:
        target = "max" if r["target_mbps"] is None else f"{r['target_mbps']:.0f}"
        print(f"{target:>13} {r['mbps']:>10.0f} {r['packets_per_s']:>10.0f} {r['frames']:>7d} {r['complete']:>8d} "
              f"{r['dropped_by_ring']:>10d} {r['seq_gaps']:>8d} {str(r['zero_loss']):>9}")
    print(f"highest zero-loss rate: {best:.0f} Mbit/s; the DCA1000's own maximum: {DCA1000_MAX_MBPS:.0f} Mbit/s "
          f"(ratio {best / DCA1000_MAX_MBPS:.2f})")


def _bench_with_dsp(seconds: float, frame_bits: int, doppler_cells: int | None) -> None:
    import dataclasses

    from radarodom.cfg import RadarConfig, shipped_config_path
    from radarodom.dsp.heatmap import HeatmapMaker
    from radarodom.dsp.processor import FrameProcessor

    cfg = RadarConfig.from_file(shipped_config_path())
    # 128 loops at 30 Hz need short chirps: idle 7 us as in TI's profiles (18 ms of chirping).
    cfg = cfg.replace(dataclasses.replace(cfg.profile, idle_time_us=7.0))
    cfg = cfg.replace(dataclasses.replace(cfg.frame, num_loops=LAYOUT.num_loops, frame_period_ms=1000 / 30))
    proc = FrameProcessor(cfg, calibrated=True)  # the simulator's ideal board, as sim:// says
    heatmaps = HeatmapMaker(proc, doppler_cells=doppler_cells)

    def dsp(cube):
        heatmaps.range_azimuth(proc.process(cube).spectrum)

    row = run_rate(1 / 30, seconds, 5.0, dsp)
    mode = "every cell's Doppler" if doppler_cells is None else f"Doppler for {doppler_cells} cells"
    print(f"30 Hz of {LAYOUT.shape} frames ({30 * frame_bits / 1e6:.0f} Mbit/s), DSP on every frame ({mode}): "
          f"{row['frames']} frames, {row['complete']} complete, {row['dropped_by_ring']} dropped by the ring, "
          f"{row['seq_gaps']} packets lost: zero loss {row['zero_loss']}")


if __name__ == "__main__":
    main()
