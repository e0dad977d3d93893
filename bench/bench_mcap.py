"""What the ROS 2 outputs cost the pipeline per frame: the MCAP sink (radar-capture --mcap) and the
ROS 2 publisher's messages (radar-capture --ros2: the odometry, TF, point cloud, heatmap image and
axes, diagnostics), on the simulated corridor at 10 Hz (the shipped cfg).

The corridor's frames go through radar-capture's pipeline once (DSP and estimator, defaults),
keeping every frame's results; then each output is given the same results frame by frame, as the
pipeline gives them, and timed (wall clock and the thread's CPU time):

- ``mcap``: ``McapSink.write`` per frame and its ``close``, amortized over the frames (a chunk is
  compressed and written every ~20 frames, so the mean holds that cost, the median does not);
- ``mcap, mounted``: the same with a mount (the base's pose worked out per frame);
- ``ros2 extra``: ``Publisher.odometry + pointcloud + heatmap`` with ``ros2=True`` less the same
  without it (plain Zenoh messages only), sessions on loopback with no subscriber.

Anchor, timed in the same run: the estimator's median time per frame (``PipelineStats.estimator_s``);
the ratio says what an output costs next to it. The goal (issue 21): under 1 ms per frame.

    python bench/bench_mcap.py [--seconds 10] [--repeats 3] [--json FILE]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as radar-capture

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import socket  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from radarodom.driver.sources import open_source  # noqa: E402
from radarodom.estimator.config import EstimatorConfig  # noqa: E402
from radarodom.mount import Mount  # noqa: E402
from radarodom.pipeline import Pipeline  # noqa: E402
from radarodom.pipeline.mcap_sink import McapSink  # noqa: E402
from radarodom.pipeline.sinks import Sink  # noqa: E402
from radarodom.publish import Publisher, ZenohOptions  # noqa: E402


class Kept(Sink):
    wants_heatmaps = True

    def __init__(self) -> None:
        self.results = []

    def write(self, result, stats) -> None:
        self.results.append((result, stats))


def _free_endpoint() -> str:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"


def _clocks():
    return time.perf_counter(), time.thread_time()


def time_mcap(source, kept, mount: Mount, directory: str) -> tuple[list[float], list[float], int]:
    """(wall s per write, cpu s per write) with close added to the last, and the file's bytes."""
    path = os.path.join(directory, f"bench_{time.monotonic_ns()}.mcap")
    sink = McapSink(path, source, mount=mount)
    wall, cpu = [], []
    for result, stats in kept:
        w0, c0 = _clocks()
        sink.write(result, stats)
        w1, c1 = _clocks()
        wall.append(w1 - w0)
        cpu.append(c1 - c0)
    w0, c0 = _clocks()
    sink.close(kept[-1][1])
    w1, c1 = _clocks()
    wall[-1] += w1 - w0
    cpu[-1] += c1 - c0
    size = os.path.getsize(path)
    os.remove(path)
    return wall, cpu, size


def _publish_all(publisher: Publisher, kept) -> tuple[list[float], list[float]]:
    wall, cpu = [], []
    for result, _ in kept:
        frame = result.frame
        w0, c0 = _clocks()
        if result.state is not None:
            publisher.odometry(result.state)
        if result.points is not None:
            publisher.pointcloud(frame.index, frame.timestamp, result.points)
        if result.heatmap is not None:
            publisher.heatmap(frame.index, frame.timestamp, result.heatmap)
        w1, c1 = _clocks()
        wall.append(w1 - w0)
        cpu.append(c1 - c0)
    return wall, cpu


