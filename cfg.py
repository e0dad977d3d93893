"""The radar configuration: a TI mmWave SDK 3.x ``.cfg`` for the xWR18xx.

:class:`RadarConfig` parses the CLI text (``%`` comments, blank lines, CRLF),
keeps every line so it can be written back and sent to the radar, types the
commands that decide the raw data and the processing, validates them the way
the firmware would (with ``file:line: command: field:`` in every error), and
derives the radar's physics as properties with units in their names.

Wavelength convention: velocities use the wavelength at the centre of the ADC
sampling window, because that is the frequency the Doppler phase of a
range-FFT peak advances with.  TI's tools use the start frequency, so their
velocity figures are larger by ``carrier_frequency_hz / start_frequency_hz``
(about 2.7 % for a 77 GHz, 100 MHz/us profile).
"""

from __future__ import annotations

import logging
import os
from typing import Any, Iterator, Sequence

from . import cfg_commands as cc
from .cfg_checks import REQUIRED_COMMANDS, ConfigChecks  # noqa: F401  (REQUIRED_COMMANDS re-exported)
from .cfg_fields import shown
from .cfg_physics import (  # noqa: F401  (re-exported: radarodom.cfg is where users find them)
    BYTES_PER_COMPLEX_SAMPLE, DCA1000_DEFAULT_PACKET_DELAY_US, DCA1000_PACKET_DATA_BYTES,
    DCA1000_PACKET_DELAY_RANGE_US, DCA1000_THROUGHPUT_TABLE, MAX_RF_FREQUENCY_HZ, SPEED_OF_LIGHT,
    ConfigPhysics, dca1000_capacity_mbps)
from .cfg_text import MAX_CFG_BYTES, CfgLine, WarningSummary, read_cfg_file, tokenize
from .errors import ConfigError, UsageError, given_path

__all__ = ["RadarConfig", "CfgLine", "MAX_CFG_BYTES", "shipped_config_path", "dca1000_capacity_mbps"]

log = logging.getLogger(__name__)

#: Typed commands that may appear more than once: name -> field that keys them.
KEYED_COMMANDS = {"cfarCfg": "proc_direction", "cfarFovCfg": "proc_direction"}
#: Commands the driver sends itself around the cfg's own lines.
SESSION_COMMANDS = ("sensorStop", "flushCfg", "sensorStart")
#: The lvdsStreamCfg line raw capture needs (header off, ADC data, no SW data).
RAW_LVDS_LINE = "lvdsStreamCfg -1 0 1 0"


#: The radar configuration shipped in ``configs/`` and used when none is given.
DEFAULT_CONFIG_NAME = "awr1843_raw.cfg"
#: The one ``tidemo://`` uses when none is given: the same radar with 128 samples, whose frames
#: the demo's UART carries at 10 frames/s, and the chip's CFAR at 10 dB.
TIDEMO_CONFIG_NAME = "awr1843_tidemo.cfg"


def _path_text(path: Any) -> str:
    """A cfg's origin as text for messages (bytes paths decoded, None as ``<cfg>``)."""
    if path is None:
        return "<cfg>"
    if isinstance(path, bytes):
        return os.fsdecode(path)
    if isinstance(path, (str, os.PathLike)):
        where = os.fspath(path)
        return os.fsdecode(where) if isinstance(where, bytes) else where
    raise ConfigError(f"expected a file path or None, got {type(path).__name__}")


def shipped_config_path(name: str = DEFAULT_CONFIG_NAME) -> str:
    """Path of a cfg shipped with radarodom (``configs/<name>``), installed or not."""
    from importlib import resources

    return str(resources.files(__package__).joinpath("configs", name))


