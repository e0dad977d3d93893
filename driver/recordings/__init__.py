"""Recordings: radarodom's capture directories (read by :mod:`.capture_dir`, written by
:mod:`.capture_writer`, checked by :mod:`.capture_check`), TI's recorder files
(:mod:`.ti_recorder`), pcap files of DCA1000 traffic (:mod:`.pcap`), and the ``replay://``
source that plays them (:mod:`.replay`)."""
