"""TI's own detection lines, read into radarodom's: ``cfarCfg`` as :class:`~.cfar.CfarParams`, and
``cfarFovCfg`` as a mask of ranges and radial velocities (``DspConfig.ti_like``)."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

import numpy as np

from ..cfg_commands import CfarCfg, CfarFovCfg
from ..errors import ConfigError, UsageError
from .cfar import CfarParams

log = logging.getLogger(__name__)

#: TI ``cfarCfg`` mode -> our method (SDK 3.x: 0 CFAR_CA, 1 CFAR_CAGO, 2 CFAR_CASO).
TI_MODES = {0: "ca", 1: "cago", 2: "caso"}
#: ``cfarFovCfg`` procDirection -> what its limits bound.
FOV_DIRECTIONS = {0: "range (m)", 1: "radial velocity (m/s)"}


def params_from_ti(cfar_cfg: CfarCfg) -> CfarParams:
    """Our detector for one of the cfg's ``cfarCfg`` lines.

    ``mode`` 0/1/2 -> 'ca'/'cago'/'caso'; ``noiseWin`` -> ``train``; ``guardLen`` ->
    ``guard``; ``cyclic`` -> ``cyclic``; ``thresholdScale`` (dB) -> ``threshold_db``.
    ``divShift`` is not used: we divide by the exact number of training cells (TI
    shifts by ``divShift`` bits, meant to be ceil(log2(2 noiseWin)) for CA and
    ceil(log2(noiseWin)) for CAGO/CASO; other values are logged).  ``peakGrouping`` is
    not part of :class:`CfarParams`: pass ``bool(cfar_cfg.peak_grouping)`` to
    :func:`cfar_2d_ti`.  ``subFrameIdx`` is ignored (legacy frames only).

    How the threshold relates (an approximation, stated honestly)
    ------------------------------------------------------------
    In the xWR18xx demo (SDK 3.x, DSP chain) the detection matrix holds, per cell, the
    sum over the Nv virtual antennas of log2|X| in Q8 (``log2Abs``), shifted right by
    ceil(log2 Nv) bits; CFAR averages those log values over the training cells
    (``noise sum >> divShift``) and detects when ``CUT > noise + thresholdScale``, with
    the CLI's dB converted as ``dB * 256 / 6 * Nv / 2**ceil(log2 Nv)`` (the demo's
    ``MmwDemo_convertCfarToLinear``; TI E2E threads 623550 and 642095 explain the 256
    (Q8), the Nv (non-coherent sum) and the 6 (dB per log2 unit)).  Per antenna that
    is mean(log2|X_CUT|) - mean(log2|X_train|) > dB / 6, and since 20 log10|X| =
    6.02 log2|X|: 10 log10 P_CUT - mean(10 log10 P_train) > 1.0034 dB, i.e. a **power
    ratio of about 10^(dB/10) over the geometric mean** of the training power.  We use
    that ratio over the **arithmetic mean** of linear power.  The two differ:

    * for exponential (Rayleigh-amplitude) noise, E[ln P] = ln(mean P) - 0.5772 (the
      Euler-Mascheroni constant), so the geometric mean is 2.5 dB below the arithmetic
      mean.  A steady target must be about (dB - 2.5) dB above the mean noise power to
      pass TI's test, and dB above it to pass ours: ours is ~2.5 dB stricter;
    * TI averages logs over antennas before detecting (a different statistic), so the
      false-alarm rate at a given dB differs too.  For a controlled false-alarm rate
      build :class:`CfarParams` with ``pfa`` instead.
    """
    if not isinstance(cfar_cfg, CfarCfg):
        raise UsageError(f"expected a CfarCfg, got {type(cfar_cfg).__name__}")
    try:
        method = TI_MODES[cfar_cfg.mode]
    except KeyError:
        raise ConfigError(f"mode {cfar_cfg.mode} is not one of 0 (CA), 1 (CAGO), 2 (CASO)",
                          command="cfarCfg", field="mode") from None
    cells = 2 * cfar_cfg.noise_win if method == "ca" else cfar_cfg.noise_win
    expected_shift = math.ceil(math.log2(cells)) if cells > 1 else 0
    if cfar_cfg.div_shift != expected_shift:
        log.info("cfarCfg (procDirection %d): divShift %d is not ceil(log2(%d)) = %d; radarodom "
                 "divides by the exact number of training cells and ignores it",
                 cfar_cfg.proc_direction, cfar_cfg.div_shift, cells, expected_shift)
    try:
        return CfarParams(method=method, guard=cfar_cfg.guard_len, train=cfar_cfg.noise_win,
                          threshold_db=float(cfar_cfg.threshold_db), cyclic=bool(cfar_cfg.cyclic))
    except ConfigError as exc:
        raise ConfigError(exc.message, command="cfarCfg", field=exc.field) from None


def fov_mask(range_m: np.ndarray, velocity_mps: np.ndarray,
             fov: Mapping[int, CfarFovCfg]) -> np.ndarray:
    """Which cells or detections lie inside the cfg's ``cfarFovCfg`` limits.

    Parameters
    ----------
    range_m
        Range, m, any shape.
    velocity_mps
        Radial velocity, m/s, a shape that broadcasts with ``range_m`` (equal shapes for
        per-detection values; ``velocity[:, None]`` and ``range[None, :]`` for a map).
    fov
        ``RadarConfig.cfar_fov``: procDirection 0 -> range limits in m, 1 -> Doppler
        (radial velocity) limits in m/s; a missing direction leaves that axis unbounded.

    Returns
    -------
    bool array of the broadcast shape: ``min <= value <= max`` on every given direction.
    """
    r = np.asarray(range_m, dtype=np.float64)
    v = np.asarray(velocity_mps, dtype=np.float64)
    try:
        shape = np.broadcast_shapes(r.shape, v.shape)
    except ValueError:
        raise UsageError(f"range_m shaped {r.shape} and velocity_mps shaped {v.shape} do not "
                         f"broadcast") from None
    if not isinstance(fov, Mapping):
        raise UsageError(f"fov must be a mapping procDirection -> CfarFovCfg, got {type(fov).__name__}")
    mask = np.ones(shape, dtype=bool)
    for direction, lim in fov.items():  # at most two entries
        if direction not in FOV_DIRECTIONS:
            raise ConfigError(f"procDirection {direction!r} is not 0 (range) or 1 (Doppler)",
                              command="cfarFovCfg", field="procDirection")
        if not isinstance(lim, CfarFovCfg):
            raise UsageError(f"fov[{direction}] must be a CfarFovCfg, got {type(lim).__name__}")
        if lim.proc_direction != direction:
            raise ConfigError(f"keyed as {direction} but its procDirection is {lim.proc_direction}",
                              command="cfarFovCfg", field="procDirection")
        if lim.min_value > lim.max_value:
            raise ConfigError(f"min {lim.min_value:g} is above max {lim.max_value:g}",
                              command="cfarFovCfg", field="min (meters or m/s)")
        values = r if direction == 0 else v
        mask &= (values >= lim.min_value) & (values <= lim.max_value)
    return mask



__all__ = ["FOV_DIRECTIONS", "TI_MODES", "fov_mask", "params_from_ti"]
