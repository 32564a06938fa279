"""Stop a plot safely and finish it later: resume states and resumed programs.

When a plot stops early (Ctrl-C, a serial fault, a plotter error), the streaming
engine has already lifted the tool and counted, conservatively, how many bytes the
plotter executed.  :func:`plot` then saves a :class:`ResumeState` and tells the user
``foldfab plot JOB --device NAME --resume TOKEN``.  Resuming rebuilds the program
exactly as before, refuses if it changed (SHA-256 of the text), and streams
:func:`resume_program`: the program's own preamble (``IN;``, or ``G21 G90 G17`` and
the pen up), the tool state in force at the first stroke not yet drawn (the last
``SP``/``FS``/``VS`` before it, or the last G-code motion mode and feed), a move with
the tool up to that stroke's start, then the original text from that stroke on.
No stroke is lost and only the interrupted stroke can be drawn twice.

The acknowledged count lags behind the plotter: a plotter whose host died or whose
cable was pulled goes on drawing what its buffer holds.  Before resuming, an HP-GL
plotter is therefore asked where its pen is (:func:`locate_resume`): what it still
holds is discarded, and the strokes it drew after the last acknowledgement are
skipped (:func:`first_undrawn` never skips one it did not draw).  A GRBL board that
resets when its port opens (an Arduino's DTR) has lost its position, so such a job
resumes at the last acknowledged line.

Resume states are JSON files in ``$XDG_STATE_HOME/foldfab/resume/`` (default
``~/.local/state``), one per token, written atomically::

    {"version": 1, "token": "3f9a1c", "created": "2026-01-31T12:00:00+00:00",
     "job": "/abs/path/job.toml", "device": "hp7475a", "port": "/dev/ttyUSB0",
     "program_sha256": "...", "program_bytes": 9156,
     "stroke": 41, "strokes": 279, "pauses_done": 0, "reason": "...", "locate": true}

``stroke`` is the index (in ``interpret(program).strokes``) of the first stroke not
known to be drawn; ``pauses_done`` counts the operator pauses already confirmed;
``locate`` is false when the plotter reported an error (it skipped an instruction, so
its position would place the resume past a stroke it did not draw correctly).
"""

from __future__ import annotations

import hashlib
import json
import re
import secrets
import threading
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from foldfab.errors import FoldfabError
from foldfab.xdg import foldfab_dir

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.interpret import Stroke
    from foldfab.progress import ProgressEvent
    from foldfab.program import Program
    from foldfab.stream import PenPosition, StreamResult, StreamStopped

STATE_VERSION = 1
_TOKEN = re.compile(r"[0-9a-f]{6,32}")


def program_hash(program: Program) -> str:
    """SHA-256 of the program text: a resumed job must send the very same program."""
    return hashlib.sha256(program.text.encode("ascii")).hexdigest()


def state_dir() -> Path:
    """``$XDG_STATE_HOME/foldfab/resume`` (default ``~/.local/state/foldfab/resume``)."""
    return foldfab_dir("XDG_STATE_HOME") / "resume"


@dataclass(frozen=True)
class ResumeState:
    """Where an interrupted plot stopped (see the module docstring for the file format)."""

    token: str
    job: str
    device: str
    port: str
    program_sha256: str
    program_bytes: int
    stroke: int
    strokes: int
    pauses_done: int
    reason: str
    locate: bool = True
    """Ask the plotter where it stopped before resuming (not after it reported an error)."""
    created: str = field(default_factory=lambda: datetime.now(timezone.utc).isoformat(timespec="seconds"))
    version: int = STATE_VERSION

    @property
    def path(self) -> Path:
        return state_dir() / f"{self.token}.json"


def new_token() -> str:
    """A short token naming a resume state that does not exist yet."""
    while True:
        token = secrets.token_hex(3)
        if not (state_dir() / f"{token}.json").exists():
            return token


def save_state(state: ResumeState) -> Path:
    """Write ``state`` atomically; return its path."""
    from foldfab.atomic import write_text

    state.path.parent.mkdir(parents=True, exist_ok=True)
    write_text(state.path, json.dumps(asdict(state), indent=2) + "\n")
    return state.path


