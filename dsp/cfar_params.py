"""CFAR parameters (:class:`CfarParams`): the method, guard and training cells, the threshold
as a level or a false-alarm probability, and the scale, edge scale and noise factor they imply.
The detection itself, and the conventions these parameters follow, are in :mod:`.cfar`."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..plain_numbers import beyond_text, is_whole_number
from .cfar_pfa import noise_factor, ordered_scale, split_scale, summed_scale

#: CFAR methods :class:`CfarParams` accepts.
METHODS = ("ca", "cago", "caso", "os")

_COMMAND = "CfarParams"
#: The highest threshold a CFAR takes, dB; its power ratio, 10^(dB/10), overflows past 3083 dB.
MAX_THRESHOLD_DB = 200.0


def _fail(message: str, fld: str | None = None) -> ConfigError:
    return ConfigError(message, command=_COMMAND, field=fld)


def _round_half_up(x: float) -> int:
    return math.floor(x + 0.5)


def _as_int(value: Any, name: str, lo: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise _fail(f"must be an integer, got {value!r}", name)
    if value < lo:
        raise _fail(f"must be at least {lo}, got {value}", name)
    return int(value)


def _as_optional_float(value: Any, name: str) -> float | None:
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise _fail(f"must be a number, got {value!r}", name)
    value = float(value)
    if not math.isfinite(value):
        raise _fail(f"must be finite, got {value!r}", name)
    return value


# --------------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class CfarParams:
    """One CFAR detector along one axis.

    Give exactly one of ``threshold_db`` (scale ``10 ** (threshold_db / 10)``, a power
    ratio over the noise estimate, dB >= 0) and ``pfa`` (false-alarm probability in
    (0, 1), scale derived for exponential noise: see the module docstring for the
    formulas).  Invalid combinations raise :class:`ConfigError`.
    """

    #: 'ca' | 'cago' | 'caso' | 'os'.
    method: str
    #: Guard cells on each side of the cell under test.
    guard: int
    #: Training cells on each side (beyond the guard cells); N = 2 * train in all.
    train: int
    #: Threshold over the noise estimate, dB (power ratio 10^(dB/10)).
    threshold_db: float | None = None
    #: Design false-alarm probability per cell.
    pfa: float | None = None
    #: Wrap the window around the ends (Doppler); else one-sided windows at the ends.
    cyclic: bool = False
    #: OS only: rank k (1-based) of the training cell used as noise; None: 0.75 N.
    os_rank: int | None = None
    #: Independent exponential powers summed in each cell (the virtual antennas of a
    #: map summed over them): the noise is then Gamma(channels), far less spread,
    #: and a Pfa needs a lower scale.  The frame processor sets it.
    channels: int = 1
    #: Correlation of the powers of cells 1, 2, ... apart along the axis (0..1 each; cells
    #: further apart: 0).  A window before the FFT makes neighbouring cells correlated (Hann:
    #: 0.45 one apart, 0.03 two apart), so a training window holds fewer independent cells than
    #: it has and its noise estimate spreads more: a Pfa then needs a higher scale.  The frame
    #: processor sets it from its windows.  Empty: independent cells.
    correlation: tuple[float, ...] = ()

    _scale: float = field(init=False, repr=False, compare=False)
    _edge_scale: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.method, str) or self.method.lower() not in METHODS:
            raise _fail(f"must be one of {', '.join(METHODS)}, got {self.method!r}", "method")
        set_ = object.__setattr__
        set_(self, "method", self.method.lower())
        set_(self, "guard", _as_int(self.guard, "guard", 0))
        set_(self, "train", _as_int(self.train, "train", 1))
        if isinstance(self.cyclic, (bool, np.bool_)) or self.cyclic in (0, 1):
            set_(self, "cyclic", bool(self.cyclic))
        else:
            raise _fail(f"must be a bool, got {self.cyclic!r}", "cyclic")
        thr = _as_optional_float(self.threshold_db, "threshold_db")
        pfa = _as_optional_float(self.pfa, "pfa")
        if (thr is None) == (pfa is None):
            raise _fail("give exactly one of threshold_db and pfa"
                        + (" (both given)" if thr is not None else " (neither given)"),
                        "threshold_db" if thr is not None else "pfa")
        if thr is not None and not 0.0 <= thr <= MAX_THRESHOLD_DB:
            # (below 0 the threshold is under the noise estimate; above 200 dB, a power ratio of 1e20,
            # beyond any radar's dynamic range: 1e30 dB overflowed the ratio)
            raise _fail(f"must be in [0, {MAX_THRESHOLD_DB:g}] dB, got {beyond_text(thr, 0.0, MAX_THRESHOLD_DB)}",
                        "threshold_db")
        if pfa is not None and not 0.0 < pfa < 1.0:
            raise _fail(f"must be in (0, 1), got {pfa:g}", "pfa")
        set_(self, "threshold_db", thr)
        set_(self, "pfa", pfa)
        n = 2 * self.train
        if self.os_rank is not None:
            if self.method != "os":
                raise _fail(f"only applies to method 'os', not {self.method!r}", "os_rank")
            rank = _as_int(self.os_rank, "os_rank", 1)
            if rank > n:
                raise _fail(f"must be at most the {n} training cells (2 * train), got {rank}",
                            "os_rank")
            set_(self, "os_rank", rank)
        set_(self, "channels", _as_int(self.channels, "channels", 1))
        try:
            correlation = tuple(float(c) for c in self.correlation)
        except (TypeError, ValueError):
            raise _fail(f"must be a list of numbers, got {self.correlation!r}", "correlation") from None
        if not all(0.0 <= c <= 1.0 for c in correlation):
            raise _fail(f"each must be within 0..1, got {correlation}", "correlation")
        set_(self, "correlation", correlation)
        set_(self, "_scale", self._compute_scale(n, self.rank))
        edge = self._scale if pfa is None or self.cyclic else self._compute_scale(self.train,
                                                                                  self.edge_rank,
                                                                                  one_sided=True)
        set_(self, "_edge_scale", edge)

    # ------------------------------------------------------------------ derived
    @property
    def num_train(self) -> int:
        """Training cells in a full (two-sided) window: N = 2 * train."""
        return 2 * self.train

    @property
    def window(self) -> int:
        """Cells the full window spans, CUT included: 2 * (guard + train) + 1."""
        return 2 * (self.guard + self.train) + 1

    @property
    def rank(self) -> int | None:
        """OS rank k in use (1-based), None for the cell-averaging methods."""
        if self.method != "os":
            return None
        if self.os_rank is not None:
            return self.os_rank
        return min(max(_round_half_up(0.75 * self.num_train), 1), self.num_train)

    @property
    def edge_rank(self) -> int | None:
        """OS rank over the ``train`` cells of a one-sided (non-cyclic edge) window."""
        if self.method != "os":
            return None
        return min(max(_round_half_up(self.rank * self.train / self.num_train), 1), self.train)

    @property
    def scale(self) -> float:
        """Threshold factor alpha (linear power ratio) over the noise estimate."""
        return self._scale

    @property
    def edge_scale(self) -> float:
        """alpha for cells with a one-sided window (non-cyclic ends); equals
        :attr:`scale` with ``threshold_db`` or ``cyclic``."""
        return self._edge_scale

    def effective_cells(self, m: int) -> float:
        """Independent cells that *m* contiguous training cells are worth: m^2 over the sum of
        their powers' correlations (the cells whose mean has the same spread), m without
        :attr:`correlation`."""
        c = self.correlation
        total = m + 2.0 * sum((m - k) * c[k - 1] for k in range(1, min(m, len(c) + 1)))
        return m * m / total

    @property
    def noise_factor(self) -> float:
        """The noise estimate's mean over the noise's, for the noise the Pfa is designed for
        (Gamma(channels) cells, :attr:`correlation`): 1 for CA, above 1 for CAGO and OS's upper
        ranks, below for CASO.  An estimate over it is the mean noise power, which an SNR is
        against."""
        rank = None if self.method != "os" else self.rank * self.effective_cells(self.train) / self.train
        return noise_factor(self.method, self.effective_cells(self.train), self.channels, rank)

    def _compute_scale(self, n: int, k: int | None, one_sided: bool = False) -> float:
        if self.threshold_db is not None:
            return 10.0 ** (self.threshold_db / 10.0)
        pfa = self.pfa
        if self.correlation:
            # The formulas below with the training window's independent-cell worth in place of
            # its cell count (moment matching: exact for the cell-averaging family on a Hann
            # window; for OS the rank scales with it, measured conservative).
            side = self.effective_cells(self.train)
            if one_sided or self.method in ("cago", "caso"):
                method = self.method if not one_sided or self.method == "os" else "ca"
                cells = side
            else:
                method, cells = self.method, 2.0 * side
            rank = None if k is None else k * cells / n
            return summed_scale(method, cells, self.channels, rank, pfa)
        if self.channels > 1:
            method = "ca" if one_sided and self.method != "os" else self.method
            side = n if method in ("ca", "os") else n // 2
            return summed_scale(method, side, self.channels, k, pfa)
        if self.method == "os":
            return ordered_scale(n, k, pfa)
        if self.method == "ca" or one_sided:
            return n * (pfa ** (-1.0 / n) - 1.0)
        return split_scale(self.method, n // 2, pfa)

    # ------------------------------------------------------------------ (de)serialise
    def to_dict(self) -> dict[str, Any]:
        """The constructor's arguments, JSON-ready."""
        return {"method": self.method, "guard": self.guard, "train": self.train,
                "threshold_db": self.threshold_db, "pfa": self.pfa, "cyclic": self.cyclic,
                "os_rank": self.os_rank, "channels": self.channels, "correlation": list(self.correlation)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> CfarParams:
        """Inverse of :meth:`to_dict`; unknown or missing keys raise :class:`ConfigError`."""
        if not isinstance(data, Mapping):
            raise _fail(f"expected a mapping, got {type(data).__name__}")
        known = ("method", "guard", "train", "threshold_db", "pfa", "cyclic", "os_rank", "channels", "correlation")
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise _fail(f"unknown key(s) {', '.join(map(str, unknown))}; known: {', '.join(known)}")
        missing = [k for k in ("method", "guard", "train") if k not in data]
        if missing:
            raise _fail(f"missing key(s) {', '.join(missing)}")
        return cls(**dict(data))

    def updated(self, data: Mapping[str, Any]) -> CfarParams:
        """These parameters with *data*'s keys given over them (a settings file names only what it
        changes); a ``threshold_db`` or ``pfa`` given replaces the other, a method other than ``os``
        drops the ordered statistic's ``os_rank``, and a ``train`` given without it scales it (the
        same quantile of the training cells: the median stays the median).  Errors as
        :meth:`from_dict`'s."""
        if not isinstance(data, Mapping):
            raise _fail(f"expected a mapping, got {type(data).__name__}")
        base = self.to_dict()
        if "threshold_db" in data or "pfa" in data:
            base["threshold_db"] = base["pfa"] = None
        if str(data.get("method", "os")).lower() != "os":  # ("OS" is os too: __post_init__ takes either case)
            base["os_rank"] = None
        elif base["os_rank"] is not None and "os_rank" not in data and is_whole_number(data.get("train")) \
                and data["train"] > 0:
            base["os_rank"] = max(1, round(base["os_rank"] * data["train"] / base["train"]))
        return CfarParams.from_dict({**base, **data})
