"""Helpers the tests share (imported as ``helpers``: tests/conftest.py puts tests/ on sys.path),
and the repository's paths, so that no test depends on how deep its file lies."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent
"""The repository: README.md, jobs/, devices/, benchmarks/."""
JOB_FOLDER = ROOT / "jobs"
JOBS = sorted(JOB_FOLDER.glob("*.toml"))
"""The example jobs."""
