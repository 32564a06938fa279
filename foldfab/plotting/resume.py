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
resumes at the last acknowledged line.  A position is no proof when it is also the
power-on state (pen up at the origin: a board switched off and on that does not greet
looks exactly like one parked there) or when it would place the resume at the end of
the program while strokes are unacknowledged (:attr:`Location.doubt`): :func:`plot`
then asks ``choose`` (the command line asks the operator on a terminal) or stops with
:class:`ResumeAmbiguous`, its token kept; ``from_stroke`` is the operator's answer
(``--from-stroke N``).  Nothing ever resumes past doubtful evidence by itself.

Resume states are JSON files in ``$XDG_STATE_HOME/foldfab/resume/`` (default
``~/.local/state``), one per token, written atomically::

    {"version": 1, "token": "3f9a1c", "created": "2026-01-31T12:00:00+00:00",
     "job": "/abs/path/job.toml", "device": "hp7475a", "port": "/dev/ttyUSB0",
     "program_sha256": "...", "program_bytes": 9156,
     "stroke": 41, "strokes": 279, "pauses_done": 0, "reason": "...", "locate": true}

``stroke`` is the index (in ``interpret(program).strokes``) of the first stroke not known to be
drawn (``strokes``: all are, the closing is left); ``pauses_done`` counts the operator pauses
already confirmed; ``locate`` is false when the plotter reported an error (it skipped an
instruction, so its position would place the resume past a stroke it did not draw correctly).
A state file is input like a job file: :func:`load_state` reads only a regular file of at most
:data:`STATE_MAX_BYTES`, without following links, and checks every field's type and range (the
program's own counts in :func:`check_state`); a token is a name matching :data:`TOKEN_PATTERN`,
the one inside the file must be its file's, so no path ever leaves the state folder.
"""

from __future__ import annotations

import hashlib
import json
import re
import secrets
import threading
from dataclasses import asdict, dataclass, field, fields, replace
from functools import partial
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from foldfab.errors import FoldfabError
from foldfab.xdg import foldfab_dir

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.programs.machine import Stroke
    from foldfab.plotting.progress import ProgressEvent
    from foldfab.programs.program import Program
    from foldfab.plotting.engines.base import PenPosition, StreamResult, StreamStopped

STATE_VERSION = 1
TOKEN_PATTERN = re.compile(r"[0-9a-f]{6,32}")
"""A token is only ever a name: 6 to 32 lowercase hex digits (never a path)."""
STATE_MAX_BYTES = 64 * 1024
"""A resume state is a few hundred bytes; a larger file is not one foldfab wrote."""
_SHA256 = re.compile(r"[0-9a-f]{64}")
REASON_MAX = 16384
"""Characters of the stop's reason a state keeps."""


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
        return state_path(self.token)


def state_path(token: str) -> Path:
    """The file of the state named ``token``, inside :func:`state_dir` (a token is a name, never a path)."""
    if not isinstance(token, str) or not TOKEN_PATTERN.fullmatch(token):
        raise FoldfabError(f"--resume {token}: not a resume token (foldfab prints one when a plot stops: "
                           "6 to 32 characters 0-9 and a-f)")
    return state_dir() / f"{token}.json"


def new_token() -> str:
    """A short token naming a resume state that does not exist yet."""
    while True:
        token = secrets.token_hex(3)
        if not state_path(token).exists():
            return token


def save_state(state: ResumeState) -> Path:
    """Write ``state`` atomically; return its path."""
    from foldfab.atomic import write_text

    state.path.parent.mkdir(parents=True, exist_ok=True)
    write_text(state.path, json.dumps(asdict(state), indent=2) + "\n")
    return state.path


