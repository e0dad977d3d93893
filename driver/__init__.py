"""Getting radar frames.  One door: :func:`open_source` opens a source by URL
(``dca1000://``, ``tidemo://``, ``replay://``, ``sim://``, ``coloradar://``; :mod:`.sources`).
Behind it, one room each: the live radar with a DCA1000 (:mod:`.live`), the radar alone through
TI's demo firmware's UART output and its recordings (:mod:`.tidemo`), recordings
(:mod:`.recordings`), the simulator (:mod:`.sim`), ColoRadar runs (:mod:`.coloradar`), and the
hardware emulators (:mod:`.emulators`)."""

from .sources import Frame, Source, open_source, register_scheme  # noqa: F401
