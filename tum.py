"""TUM trajectory files: ``t x y z qx qy qz qw`` per line (docs/conventions.md).

The one reader and the one line formatter of the project: the capture
directory's ``groundtruth.tum``, the estimator's ``--odom-out`` and
``radar-eval`` all go through here, so every file is readable by ``evo``.
Units: seconds, metres; quaternions are (qx, qy, qz, qw), Hamilton, unit norm.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .errors import CaptureError, CaptureFormatError, UsageError, given_path
from .line_file import LineFile
from .plain_numbers import plain_float

log = logging.getLogger(__name__)


def yaw_quaternion(yaw) -> np.ndarray:
    """(qx, qy, qz, qw) of a rotation by *yaw* (rad) about z; shape ``yaw.shape + (4,)``."""
    try:
        yaw = np.asarray(yaw, dtype=float)
    except (TypeError, ValueError):
        raise UsageError(f"yaw: a number or an array of numbers (rad), got {type(yaw).__name__}") from None
    q = np.zeros(yaw.shape + (4,))
    q[..., 2] = np.sin(yaw / 2.0)
    q[..., 3] = np.cos(yaw / 2.0)
    return q


def quaternion_yaw(quaternions) -> np.ndarray:
    """Heading (rad, in (-pi, pi]) of quaternions (..., 4) xyzw: the z angle of the
    z-y-x Euler decomposition, so a tilted body still gives the direction it faces.
    The quaternions need not be normalised."""
    try:
        q = np.asarray(quaternions, dtype=float)
    except (TypeError, ValueError):
        raise UsageError(f"quaternions: an array (..., 4) of xyzw, got {type(quaternions).__name__}") from None
    if q.ndim == 0 or q.shape[-1] != 4:
        raise UsageError(f"quaternions: an array (..., 4) of xyzw, got shape {q.shape}")
    x, y, z, w = np.moveaxis(_scaled(q), -1, 0)
    return np.arctan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def _scaled(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) divided by their largest component's size (none zero: left as they are),
    so that their squares neither underflow (a TUM file's 1e-300) nor overflow."""
    big = np.max(np.abs(q), axis=-1, keepdims=True)
    return q / np.where(big > 0, big, 1.0)


def unit_quaternions(quaternions: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) made unit length, however small or large they were (none zero)."""
    q = _scaled(np.asarray(quaternions, dtype=float))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def refuse_binary(path: str, lineno: int, text: str, why: str) -> None:
    """:class:`CaptureFormatError` naming ``path:lineno`` for a line of a text file holding a NUL or
    bytes that are not UTF-8 (read with ``errors="replace"``): quoting such a line would print its
    bytes, so the message says what the file should hold (*why*) instead."""
    if "\0" in text or "\ufffd" in text:
        raise CaptureFormatError(f"{path}:{lineno}: binary data, not text{why}")


def parse_numbers(path: str, lineno: int, text: str, count: int | None, what: str) -> list[float]:
    """The finite numbers of one line of a text file: exactly *count* of them when given,
    else at least one, each a plain decimal number (:mod:`radarodom.plain_numbers`);
    :class:`CaptureFormatError` naming ``path:lineno`` and *what* was expected otherwise."""
    tokens = text.split()
    values = [plain_float(v) for v in tokens]
    if not values or (count is not None and len(values) != count) or None in values:
        odd = [t for t, v in zip(tokens, values) if v is None]
        if odd and all(_python_float(t) is not None for t in odd) and \
                all(not math.isfinite(_python_float(t)) for t in odd):
            raise CaptureFormatError(_not_finite(path, lineno, text, tokens, [_python_float(t) for t in tokens],
                                                 count, what))
        if odd and all(_python_float(t) is not None for t in odd):
            raise CaptureFormatError(f"{path}:{lineno}: {odd[0][:20]!r} is not a plain decimal number "
                                     f"(expected {what})")
        if count is not None and len(tokens) != count and not odd:  # the count is what is wrong: say so
            plural = "" if count == 1 else "s"
            raise CaptureFormatError(f"{path}:{lineno}: expected {count} number{plural} ({what}), got "
                                     f"{len(tokens)}: {_shortened(text)!r}")
        raise CaptureFormatError(f"{path}:{lineno}: expected {what}, got {text[:60]!r}")
    if not all(math.isfinite(v) for v in values):
        raise CaptureFormatError(_not_finite(path, lineno, text, tokens, values, count, what))
    return values


def _not_finite(path: str, lineno: int, text: str, tokens: list[str], values: list, count: int | None,
                what: str) -> str:
    """The message for a line whose *values* (floats, None where not one) are not all finite: the
    field named where *what* is the quoted list of the line's fields ("'t x y z qx qy qz qw'")."""
    names = what[1:-1].split() if len(what) > 1 and what[0] == what[-1] == "'" else []
    bad = next(i for i, v in enumerate(values) if v is not None and not math.isfinite(v))
    if count is not None and len(names) == count == len(tokens):
        return f"{path}:{lineno}: {names[bad]} is not a finite number ({tokens[bad][:20]!r})"
    return f"{path}:{lineno}: not a finite number: {text[:60]!r}"


