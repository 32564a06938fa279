"""Fabrication is safe to run concurrently: parallel threads get byte for byte the programs
that one-at-a-time runs give (the studio and the CLI's worker threads fabricate side by side)."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

from foldfab.design import build_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate
from foldfab.job import parse_job

DEVICES = ("hp7475a", "grbl")
STRATEGIES = ("force", "perforate", "two-sided")
METHODS = ("greedy", "two-opt")


def _job(i: int):
    """Twenty different designs: regular and star trajectories, profiles of different heights."""
    height = 10 + 3 * i
    profile = f"[[0, 0], [{1 + 0.3 * (i % 5)}, {height / 2}], [0, {height}]]"
    if i % 2:
        trajectory = f'template = "regular"\ncorners = {4 + 2 * (i % 3)}\nradius = {30 + i}'
    else:
        trajectory = f'template = "star"\npoints = {3 + i % 3}\nouter_radius = {40 + i}\ninner_radius = {(40 + i) * 0.6}'
    return parse_job(f"""
[design]
name = "parallel {i}"
[profile]
points = {profile}
[trajectory]
{trajectory}
[fabrication]
strategy = "{STRATEGIES[i % 3]}"
sheet = "A3 landscape"
optimize = "{METHODS[i % 2]}"
scale = 0.5
""", f"<parallel {i}>")


def test_twenty_parallel_fabrications_match_one_at_a_time():
    cases = [(build_design(_job(i), check_penetration=False), load_device(DEVICES[i % 2])) for i in range(20)]
    alone = [fabricate(design, device).program.text for design, device in cases]
    assert len(set(alone)) == 20
    start = threading.Barrier(20, timeout=60)

    def run(case):
        start.wait()  # all threads enter vpype together
        return fabricate(*case).program.text
    with ThreadPoolExecutor(20) as pool:
        together = list(pool.map(run, cases))
    assert [i for i in range(20) if together[i] != alone[i]] == []
