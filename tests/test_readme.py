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
    assert "foldfab" in commands[0] and "pytest" in commands[1]


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    assert _commands()[1] in ci.splitlines()


def test_main_command_uses_an_existing_job():
    jobs = re.findall(r"jobs/[\w-]+\.toml", _commands()[0])
    assert jobs and all((ROOT / job).is_file() for job in jobs)
