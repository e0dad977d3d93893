"""What the live view (``radar-capture --view``) costs the pipeline per frame, at 10 Hz.

A recording of the simulated corridor (``radar-sim``, 10 Hz, with its ground truth; made once
into ``--data``) is replayed in real time (``replay://DIR?rate=1``) through the pipeline
radar-capture builds (DSP, estimator), in alternating runs: with a sink that does nothing (the
anchor), with one that spins 0.4 ms of CPU per frame (``busy``: the wall time that much work
gets on the machine), and with the view as radar-capture opens it (radarodom.view.open_view):
``save`` to a temporary .rrd (drawn in a thread of the radar's process), ``web`` serving the web
viewer and its data with no browser attached (drawn in a process of its own, as the ``spawn``
and ``connect:`` views are), and ``save-process`` (the same file as ``save``, drawn from a
process of its own), ``--repeats`` times each.

For every frame, in the pipeline's thread: the wall and CPU time of ``Pipeline.process`` (the
products, the estimator and every sink), and of the sink's ``write`` alone (the anchor's: what
the machine's own interruptions give a call that does nothing).  For the whole run: the CPU time
the view's process used (per frame), the frames drawn and dropped.  Reported: medians (and the
90th percentile of process, the mean and 99th percentile of write), the view's added time (the
median with the view less the median of the anchor runs) and the ratio.

    python bench/bench_view.py [--seconds 20] [--repeats 3] [--targets busy save web save-process] [--data DIR] [--json]
"""

from __future__ import annotations

import os

# As radar-capture: one BLAS thread (set before numpy loads).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from radarodom.driver.sources import open_source  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.pipeline import Pipeline, Sink  # noqa: E402

TARGETS = ("busy", "save", "web", "save-process")
#: CPU the ``busy`` sink spends per frame, s: about what the view's write takes.
BUSY_S = 0.0004


class Timed:
    """Wall and CPU (this thread's) times of calls, s."""

    def __init__(self) -> None:
        self.wall: list[float] = []
        self.cpu: list[float] = []

    def __call__(self, function, *args):
        start, cpu = time.perf_counter(), time.thread_time()
        result = function(*args)
        self.cpu.append(time.thread_time() - cpu)
        self.wall.append(time.perf_counter() - start)
        return result

    def ms(self, which: str) -> np.ndarray:
        return np.array(getattr(self, which)[1:]) * 1e3  # the first frame builds the DSP's plans


class TimedPipeline(Pipeline):
    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.timed = Timed()

    def process(self, frame):
        return self.timed(super().process, frame)


class NullSink(Sink):
    def write(self, result, stats) -> None:
        pass


class BusySink(Sink):
    """Spins BUSY_S of CPU per frame: the wall time that much work gets on this machine."""

    def write(self, result, stats) -> None:
        start = time.thread_time()
        while time.thread_time() - start < BUSY_S:
            pass


def recording(data: str, seconds: float) -> str:
    """The corridor recorded at 10 Hz for *seconds* (made once)."""
    out = os.path.join(data, f"corridor_{seconds:g}s")
    if not os.path.exists(os.path.join(out, "capture.json")):
        os.makedirs(data, exist_ok=True)
        subprocess.run([sys.executable, "-m", "radarodom.tools.radar_sim", "corridor", "--duration", f"{seconds:g}",
                        "--out", out, "-q"], check=True)
    return out


def open_sink(target: str | None, source, estimator: EstimatorConfig, tmp: str) -> Sink:
    from radarodom.view import ViewTarget, open_view
    from radarodom.view.target import free_web_port

    if target is None:
        return NullSink()
    if target == "busy":
        return BusySink()
    spec = (ViewTarget("web", port=free_web_port()) if target == "web"
            else ViewTarget("save", path=os.path.join(tmp, f"view_{time.monotonic_ns()}.rrd")))
    forced = True if target == "save-process" else None  # else as radar-capture chooses
    return open_view(spec, estimator=estimator, config=source.config, process=forced)


