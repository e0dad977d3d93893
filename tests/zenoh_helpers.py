"""Real Zenoh sessions on loopback for the publishing tests: peers with multicast
scouting off and explicit tcp/127.0.0.1 endpoints on free ports, and a real
estimator run (synthetic frames) to publish."""

from __future__ import annotations

import contextlib
import json
import math
import socket
import threading
import time
from typing import Callable, Iterator, Sequence

import estimator_synth as synth
from conftest import free_endpoint  # noqa: F401  (the tests import it from here too)
import numpy as np
import zenoh

from radarodom.estimator.odometry import RadarOdometry
from radarodom.publish import DEFAULT_ENDPOINT


def default_endpoint_free() -> bool:
    """Whether the publisher's default port can be listened on here."""
    host, port = DEFAULT_ENDPOINT.split("/", 1)[1].rsplit(":", 1)
    with socket.socket() as sock:
        # As zenoh's listener does: connections of earlier tests in TIME_WAIT do not count.
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, int(port)))
        except OSError:
            return False
    return True


@contextlib.contextmanager
def peer(*, listen: Sequence[str] = (), connect: Sequence[str] = ()) -> Iterator[zenoh.Session]:
    """A plain zenoh peer session (no radarodom code), closed on exit."""
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", json.dumps(list(listen)))
    config.insert_json5("connect/endpoints", json.dumps(list(connect)))
    config.insert_json5("connect/retry", "{period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2}")
    session = zenoh.open(config)
    try:
        yield session
    finally:
        session.close()


class Inbox:
    """Samples of a callback subscriber: (key, encoding, payload bytes, attachment bytes or None)."""

    def __init__(self) -> None:
        self.samples: list[tuple[str, str, bytes, bytes | None]] = []
        self._lock = threading.Lock()

    def __call__(self, sample: zenoh.Sample) -> None:
        attachment = None if sample.attachment is None else sample.attachment.to_bytes()
        with self._lock:
            self.samples.append((str(sample.key_expr), str(sample.encoding), sample.payload.to_bytes(), attachment))

    def payloads(self) -> list[bytes]:
        with self._lock:
            return [s[2] for s in self.samples]


def subscribe(session: zenoh.Session, key: str) -> Inbox:
    inbox = Inbox()
    inbox.subscriber = session.declare_subscriber(key, inbox)  # undeclared with the session
    return inbox


def wait_for(condition: Callable[[], bool], timeout: float = 5.0, interval: float = 0.01) -> bool:
    """Poll *condition* until true or *timeout* s; returns its last value."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return condition()
        time.sleep(interval)
    return True


def estimator_run(frames: int = 31, seed: int = 2):
    """[(state, points, heatmap)] of the real estimator on synthetic frames at 10 Hz:
    a straight line then an arc."""
    trajectory = synth.Trajectory([(2.0, 1.0, 0.0), (1.0, 0.5, math.radians(20.0))])
    world, amplitude = synth.scene(trajectory, 40, seed=seed)
    rng = np.random.default_rng(seed + 1)
    odometry = RadarOdometry()
    out = []
    for i in range(frames):
        t = 1000.0 + i / 10.0
        pose = trajectory.pose(t - 1000.0)
        vx, vy, _ = trajectory.twist(t - 1000.0)
        cloud, heatmap = synth.frame(world, amplitude, pose, (vx, vy), rng)
        out.append((odometry.step(t, cloud, heatmap), cloud, heatmap))
    return out
