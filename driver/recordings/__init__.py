"""Recordings: radarodom's capture directories (:mod:`.capture_dir`, checked by
:mod:`.capture_check`), TI's recorder files (:mod:`.ti_recorder`), pcap files of DCA1000
traffic (:mod:`.pcap`), and the ``replay://`` source that plays them (:mod:`.replay`)."""
