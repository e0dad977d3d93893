"""radarodom: radar-only odometry for the TI AWR1843BOOST with a DCA1000EVM.

The repository root is this package.  Its subpackages:

- ``radarodom.driver``: capture sources chosen by URL (``replay://``, later
  ``dca1000://`` and ``sim://``), capture directories, wire formats.
- ``radarodom.dsp``: range/Doppler/angle processing (imports no driver code).
- ``radarodom.estimator``: ego-velocity, yaw and odometry (imports no driver code).
- ``radarodom.tools``: the command-line programs.

Shared foundations live at the top level: :mod:`radarodom.errors` (the one
exception family), :mod:`radarodom.cfg` (the TI ``.cfg`` model),
:mod:`radarodom.antenna` (the AWR1843BOOST virtual array) and
:mod:`radarodom.rawframe` (raw ADC byte layout <-> complex cube).
"""

import logging

__version__ = "0.1.0"

# pytest imports the checkout's root (this file) as a test package, and alone as a module named
# "__init__" when the folder's name is no identifier ("radarodom-main" from a zip): then there is
# no package to import from, and nothing to re-export.
if __spec__ is not None and __spec__.parent:
    from .errors import (  # noqa: F401  (re-exported API)
        CaptureError,
        ConfigError,
        DeviceError,
        RadarodomError,
        SourceError,
        UsageError,
    )

# Library code only logs; applications decide where records go.
logging.getLogger(__name__).addHandler(logging.NullHandler())
