"""What the tidemo tests share: a cfg the demo's UART carries at 10 frames/s (conftest's SMALL_CFG
with 64 samples and 16 loops, 3 TX: a 2 KB static heatmap), with TI's CFAR lines and no
lvdsStreamCfg (the demo's UART output needs none)."""

from __future__ import annotations

from conftest import SMALL_CFG

_DEMO_LINES = """\
guiMonitor -1 1 0 0 1 0 0
cfarCfg -1 0 2 8 4 3 0 15 1
cfarCfg -1 1 0 4 2 3 1 15 1
multiObjBeamForming -1 0 0.5
clutterRemoval -1 0
compRangeBiasAndRxChanPhase 0.0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0
aoaFovCfg -1 -90 90 -90 90
cfarFovCfg -1 0 0 10.0
cfarFovCfg -1 1 -9 9
"""


def _swapped(text: str, *pairs: tuple[str, str]) -> str:
    for old, new in pairs:
        if old not in text:
            raise ValueError(f"conftest.SMALL_CFG has no line {old!r} any more: update tidemo_helpers.py")
        text = text.replace(old, new)
    return text


TIDEMO_CFG = _swapped(SMALL_CFG,
                      ("% small test profile", "% tidemo test profile: 64 samples, 16 loops, 3 TX, 10 frames/s"),
                      ("96 1 16 8000 0 0 30", "96 1 64 8000 0 0 30"),  # profileCfg's numAdcSamples
                      ("frameCfg 0 2 4 0 50 1 0", "frameCfg 0 2 16 0 100 1 0"),
                      ("lvdsStreamCfg -1 0 1 0\n", _DEMO_LINES))
