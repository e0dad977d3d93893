"""Emulators of the hardware, speaking the real protocols over real sockets
and pseudo-terminals: a fake DCA1000 (UDP) and a fake AWR1843 CLI (pty).
Used by the tests and by ``radar-emulate`` to try the live path without a radar."""
