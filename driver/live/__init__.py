"""The live radar: the AWR1843's UART CLI, the DCA1000's UDP wire formats, the receiver that
assembles frames from packets, the frame ring, device discovery, and the ``dca1000://``
source (:mod:`.source`) that puts them together."""