def load_state(token: str) -> ResumeState:
    """The saved state named ``token``; a clear error if there is none, it is unreadable, or any
    field is not what foldfab writes (the file is input like a job file: checked, never trusted)."""
    path = state_path(token)
    where = f"--resume {token}: {path}"
    text = _read_state_file(path, token)
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise FoldfabError(f"{where}: cannot read it: not JSON ({exc}); {_DAMAGED}") from None
    names = [f.name for f in fields(ResumeState)]
    if not isinstance(data, dict) or set(data) != set(names):
        got = (f"keys {', '.join(sorted(map(str, set(data) ^ set(names))))} differ" if isinstance(data, dict)
               else f"a JSON {type(data).__name__}, not an object")
        raise FoldfabError(f"{where} is not a foldfab resume state ({got}); {_DAMAGED}")
    version = data["version"]
    if not _whole(version, 1) or version != STATE_VERSION:
        raise FoldfabError(f"--resume {token}: {path} has version {_show(version)}; "
                           f"this foldfab reads version {STATE_VERSION}")
    checks = dict(_CHECKS, token=(lambda v: v == token, f"the token of its file name, {token!r}"))
    for key in names:
        test, expected = checks.get(key, (None, ""))
        if test is not None and not test(data[key]):
            raise FoldfabError(f"{where}: {key} = {_show(data[key])}: expected {expected}; {_DAMAGED}")
    if data["stroke"] > data["strokes"]:
        raise FoldfabError(f"{where}: stroke = {data['stroke']}: expected at most strokes "
                           f"({data['strokes']}: every stroke drawn, the closing left); {_DAMAGED}")
    return ResumeState(**data)


_DAMAGED = "the resume state is damaged or not foldfab's: delete it and plot the job again on a new sheet"


def _read_state_file(path: Path, token: str) -> str:
    """The text of a state file: a regular file (not a link, folder or pipe) of at most
    :data:`STATE_MAX_BYTES` (:func:`foldfab.files.read_text`, links not followed)."""
    from foldfab.files import MissingFile, read_text

    try:
        return read_text(path, "resume state", STATE_MAX_BYTES, encoding="utf-8", follow_links=False)
    except MissingFile:
        raise FoldfabError(f"--resume {token}: no saved plot with that token in {path.parent} "
                           "(it is deleted once the plot finishes)") from None


def _whole(value: object, low: int) -> bool:
    """A JSON whole number (not a boolean) of at least ``low``."""
    return isinstance(value, int) and not isinstance(value, bool) and value >= low


def _text(limit: int, also: Callable[[str], bool] = lambda v: True) -> Callable[[object], bool]:
    """A test for text of 1 to ``limit`` characters, no NUL, that passes ``also``."""
    return lambda v: isinstance(v, str) and 0 < len(v) <= limit and "\0" not in v and also(v)


def _show(value: object) -> str:
    """``value`` as JSON, cut short: for a message."""
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


_CHECKS: dict[str, tuple[Callable[[object], bool], str]] = {
    "created": (_text(64), "a date and time (text)"),
    "job": (_text(4096, lambda v: Path(v).is_absolute()), "the job file's absolute path"),
    "device": (_text(256), "a device profile name"),
    "port": (_text(4096), "a serial port or URL"),
    "program_sha256": (lambda v: isinstance(v, str) and bool(_SHA256.fullmatch(v)), "64 hex digits"),
    "program_bytes": (lambda v: _whole(v, 1), "a byte count of at least 1"),
    "stroke": (lambda v: _whole(v, 0), "a stroke index of at least 0"),
    "strokes": (lambda v: _whole(v, 1), "a stroke count of at least 1"),
    "pauses_done": (lambda v: _whole(v, 0), "a count of at least 0"),
    "reason": (_text(REASON_MAX), "the reason the plot stopped (text)"),
    "locate": (lambda v: isinstance(v, bool), "true or false"),
}
"""What each field of a resume state must be (version and token are checked on their own)."""


def check_state(state: ResumeState, program: Program, job: str, device: DeviceProfile,
                strokes: list[Stroke]) -> None:
    """Refuse to resume ``state`` with a different job, device or program (``strokes``: the
    program's), or at a stroke or pause count that program does not have."""
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
    where = f"--resume {state.token}: {state.path}"
    if (state.program_bytes, state.strokes) != (len(program.text), len(strokes)):
        raise FoldfabError(f"{where}: program_bytes = {state.program_bytes}, strokes = {state.strokes}: "
                           f"expected {len(program.text)} and {len(strokes)} (this program's); {_DAMAGED}")
    # (load_state checked stroke <= strokes) a pause is confirmed only once every stroke before it is done
    before = sum(p.offset <= resume_cut(program, strokes, state.stroke) for p in program.pauses)
    if state.pauses_done > before:
        raise FoldfabError(f"{where}: pauses_done = {state.pauses_done}: expected at most {before} (the "
                           f"pauses before stroke {state.stroke + 1}); {_DAMAGED}")