def run(capture: str, target: str | None, tmp: str) -> dict:
    """One real-time replay of *capture*, with the view sent to *target* (None: the anchor)."""
    estimator = EstimatorConfig()
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    me = resource.getrusage(resource.RUSAGE_SELF)
    with open_source(f"replay://{capture}?rate=1") as source:
        sink = open_sink(target, source, estimator, tmp)
        writes = Timed()
        write = sink.write
        sink.write = lambda result, stats: writes(write, result, stats)
        pipeline = TimedPipeline(source, estimator=estimator, sinks=[sink])
        stats = pipeline.run()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    view_cpu = (after.ru_utime + after.ru_stime - children.ru_utime - children.ru_stime)
    mine = resource.getrusage(resource.RUSAGE_SELF)
    process_cpu = mine.ru_utime + mine.ru_stime - me.ru_utime - me.ru_stime
    t = pipeline.timed
    out = {"target": target or "none", "frames": stats.frames,
           "median_ms": float(np.median(t.ms("wall"))), "p90_ms": float(np.percentile(t.ms("wall"), 90)),
           "cpu_median_ms": float(np.median(t.ms("cpu"))),
           "write_mean_ms": float(writes.ms("wall").mean()), "write_median_ms": float(np.median(writes.ms("wall"))),
           "write_p99_ms": float(np.percentile(writes.ms("wall"), 99)),
           "write_cpu_mean_ms": float(writes.ms("cpu").mean()),
           "write_cpu_median_ms": float(np.median(writes.ms("cpu"))),
           # The view's own drawing: its process's CPU (web, save-process), or in this process's (save).
           "view_process_cpu_ms": 1e3 * view_cpu / max(stats.frames, 1),
           "process_cpu_ms": 1e3 * process_cpu / max(stats.frames, 1)}
    if target not in (None, "busy"):
        out.update(drawn=sink.drawn, dropped=sink.dropped)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="seconds of the corridor per run (10 Hz)")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each kind, alternating")
    parser.add_argument("--targets", nargs="+", default=list(TARGETS), choices=TARGETS)
    parser.add_argument("--data", default=os.path.expanduser("~/.cache/radarodom/view"),
                        help="where the recording is made once")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    capture = recording(args.data, args.seconds)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeats):
            for target in [None, *args.targets]:
                results.append(run(capture, target, tmp))
                print(json.dumps(results[-1]), file=sys.stderr, flush=True)
    anchor = float(np.median([r["median_ms"] for r in results if r["target"] == "none"]))
    cpu_anchor = float(np.median([r["cpu_median_ms"] for r in results if r["target"] == "none"]))
    for r in results:
        r["added_ms"], r["ratio"] = r["median_ms"] - anchor, r["median_ms"] / anchor
        r["cpu_added_ms"] = r["cpu_median_ms"] - cpu_anchor
    machine = f"{platform.node()}, {platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    if args.json:
        print(json.dumps({"machine": machine, "load": os.getloadavg()[0], "date": time.strftime("%Y-%m-%d"),
                          "runs": results}))
        return 0
    print(f"{time.strftime('%Y-%m-%d')}, {machine}, Python {platform.python_version()}, load average "
          f"{os.getloadavg()[0]:.1f} at the end; {args.seconds:g} s of the corridor at 10 Hz per run\n")
    print("| view | process median ms | p90 | added | ratio | CPU median ms | CPU added | write mean ms | median "
          "| p99 | write CPU mean ms | view process CPU ms/frame | radar process CPU ms/frame | drawn | dropped |")
    print("| --- |" + " ---: |" * 14)
    for r in results:
        drawn = f"{r['drawn']} | {r['dropped']}" if "drawn" in r else "- | -"
        print(f"| {r['target']} | {r['median_ms']:.1f} | {r['p90_ms']:.1f} | {r['added_ms']:+.2f} | {r['ratio']:.3f} | "
              f"{r['cpu_median_ms']:.2f} | {r['cpu_added_ms']:+.2f} | {r['write_mean_ms']:.3f} | "
              f"{r['write_median_ms']:.3f} | {r['write_p99_ms']:.2f} | {r['write_cpu_mean_ms']:.3f} | "
              f"{r['view_process_cpu_ms']:.1f} | {r['process_cpu_ms']:.1f} | {drawn} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
