"""What the tidemo tests share: a cfg the demo's UART carries at 10 frames/s (64 samples, 16 loops,
3 TX: a 2 KB static heatmap), with TI's CFAR lines."""

from __future__ import annotations

TIDEMO_CFG = """\
% tidemo test profile: 64 samples, 16 loops, 3 TX, 10 frames/s
sensorStop
flushCfg
dfeDataOutputMode 1
channelCfg 15 7 0
adcCfg 2 1
adcbufCfg -1 0 1 1 1
profileCfg 0 77 100 6 40 0 0 96 1 64 8000 0 0 30
chirpCfg 0 0 0 0 0 0 0 1
chirpCfg 1 1 0 0 0 0 0 4
chirpCfg 2 2 0 0 0 0 0 2
frameCfg 0 2 16 0 100 1 0
lowPower 0 0
guiMonitor -1 1 0 0 1 0 0
cfarCfg -1 0 2 8 4 3 0 15 1
cfarCfg -1 1 0 4 2 3 1 15 1
multiObjBeamForming -1 0 0.5
clutterRemoval -1 0
compRangeBiasAndRxChanPhase 0.0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0
aoaFovCfg -1 -90 90 -90 90
cfarFovCfg -1 0 0 10.0
cfarFovCfg -1 1 -9 9
sensorStart
"""