def resume_program(program: Program, device: DeviceProfile, stroke: int,
                   pauses_done: int | None = None) -> Program:
    """The part of ``program`` from stroke number ``stroke`` on, ready to send to an idle plotter.

    Pauses the operator has not confirmed yet (beyond ``pauses_done``; by default every
    pause before the stroke counts as confirmed) are asked again before the tool moves.
    Strokes of the result are ``interpret(program).strokes[stroke:]``, in order, with the
    same tool, force and speed.  At ``stroke == len(strokes)`` that is none: the result is
    the program's closing alone (the tool lifted and put away, the head parked), which a
    job whose every stroke was drawn before its stop still owes the plotter.
    """
    from foldfab.programs.interpret import interpret
    from foldfab.programs.program import PauseMark, Program

    strokes = interpret(program, device).strokes
    if not 0 <= stroke <= len(strokes):
        raise FoldfabError(f"cannot resume at stroke {stroke + 1}: the program draws "
                           f"{len(strokes)} strokes")
    cut = resume_cut(program, strokes, stroke)
    text = program.text
    preamble = text[:_preamble_end(program, strokes)]  # IN; | units, modes and the tool up
    before = [p for p in program.pauses if p.offset <= cut]
    done = len(before) if pauses_done is None else pauses_done
    pending = before[done:] if stroke < len(strokes) else []  # nothing is left to draw after a pause
    pause_text = "" if not pending or program.protocol != "gcode" else "M0\n"
    head = preamble + pause_text
    state, travel = ((_tool_state(program, device, cut), _travel(device, strokes[stroke].points[0], program.protocol))
                     if stroke < len(strokes) else ("", ""))  # the closing lifts the tool and parks by itself
    # HP-GL and GP-GL select the tool, then move (as the writers do); G-code's travel is a G0, so
    # the motion mode and feed are restored after it.
    prelude = head + (state + travel if program.protocol != "gcode" else travel + state)
    if program.protocol == "ebb":  # relative moves: home first (HM), then from there
        from foldfab.programs.ebb import homing

        head = homing(device) + preamble
        prelude = head + travel
    shift = len(prelude) - cut
    pauses = [PauseMark(len(head), pending[0].step, " ".join(p.message for p in pending))] \
        if pending else []
    pauses += [replace(p, offset=p.offset + shift) for p in program.pauses if p.offset > cut]
    current = program.section_at(cut)
    sections = [replace(current, offset=0)] if current is not None else []
    sections += [replace(s, offset=s.offset + shift) for s in program.sections if s.offset > cut]
    return Program(prelude + text[cut:], program.protocol, program.device, tuple(sections),
                   tuple(pauses))


def resume_cut(program: Program, strokes: list[Stroke], stroke: int) -> int:
    """Offset in ``program`` (whose strokes are ``strokes``) from which a resume at ``stroke`` sends
    the original text: the stroke's start; with every stroke drawn, where the last lifts the tool
    (the program's closing; EBB: nothing, its closing moves are relative and the homing parks)."""
    if stroke < len(strokes):
        return strokes[stroke].offset
    return len(program.text) if program.protocol == "ebb" else strokes[-1].end if strokes else \
        _preamble_end(program, strokes)


def _preamble_end(program: Program, strokes: list[Stroke]) -> int:
    """Where the set-up ends: the first section, or (a queue's stored program need not be foldfab's)
    the first stroke."""
    return program.sections[0].offset if program.sections else strokes[0].offset if strokes else len(program.text)


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
    from foldfab.programs.interpret import pen_states

    start = strokes[stroke - 1].end if stroke > 0 else 0
    tolerance = _tolerance(program)
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


