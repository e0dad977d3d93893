"""End-to-end latency and dropped frames of the whole pipeline at 10, 20 and 30 Hz.

For each frame rate, a cfg like the shipped one with that frame period, and two sources:

- emulated DCA1000: ``radar-emulate --capture DIR`` (a fake AWR1843 on a pty and a fake
  DCA1000 streaming real UDP on loopback, in its own process) with a recording of the
  corridor made at that rate, and the ``dca1000://`` URL it prints;
- simulator: ``sim://corridor`` in real time (the simulator then shares the process, and its
  own cost, with the pipeline).

The pipeline radar-capture builds (radarodom.pipeline: capture -> DSP -> estimator -> Zenoh
publishing, a peer on loopback with no subscriber needed) runs in this process, and its
statistics give the end-to-end latency of each frame (its last packet received, or its
making, -> every output written) as percentiles; the source's, the frames dropped by slow
processing and the packets lost.

    python bench/bench_pipeline.py [--seconds 20] [--rates 10 20 30] [--data DIR]
"""

from __future__ import annotations

import os

# As radar-capture: one BLAS thread (set before numpy loads).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import signal  # noqa: E402
import socket  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

from radarodom.cfg import RadarConfig, shipped_config_path  # noqa: E402
from radarodom.driver.sources import open_source  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.pipeline import Pipeline  # noqa: E402
from radarodom.pipeline.zenoh_sink import PublisherSink  # noqa: E402
from radarodom.publish import Publisher, ZenohOptions  # noqa: E402


def cfg_at(rate_hz: float, directory: str) -> str:
    """The shipped cfg with a frame period of 1 / rate_hz; its path."""
    path = os.path.join(directory, f"awr1843_{rate_hz:g}hz.cfg")
    lines = []
    with open(shipped_config_path(), encoding="ascii") as fh:
        for line in fh:
            if line.startswith("frameCfg"):
                f = line.split()
                f[5] = f"{1000.0 / rate_hz:g}"
                line = " ".join(f) + "\n"
            lines.append(line)
    with open(path, "w", encoding="ascii") as fh:
        fh.writelines(lines)
    return path


def recording(rate_hz: float, cfg: str, directory: str, seconds: float) -> str:
    out = os.path.join(directory, f"corridor_{rate_hz:g}hz")
    if not os.path.exists(os.path.join(out, "capture.json")):
        subprocess.run([sys.executable, "-m", "radarodom.tools.radar_sim", "corridor", "--cfg", cfg,
                        "--duration", str(seconds), "--out", out, "-q"], check=True)
    return out


def _free_endpoint() -> str:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"


def run_pipeline(url: str, cfg: str, seconds: float) -> dict:
    """radar-capture's pipeline on *url* for *seconds* of stream time: its statistics."""
    with Publisher(ZenohOptions(listen=[_free_endpoint()])) as publisher, \
            open_source(url, RadarConfig.from_file(cfg)) as source:
        pipeline = Pipeline(source, estimator=EstimatorConfig(), sinks=[PublisherSink(publisher, source)],
                            max_duration_s=seconds)
        stats = pipeline.run()
        live = source.describe()
    p50, p99 = stats.latency.percentiles_ms(50, 99)
    return {"frames": stats.frames, "secs": stats.elapsed_s, "hz": stats.mean_rate_hz, "p50": p50, "p99": p99,
            "dropped": live.get("frames_dropped", 0), "lost": live.get("packets_lost", 0)}


def emulated(rate_hz: float, capture_dir: str, seconds: float) -> dict:
    emu = subprocess.Popen([sys.executable, "-m", "radarodom.tools.radar_emulate", "--capture", capture_dir],
                           stdout=subprocess.PIPE, text=True)
    try:
        command = ""
        while not command.startswith("radar-capture"):
            command = emu.stdout.readline()
            if not command:
                raise RuntimeError("radar-emulate ended before printing its command")
        url = command.split("--source", 1)[1].split()[0].strip("'")
        return run_pipeline(url, os.path.join(capture_dir, "radar.cfg"), seconds)
    finally:
        emu.send_signal(signal.SIGINT)
        emu.wait(timeout=10)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=20.0, help="stream time per run")
    parser.add_argument("--rates", type=float, nargs="+", default=[10.0, 20.0, 30.0])
    parser.add_argument("--data", default=os.path.expanduser("~/.cache/radarodom/bench_pipeline"))
    args = parser.parse_args(argv)
    os.makedirs(args.data, exist_ok=True)
    rows = []
    for rate in args.rates:
        cfg = cfg_at(rate, args.data)
        rec = recording(rate, cfg, args.data, args.seconds + 5)
        for source, result in (("emulated DCA1000", lambda: emulated(rate, rec, args.seconds)),
                               ("simulator", lambda: run_pipeline("sim://corridor", cfg, args.seconds))):
            started = time.monotonic()
            r = result()
            r.update(rate=rate, source=source, wall=time.monotonic() - started)
            rows.append(r)
            print(r, file=sys.stderr)
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, {time.strftime('%Y-%m-%d')}\n")
    print("| rate | source | frames | achieved Hz | dropped | lost packets | latency p50 ms | p99 ms | period ms |")
    print("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for r in rows:
        print(f"| {r['rate']:g} Hz | {r['source']} | {r.get('frames', 0):.0f} | {r.get('hz', 0):.1f} | "
              f"{r.get('dropped', 0):.0f} | {r.get('lost', 0):.0f} | {r.get('p50', float('nan')):.1f} | "
              f"{r.get('p99', float('nan')):.1f} | {1000 / r['rate']:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
