"""TI's mmWave SDK 3.x demo firmware's own output on the radar's data UART (``tidemo://``): the
packet format (:mod:`.wire`), the framer (:mod:`.framer`), what the demo sends for a cfg and
whether the UART carries it (:mod:`.layout`), the packets as radarodom's products
(:mod:`.products`), the live source (:mod:`.source`, :mod:`.ports`), its recording
(:mod:`.recording`) and replay (:mod:`.replay`)."""