def time_ros2_extra(kept, mount: Mount) -> tuple[list[float], list[float]]:
    """Per frame: (with ROS 2) - (without), wall and CPU, each side alone on its own session."""
    out = []
    for ros2 in (False, True):
        with Publisher(ZenohOptions(listen=[_free_endpoint()], connect=(), ros2=ros2), mount=mount) as pub:
            _publish_all(pub, kept[:3])  # the sessions' first puts, before timing
            out.append(_publish_all(pub, kept))
    (plain_wall, plain_cpu), (ros_wall, ros_cpu) = out
    return ([a - b for a, b in zip(ros_wall, plain_wall)], [a - b for a, b in zip(ros_cpu, plain_cpu)])


def summary(values: list[float]) -> dict:
    a = 1e3 * np.asarray(values)
    return {"mean_ms": float(a.mean()), "p50_ms": float(np.median(a)), "p99_ms": float(np.percentile(a, 99)),
            "max_ms": float(a.max())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="seconds of the corridor (10 frames a second)")
    parser.add_argument("--repeats", type=int, default=3, help="timed passes of each output (the median is kept)")
    parser.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    args = parser.parse_args()

    kept = Kept()
    with open_source(f"sim://corridor?rate=max&duration={args.seconds:g}") as source:
        stats = Pipeline(source, estimator=EstimatorConfig(), sinks=[kept]).run()
        anchor_ms = 1e3 * float(np.median(stats.estimator_s))
        mounted = Mount(0.3, 0.0, 0.25, math.radians(5.0))
        rows: dict[str, list] = {"mcap": [], "mcap, mounted": [], "ros2 extra": []}
        sizes = []
        with tempfile.TemporaryDirectory() as tmp:
            for _ in range(args.repeats):
                wall, cpu, size = time_mcap(source, kept.results, Mount(), tmp)
                rows["mcap"].append((summary(wall), summary(cpu)))
                sizes.append(size)
                wall, cpu, _ = time_mcap(source, kept.results, mounted, tmp)
                rows["mcap, mounted"].append((summary(wall), summary(cpu)))
                rows["ros2 extra"].append(tuple(summary(v) for v in time_ros2_extra(kept.results, mounted)))

    def median_of(runs, which, key):
        return float(np.median([r[which][key] for r in runs]))

    frames = len(kept.results)
    result = {"machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.processor() or platform.system()}",
              "python": platform.python_version(), "date": datetime.date.today().isoformat(),
              "load_average": os.getloadavg(), "frames": frames, "anchor_estimator_ms": anchor_ms,
              "mcap_bytes_per_frame": float(np.median(sizes)) / frames, "outputs": {}}
    print(f"{frames} frames of the simulated corridor (10 Hz, shipped cfg); {result['machine']}; "
          f"load average {result['load_average'][0]:.1f}; {result['date']}")
    print(f"anchor: the estimator's median time per frame, {anchor_ms:.2f} ms\n")
    print("| output | wall mean ms | wall p50 | wall p99 | CPU mean ms | CPU / estimator | goal < 1 ms |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | :---: |")
    for name, runs in rows.items():
        wall_mean, cpu_mean = median_of(runs, 0, "mean_ms"), median_of(runs, 1, "mean_ms")
        result["outputs"][name] = {"wall_mean_ms": wall_mean, "wall_p50_ms": median_of(runs, 0, "p50_ms"),
                                   "wall_p99_ms": median_of(runs, 0, "p99_ms"), "cpu_mean_ms": cpu_mean,
                                   "cpu_ratio_to_estimator": cpu_mean / anchor_ms}
        r = result["outputs"][name]
        print(f"| {name} | {wall_mean:.3f} | {r['wall_p50_ms']:.3f} | {r['wall_p99_ms']:.3f} | {cpu_mean:.3f} | "
              f"{r['cpu_ratio_to_estimator']:.3f} | {'yes' if cpu_mean < 1.0 else 'no'} |")
    print(f"\nMCAP size: {result['mcap_bytes_per_frame'] / 1e3:.1f} kB per frame")
    if args.json:
        with open(args.json, "w", encoding="ascii") as fh:
            json.dump(result, fh, indent=1)


if __name__ == "__main__":
    main()
