"""ColoRadar runs (Kramer et al., IJRR 2022): the reader (:mod:`.run`, :class:`ColoRadarRun`)
with its streams' files (:mod:`.streams`), file formats (:mod:`.files`) and frame conventions
(:mod:`.geometry`), the mapping of its waveform and coupling onto radarodom's (:mod:`.waveform`,
:mod:`.coupling`), and the ``coloradar://`` source (:mod:`.source`)."""

from .run import ColoRadarRun  # noqa: F401
