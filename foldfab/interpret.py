"""Deprecated path of :func:`foldfab.programs.interpret.interpret` (until foldfab 0.3)."""

import warnings

from foldfab.programs.interpret import interpret

warnings.warn("foldfab.interpret is foldfab.programs.interpret since the package layout of December 2026; "
              "the old path goes in foldfab 0.3", DeprecationWarning, stacklevel=2)

__all__ = ["interpret"]
