"""Helpers the tests share (imported as ``helpers``: tests/conftest.py puts tests/ on sys.path),
and the repository's paths, so that no test depends on how deep its file lies."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent
"""The repository: README.md, jobs/, devices/, benchmarks/."""
JOB_FOLDER = ROOT / "jobs"
JOBS = sorted(JOB_FOLDER.glob("*.toml"))
"""The example jobs."""
HEXAGON = JOB_FOLDER / "hexagon-fig8a.toml"
"""The issue's example job: 28 strokes, quick to fabricate."""
GPGL_DEVICES = ["silhouette-cameo-4", "silhouette-portrait-3", "graphtec-ce6000-gpgl"]
"""The shipped GP-GL profiles: two tool holders, one, and a Graphtec in GP-GL mode."""
DEVICES = ["hp7475a", "graphtec-ce6000", "roland-gx24", "grbl", *GPGL_DEVICES]
"""The shipped device profiles, one of each protocol and flow control, and the GP-GL ones."""