def load_state(token: str) -> ResumeState:
    """The saved state named ``token``; a clear error if there is none or it is unreadable."""
    if not _TOKEN.fullmatch(token):
        raise FoldfabError(f"--resume {token}: not a resume token (foldfab prints one when a plot stops)")
    from foldfab.files import SMALL_LIMIT, read_text

    path = state_dir() / f"{token}.json"
    try:
        data = json.loads(read_text(path, "resume state", SMALL_LIMIT, encoding="utf-8"))
    except FileNotFoundError:
        raise FoldfabError(f"--resume {token}: no saved plot with that token in {path.parent} "
                           "(it is deleted once the plot finishes)") from None
    except ValueError as exc:
        raise FoldfabError(f"--resume {token}: cannot read {path}: {exc}") from None
    try:
        state = ResumeState(**data)
    except TypeError:
        raise FoldfabError(f"--resume {token}: {path} is not a foldfab resume state") from None
    if state.version != STATE_VERSION:
        raise FoldfabError(f"--resume {token}: {path} has version {state.version}; "
                           f"this foldfab reads version {STATE_VERSION}")
    return state


def check_state(state: ResumeState, program: Program, job: str, device: DeviceProfile) -> None:
    """Refuse to resume ``state`` with a different job, device or program."""
    if state.device != device.name:
        raise FoldfabError(f"--resume {state.token}: that plot ran on device {state.device!r}, "
                           f"not {device.name!r}; use --device {state.device}")
    if Path(state.job) != Path(job).resolve():
        raise FoldfabError(f"--resume {state.token}: that plot was {state.job}, not {Path(job).resolve()}")
    if state.program_sha256 != program_hash(program):
        raise FoldfabError(
            f"--resume {state.token}: the program of {job} for {device.name} changed since the plot "
            "stopped (job file, device profile or foldfab version); resuming would misplace the "
            "strokes, so plot the whole job again on a new sheet")


def resume_program(program: Program, device: DeviceProfile, stroke: int,
                   pauses_done: int | None = None) -> Program:
    """The part of ``program`` from stroke number ``stroke`` on, ready to send to an idle plotter.

    Pauses the operator has not confirmed yet (beyond ``pauses_done``; by default every
    pause before the stroke counts as confirmed) are asked again before the tool moves.
    Strokes of the result are ``interpret(program).strokes[stroke:]``, in order, with the
    same tool, force and speed.
    """
    from foldfab.interpret import interpret
    from foldfab.program import PauseMark, Program

    strokes = interpret(program, device).strokes
    if not 0 <= stroke < len(strokes):
        raise FoldfabError(f"cannot resume at stroke {stroke + 1}: the program draws "
                           f"{len(strokes)} strokes")
    target = strokes[stroke]
    cut = target.offset
    text = program.text
    preamble = text[:program.sections[0].offset]  # IN; | units, modes and the tool up
    before = [p for p in program.pauses if p.offset <= cut]
    done = len(before) if pauses_done is None else pauses_done
    pending = before[done:]
    pause_text = "" if not pending or program.protocol == "hpgl" else "M0\n"
    state, travel = _tool_state(program, device, cut), _travel(device, target.points[0], program.protocol)
    head = preamble + pause_text
    # HPGL selects the tool, then moves (as the writer does); G-code's travel is a G0, so the
    # motion mode and feed are restored after it.
    prelude = head + (state + travel if program.protocol == "hpgl" else travel + state)
    shift = len(prelude) - cut
    pauses = [PauseMark(len(head), pending[0].step, " ".join(p.message for p in pending))] \
        if pending else []
    pauses += [replace(p, offset=p.offset + shift) for p in program.pauses if p.offset > cut]
    current = program.section_at(cut)
    sections = [replace(current, offset=0)] if current is not None else []
    sections += [replace(s, offset=s.offset + shift) for s in program.sections if s.offset > cut]
    return Program(prelude + text[cut:], program.protocol, program.device, tuple(sections),
                   tuple(pauses))


