"""Where foldfab keeps its own files: under the XDG base directories.

Profiles a user adds live in the config home, the job queue in the data home and the
states of interrupted plots in the state home.  One rule serves all three, as the XDG
Base Directory Specification states it: a variable that is unset, empty or not an absolute
path is ignored, and its default under the home folder is taken instead.
"""

from __future__ import annotations

import os
from pathlib import Path

DEFAULTS = {"XDG_CONFIG_HOME": (".config",), "XDG_DATA_HOME": (".local", "share"),
            "XDG_STATE_HOME": (".local", "state")}


def foldfab_dir(variable: str) -> Path:
    """``$variable/foldfab``, or the variable's default (e.g. ``~/.local/state``) ``/foldfab``."""
    value = os.environ.get(variable, "")
    base = Path(value) if os.path.isabs(value) else Path.home().joinpath(*DEFAULTS[variable])
    return base / "foldfab"
