"""Each command loads only what it uses: the parser reads no library, and a command group that
needs no plotting, queue store, mesh or PDF library never starts one (their start-up is most of
what a short command costs).  Run in a fresh interpreter per command, as the console script is."""

from __future__ import annotations

import os
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


def after(argv: list[str], expression: str, cwd, setup: str = "", env: dict[str, str] | None = None):
    """The value of ``expression`` (Python, a list or bool; after the code ``setup``) in the process
    that ran ``foldfab ARGV`` (with the environment ``env``), once the command is done (it must succeed)."""
    code = ("import gc, os, sys, runpy\nsys.argv = ['foldfab', *sys.argv[1:]]\n"
            "try:\n    runpy.run_module('foldfab', run_name='__main__')\nexcept SystemExit as exc:\n"
            f"    assert not exc.code, exc.code\n{setup}\n"
            f"print(repr({expression}), file=sys.stderr)\n")
    result = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, cwd=cwd,
                            timeout=300, env=env)
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


def test_numpy_and_scipy_start_no_idle_threads(tmp_path):
    """OpenBLAS's threads (one per core and library) spin at start and after work, for matrices of
    three by three: no command starts them, unless the user asks for them."""
    argv = ["export", JOB, "--device", "hp7475a", "-o", str(tmp_path / "h.plt")]
    assert after(argv, "len(os.listdir('/proc/self/task'))", tmp_path) == 1
    asked = dict(os.environ, OPENBLAS_NUM_THREADS="2")
    assert after(argv, "os.environ['OPENBLAS_NUM_THREADS']", tmp_path, env=asked) == "2"


MALLINFO = """
import ctypes
class Info(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd",
                                                     "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]
mallinfo2 = ctypes.CDLL(None).mallinfo2
mallinfo2.restype = Info
"""
"""glibc's ``mallinfo2``: ``arena`` is what the heap holds from the system."""


@pytest.mark.parametrize("argv, keeps", [
    (["export", JOB, "--device", "hp7475a", "-o", "{tmp}/h.plt"], True),
    (["design", JOB], True),
    (["devices"], False),
    (["plot", DIAMOND, "--device", "hp7475a", "--port", "sim://?time=instant", "--yes"], False),
])
def test_a_command_that_builds_one_thing_keeps_freed_memory_for_its_next_arrays(argv, keeps, tmp_path):
    """A large export frees and allocates arrays of megabytes by turns: the heap keeps 64 MB
    spare at its top rather than handing it back to be faulted in again, page by page; a command
    that runs on (plotting) leaves the allocator as it is."""
    arena = after([arg.format(tmp=tmp_path) for arg in argv], "mallinfo2().arena", tmp_path, setup=MALLINFO)
    assert (arena >= 64 << 20) is keeps
