"""``foldfab profile``: a job with a generated profile, written only when it reads back and builds."""

from __future__ import annotations

import numpy as np
import pytest

from foldfab.design import load_design
from foldfab.job import load_job
from helpers import JOB_FOLDER
from helpers.cli import run


@pytest.mark.parametrize("kind", ["sine", "arc", "spline", "smooth"])
def test_each_generator_writes_a_job_that_builds(capsys, tmp_path, kind):
    out = tmp_path / "wave.toml"
    rc, text, err = run(capsys, "profile", JOB_FOLDER / "hexagon-fig8a.toml", kind, "--amplitude", "20",
                        "--period", "10", "--points", "61", "-o", out)
    assert rc == 0 and not err and f"{kind} profile of" in text
    job = load_job(out)
    original = load_job(JOB_FOLDER / "hexagon-fig8a.toml")
    assert job.trajectory == original.trajectory and job.crease == original.crease
    points = np.array(job.profile.points)
    if kind in ("sine", "arc"):
        assert len(points) == 61 and np.all(np.diff(points[:, 1]) > 0)
    design = load_design(out)      # valid: the wave is clamped (u <= 11.547 on this hexagon) and leaves the tab room
    assert len(design.penetrations) == 0 and points[:, 0].max() <= 11.5471


def test_mistakes_are_one_line_and_nothing_is_written(capsys, tmp_path):
    out = tmp_path / "wave.toml"
    for argv, fragment in ((["sine", "--points", "5000"], "points must be from 2 to 2000"),
                           (["sine", "--period", "0"], "period must be")):
        rc, text, err = run(capsys, "profile", JOB_FOLDER / "hexagon-fig8a.toml", *argv, "-o", out)
        assert rc == 2 and fragment in err and len(err.strip().splitlines()) == 1 and not out.exists()
    out.write_text("kept")
    rc, _, err = run(capsys, "profile", JOB_FOLDER / "hexagon-fig8a.toml", "sine", "-o", out)
    assert rc == 2 and "exists; pass --force" in err and out.read_text() == "kept"