@dataclass(frozen=True)
class Location:
    """Where a resume may start, as far as asking the plotter tells (:func:`locate`)."""

    acknowledged: int
    """The first stroke not acknowledged: every stroke before it is drawn."""
    stroke: int
    """The first stroke the plotter's position says it did not draw (``acknowledged`` when it says nothing)."""
    strokes: int
    """How many strokes the program draws."""
    note: str
    """How it was found."""
    doubt: str = ""
    """Why the position is no proof that the strokes from ``acknowledged`` to ``stroke`` were
    drawn (empty: it is); the operator then chooses (:class:`ResumeAmbiguous`)."""

    @property
    def safe(self) -> int:
        """Where to resume without an operator: no stroke is ever skipped on doubtful evidence."""
        return self.acknowledged if self.doubt else self.stroke


POWER_ON = (0.0, 0.0)
"""Where a plotter's pen is, up, when it has just been switched on (GRBL without homing: the
machine origin; HP-GL plotters: their origin)."""


def locate(program: Program, device: DeviceProfile, port: str, stroke: int, pauses_done: int,
           strokes: list[Stroke] | None = None, **settings) -> Location:
    """Where to resume: ``stroke`` (the first not acknowledged), moved on past the strokes
    the plotter drew after its host lost it, as far as asking the plotter can tell
    (:func:`foldfab.plotting.stream.locate_pen`, :func:`first_undrawn`).  ``strokes``: the program's,
    where the caller has them already; ``settings`` are :func:`foldfab.plotting.transport.open_port`'s.

    A position is doubtful proof (:attr:`Location.doubt`) when it is also the power-on
    state (a board switched off and on that does not greet on opening looks exactly like
    one that parked there) or when it places the resume at the end of the program while
    strokes are unacknowledged."""
    from foldfab.programs.interpret import interpret
    from foldfab.plotting.engines.base import CHECK_EVERY
    from foldfab.plotting.stream import locate_pen
    from foldfab.plotting.transport import open_port

    strokes = interpret(program, device).strokes if strokes is None else strokes
    here = partial(Location, stroke, stroke, len(strokes))
    try:
        link = open_port(port, device, **settings)
        try:
            pen = locate_pen(link, device)
        finally:
            link.close()
    except (FoldfabError, OSError) as exc:
        return here(f"could not ask the plotter where it stopped ({exc})")
    if pen is None:
        return here("the plotter was initialized since it stopped (switched off and on, or "
                    "reset when its port opened), so its position says nothing")
    # What the engine can have sent beyond its last acknowledgement (and the queue's last save),
    # never past a pause the operator has not confirmed (the engine stops sending there).
    limit = strokes[stroke].offset + 4 * max(device.buffer.size, CHECK_EVERY)
    unconfirmed = [p.offset for p in program.pauses][pauses_done:]
    if unconfirmed:
        limit = min(limit, unconfirmed[0])
    found = first_undrawn(program, device, strokes, stroke, pen, limit)
    at = f"{pen.x:g},{pen.y:g} (pen {'down' if pen.down else 'up'})"
    if found is None:
        return here(f"the pen is at {at}, where this job does not leave it, so its position says nothing")
    note = f"the plotter had drawn {found - stroke} more stroke(s) after the last acknowledgement"
    if found == stroke:
        return Location(stroke, found, len(strokes), note)
    reasons = []
    if not pen.down and max(abs(pen.x - POWER_ON[0]), abs(pen.y - POWER_ON[1])) <= _tolerance(program):
        reasons.append("the pen is up at the origin, where a plotter switched off and on is too")
    if found == len(strokes):
        reasons.append("that would mean it finished the job on its own")
    doubt = (f"the plotter's pen is at {at}, where the job leaves it once stroke {found} is drawn, but "
             f"{' and '.join(reasons)}") if reasons else ""
    return Location(stroke, found, len(strokes), note, doubt)


def locate_resume(program: Program, device: DeviceProfile, port: str, stroke: int,
                  pauses_done: int, **settings) -> tuple[int, str]:
    """:func:`locate` for a resume with nobody to ask (the queue worker): the stroke to resume at,
    never past doubtful evidence, and a note saying how it was found."""
    found = locate(program, device, port, stroke, pauses_done, **settings)
    if found.doubt:
        return found.safe, f"{found.doubt}: resuming at the last acknowledged stroke"
    return found.stroke, found.note


