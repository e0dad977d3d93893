"""The pyserial URL ``fakeawr1843://[name]``: a client of the fake AWR1843's CLI pty by URL.

:class:`FakeAwr1843Serial` is the port, :func:`serial_class_for_url` pyserial's hook for it and
:func:`register_url_handler` what makes ``serial.serial_for_url("fakeawr1843://...")`` find it.
:mod:`.fake_awr1843` calls :func:`register_url_handler` when it is imported, after setting
:attr:`FakeAwr1843Serial.make_fake` to :class:`~.fake_awr1843.FakeAwr1843`: this module serves
the board's pty but does not import the board (which enters its named instances in
:data:`_NAMED`), so that the two do not import each other.
"""

from __future__ import annotations

import sys
import types
import weakref
from collections.abc import Callable

import serial
import serial.serialposix

from .awr1843_pty import Awr1843Pty

#: Fakes created with a name, for ``fakeawr1843://<name>``.
_NAMED: weakref.WeakValueDictionary[str, Awr1843Pty] = weakref.WeakValueDictionary()

URL_SCHEME = "fakeawr1843"


class FakeAwr1843Serial(serial.serialposix.Serial):
    """pyserial port for ``fakeawr1843://[name]``.

    ``fakeawr1843://`` starts a private :class:`~.fake_awr1843.FakeAwr1843`, closed with the
    port; ``fakeawr1843://<name>`` attaches to the live fake created with
    ``FakeAwr1843(name=<name>)`` (opening its pty if needed).  Either way the
    port is a real pty client; the fake is :attr:`fake`.
    """

    fake: Awr1843Pty | None = None
    _owns_fake = False
    #: Makes the private fake of ``fakeawr1843://``: :class:`~.fake_awr1843.FakeAwr1843`,
    #: set by :mod:`.fake_awr1843` when it is imported (this module does not import it).
    make_fake: Callable[[], Awr1843Pty] | None = None

    def open(self) -> None:
        url = self._port
        if not isinstance(url, str) or not url.lower().startswith(URL_SCHEME + "://"):
            raise serial.SerialException(f"not a {URL_SCHEME}:// URL: {url!r}")
        name = url[len(URL_SCHEME) + 3:].split("?", 1)[0].strip("/")
        if name:
            fake = _NAMED.get(name)
            if fake is None:
                raise serial.SerialException(f"no FakeAwr1843 named {name!r}")
            owns = False
        else:
            if self.make_fake is None:
                raise serial.SerialException(f"{URL_SCHEME}:// needs {__package__}.fake_awr1843 imported")
            fake, owns = self.make_fake(), True
        path = fake.path or fake.open_pty()
        self.fake, self._owns_fake = fake, owns
        self.portstr = path  # PosixSerial opens portstr; port keeps the URL
        try:
            super().open()
        except BaseException:
            if owns:
                fake.close()
            raise

    def close(self) -> None:
        super().close()
        if self._owns_fake and self.fake is not None:
            self.fake.close()


def serial_class_for_url(url: str):
    """pyserial's protocol-handler hook."""
    return url, FakeAwr1843Serial


def register_url_handler() -> None:
    """Make ``serial.serial_for_url("fakeawr1843://...")`` work (idempotent)."""
    handler = f"{__package__}.protocol_{URL_SCHEME}"
    if handler not in sys.modules:
        module = types.ModuleType(handler, "pyserial handler for fakeawr1843:// (awr1843_url.py)")
        module.serial_class_for_url = serial_class_for_url  # type: ignore[attr-defined]
        module.Serial = FakeAwr1843Serial  # type: ignore[attr-defined]
        sys.modules[handler] = module
    if __package__ not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(__package__)


__all__ = ["URL_SCHEME", "FakeAwr1843Serial", "register_url_handler", "serial_class_for_url"]
