"""Each command loads only what it uses: the parser reads no library, and a command group that
needs no plotting, queue store, mesh or PDF library never starts one (their start-up is most of
what a short command costs).  Run in a fresh interpreter per command, as the console script is."""

from __future__ import annotations

import subprocess
import sys

import pytest

from helpers import ROOT

PLOTTING = {"vpype", "scipy", "shapely"}
"""Sorting and merging the strokes of a program."""
STORE = {"sqlite3", "psycopg"}
"""A queue store."""
LINK = {"serial", "usb"}
"""A port to a plotter."""
MESH, PDF = {"trimesh"}, {"reportlab"}
QUEUE = {"foldfab.queue.records", "foldfab.queue.snapshot", "foldfab.queue.store", "foldfab.plotting.progress"}
"""The queue's records (dataclasses, a few milliseconds of start-up): the parser reads its limits only."""
READ_BACK = {f"foldfab.programs.{name}" for name in ("machine", "read_hpgl", "read_gcode", "read_gpgl", "read_ebb")}
"""The program readers: an export whose writer records what it draws (HP-GL, G-code) reads nothing back."""
SPLIT = {"foldfab.geometry.split"}
"""Splitting a design into pieces: only a job that asks for it."""
PARSER_ONLY = PLOTTING | STORE | LINK | MESH | PDF | QUEUE | {"numpy", "secrets", "socket"}
"""What reading the parser (``--help`` of any command) loads none of."""
JOB = str(ROOT / "jobs" / "hexagon-fig8a.toml")
DIAMOND = str(ROOT / "jobs" / "diamond-fig9.toml")


def after(argv: list[str], expression: str, cwd):
    """The value of ``expression`` (Python, a list or bool) in the process that ran ``foldfab ARGV``,
    once the command is done (it must succeed)."""
    code = ("import gc, sys, runpy\nsys.argv = ['foldfab', *sys.argv[1:]]\n"
            "try:\n    runpy.run_module('foldfab', run_name='__main__')\nexcept SystemExit as exc:\n"
            "    assert not exc.code, exc.code\n"
            f"print(repr({expression}), file=sys.stderr)\n")
    result = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, cwd=cwd,
                            timeout=300)
    assert result.returncode == 0, result.stderr
    return eval(result.stderr.strip().splitlines()[-1])  # a value printed by the child


def loaded(argv: list[str], watched: set[str], cwd) -> list[str]:
    """The modules of ``watched`` in ``sys.modules`` after ``foldfab ARGV`` (which must succeed)."""
    return after(argv, f"sorted(m for m in {sorted(watched)!r} if m in sys.modules)", cwd)


@pytest.mark.parametrize("argv", [["--help"], *([group, "--help"] for group in
                                  ("design", "export", "preview", "plot", "print", "sim", "studio", "queue",
                                   "devices", "ports")),
                                  ["queue", "add", "--help"], ["queue", "list", "--help"], ["queue", "run", "--help"]])
def test_help_reads_the_parser_only(argv, tmp_path):
    assert loaded(argv, PARSER_ONLY, tmp_path) == []


@pytest.mark.parametrize("argv, heavy", [
    (["design", JOB], PLOTTING | STORE | LINK | MESH | PDF | QUEUE),
    (["design", JOB, "--mesh", "{tmp}/h.glb"], PLOTTING - {"scipy", "shapely"} | STORE | LINK | PDF | QUEUE),
    (["export", JOB, "--device", "hp7475a", "-o", "{tmp}/h.plt"], STORE | LINK | MESH | PDF | QUEUE | READ_BACK | SPLIT),
    (["preview", JOB, "--device", "hp7475a", "-o", "{tmp}/h.svg"], STORE | LINK | MESH | PDF),
    (["print", JOB, "-o", "{tmp}/h.pdf"], PLOTTING | STORE | LINK | MESH),
    (["plot", DIAMOND, "--device", "hp7475a", "--port", "sim://?time=instant", "--yes"], STORE | MESH | PDF),
    (["queue", "list", "--queue", "{tmp}/q.sqlite3"], PLOTTING | LINK | MESH | PDF | {"numpy"}),
    (["devices"], PLOTTING | STORE | LINK | MESH | PDF | {"numpy"}),
    (["ports"], PLOTTING | STORE | MESH | PDF),
])
def test_a_command_imports_only_what_it_uses(argv, heavy, tmp_path):
    """``design`` builds geometry only; ``print`` draws no program; ``plot`` keeps no queue; the
    queue's list, ``devices`` and ``ports`` compute nothing."""
    assert loaded([arg.format(tmp=tmp_path) for arg in argv], heavy, tmp_path) == []


@pytest.mark.parametrize("argv, collects", [
    (["design", JOB], False),
    (["export", JOB, "--device", "hp7475a", "-o", "{tmp}/h.plt"], False),
    (["preview", JOB, "--device", "hp7475a", "-o", "{tmp}/h.svg"], False),
    (["print", JOB, "-o", "{tmp}/h.pdf"], False),
    (["plot", DIAMOND, "--device", "hp7475a", "--port", "sim://?time=instant", "--yes"], True),
    (["queue", "list", "--queue", "{tmp}/q.sqlite3"], True),
    (["devices"], True),
])
def test_only_a_command_that_builds_one_thing_runs_without_the_cyclic_collector(argv, collects, tmp_path):
    """Loading the libraries is cheaper without cyclic collection (nothing of it is garbage); a
    command that runs on (plotting, the queue's worker, the studio) collects as usual."""
    assert after([arg.format(tmp=tmp_path) for arg in argv], "gc.isenabled()", tmp_path) is collects
