"""What the fake AWR1843's demo firmware prints of itself (mmWave SDK 3.x, the xWR18xx demo): its
version and boot banner, the commands it knows beyond radarodom's cfg model, and their usage
for ``help``."""

from __future__ import annotations

import dataclasses

from ... import cfg_commands as cc

#: SDK version the fake claims to run.
SDK_VERSION = "03.05.00.04"

#: What ``version`` prints before ``Done``: the fields the SDK 3.x demo prints;
#: the RF firmware and mmWaveLink numbers are plausible, not copied from a board.
VERSION_LINES = (
    "Platform                : xWR18xx",
    f"mmWave SDK Version      : {SDK_VERSION}",
    "Device Info             : AWR18XX non-secure ES 02.00",
    "RF F/W Version          : 02.02.00.01.20.07.23",
    "RF F/W Patch            : 00.00.00.00.00.00.00",
    "mmWaveLink Version      : 01.02.06.06",
)

#: What a reset (RESET_AR_DEV, power-up) prints before the first prompt.
BOOT_BANNER = (
    "******************************************",
    f"xWR18xx MMW Demo {SDK_VERSION}",
    "******************************************",
)

#: Commands the demo knows besides those radarodom types or keeps verbatim,
#: with their argument counts (SDK 3.5 user guide).  radarodom refuses them
#: in a cfg; the firmware accepts them and fails only at sensorStart.
EXTRA_COMMANDS: dict[str, tuple[int, ...]] = {
    "advFrameCfg": (5,),
    "subFrameCfg": (10,),
}

#: Known commands that do not change the configuration: allowed while running.
RUNTIME_COMMANDS = frozenset({"sensorStart", "sensorStop", "version", "help", "queryDemoStatus"})

#: Verbatim commands' argument names, for ``help`` (SDK 3.5 user guide).
VERBATIM_USAGE = {
    "sensorStart": "[doReconfig(optional, default:enabled)]",
    "sensorStop": "No arguments",
    "flushCfg": "No arguments",
    "guiMonitor": "<subFrameIdx> <detectedObjects> <logMagRange> <noiseProfile> "
                  "<rangeAzimuthHeatMap> <rangeDopplerHeatMap> <statsInfo>",
    "measureRangeBiasAndRxChanPhase": "<enabled> <targetDistance> <searchWin>",
    "CQRxSatMonitor": "<profile> <satMonSel> <priSliceDuration> <numSlices> <rxChanMask>",
    "CQSigImgMonitor": "<profile> <numSlices> <numSamplePerSlice>",
    "analogMonitor": "<rxSaturation> <sigImgBand>",
    "calibData": "<save enable> <restore enable> <Flash offset>",
    "bpmCfg": "<subFrameIdx> <enabled> <chirp0Idx> <chirp1Idx>",
    "configDataPort": "<baudrate> <ackPing>",
    "queryDemoStatus": "No arguments",
    "idlePowerCycle": "<subFrameIdx> <enDSPpowerdown> <enDSSclkgate> <enMMWclkgate> "
                      "<enBSSclkgate> <enRFpowerdown>",
    "version": "No arguments",
    "help": "No arguments",
    "advFrameCfg": "<numOfSubFrames> <forceProfile> <numFrames> <triggerSelect> <frameTrigDelay>",
    "subFrameCfg": "<subFrameNum> <forceProfileIdx> <chirpStartIdx> <numOfChirps> <numLoops> "
                   "<burstPeriodicity> <chirpStartIdxOffset> <numOfBurst> <numOfBurstLoops> "
                   "<subFramePeriodicity>",
}

#: Explanatory line the demo prints before "Error -1" for a malformed command.
INVALID_USAGE = "Error: Invalid usage of the CLI command"


def known_commands() -> tuple[str, ...]:
    """Every command name the fake firmware recognises."""
    return (*cc.TYPED_COMMANDS, *cc.VERBATIM_COMMANDS, *EXTRA_COMMANDS)


def usage(name: str) -> str:
    """The arguments ``help`` lists for the command *name* (its cfg fields' TI names)."""
    cls = cc.TYPED_COMMANDS.get(name)
    if cls is None:
        return VERBATIM_USAGE.get(name, "")
    if cls is cc.CompRangeBiasAndRxChanPhase:
        return f"<rangeBias> <Re00> <Im00> ... ({cc.NUM_COMP_VIRTUAL_ANTENNAS} virtual antennas)"
    return " ".join(f"<{f.metadata['ti_name']}>" for f in dataclasses.fields(cls))
