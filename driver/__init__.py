"""Getting radar frames: sources chosen by URL (:func:`open_source`), capture
directories, TI recorder files, and the DCA1000 wire formats."""

from .sources import Frame, Source, open_source, register_scheme  # noqa: F401