def _shortened(text: str, limit: int = 60) -> str:
    """*text* itself when short, else its start and end (an extra column is at the end)."""
    return text if len(text) <= limit else f"{text[:limit // 2 - 2]} ... {text[-(limit // 2 - 3):]}"


def _python_float(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def _number(value) -> float:
    """*value* as a float; TypeError for text (float() would parse "0": a caller's slip) and None."""
    if isinstance(value, (str, bytes)) or value is None:
        raise TypeError(value)
    return float(value)


def format_tum_line(t: float, position: Sequence[float], quaternion: Sequence[float]) -> str:
    """One TUM line with its newline: *t* (s) to 9 decimals (nanoseconds, as the
    frame timestamps), the position (3,) m and quaternion (4,) xyzw to 9 digits."""
    try:
        values = [_number(v) for v in position] + [_number(v) for v in quaternion]
        t = _number(t)
    except (TypeError, ValueError):
        raise UsageError(f"a TUM pose is numbers: t, a position (3) and a quaternion (4), got t={t!r}, "
                         f"{position!r}, {quaternion!r}") from None
    if len(values) != 7:
        raise UsageError(f"a TUM pose is a position (3) and a quaternion (4), got {len(values)} numbers")
    if not all(math.isfinite(v) for v in values) or not math.isfinite(t):
        raise UsageError(f"refusing to write a non-finite pose at t={t}: {values}")
    return f"{t:.9f} " + " ".join(f"{v:.9g}" for v in values) + "\n"


@dataclass(frozen=True)
class TumTrajectory:
    """Poses from a TUM file.

    ``times`` (n,) s, ``positions`` (n, 3) m, ``quaternions`` (n, 4) xyzw;
    ``source`` names the file (for messages) and ``lines`` (n,) holds each pose's
    1-based line number in it (0 when the poses did not come from a file).
    """

    times: np.ndarray
    positions: np.ndarray
    quaternions: np.ndarray
    source: str = ""
    lines: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ("times", "positions", "quaternions"):  # lists taken as the arrays they stand for
            try:
                object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))
            except (TypeError, ValueError):
                raise UsageError(f"a trajectory's {name} must be numbers, got {type(getattr(self, name)).__name__}") \
                    from None
        if self.times.ndim != 1:
            raise UsageError(f"a trajectory's times must be (n,), got {self.times.shape}")
        n = len(self.times)
        if self.positions.shape != (n, 3) or self.quaternions.shape != (n, 4):
            raise UsageError(f"a trajectory of {n} times needs positions (n, 3) and quaternions (n, 4), "
                             f"got {self.positions.shape} and {self.quaternions.shape}")
        if self.lines is None:
            object.__setattr__(self, "lines", np.zeros(n, dtype=int))

    @classmethod
    def from_se2(cls, times, poses, *, source: str = "") -> "TumTrajectory":
        """Planar poses *poses* (n, 3): x, y (m), yaw (rad); z = 0, yaw-only quaternions."""
        poses = np.asarray(poses, dtype=float)
        if poses.shape != (3,) and (poses.ndim != 2 or poses.shape[1] != 3):
            raise UsageError(f"planar poses must be (n, 3): x, y, yaw; got {poses.shape}")
        poses = poses.reshape(-1, 3)
        positions = np.zeros((len(poses), 3))
        positions[:, :2] = poses[:, :2]
        return cls(np.asarray(times, dtype=float).reshape(-1), positions, yaw_quaternion(poses[:, 2]),
                   source=source)

    def __len__(self) -> int:
        return len(self.times)

    @property
    def yaw(self) -> np.ndarray:
        """Heading (n,) rad in (-pi, pi], counter-clockwise from the world x axis."""
        return quaternion_yaw(self.quaternions)

    def se2(self) -> np.ndarray:
        """Planar poses (n, 3): x, y (m) and yaw (rad); z, roll and pitch are dropped."""
        return np.column_stack([self.positions[:, 0], self.positions[:, 1], self.yaw])

    def pose(self, i: int) -> tuple[float, ...]:
        """Pose *i* as ``(x, y, z, qx, qy, qz, qw)``."""
        i = self._index(i)
        return (*self.positions[i], *self.quaternions[i])

    def _index(self, i) -> int:
        """*i* if it indexes a pose (negative from the end), else UsageError."""
        if not isinstance(i, (int, np.integer)) or isinstance(i, bool) or not -len(self) <= i < len(self):
            raise UsageError(f"pose {i!r}: an index of the trajectory's {len(self)} poses")
        return int(i)

    def take(self, indices) -> "TumTrajectory":
        """The poses at *indices* (an index array or a boolean mask), same source."""
        try:
            times = self.times[indices]
        except (IndexError, TypeError, ValueError) as exc:
            raise UsageError(f"take: indices of the trajectory's {len(self)} poses, or a mask of as many "
                             f"booleans: {exc}") from None
        return TumTrajectory(times, self.positions[indices], self.quaternions[indices], self.source,
                             self.lines[indices])

    def where(self, i: int) -> str:
        """``file:line`` of pose *i*, for messages."""
        line = int(self.lines[self._index(i)])
        return f"{self.source or '<trajectory>'}:{line}" if line else f"{self.source or '<trajectory>'}"


