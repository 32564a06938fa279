"""Fixtures the studio's browser tests share."""

from __future__ import annotations

import pytest

from helpers.browser import chromium


@pytest.fixture(scope="module")
def browser():
    """Debian's Chromium, headless, once per module."""
    with chromium() as browser:
        yield browser
