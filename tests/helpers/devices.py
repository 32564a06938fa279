"""Device profiles the tests break on purpose."""

from __future__ import annotations

from pathlib import Path

import pytest

from foldfab.devices import load_device
from foldfab.errors import FoldfabError


def broken(tmp_path: Path, edit, base: str = "grbl") -> str:
    """Write the ``base`` profile through ``edit``; the one-line FoldfabError message, which
    names the file."""
    path = tmp_path / "broken.toml"
    path.write_text(edit(Path(load_device(base).source).read_text()))
    with pytest.raises(FoldfabError) as error:
        load_device(str(path))
    message = str(error.value)
    assert str(path) in message and "\n" not in message
    return message