def read_tum(path: str | os.PathLike) -> TumTrajectory:
    """Read a TUM trajectory (``t x y z qx qy qz qw`` per line, ``#`` comments, blank lines).

    A last line without its end of line (a writer cut off mid-line) is ignored
    with a warning.  Raises :class:`CaptureFormatError` naming ``file:line`` for
    a line that is not eight finite numbers or has a zero quaternion, and
    :class:`CaptureError` when the file cannot be read or *path* is no path (bytes are one).
    """
    name = given_path(path, CaptureError)
    rows: list[list[float]] = []
    lines: list[int] = []
    try:
        with open(name, encoding="utf-8-sig", errors="replace") as fh:  # a BOM (Notepad's) ignored
            for lineno, line in enumerate(fh, start=1):
                text = line.strip()
                if not text or text.startswith("#"):
                    continue
                refuse_binary(name, lineno, text, ": a TUM file is lines of 't x y z qx qy qz qw'")
                if not line.endswith("\n"):
                    log.warning("%s:%d: ignoring a last line without end of line", name, lineno)
                    break
                values = parse_numbers(name, lineno, text, 8, "'t x y z qx qy qz qw'")
                if not any(values[4:]):
                    raise CaptureFormatError(f"{name}:{lineno}: the quaternion is zero")
                rows.append(values)
                lines.append(lineno)
    except OSError as exc:
        raise CaptureError(f"cannot read {name}: {exc.strerror or exc}") from None
    arr = np.array(rows, dtype=float).reshape(-1, 8)
    return TumTrajectory(arr[:, 0], arr[:, 1:4], arr[:, 4:8], name, np.array(lines, dtype=int))


class TumWriter:
    """Write poses to a new TUM file, one line each, handed to the kernel per line.

    Refuses an existing file (:class:`CaptureExistsError`): radarodom never
    overwrites recorded data.  Use as a context manager.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = given_path(path, CaptureError)
        # Each line straight to the kernel: a process killed mid-run leaves whole lines behind,
        # and a write that fails (a full disk) is cut back to the lines before it.
        self._file = LineFile(self.path)

    def write(self, t: float, x: float, y: float, yaw: float) -> None:
        """A planar pose: x, y (m) and yaw (rad) at time *t* (s); z = 0."""
        self.write_pose(t, (x, y, 0.0), yaw_quaternion(yaw))

    def write_pose(self, t: float, position: Sequence[float], quaternion: Sequence[float]) -> None:
        """A pose: position (3,) m and quaternion (4,) xyzw at time *t* (s)."""
        self._file.write(format_tum_line(t, position, quaternion))

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> "TumWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
