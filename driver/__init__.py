"""Getting radar frames.  One door: :func:`open_source` opens a source by URL
(``dca1000://``, ``replay://``, ``sim://``, ``coloradar://``; :mod:`.sources`).  Behind it, one
room each: the live radar (:mod:`.live`), recordings (:mod:`.recordings`), the simulator
(:mod:`.sim`), ColoRadar runs (:mod:`.coloradar`), and the hardware emulators
(:mod:`.emulators`)."""

from .sources import Frame, Source, open_source, register_scheme  # noqa: F401
