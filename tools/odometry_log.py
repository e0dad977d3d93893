"""An odometry run's messages as radar-eval reads them: each step's quality flags, and its pose,
yaw rate and covariances.

A TUM file holds poses only.  The flags and the covariances come from the odometry v1 messages
(:mod:`radarodom.messages`, schema ``radarodom/odom``) written one JSON object per line:
what ``radar-echo --json odom`` prints while ``radar-capture`` publishes (its ``key`` field
is ignored).  Objects of another schema (``radar-echo --json odom status`` interleaves status
messages) are skipped; every odometry object is checked as a subscriber checks it.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from dataclasses import dataclass

import numpy as np

from .. import messages, strict_json
from ..plain_numbers import time_text
from ..errors import CaptureFormatError, MessageError, UsageError, given_path
from ..estimator.quality import Flag

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class OdometryLog:
    """The odometry steps of a run: ``times`` (k,) s, increasing, and ``flags`` (k,) tuples of
    flag names (empty: a good step); ``source`` names the file.  Read from a file, also each
    message's ``frames`` (k,), ``poses`` (k, 3) x, y m and yaw rad, ``yaw_rates`` (k,) rad/s and
    its ``pose_covariance`` and ``twist_covariance`` (k, 3, 3)."""

    times: np.ndarray
    flags: tuple[tuple[str, ...], ...]
    source: str = ""
    frames: np.ndarray | None = None
    poses: np.ndarray | None = None
    yaw_rates: np.ndarray | None = None
    pose_covariance: np.ndarray | None = None
    twist_covariance: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.times)

    def names(self) -> list[str]:
        """The flags that occur, in :class:`Flag`'s order, then any other (a newer estimator's)
        sorted."""
        seen = {f for step in self.flags for f in step}
        known = [str(f) for f in Flag if str(f) in seen]
        return known + sorted(seen - set(known))

    def count(self, name: str) -> int:
        """How many steps carry the flag *name*."""
        return sum(name in step for step in self.flags)

    def since(self, t0: float) -> "OdometryLog":
        """The same steps with times counted from *t0* (s)."""
        return dataclasses.replace(self, times=self.times - t0)

    def within(self, start: float, end: float) -> "OdometryLog":
        """The steps with start <= t <= end."""
        keep = np.flatnonzero((self.times >= start) & (self.times <= end))
        rows = {name: None if getattr(self, name) is None else getattr(self, name)[keep]
                for name in ("frames", "poses", "yaw_rates", "pose_covariance", "twist_covariance")}
        return OdometryLog(self.times[keep], tuple(self.flags[i] for i in keep), self.source, **rows)


def read_odometry_log(path: str | os.PathLike) -> OdometryLog:
    """The odometry messages in the JSON-lines file *path* (module text): their flags, poses, rates and
    covariances.

    Raises :class:`CaptureFormatError` naming ``path:line`` for a line that is not a JSON
    object or an odometry message that breaks its schema, or when the times do not increase;
    :class:`UsageError` when the file is missing or holds no odometry message.
    """
    path = given_path(path, UsageError, "file path (the odometry messages)")
    times: list[float] = []
    flags: list[tuple[str, ...]] = []
    frames: list[int] = []
    steps: list[tuple[float, float, float, float]] = []  # x, y, yaw, yaw rate
    covariances: list[tuple[list, list]] = []
    skipped = 0
    cut = None  # the last line's number when it had no end of line
    try:
        with open(path, encoding="utf-8-sig") as fh:  # a BOM (a Windows editor's) ignored
            for lineno, line in enumerate(fh, start=1):
                if not line.strip():
                    continue
                if not line.endswith("\n"):  # as a TUM file's: a writer killed mid-line
                    cut = lineno
                    break
                try:  # (bounded: depth, digits, non-finite numbers, as a subscriber reads a message)
                    obj = strict_json.loads(line, max_bytes=messages.MAX_JSON_BYTES)
                except ValueError as exc:
                    raise CaptureFormatError(f"{path}:{lineno}: not an odometry message: {exc}") from None
                if not isinstance(obj, dict):
                    raise CaptureFormatError(f"{path}:{lineno}: not a JSON object")
                if obj.get("schema") != messages.ODOM_SCHEMA:
                    skipped += 1
                    continue
                try:
                    m = messages.parse_odometry(line.encode("utf-8"))
                except MessageError as exc:
                    raise CaptureFormatError(f"{path}:{lineno}: {exc}") from None
                if times and m["t"] <= times[-1]:
                    raise CaptureFormatError(f"{path}:{lineno}: time {time_text(m['t'], 9)} s is not after the "
                                             f"previous message's {time_text(times[-1], 9)} s; one run's messages, "
                                             "in order, are needed")
                for name in ("pose_covariance", "twist_covariance"):
                    least = min(m[name][0::4])
                    if least < 0.0:
                        raise CaptureFormatError(f"{path}:{lineno}: {name}: a variance (its diagonal: items 1, 5, 9) "
                                                 f"is negative ({least:g}): not a covariance")
                times.append(float(m["t"]))
                flags.append(tuple(m["flags"]))
                frames.append(m["frame"])
                steps.append((m["x"], m["y"], m["yaw"], m["yaw_rate"]))
                covariances.append((m["pose_covariance"], m["twist_covariance"]))
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise UsageError(f"{path}: not a file") from None
    except UnicodeDecodeError as exc:
        raise CaptureFormatError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror or exc}") from None
    if cut is not None and times:
        log.warning("%s:%d: ignoring a last line without end of line", path, cut)
    if not times:
        cut_off = f" but line {cut}, which has no end of line (cut off?)" if cut is not None else ""
        raise UsageError(f"{path}: no odometry message ({messages.ODOM_SCHEMA}) in it{cut_off}; write one with "
                         f"radar-echo --json odom > FILE while radar-capture publishes (or radar-capture --odom-json)")
    if skipped:
        log.info("%s: %d lines of other messages skipped", path, skipped)
    cov = np.asarray(covariances, float).reshape(len(times), 2, 3, 3)
    rows = np.asarray(steps, float)
    return OdometryLog(np.asarray(times), tuple(flags), path, frames=np.asarray(frames, np.uint64), poses=rows[:, :3],
                       yaw_rates=rows[:, 3], pose_covariance=cov[:, 0], twist_covariance=cov[:, 1])
