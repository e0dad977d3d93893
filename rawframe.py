"""Raw ADC bytes of the xWR18xx + DCA1000 <-> complex cubes.

One frame on the LVDS stream (SWRA581B section 6; protocol.md) is
loops (outer) x chirps of a loop in frameCfg order (one TX slot each) x
enabled RX ascending x ADC samples, each sample a signed 16-bit I and Q.

Within each RX's samples the two LVDS lanes interleave: a group of four int16
holds two samples' first component, then the same two samples' second
component (:data:`LVDS_GROUP`).  Which component is first depends on
``adcbufCfg`` SampleSwap: 1 (every SDK cfg) puts Q first, ``Q0 Q1 I0 I1``;
0 puts I first, ``I0 I1 Q0 Q1`` (mmWave Studio captures).

TI's DCA1000 recorder rewrites each group to one sample at a time
(``ReorderAlgorithm``: ``a0 a1 b0 b1 -> a0 b0 a1 b1``) when its
``reorderEnable`` is set, which keeps the component order:
:data:`IQ_SAMPLE`.

Cubes are complex64 arrays shaped (loops, tx_slots, rx, samples), or with a
leading frames axis, with I as the real and Q as the imaginary part.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .errors import CaptureFormatError, UsageError, quoted

if TYPE_CHECKING:  # pragma: no cover
    from .cfg import RadarConfig

#: Two samples on two LVDS lanes: both samples' first component, then both second ones.
LVDS_GROUP = np.dtype([("first", "<i2", (2,)), ("second", "<i2", (2,))])
#: One sample in TI's reordered recorder files: first component, then second.
IQ_SAMPLE = np.dtype([("first", "<i2"), ("second", "<i2")])

INT16_MIN, INT16_MAX = -32768, 32767


@dataclass(frozen=True)
class RawLayout:
    """How one frame's bytes map onto the cube."""

    num_loops: int
    num_tx_slots: int
    num_rx: int
    num_samples: int
    #: True when Q comes before I (adcbufCfg SampleSwap = 1).
    q_first: bool = True
    #: True for TI's reordered recorder files (one sample at a time),
    #: False for the raw LVDS stream (two samples at a time).
    iq_interleaved: bool = False

    @classmethod
    def from_config(cls, cfg: "RadarConfig", *, iq_interleaved: bool = False) -> "RawLayout":
        if not hasattr(cfg, "cube_shape") or not hasattr(cfg, "adcbuf"):  # (cfg imports this module)
            raise UsageError(f"cfg: a RadarConfig (RadarConfig.from_file(path) reads one), got {type(cfg).__name__}")
        loops, slots, rx, samples = cfg.cube_shape
        return cls(loops, slots, rx, samples, bool(cfg.adcbuf.sample_swap), iq_interleaved)

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """Cube shape of one frame: (loops, tx_slots, rx, samples)."""
        return (self.num_loops, self.num_tx_slots, self.num_rx, self.num_samples)

    @property
    def samples_per_frame(self) -> int:
        return self.num_loops * self.num_tx_slots * self.num_rx * self.num_samples

    @property
    def frame_bytes(self) -> int:
        return self.samples_per_frame * 4

    @property
    def _record(self) -> np.dtype:
        return IQ_SAMPLE if self.iq_interleaved else LVDS_GROUP

    def decode(self, buf, out: np.ndarray | None = None) -> np.ndarray:
        """Decode whole frames.

        *buf* is any buffer of ``k * frame_bytes`` bytes.  Returns complex64
        shaped (loops, tx_slots, rx, samples) for one frame (k = 1 and *out*
        not given with a frames axis), else (k, loops, tx_slots, rx, samples).
        *out*, when given, is filled and returned (no allocation).
        """
        try:
            nbytes = memoryview(buf).nbytes
        except TypeError:
            raise UsageError(f"decode: a frame's bytes (bytes, bytearray, memoryview or a uint8 array), got "
                             f"{type(buf).__name__}") from None
        if nbytes == 0 or nbytes % self.frame_bytes:
            raise CaptureFormatError(
                f"{nbytes} bytes is not a whole number of {self.frame_bytes}-byte frames")
        k = nbytes // self.frame_bytes
        if out is not None:
            _check_out(out, k, self.shape)
        shape = self.shape if (k == 1 and (out is None or out.ndim == 4)) else (k, *self.shape)
        if out is None:
            out = np.empty(shape, np.complex64)
        rec = np.frombuffer(buf, dtype=self._record)
        i_part, q_part = (rec["second"], rec["first"]) if self.q_first else (rec["first"], rec["second"])
        out.real[...] = i_part.reshape(shape)
        out.imag[...] = q_part.reshape(shape)
        return out

    def encode(self, cube: np.ndarray) -> bytes:
        """Bytes of one or more frames (inverse of :meth:`decode`).

        *cube* is a numeric array (integer, float or complex: not bool, object or text) holding
        integer-valued I + jQ shaped like :meth:`decode` returns, one frame or a frames axis of at
        least one; anything else is a :class:`UsageError` saying what it got.  Values are rounded
        to int16 and must fit without clipping.
        """
        _check_cube(cube, self.shape)
        i_part, q_part = np.rint(cube.real), np.rint(cube.imag)
        if not (np.isfinite(i_part).all() and np.isfinite(q_part).all()):
            raise CaptureFormatError("the cube holds NaN or infinite samples")
        lo, hi = min(i_part.min(), q_part.min()), max(i_part.max(), q_part.max())
        if lo < INT16_MIN or hi > INT16_MAX:
            raise CaptureFormatError(f"samples span {lo:g}..{hi:g}, beyond int16: scale the cube first")
        rec = np.empty(cube.size // (1 if self.iq_interleaved else 2), dtype=self._record)
        first, second = (q_part, i_part) if self.q_first else (i_part, q_part)
        rec["first"] = first.reshape(rec["first"].shape)
        rec["second"] = second.reshape(rec["second"].shape)
        return rec.tobytes()


def _check_out(out, frames: int, shape: tuple[int, ...]) -> None:
    """:class:`UsageError` unless *out* is a writable complex64 array for *frames* frames of
    *shape*: numpy's own errors for a list, a wrong dtype or a read-only array name no argument."""
    shapes = [(frames, *shape)] if frames > 1 else [shape, (1, *shape)]
    wanted = " or ".join(str(s) for s in shapes)
    frames_text = f"{frames} frames" if frames > 1 else "one frame"
    if not isinstance(out, np.ndarray) or out.dtype != np.complex64 or out.shape not in shapes:
        got = _described(out)
    elif not out.flags.writeable:
        got = "a read-only array"
    else:
        return
    raise UsageError(f"out: a writable complex64 array shaped {wanted} ({frames_text}), or None for a new one; "
                     f"got {got}")


def _check_cube(cube, shape: tuple[int, ...]) -> None:
    """:class:`UsageError` unless *cube* is a numeric array of one frame of *shape* or of a frames
    axis of at least one: numpy's asarray took anything (a bool or str array, a list, None) and
    failed later with a ValueError or a ufunc's TypeError that named no argument."""
    if (isinstance(cube, np.ndarray) and cube.dtype.kind in "iufc"
            and (cube.shape == shape or (cube.ndim == len(shape) + 1 and cube.shape[1:] == shape
                                         and cube.shape[0] >= 1))):
        return
    raise UsageError(f"cube: a numeric (integer, float or complex) array shaped {shape} (one frame) or "
                     f"(frames, {', '.join(map(str, shape))}) (frames >= 1); got {_described(cube)}")


def _described(value) -> str:
    """What an array argument got, as the checks above say it: its dtype and shape, or its type and value."""
    if isinstance(value, np.ndarray):
        return f"{value.dtype} shaped {value.shape}"
    return f"{type(value).__name__} {quoted(value)}"


def unusable_samples(cube: np.ndarray) -> str:
    """Why the DSP's power of *cube*'s frame is not finite, in the cube's terms: which samples are
    not, or how large they are."""
    bad = ~np.isfinite(cube)
    if bad.any():
        loop, slot, rx, sample = (int(i) for i in np.unravel_index(np.argmax(bad), cube.shape))
        return (f"the frame's ADC samples hold {int(bad.sum())} NaN or infinite value(s) of {cube.size} (the first "
                f"at loop {loop}, TX slot {slot}, RX {rx}, sample {sample}); the DSP takes finite I + jQ samples, "
                "as a radar's bytes decode to (Frame.cube())")
    return (f"the frame's ADC samples reach {float(np.abs(cube).max()):.3g}, too large for the DSP's float32 "
            "power (a radar's 16-bit samples reach 32768); scale the cube down")
