"""Where the DSP detects: the shortest and longest range of a detection, from the DSP's settings,
the cfg's range window (cfarFovCfg, procDirection 0) and the usable range (beat frequencies up to
80 % of the IF band, less the board's range bias); and, when nothing is left between them, an
error that names the line or the setting that closed the window."""

from __future__ import annotations

import logging

from ..cfg import RadarConfig
from ..cfg_text import CfgLine
from ..errors import ConfigError
from .config import DspConfig

log = logging.getLogger(__name__)

#: cfarFovCfg's fields, as the cfg's own errors name them.
FOV_MIN, FOV_MAX = "min (meters or m/s)", "max (meters or m/s)"


def detection_range(cfg: RadarConfig, params: DspConfig, range_bias_m: float) -> tuple[float, float]:
    """(shortest, longest) range of a detection, m (see FrameProcessor.detection_range_m);
    :class:`ConfigError` where the two meet, naming what set them."""
    fov_line = cfg.cfar_fov_line(0)
    fov = None if fov_line is None else fov_line.value
    lo = params.min_range_m if fov is None else max(params.min_range_m, fov.min_value)
    # The IF band's limit is on the beat frequency, before the range bias comes off.
    usable = cfg.max_range_m - range_bias_m
    if params.max_range_m is not None:
        hi = params.max_range_m
    elif fov is not None:  # never beyond the usable range
        hi = min(fov.max_value, usable)
        note = cfg.range_fov_note(range_bias_m)
        if note is not None:
            log.info("%s", note)
    else:
        hi = usable
    if hi <= lo:
        raise _nothing_left(cfg, fov_line, params, lo, hi, usable, range_bias_m)
    return lo, hi


def _nothing_left(cfg: RadarConfig, fov_line: CfgLine | None, params: DspConfig, lo: float, hi: float, usable: float,
                  range_bias_m: float) -> ConfigError:
    """The error of a closed window, located at what closed it: the DSP's own limit, the cfg's
    range window, its range bias, or its profile's range."""
    window = f"nothing is left to detect in between {lo:.3g} m and {hi:.3g} m"
    if params.max_range_m is not None:
        return ConfigError(f"{window} (DspConfig min_range_m {params.min_range_m:g} m and max_range_m "
                           f"{params.max_range_m:g} m, and the cfg's range window)", field="max_range_m")
    if fov_line is not None:
        fov = fov_line.value
        if lo == fov.min_value > params.min_range_m:
            return ConfigError(f"the range window starts at {lo:g} m, beyond the usable range ({usable:.2f} m): "
                               f"{window}; start it lower", path=cfg.path, line=fov_line.line,
                               command="cfarFovCfg", field=FOV_MIN)
        if hi == fov.max_value:
            return ConfigError(f"the range window ends at {hi:g} m, at or below radarodom's shortest range "
                               f"({lo:g} m): {window}; end it further out",
                               path=cfg.path, line=fov_line.line, command="cfarFovCfg", field=FOV_MAX)
    bias_line = cfg.line_of("compRangeBiasAndRxChanPhase")
    if range_bias_m > 0 and bias_line is not None:
        return ConfigError(f"a range bias of {range_bias_m:g} m leaves {usable:.2f} m of the profile's usable "
                           f"{cfg.max_range_m:.2f} m: {window}; is it the board's? radar-calibrate measures it",
                           path=cfg.path, line=bias_line.line, command="compRangeBiasAndRxChanPhase",
                           field="rangeBias")
    profile = cfg.line_of("profileCfg")
    return ConfigError(f"the profile's usable range is {usable:.2f} m (beat frequencies up to 80 % of the IF "
                       f"band, less a range bias of {range_bias_m:g} m): {window}", path=cfg.path,
                       line=None if profile is None else profile.line, command="profileCfg")
