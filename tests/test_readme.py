"""The README's commands are the ones that work: CI runs the README's test command verbatim."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _commands() -> list[str]:
    return re.findall(r"```sh\n(.+?)\n```", (ROOT / "README.md").read_text(), flags=re.S)


def test_readme_has_exactly_two_commands():
    commands = _commands()
    assert len(commands) == 2
    assert "foldfab" in commands[0] and commands[1].startswith("scripts/test")


def test_the_test_command_sets_up_what_the_tests_need():
    """On a fresh machine the README's test command alone must pass: it installs the Debian
    packages the tests use (the HPGL reader, the browser), the virtual environment and the test
    extra, then runs pytest."""
    script = ROOT / _commands()[1].split()[0]
    assert script.is_file() and script.stat().st_mode & 0o111
    text = script.read_text()
    for need in ("hp2xx", "chromium", "python3-venv", "apt-get install", 'pip install -q -e ".[test]"',
                 "-m pytest"):
        assert need in text, need


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    assert _commands()[1] in ci.splitlines()
    assert "apt-get" not in ci  # the README's command does it all, or it would fail on a fresh machine


def test_main_command_uses_an_existing_job():
    jobs = re.findall(r"jobs/[\w-]+\.toml", _commands()[0])
    assert jobs and all((ROOT / job).is_file() for job in jobs)
