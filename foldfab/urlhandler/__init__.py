"""Deprecated home of foldfab's pyserial URL handlers: use ``foldfab.plotting.urlhandler``.

Kept until foldfab 0.3 so that a pyserial configuration naming ``foldfab.urlhandler`` in
``serial.protocol_handler_packages`` still opens ``sim://``.
"""

import warnings

warnings.warn("foldfab.urlhandler is foldfab.plotting.urlhandler since the package layout of December 2026; "
              "the old path goes in foldfab 0.3", DeprecationWarning, stacklevel=2)
