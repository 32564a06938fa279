"""The job snapshot a queued job runs: the program, the job file's and the device profile's texts.

Store-independent: made when a job is added (:func:`make_snapshot`), its program serialized
for any store (:func:`program_meta`, :func:`program_from`), its device profile loaded back as it
was (:func:`load_snapshot_device`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.programs.program import Program


@dataclass(frozen=True)
class Snapshot:
    """What a queued job runs: the program and the texts it was built from."""

    name: str
    job_path: str
    job_text: str
    device: str
    device_text: str
    program: Program

    @property
    def sha256(self) -> str:
        """SHA-256 of the program text."""
        from foldfab.plotting.resume import program_hash

        return program_hash(self.program)


# --- program (de)serialization -------------------------------------------------------------


def program_meta(program: Program) -> str:
    return json.dumps({
        "protocol": program.protocol, "device": program.device,
        "sections": [[s.offset, s.step, s.layer_id, s.name, s.repeat,
                      [s.tool.pen, s.tool.force, s.tool.speed, s.tool.passes]] for s in program.sections],
        "pauses": [[p.offset, p.step, p.message] for p in program.pauses]})


def program_from(text: str, meta: str) -> Program:
    from foldfab.devices import Tool
    from foldfab.programs.program import PauseMark, Program, Section

    data = json.loads(meta)
    return Program(text, data["protocol"], data["device"],
                   tuple(Section(o, st, lid, n, r, Tool(*tool)) for o, st, lid, n, r, tool in data["sections"]),
                   tuple(PauseMark(o, st, m) for o, st, m in data["pauses"]))


def make_snapshot(job_path: Path, job_text: str, name: str, device: DeviceProfile, program: Program) -> Snapshot:
    """The snapshot of a built job: the texts are read now, so later edits change nothing."""
    from foldfab.files import SMALL_LIMIT, read_text

    device_text = read_text(device.source, "device profile", SMALL_LIMIT, encoding="utf-8")
    return Snapshot(name, str(Path(job_path).resolve()), job_text, device.name, device_text, program)


def load_snapshot_device(snapshot: Snapshot) -> DeviceProfile:
    """The device profile as it was when the job was queued."""
    import tempfile

    from foldfab.devices import load_device

    with tempfile.TemporaryDirectory(prefix="foldfab-queue-") as folder:
        path = Path(folder) / f"{snapshot.device}.toml"
        path.write_text(snapshot.device_text, encoding="utf-8")
        return load_device(path)


def drawn_length(snapshot: Snapshot) -> float:
    """mm the snapshot's program draws in all: known when it is queued, so a queued job's
    ``drawn_total_mm`` is its length before any worker has run it."""
    from foldfab.programs.interpret import interpret

    return sum(stroke.length for stroke in interpret(snapshot.program, load_snapshot_device(snapshot)).strokes)