def first_undrawn(program: Program, device: DeviceProfile, strokes: list[Stroke], stroke: int,
                  pen: PenPosition, limit: int) -> int | None:
    """The first stroke not drawn, if the plotter ran ``program`` up to where its pen is now.

    The plotter executed a prefix of the program that covers every stroke before
    ``stroke`` (of ``strokes``, the program's) and ends before byte ``limit``.  Of the
    states the program leaves the pen in (after each HP-GL coordinate pair or G-code
    line, pen up or down), the earliest one at ``pen`` within that range is taken: the
    true one is among them, so the answer never lies beyond it and no stroke is skipped.
    None if no state matches (the plotter did not run this program: its position says
    nothing).
    """
    from foldfab.interpret import pen_states

    start = strokes[stroke - 1].end if stroke > 0 else 0
    tolerance = 0.5 if program.protocol == "hpgl" else 0.0015  # a plotter unit; GRBL's 3 decimals
    for end, machine in pen_states(program.text, program.protocol, device):
        if end > limit:
            return None
        down = machine.stroke is not None
        if end < start or down != pen.down or abs(machine.position[0] - pen.x) > tolerance \
                or abs(machine.position[1] - pen.y) > tolerance:
            continue
        done = len(machine.result.strokes)  # strokes lifted so far
        if down and done < len(strokes) and len(machine.stroke) == len(strokes[done].points):
            done += 1  # at the last point of the stroke being drawn: it is complete
        return max(done, stroke)
    return None


def locate_resume(program: Program, device: DeviceProfile, port: str, stroke: int,
                  pauses_done: int, **settings) -> tuple[int, str]:
    """Where to resume: ``stroke`` (the first not acknowledged), moved on past the strokes
    the plotter drew after its host lost it, as far as asking the plotter can tell
    (:func:`foldfab.stream.locate_pen`, :func:`first_undrawn`).  Returns the stroke and
    a note saying how it was found.  ``settings`` are :func:`foldfab.transport.open_port`'s."""
    from foldfab.interpret import interpret
    from foldfab.stream import CHECK_EVERY, locate_pen
    from foldfab.transport import open_port

    try:
        link = open_port(port, device, **settings)
        try:
            pen = locate_pen(link, device)
        finally:
            link.close()
    except (FoldfabError, OSError) as exc:
        return stroke, f"could not ask the plotter where it stopped ({exc})"
    if pen is None:
        return stroke, ("the plotter was initialized since it stopped (switched off and on, or "
                        "reset when its port opened), so its position says nothing")
    strokes = interpret(program, device).strokes
    if stroke >= len(strokes):
        return stroke, ""
    # What the engine can have sent beyond its last acknowledgement (and the queue's last save),
    # never past a pause the operator has not confirmed (the engine stops sending there).
    limit = strokes[stroke].offset + 4 * max(device.buffer.size, CHECK_EVERY)
    unconfirmed = [p.offset for p in program.pauses][pauses_done:]
    if unconfirmed:
        limit = min(limit, unconfirmed[0])
    found = first_undrawn(program, device, strokes, stroke, pen, limit)
    if found is None:
        return stroke, (f"the pen is at {pen.x},{pen.y}, where this job does not leave it, so its "
                        "position says nothing")
    return found, f"the plotter had drawn {found - stroke} more stroke(s) after the last acknowledgement"


def _tool_state(program: Program, device: DeviceProfile, offset: int) -> str:
    """Commands restoring the tool state ``program`` has set by byte ``offset``."""
    text = program.text[:offset]
    if program.protocol == "hpgl":
        from foldfab.interpret import HPGLTokenizer

        tokenizer = HPGLTokenizer()
        commands = tokenizer.feed(text.encode("latin-1")) + tokenizer.close()
        ends = [c.offset for c in commands[1:]] + [len(text)]
        latest: dict[tuple, str] = {}
        for command, end in zip(commands, ends):
            if command.name in ("IN", "DF"):
                latest.clear()
            elif command.name in ("SP", "FS", "VS"):
                key = (command.name, command.params[1:2])  # "VS v,pen" sets one pen's speed
                latest.pop(key, None)
                latest[key] = text[command.offset:end]
        return "".join(latest.values())
    from foldfab.interpret import pen_states
    from foldfab.program import fmt_number

    for _, machine in pen_states(text, "gcode", device):
        pass  # to the end of the text: the modes in force there
    if machine.feed is None:
        return "G0\n" if machine.motion == "G0" else ""
    return f"{machine.motion} F{fmt_number(machine.feed * 60 / machine.scale, 3)}\n"


def _travel(device: DeviceProfile, point, protocol: str) -> str:
    """A pen-up move to ``point`` (sheet mm) in device coordinates."""
    import numpy as np

    from foldfab.program import fmt_number

    x, y = device.frame(device.sheet).to_device(np.asarray([point]))[0].tolist()
    if protocol == "hpgl":
        return f"PU{round(x)},{round(y)};"
    return f"G0 X{fmt_number(x, 3)} Y{fmt_number(y, 3)}\n"


