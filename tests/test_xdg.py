"""foldfab's own folders follow the XDG Base Directory Specification."""

from __future__ import annotations

from pathlib import Path

import pytest

from foldfab.devices.load import _user_dir
from foldfab.queue.sqlite import default_queue_path
from foldfab.plotting.resume import state_dir
from foldfab.xdg import foldfab_dir

FOLDERS = [("XDG_CONFIG_HOME", ".config", lambda: _user_dir(), "devices"),
           ("XDG_DATA_HOME", ".local/share", lambda: default_queue_path(), "queue.sqlite3"),
           ("XDG_STATE_HOME", ".local/state", lambda: state_dir(), "resume")]


@pytest.mark.parametrize("variable, default, where, leaf", FOLDERS, ids=[f[0] for f in FOLDERS])
def test_each_folder_is_under_its_xdg_home(variable, default, where, leaf, tmp_path, monkeypatch):
    monkeypatch.delenv("FOLDFAB_QUEUE", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv(variable, str(tmp_path / "xdg"))
    assert where() == tmp_path / "xdg" / "foldfab" / leaf
    # unset, empty or relative (the specification: "consider the path invalid and ignore it")
    for value in (None, "", "relative/dir"):
        if value is None:
            monkeypatch.delenv(variable)
        else:
            monkeypatch.setenv(variable, value)
        assert where() == tmp_path / "home" / default / "foldfab" / leaf
        assert foldfab_dir(variable) == tmp_path / "home" / Path(default) / "foldfab"