def _tolerance(program: Program) -> float:
    """How far apart two pen positions (device units) still match: half a plotter unit, GRBL's
    3 decimals."""
    return 0.5 if program.protocol != "gcode" else 0.0015


def _tool_state(program: Program, device: DeviceProfile, offset: int) -> str:
    """Commands restoring the tool state ``program`` has set by byte ``offset``."""
    text = program.text[:offset]
    if program.protocol == "ebb":
        return ""  # the servo settings are in the preamble; speeds are in the moves themselves
    if program.protocol == "gpgl":
        from foldfab.programs.read_gpgl import tool_state

        return tool_state(text)
    if program.protocol == "hpgl":
        from foldfab.programs.read_hpgl import HPGLTokenizer

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
    from foldfab.programs.interpret import pen_states
    from foldfab.programs.program import fmt_number

    for _, machine in pen_states(text, "gcode", device):
        pass  # to the end of the text: the modes in force there
    beam = f"{machine.beam} S{fmt_number(machine.spindle, 3)}\n" if machine.beam else ""  # a laser's M4 and power
    if machine.feed is None:
        return beam + ("G0\n" if machine.motion == "G0" else "")
    return beam + f"{machine.motion} F{fmt_number(machine.feed * 60 / machine.scale, 3)}\n"


def _travel(device: DeviceProfile, point, protocol: str) -> str:
    """A pen-up move to ``point`` (sheet mm) in device coordinates."""
    import numpy as np

    from foldfab.programs.program import fmt_number

    x, y = device.frame(device.sheet).to_device(np.asarray([point]))[0].tolist()
    if protocol == "hpgl":
        return f"PU{round(x)},{round(y)};"
    if protocol == "ebb":
        from foldfab.programs.ebb import travel

        return travel(device, np.asarray([x, y]))
    if protocol == "gpgl":
        return f"M{round(x)},{round(y)}\x03"
    return f"G0 X{fmt_number(x, 3)} Y{fmt_number(y, 3)}\n"


class ResumeNotStarted(FoldfabError):
    """A resume that could not start (the port would not open, the plotter was in an alarm):
    nothing was sent, so its ``token`` stays valid."""

    def __init__(self, error: FoldfabError, token: str):
        super().__init__(str(error))
        self.token = token


class ResumeAmbiguous(ResumeNotStarted):
    """Where the plot stopped is doubtful (:attr:`Location.doubt`) and nobody chose where to
    resume: nothing was sent, the token stays valid, and ``location`` holds the choices."""

    def __init__(self, location: Location, token: str):
        super().__init__(FoldfabError(
            f"where the plot stopped is uncertain: {location.doubt}; the last acknowledged stroke is "
            f"{location.acknowledged + 1} of {location.strokes}, so resuming there draws again what the "
            "plotter may have drawn since, and trusting its position may leave strokes undrawn"), token)
        self.location = location


class PlotStopped(FoldfabError):
    """A plot stopped before its end, after the safe stop; ``token`` names its resume state."""

    def __init__(self, stop: StreamStopped, token: str, stroke: int, strokes: int):
        left = (f"{strokes - stroke} of {strokes} strokes left" if stroke < strokes else "every stroke was "
                "drawn, the closing (tool up, head parked) was not confirmed") + f" (resume token {token})"
        super().__init__(f"{stop}; {'tool lifted' if stop.lifted else 'the tool may still be down'}; {left}")
        self.stop, self.token, self.stroke, self.strokes = stop, token, stroke, strokes
        self.exit_code = stop.exit_code


