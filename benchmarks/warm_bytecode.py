"""Start-up figures as a user sees them: foldfab's bytecode compiled and cached.

Python caches a module's bytecode on its first import, so a user's second ``foldfab``
command no longer compiles foldfab's source.  A machine with ``PYTHONDONTWRITEBYTECODE``
set (this test machine has it) never writes that cache and would time the compiler on
every run (about 30 ms of a paper-scale export), so the benchmarks write it first.
"""

from __future__ import annotations

import compileall
from pathlib import Path


def cache_foldfab_bytecode(root: Path = Path(__file__).resolve().parent.parent) -> None:
    """Compile the modules of the foldfab in ``root`` (default this one) to ``__pycache__``
    (py_compile writes whatever the environment says)."""
    compileall.compile_dir(root / "foldfab", quiet=1)
