"""Limits on what foldfab reads and builds: only regular files of a bounded size, wherever a
path is read (job files, SVG inputs, device profiles, resume states, the studio's open field),
and designs of a bounded number of faces, refused before they are built.

Every case runs in a child process with a memory limit and a timeout: a reader that follows
``/dev/zero`` or waits on a FIFO must fail the test, not take the machine with it."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from foldfab.design import build_design
from foldfab.errors import DesignError
from foldfab.job import job_data, parse_job
from foldfab.limits import MAX_FACES
from helpers import HEXAGON

MEMORY = 3 * 2**30
TIMEOUT = 120  # seconds: generous for a busy machine; a blocked reader never returns at all


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))


def child(args: list[str], env: dict | None = None) -> subprocess.CompletedProcess:
    """``args`` run with the memory limit and timeout (a timeout fails the test)."""
    return subprocess.run(args, capture_output=True, text=True, timeout=TIMEOUT, preexec_fn=_limited,
                          env={**os.environ, **(env or {})}, stdin=subprocess.DEVNULL)


def cli(*argv, env: dict | None = None) -> str:
    """``foldfab argv``: it must fail with exit 2 and one line; that line."""
    done = child([sys.executable, "-m", "foldfab", *map(str, argv)], env)
    assert done.returncode == 2, done.stderr
    assert done.stdout == "" and "Traceback" not in done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("foldfab: error: "), done.stderr
    return lines[0]


def library(code: str, env: dict | None = None) -> str:
    """The FoldfabError message ``code`` raises, run in a child process."""
    program = "from foldfab.errors import FoldfabError\ntry:\n" + textwrap.indent(textwrap.dedent(code), "    ") + \
              "\nexcept FoldfabError as exc:\n    print(exc)\nelse:\n    print('no error')\n"
    done = child([sys.executable, "-c", program], env)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


@pytest.fixture(params=["device", "fifo", "folder", "too large"])
def unreadable(request, tmp_path) -> tuple[Path, str]:
    """A path that is no regular file of a sensible size, and what the error calls it."""
    if request.param == "device":
        return Path("/dev/zero"), "is a character device"
    path = tmp_path / "input"
    if request.param == "fifo":
        os.mkfifo(path)
        return path, "is a FIFO (named pipe)"
    if request.param == "folder":
        path.mkdir()
        return path, "is a folder"
    with open(path, "wb") as handle:  # sparse: 64 MB and one byte, written in no time
        handle.truncate(64 * 2**20 + 1)
    return path, "larger than"  # than 64 MB (job, SVG) or 1 MB (device profile, resume state)


def test_a_job_that_is_no_regular_file_is_refused(unreadable):
    path, kind = unreadable
    line = cli("design", path)
    assert f"{path}: {kind}" in line
    assert f"{path}: {kind}" in library(f"from foldfab.job import load_job\nload_job({str(path)!r})")


def test_an_svg_input_that_is_no_regular_file_is_refused(unreadable, tmp_path):
    path, kind = unreadable
    job = tmp_path / "svg.toml"
    job.write_text(f'[profile]\nsvg = "{path}"\n[trajectory]\ntemplate = "regular"\ncorners = 6\nradius = 40\n')
    assert f"{path}: {kind}" in cli("design", job)
    assert f"{path}: {kind}" in library(f"from foldfab.design import load_design\nload_design({str(job)!r})")


def test_a_device_profile_that_is_no_regular_file_is_refused(unreadable, tmp_path):
    path, kind = unreadable
    device = str(path) if "/" in str(path) else f"./{path}"
    assert f"{path}: {kind}" in cli("export", HEXAGON, "--device", device, "-o", tmp_path / "out.hpgl")
    assert f"{path}: {kind}" in library(f"from foldfab.devices import load_device\nload_device({device!r})")
    assert not (tmp_path / "out.hpgl").exists()


def test_a_resume_state_that_is_no_regular_file_is_refused(unreadable, tmp_path):
    path, kind = unreadable
    token = "a" * 32
    folder = tmp_path / "state" / "foldfab" / "resume"
    folder.mkdir(parents=True)
    state = folder / f"{token}.json"
    if path == Path("/dev/zero"):  # cannot be moved: a link to it (state files are never read through links)
        state.symlink_to(path)
        kind = "is a symbolic link"
    else:
        path.rename(state)
    env = {"XDG_STATE_HOME": str(tmp_path / "state")}
    message = library(f"from foldfab.plotting.resume import load_state, state_dir\n"
                      f"assert state_dir() == __import__('pathlib').Path({str(folder)!r})\nload_state({token!r})", env)
    assert f"{state}: {kind}" in message


def test_the_studio_opens_only_regular_files(unreadable, tmp_path):
    path, kind = unreadable
    answer = library(f"""
        import json
        from foldfab.studio.api import Studio
        response = Studio({str(tmp_path)!r}, {str(HEXAGON)!r}).handle("POST", "/api/open",
                                                                   json.dumps({{"target": {str(path)!r}}}).encode())
        print(response.status, json.loads(response.body)["error"])""")
    assert answer.startswith("400 ") and f"{path}: {kind}" in answer


# --- faces -------------------------------------------------------------------------------------

def _zigzag(points: int) -> str:
    return "[" + ", ".join(f"[{i % 2}, {i}]" for i in range(points)) + "]"


BIG = f"""[profile]
points = {_zigzag(23)}
[trajectory]
template = "regular"
corners = 100000
radius = 100000
"""
"""22 profile segments x 100,001 trajectory segments: 2.2 million faces, over the default limit."""


def test_a_design_over_the_face_limit_is_refused_before_it_is_built(tmp_path):
    job = tmp_path / "big.toml"
    job.write_text(BIG)
    line = cli("design", job)
    assert "2,200,022 faces (22 profile segments x 100,001 trajectory segments)" in line
    assert f"the limit of {MAX_FACES:,}" in line
    assert "[design].max_faces = N" in line and "--max-faces N" in line
    with pytest.raises(DesignError, match=f"more than the limit of {MAX_FACES:,}"):
        build_design(parse_job(BIG, job))


def test_the_face_limit_is_the_jobs_or_the_command_lines(tmp_path):
    job = tmp_path / "small.toml"
    job.write_text(HEXAGON.read_text().replace('[design]\n', '[design]\nmax_faces = 10\n'))
    line = cli("design", job)
    assert "the design has 32 faces (4 profile segments x 7 trajectory segments and a glue tab)" in line and "the limit of 10;" in line
    for command in (["export", "--device", "hp7475a", "-o", tmp_path / "x.hpgl"],
                    ["preview", "--device", "hp7475a", "-o", tmp_path / "x.svg"],
                    ["queue", "add", "--device", "hp7475a", "--port", "sim://hp7475a", "--queue", tmp_path / "q.db"]):
        assert "the limit of 5;" in cli(command[0], *command[1:], job, "--max-faces", 5)
    done = child([sys.executable, "-m", "foldfab", "design", str(job), "--max-faces", "32", "--json"])
    assert done.returncode == 0 and json.loads(done.stdout)["faces"] == 32
    assert job_data(parse_job(job.read_text(), job))["design"]["max_faces"] == 10  # the studio saves it back
    done = child([sys.executable, "-m", "foldfab", "design", str(job), "--max-faces", "0"])
    assert done.returncode == 2 and "--max-faces: expected a whole number of 1 or more, got 0" in done.stderr


def test_the_studio_builds_at_most_its_own_limit(tmp_path):
    from foldfab.studio.api import STUDIO_MAX_FACES, Studio

    studio = Studio(tmp_path, HEXAGON)
    data = job_data(parse_job(HEXAGON.read_text(), HEXAGON))
    data["profile"]["points"] = [[i % 2, i] for i in range(2001)]
    data["trajectory"] = {"template": "regular", "corners": 100, "radius": 1000}
    response = studio.handle("POST", "/api/design", json.dumps({"job": data, "path": str(HEXAGON)}).encode())
    error = json.loads(response.body)["error"]
    assert response.status == 400
    assert f"more than the limit of {STUDIO_MAX_FACES:,}" in error and "foldfab design" in error


# --- strokes -----------------------------------------------------------------------------------

PERFORATED = """[profile]
points = [[0, 0], [8, 10], [0, 20], [8, 30], [0, 40]]
[trajectory]
template = "regular"
corners = 6
radius = 40
[fabrication]
strategy = "perforate"
max_strokes = {limit}
[fabrication.perforate]
valley = [0.1, 0.1]
mountain = [0.1, 0.1]
clearance = 0.1
"""


def test_a_program_over_the_stroke_limit_is_refused_before_it_is_cut(tmp_path):
    from foldfab.devices import load_device
    from foldfab.errors import FoldfabError
    from foldfab.fabricate import fabricate
    from foldfab.fabrication.spec import parse_fabrication
    from foldfab.programs.interpret import interpret

    job = tmp_path / "fine.toml"
    job.write_text(PERFORATED.format(limit=500))
    line = cli("export", job, "--device", "hp7475a", "-o", tmp_path / "x.hpgl")
    assert "strokes, more than the limit of 500;" in line and "[fabrication].max_strokes = N" in line
    assert "a longer [fabrication.perforate] pattern" in line and not (tmp_path / "x.hpgl").exists()
    design = build_design(parse_job(job.read_text(), job))
    with pytest.raises(FoldfabError, match="more than the limit of 500"):
        fabricate(design, load_device("hp7475a"))
    bound = int(line.split("up to ")[1].split(" strokes")[0].replace(",", ""))
    allowed = build_design(parse_job(PERFORATED.format(limit=bound), job))
    strokes = interpret(fabricate(allowed, load_device("hp7475a")).program, load_device("hp7475a")).strokes
    assert bound - 10 <= len(strokes) <= bound  # the count is a bound, and a close one
    from foldfab.limits import MAX_STROKES

    assert parse_fabrication({}, "x").max_strokes == MAX_STROKES


@pytest.mark.parametrize("table, key", [("[design]\nmax_faces = 0\n", "[design].max_faces: must be at least 1"),
                                        ("[design]\nmax_faces = 1.5\n", "[design].max_faces: expected a whole number"),
                                        ("[fabrication]\nmax_strokes = 0\n", "[fabrication].max_strokes: must be at least 1"),
                                        ("[fabrication]\nmax_strokes = \"many\"\n",
                                         "[fabrication].max_strokes: expected a whole number")])
def test_the_limits_in_a_job_are_checked(table, key):
    from foldfab.errors import FoldfabError
    from foldfab.fabrication.spec import job_spec

    with pytest.raises(FoldfabError, match=key.replace("[", r"\[").replace("]", r"\]").replace(".", r"\.")):
        job_spec(parse_job(table + '[profile]\npoints = [[0, 0], [5, 10]]\n[trajectory]\ntemplate = "regular"\n'
                           'corners = 6\nradius = 40\n', "job.toml"))  # as every command reads a job
