"""The README's commands are the ones that work: CI runs the README's test command verbatim."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
import urllib.request
from helpers import ROOT



def _commands() -> list[str]:
    return re.findall(r"```sh\n(.+?)\n```", (ROOT / "README.md").read_text(), flags=re.S)


def test_readme_has_exactly_two_commands():
    commands = _commands()
    assert len(commands) == 2
    assert "foldfab" in commands[0] and commands[1].startswith("scripts/test")


def test_the_test_command_sets_up_what_the_tests_need():
    """On a fresh machine the README's test command alone must pass: it installs the Debian
    packages the tests use (the HPGL reader, the PDF reader, the browser), the virtual environment and the test
    extra, then runs pytest."""
    script = ROOT / _commands()[1].split()[0]
    assert script.is_file() and script.stat().st_mode & 0o111
    text = script.read_text()
    for need in ("hp2xx", "chromium", "libatomic1", "poppler-utils", "python3-venv", "apt-get install", 'pip install -q -e ".[test]"',
                 "-m pytest"):
        assert need in text, need


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    assert _commands()[1] in ci.splitlines()
    assert "apt-get" not in ci  # the README's command does it all, or it would fail on a fresh machine


def test_main_command_uses_an_existing_job():
    jobs = re.findall(r"jobs/[\w-]+\.toml", _commands()[0])
    assert jobs and all((ROOT / job).is_file() for job in jobs)


def _tour() -> list[str]:
    """The ``$ foldfab ...`` lines of the README's console blocks, in order."""
    blocks = re.findall(r"```console\n(.+?)\n```", (ROOT / "README.md").read_text(), flags=re.S)
    return [line[2:] for block in blocks for line in block.splitlines() if line.startswith("$ ")]


def test_the_tour_has_commands_for_every_stage():
    words = {shlex.split(command)[1] for command in _tour()}
    assert {"design", "preview", "export", "plot", "queue", "studio"} <= words


def test_every_tour_command_runs(tmp_path):
    """Each tour command, as written, in a copy of the repository's jobs: exit 0 (the studio: it serves)."""
    shutil.copytree(ROOT / "jobs", tmp_path / "jobs")
    (tmp_path / "out").mkdir()
    env = {**os.environ, "XDG_STATE_HOME": str(tmp_path / "state"), "XDG_DATA_HOME": str(tmp_path / "data")}
    for command in _tour():
        argv = [sys.executable, "-m", "foldfab", *shlex.split(command)[1:]]
        if argv[3] == "studio":
            with subprocess.Popen(argv, cwd=tmp_path, env=env, stdout=subprocess.PIPE, text=True) as studio:
                try:
                    line = studio.stdout.readline()  # the server prints its address once it listens
                    address = re.search(r"http://127\.0\.0\.1:\d+/", line)
                    assert address, line
                    with urllib.request.urlopen(address.group(), timeout=60) as page:
                        assert page.status == 200
                finally:
                    studio.terminate()
            continue
        result = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600,
                                stdin=subprocess.DEVNULL)
        assert result.returncode == 0, f"{command}\n{result.stdout}\n{result.stderr}"
