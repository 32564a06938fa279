"""Fixtures the streaming, resume and locate tests share."""

import pytest

from helpers.streams import xonxoff_profile


@pytest.fixture(scope="session")
def xonxoff_device(tmp_path_factory):
    return str(xonxoff_profile(tmp_path_factory.mktemp("devices")))
