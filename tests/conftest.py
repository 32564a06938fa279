"""Test settings: hypothesis explores randomly on a developer's machine, deterministically in CI.
The shared helpers are tests/helpers (this folder is on sys.path: pytest's rootdir import mode
puts each conftest.py's folder there), their asserts rewritten as a test's are; fixtures that
tests in several folders use are here."""

import os

import pytest
from hypothesis import settings

pytest.register_assert_rewrite("helpers")

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture
def state_home(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    return tmp_path / "state"


@pytest.fixture(scope="session")
def postgres_server():
    """A real PostgreSQL server for this test session (tests/helpers/postgres.py), stopped at the end."""
    from helpers.postgres import running_server

    with running_server() as server:
        yield server