class ResumeNotStarted(FoldfabError):
    """A resume that could not start (the port would not open, the plotter was in an alarm):
    nothing was sent, so its ``token`` stays valid."""

    def __init__(self, error: FoldfabError, token: str):
        super().__init__(str(error))
        self.token = token


class PlotStopped(FoldfabError):
    """A plot stopped before its end, after the safe stop; ``token`` names its resume state."""

    def __init__(self, stop: StreamStopped, token: str | None, stroke: int, strokes: int):
        left = (f"{strokes - stroke} of {strokes} strokes left (resume token {token})" if token
                else "every stroke was drawn")
        super().__init__(f"{stop}; {'tool lifted' if stop.lifted else 'the tool may still be down'}; {left}")
        self.stop, self.token, self.stroke, self.strokes = stop, token, stroke, strokes
        self.exit_code = stop.exit_code


def plot(program: Program, device: DeviceProfile, *, job: str, port: str,
         resume: str | None = None, baudrate: int | None = None, xonxoff: bool | None = None,
         rtscts: bool | None = None, events: Callable[[ProgressEvent], None] | None = None,
         cancel: threading.Event | None = None, operator: Callable[[str], bool] | None = None,
         stall_timeout: float = 30.0) -> StreamResult:
    """Stream ``program`` (built from the job file ``job``) to ``device`` at ``port``.

    With ``resume``, only what the saved state says is left is sent, after checking the
    program is unchanged; the state is deleted once the plot finishes.  A plot that stops
    early saves (or updates) its state and raises :class:`PlotStopped`.
    """
    from foldfab.interpret import interpret
    from foldfab.progress import JobProgress
    from foldfab.stream import StreamStopped, stream
    from foldfab.transport import open_port

    state = load_state(resume) if resume else None
    strokes = interpret(program, device).strokes
    first, sending, pending, note = 0, program, 0, ""
    settings = dict(baudrate=baudrate, xonxoff=xonxoff, rtscts=rtscts)
    if state is not None:
        check_state(state, program, job, device)
        first, found = (locate_resume(program, device, port, state.stroke, state.pauses_done, **settings)
                        if state.locate else
                        (state.stroke, "the plotter reported an error, so where it stopped is not used"))
        if first >= len(strokes):  # the plotter drew the rest after its host lost it
            from foldfab.stream import StreamResult

            if events is not None:
                end = len(program.text)
                events(JobProgress(program, device).event("done", end, end, 0.0, message=found))
            state.path.unlink(missing_ok=True)
            return StreamResult(0, 0.0, 0.0, 0)
        note = f"resuming at stroke {first + 1} of {len(strokes)}" + (f": {found}" if found else "")
        sending = resume_program(program, device, first, state.pauses_done)
        cut = strokes[first].offset
        pending = sum(p.offset <= cut for p in program.pauses) - state.pauses_done
    progress = JobProgress(sending, device)
    try:
        link = open_port(port, device, **settings)
        try:
            result = stream(link, sending, device, events=events, cancel=cancel, operator=operator,
                            stall_timeout=stall_timeout, progress=progress, note=note)
        finally:
            link.close()
    except StreamStopped as stop:
        stroke = first + progress.strokes_done(stop.acknowledged)
        answered = stop.pauses_done
        if pending and answered:  # the resumed program asks its pending pauses as one
            answered += pending - 1
        pauses_done = (state.pauses_done if state is not None else 0) + answered
        token = None
        if stroke < len(strokes):
            token = state.token if state is not None else new_token()
            save_state(ResumeState(token, str(Path(job).resolve()), device.name, port,
                                   program_hash(program), len(program.text), stroke, len(strokes),
                                   pauses_done, str(stop), locate=not stop.plotter_error))
        elif state is not None:
            state.path.unlink(missing_ok=True)
        raise PlotStopped(stop, token, stroke, len(strokes)) from None
    except FoldfabError as exc:  # before anything was sent: the port, or the plotter's state at connecting
        raise exc if state is None else ResumeNotStarted(exc, state.token) from None
    if state is not None:
        state.path.unlink(missing_ok=True)
    return result
