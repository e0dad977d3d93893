"""End-to-end latency and dropped frames of the whole pipeline at 10, 20 and 30 Hz.

For each frame rate, a cfg like the shipped one with that frame period, and two sources:

- emulated DCA1000: ``radar-emulate --capture DIR`` (a fake AWR1843 on a pty and a fake
  DCA1000 streaming real UDP on loopback, in its own process) with a recording of the
  corridor made at that rate, and ``radar-capture --source dca1000://...`` against it;
- simulator: ``radar-capture --source sim://corridor`` in real time (the simulator then
  shares the process, and its own cost, with the pipeline).

radar-capture runs capture -> DSP -> estimator -> Zenoh publishing (peer on loopback, no
subscriber needed) and reports the end-to-end latency of each frame (its last packet
received, or made, -> odometry published) as percentiles, with the frames dropped by slow
processing and the packets lost.

    python bench/bench_pipeline.py [--seconds 20] [--rates 10 20 30] [--data DIR]
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import signal
import subprocess
import sys
import time

from radarodom.cfg import shipped_config_path

SUMMARY = re.compile(r"radar-capture: (?P<frames>\d+) frames? .*?in (?P<secs>[\d.]+) s, (?P<hz>[\d.]+) Hz")
LATENCY = re.compile(r"latency p50 (?P<p50>[\d.]+) ms, p99 (?P<p99>[\d.]+) ms")
DROPPED = re.compile(r"(?P<dropped>\d+) frames dropped by slow processing, (?P<lost>\d+) packets lost")


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


def parse(stdout: str) -> dict:
    out: dict = {}
    for pattern in (SUMMARY, LATENCY, DROPPED):
        m = pattern.search(stdout)
        if m:
            out.update({k: float(v) for k, v in m.groupdict().items()})
    return out


def run_capture(args: list[str], seconds: float) -> dict:
    proc = subprocess.run([sys.executable, "-m", "radarodom.tools.radar_capture", *args,
                           "--duration", str(seconds), "-q"], capture_output=True, text=True,
                          timeout=seconds * 4 + 60)
    if proc.returncode != 0:
        raise RuntimeError(f"radar-capture failed: {proc.stderr.strip()}")
    return parse(proc.stdout)


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
        return run_capture(["--source", url, "--cfg", os.path.join(capture_dir, "radar.cfg")], seconds)
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
                               ("simulator", lambda: run_capture(["--source", "sim://corridor", "--cfg", cfg],
                                                                 args.seconds))):
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