class RadarConfig(ConfigChecks, ConfigPhysics):
    """A validated xWR18xx radar configuration.

    Build one with :meth:`from_file` or :meth:`from_text`; write it back with
    :meth:`to_text`.  Typed commands are attributes (``cfg.profile``,
    ``cfg.frame``, ...); the frame layout and derived physics are properties
    (:class:`radarodom.cfg_physics.ConfigPhysics`); the checks made when it is built are
    :class:`radarodom.cfg_checks.ConfigChecks`.
    """

    def __init__(self, lines: Sequence[CfgLine], path: str | os.PathLike | None = None) -> None:
        self.path = _path_text(path)
        self._refuse_no_cfg(lines)
        self._warnings = WarningSummary(log, self.path)
        typed = []
        try:
            for ln in lines:
                if ln.kind == "command" and ln.value is None:
                    ln = self._type_line(ln)
                typed.append(ln)
            self.lines: tuple[CfgLine, ...] = tuple(typed)
            self._index()
            self._validate()
        finally:  # what was noticed before an error is still said
            self._warnings.emit()

    # ------------------------------------------------------------------ parsing
    @classmethod
    def from_text(cls, text: str, path: str | os.PathLike | None = None) -> "RadarConfig":
        """Parse cfg text; *path* only names the origin in messages."""
        where = _path_text(path)
        if not isinstance(text, str):
            raise ConfigError(f"expected cfg text, got {type(text).__name__}", path=where)
        return cls(tokenize(text, where), where)

    @classmethod
    def from_file(cls, path: str | os.PathLike) -> "RadarConfig":
        """Read and parse a cfg file of at most :data:`MAX_CFG_BYTES`.  Any failure, a path
        that is no file or no path at all included, is a :class:`ConfigError`."""
        where, text = read_cfg_file(path)
        return cls.from_text(text, where)

    def _refuse_no_cfg(self, lines: Sequence[CfgLine]) -> None:
        """A file with no command, or none a TI cfg has (another file given by mistake), is refused
        as that, before a warning for each of its lines and a field said to be missing."""
        commands = [ln for ln in lines if ln.kind == "command"]
        if not commands:
            raise ConfigError("no command in it (empty, or only comments and blank lines): not a TI mmWave "
                              "cfg, whose lines are commands such as sensorStop, channelCfg, profileCfg",
                              path=self.path)
        known = (*cc.TYPED_COMMANDS, *cc.VERBATIM_COMMANDS, *cc.UNSUPPORTED_COMMANDS)
        if not any(ln.text in known for ln in commands):
            first = commands[0]
            raise ConfigError(f"not a TI mmWave cfg: none of its {len(commands)} command line(s) is a cfg "
                              f"command (the first: {shown(first.text)})", path=self.path, line=first.line)

    def _fail(self, message: str, ln: CfgLine | None = None, fld: str | None = None) -> ConfigError:
        return ConfigError(
            message,
            path=self.path,
            line=ln.line if ln else None,
            command=ln.text if ln else None,
            field=fld,
        )

    def _type_line(self, ln: CfgLine) -> CfgLine:
        name = ln.text
        if name in cc.TYPED_COMMANDS:
            value = cc.parse_args(name, ln.args, path=self.path, line=ln.line)
            return CfgLine("command", name, ln.args, value, ln.line)
        if name in cc.UNSUPPORTED_COMMANDS:
            raise self._fail(cc.UNSUPPORTED_COMMANDS[name], ln)
        if name in cc.VERBATIM_COMMANDS:
            counts = cc.VERBATIM_COMMANDS[name]
            if len(ln.args) not in counts:
                expected = " or ".join(map(str, counts))
                raise self._fail(f"expected {expected} arguments, got {len(ln.args)}", ln)
            if name in cc.CHECKED_COMMANDS:
                value = cc.parse_args(name, ln.args, path=self.path, line=ln.line)
                return CfgLine("command", name, ln.args, value, ln.line)
            self._check_ascii(ln)
            if name in cc.UNCHECKED_COMMANDS:
                self._warnings.add(f"{name} not checked", ln.line, f"{name}: arguments not checked by "
                                   f"radarodom; sent to the radar as written")
            return ln
        self._check_ascii(ln)
        self._warnings.add("unknown command", ln.line,
                           f"unknown command {shown(name)}: not checked, sent to the radar as written; "
                           f"the radar may reject it")
        return ln

    def _check_ascii(self, ln: CfgLine) -> None:
        """A line sent as written must be one the radar's ASCII CLI can read."""
        for i, token in enumerate((ln.text, *ln.args)):
            if not token.isascii():
                where = "the command name" if i == 0 else f"argument {i}"
                raise ConfigError(f"{where} {shown(token)} is not ASCII: the radar's CLI reads ASCII only",
                                  path=self.path, line=ln.line)

    def _index(self) -> None:
        self._first: dict[str, CfgLine] = {}
        self._keyed: dict[str, dict[int, CfgLine]] = {k: {} for k in KEYED_COMMANDS}
        chirps: list[CfgLine] = []
        for ln in self.commands():
            name = ln.text
            if name == "chirpCfg":
                chirps.append(ln)
            elif name in KEYED_COMMANDS:
                key = getattr(ln.value, KEYED_COMMANDS[name])
                if key in self._keyed[name]:
                    first = self._keyed[name][key].line
                    raise self._fail(f"given twice for procDirection {key} (first at line {first})", ln)
                self._keyed[name][key] = ln
            elif name in cc.TYPED_COMMANDS:
                first = self._first.get(name)
                if first is not None and name == "profileCfg" and ln.value.profile_id != first.value.profile_id:
                    raise self._fail(f"a second profile (profileId {ln.value.profile_id}; profileId "
                                     f"{first.value.profile_id} at line {first.line}): radarodom takes one profile, "
                                     f"which every chirpCfg uses", ln, "profileId")
                if first is not None:
                    raise self._fail(f"given twice (first at line {first.line})", ln)
                self._first[name] = ln
            elif name == "bpmCfg" and ln.value.enabled:
                raise self._fail("BPM-MIMO is not supported: use TDM (bpmCfg -1 0 0 0)", ln, "enabled")
        self._chirp_lines = tuple(chirps)

    def check_raw_capture(self) -> None:
        """Raise :class:`ConfigError` unless the cfg streams raw ADC data over LVDS
        the way the DCA1000 capture needs it (``lvdsStreamCfg -1 0 1 0``)."""
        ln = self._first.get("lvdsStreamCfg")
        if ln is None:
            raise ConfigError(f"missing: add the line '{RAW_LVDS_LINE}' before sensorStart so the "
                              f"radar streams raw ADC data to the DCA1000", path=self.path,
                              command="lvdsStreamCfg")
        v = ln.value
        if v.data_fmt != 1 or v.enable_header or v.enable_sw:
            raise self._fail(f"'{ln}' does not stream raw ADC data only; change this line to "
                             f"'{RAW_LVDS_LINE}'", ln)

    @property
    def streams_raw_adc(self) -> bool:
        """True when ``lvdsStreamCfg`` streams headerless raw ADC data."""
        try:
            self.check_raw_capture()
        except ConfigError:
            return False
        return True

    # ----------------------------------------------------------------- writing
    def to_text(self) -> str:
        """The cfg as text (LF line ends); ``from_text(to_text())`` equals this config."""
        return "".join(str(ln) + "\n" for ln in self.lines)

    def write(self, path: str | os.PathLike) -> None:
        """The cfg's text to *path* (written over); :class:`ConfigError` naming it when it cannot be."""
        path = given_path(path, ConfigError, "cfg file path")
        try:
            with open(path, "w", encoding="utf-8", newline="\n") as fh:
                fh.write(self.to_text())
        except OSError as exc:
            raise ConfigError(f"cannot write the cfg: {exc.strerror or exc}", path=path) from None

    def replace(self, command: Any) -> "RadarConfig":
        """A new config with the typed *command* replacing the line of the same
        name (and procDirection, where keyed), or inserted before sensorStart."""
        name = cc.cli_name(command)
        # The typed value is left for __init__ to re-derive from the text, so
        # every field check runs on the new command as on a parsed one.
        new = CfgLine("command", name, cc.format_args(command))
        key_field = KEYED_COMMANDS.get(name)
        lines = list(self.lines)
        for i, ln in enumerate(lines):
            if ln.kind == "command" and ln.text == name and (
                key_field is None or getattr(ln.value, key_field) == getattr(command, key_field)
            ):
                lines[i] = CfgLine("command", name, new.args, None, ln.line)
                return RadarConfig(lines, self.path)
        at = next((i for i, ln in enumerate(lines) if ln.kind == "command" and ln.text == "sensorStart"),
                  len(lines))
        lines.insert(at, new)
        return RadarConfig(lines, self.path)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, RadarConfig) and self.lines == other.lines

    def __hash__(self) -> int:
        return hash(self.lines)

    def __repr__(self) -> str:
        return f"RadarConfig({self.path!r}, {len(self.lines)} lines)"

    # ---------------------------------------------------------------- commands
    def commands(self) -> Iterator[CfgLine]:
        """Every command line, in file order."""
        return (ln for ln in self.lines if ln.kind == "command")

    def commands_to_send(self) -> list[CfgLine]:
        """The command lines a driver sends between its own ``sensorStop``/``flushCfg``
        and ``sensorStart``."""
        return [ln for ln in self.commands() if ln.text not in SESSION_COMMANDS]

    def session_order_note(self) -> str | None:
        """A warning when ``sensorStart`` comes before a command that configures the radar: radarodom
        sends its own after every command, but TI's tools send the file in order, and the radar
        would start unconfigured; None otherwise."""
        commands = list(self.commands())
        start = next((i for i, ln in enumerate(commands) if ln.text == "sensorStart"), None)
        later = None if start is None else next(
            (ln for ln in commands[start + 1:] if ln.text not in SESSION_COMMANDS), None)
        if later is None:
            return None
        return (f"{self.path}:{commands[start].line}: sensorStart comes before {later.text} (line {later.line}): "
                "radarodom sends its own sensorStart after every command, but TI's tools send the file in "
                "order and would start the radar unconfigured; put sensorStart last")

    def line_of(self, name: str) -> CfgLine | None:
        """The (first) line of command *name*, or None."""
        return next((ln for ln in self.commands() if ln.text == name), None)

    def _value(self, name: str) -> Any:
        ln = self._first.get(name)
        return ln.value if ln is not None else None

    @property
    def channel(self) -> cc.ChannelCfg:
        return self._value("channelCfg")

    @property
    def adc(self) -> cc.AdcCfg:
        return self._value("adcCfg")

    @property
    def adcbuf(self) -> cc.AdcbufCfg:
        return self._value("adcbufCfg")

    @property
    def profile(self) -> cc.ProfileCfg:
        return self._value("profileCfg")

    @property
    def chirps(self) -> tuple[cc.ChirpCfg, ...]:
        return tuple(ln.value for ln in self._chirp_lines)

    @property
    def frame(self) -> cc.FrameCfg:
        return self._value("frameCfg")

    @property
    def low_power(self) -> cc.LowPower | None:
        return self._value("lowPower")

    @property
    def lvds_stream(self) -> cc.LvdsStreamCfg | None:
        return self._value("lvdsStreamCfg")

    @property
    def cfar(self) -> dict[int, cc.CfarCfg]:
        """cfarCfg by procDirection (0 range, 1 Doppler)."""
        return {k: ln.value for k, ln in self._keyed["cfarCfg"].items()}

    @property
    def cfar_fov(self) -> dict[int, cc.CfarFovCfg]:
        """cfarFovCfg by procDirection (0 range in m, 1 Doppler in m/s)."""
        return {k: ln.value for k, ln in self._keyed["cfarFovCfg"].items()}

    def cfar_fov_line(self, direction: int) -> CfgLine | None:
        """The cfarFovCfg line of procDirection *direction* (its number, for messages), or None."""
        return self._keyed["cfarFovCfg"].get(direction)

    @property
    def aoa_fov(self) -> cc.AoaFovCfg | None:
        return self._value("aoaFovCfg")

    @property
    def multi_obj_beam_forming(self) -> cc.MultiObjBeamForming | None:
        return self._value("multiObjBeamForming")

    @property
    def clutter_removal(self) -> cc.ClutterRemoval | None:
        return self._value("clutterRemoval")

    @property
    def calib_dc_range_sig(self) -> cc.CalibDcRangeSig | None:
        return self._value("calibDcRangeSig")

    @property
    def comp_range_bias_and_rx_chan_phase(self) -> cc.CompRangeBiasAndRxChanPhase | None:
        return self._value("compRangeBiasAndRxChanPhase")

    @property
    def channel_measurement(self) -> cc.MeasureRangeBiasAndRxChanPhase | None:
        """The measureRangeBiasAndRxChanPhase command when it is enabled (TI's SDK 3.x demo then
        measures its channel calibration on the chip every frame and prints the line), else None."""
        line = self.line_of("measureRangeBiasAndRxChanPhase")  # a checked command, sent as written
        return line.value if line is not None and line.value.enabled else None

    @property
    def channel_calibration(self):
        """The compRangeBiasAndRxChanPhase line as numbers (:class:`radarodom.calibration.
        ChannelCalibration`: range bias, gain and phase per path); the identity without the line."""
        from .calibration import ChannelCalibration

        return ChannelCalibration.from_config(self)

    @property
    def extended_max_velocity(self) -> cc.ExtendedMaxVelocity | None:
        return self._value("extendedMaxVelocity")


def require_config(value: Any, name: str = "cfg") -> None:
    """:class:`UsageError` unless *value* (the argument *name*) is a :class:`RadarConfig`."""
    if not isinstance(value, RadarConfig):
        raise UsageError(f"{name}: a RadarConfig (RadarConfig.from_file(path) reads one), got {type(value).__name__}")