def plot(program: Program, device: DeviceProfile, *, job: str, port: str,
         resume: str | None = None, baudrate: int | None = None, xonxoff: bool | None = None,
         rtscts: bool | None = None, events: Callable[[ProgressEvent], None] | None = None,
         cancel: threading.Event | None = None, operator: Callable[[str], bool] | None = None,
         stall_timeout: float = 30.0, from_stroke: int | None = None,
         choose: Callable[[Location], int | None] | None = None) -> StreamResult:
    """Stream ``program`` (built from the job file ``job``) to ``device`` at ``port``.

    With ``resume``, only what the saved state says is left is sent, after checking the program
    is unchanged; the state is deleted once the plot finishes.  ``from_stroke`` (an index; the
    number of strokes: every one is drawn, the closing is sent) is the operator's choice of where
    to resume, instead of asking the plotter; when the plotter's answer is doubtful, ``choose`` is
    asked (the stroke to resume at; None: stop), and without it :class:`ResumeAmbiguous` is
    raised.  A plot that stops early saves (or updates) its state and raises :class:`PlotStopped`.
    """
    from foldfab.programs.interpret import interpret
    from foldfab.plotting.progress import JobProgress
    from foldfab.plotting.engines.base import StreamStopped
    from foldfab.plotting.stream import stream
    from foldfab.plotting.transport import open_port

    if from_stroke is not None and resume is None:
        raise FoldfabError("--from-stroke chooses where a stopped plot resumes: give --resume TOKEN too")
    state = load_state(resume) if resume else None
    strokes = interpret(program, device).strokes
    first, sending, pending, note = 0, program, 0, ""
    settings = dict(baudrate=baudrate, xonxoff=xonxoff, rtscts=rtscts)
    if state is not None:
        check_state(state, program, job, device, strokes)
        first, found = _start(state, program, device, port, strokes, from_stroke, choose, settings)
        before = sum(p.offset <= resume_cut(program, strokes, first) for p in program.pauses)
        # pauses confirmed, as far as they lie before the stroke resumed at (the operator may go back)
        confirmed = min(state.pauses_done, before)
        note = (f"resuming at stroke {first + 1} of {len(strokes)}" if first < len(strokes) else
                f"all {len(strokes)} strokes are drawn: sending the closing (tool up, head parked)")
        note += f": {found}" if found else ""
        sending = resume_program(program, device, first, confirmed)
        pending = before - confirmed
        state = replace(state, pauses_done=confirmed)
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
        token = state.token if state is not None else new_token()
        save_state(ResumeState(token, str(Path(job).resolve()), device.name, port,
                               program_hash(program), len(program.text), stroke, len(strokes),
                               pauses_done, str(stop)[:REASON_MAX], locate=not stop.plotter_error))
        raise PlotStopped(stop, token, stroke, len(strokes)) from None
    except FoldfabError as exc:  # before anything was sent: the port, or the plotter's state at connecting
        raise exc if state is None else ResumeNotStarted(exc, state.token) from None
    if state is not None:
        state.path.unlink(missing_ok=True)
    return result


def _start(state: ResumeState, program: Program, device: DeviceProfile, port: str,
           strokes: list[Stroke], from_stroke: int | None,
           choose: Callable[[Location], int | None] | None, settings: dict) -> tuple[int, str]:
    """The stroke a resume starts at and a note saying why: the operator's ``from_stroke``; the
    last acknowledged one after a plotter error; else where the plotter's position places it,
    and on doubtful evidence the operator's choice (``choose``; without it, or if the operator
    declines, :class:`ResumeAmbiguous`, the token kept)."""
    if from_stroke is not None:
        if not 0 <= from_stroke <= len(strokes):
            raise FoldfabError(f"--from-stroke {from_stroke + 1}: expected a stroke of this job's "
                               f"{len(strokes)} (1 to {len(strokes)}), or {len(strokes) + 1}: every stroke is drawn")
        return from_stroke, "chosen by the operator (--from-stroke)"
    if state.stroke == len(strokes):
        return state.stroke, ""
    if not state.locate:
        return state.stroke, "the plotter reported an error, so where it stopped is not used"
    found = locate(program, device, port, state.stroke, state.pauses_done, strokes, **settings)
    if not found.doubt:
        return found.stroke, found.note
    chosen = choose(found) if choose is not None else None
    if chosen is None:
        raise ResumeAmbiguous(found, state.token)
    return chosen, f"chosen by the operator: {found.doubt}"
