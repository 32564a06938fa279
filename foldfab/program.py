"""Deprecated path of :func:`foldfab.programs.languages.write_program` (until foldfab 0.3)."""

import warnings

from foldfab.programs.languages import write_program

warnings.warn("foldfab.program is foldfab.programs.languages (write_program) since the package layout of "
              "December 2026; the old path goes in foldfab 0.3", DeprecationWarning, stacklevel=2)

__all__ = ["write_program"]
