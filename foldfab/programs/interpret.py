"""Read plotter programs back: what would the device draw, with which tool, where?

:func:`interpret` turns a program (HP-GL, G-code, EBB, GP-GL) into an :class:`Interpretation`:
pen-down strokes in sheet millimetres with the tool state the program set, pen-up
travel moves (including the first one from the park position, where the last job
left the pen, and the last one back to it), and pauses.  Given a :class:`~foldfab.programs.program.Program` rather
than bare text, strokes are also labelled with their plan step, layer and
repetition, and HPGL pauses (which exist only as offsets) are placed.

This module dispatches by protocol: the languages' readers are :mod:`~foldfab.programs.read_hpgl`,
:mod:`~foldfab.programs.read_gcode`, :mod:`~foldfab.programs.read_ebb` and :mod:`~foldfab.programs.read_gpgl`; what they
draw is in :mod:`~foldfab.programs.machine`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Iterator

from foldfab.errors import FoldfabError
from foldfab.programs.drawing import Drawn, verify as verify_drawn

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.programs.machine import Interpretation, Machine
    from foldfab.programs.program import Program


def readers() -> tuple[dict[str, type[Machine]], dict[str, Callable]]:
    """The reader of each protocol (``DeviceProfile.protocol``), and the byte-stream tokenizers of the
    languages whose steps are commands (G-code's are lines).  Imported when a program is first read:
    an export whose writer recorded what it draws reads none, and the four readers are milliseconds
    of its start-up."""
    from foldfab.programs.read_ebb import EbbMachine
    from foldfab.programs.read_gcode import GcodeMachine
    from foldfab.programs.read_gpgl import GPGLMachine, GPGLTokenizer
    from foldfab.programs.read_hpgl import HPGLMachine, HPGLTokenizer

    return ({"hpgl": HPGLMachine, "gcode": GcodeMachine, "ebb": EbbMachine, "gpgl": GPGLMachine},
            {"hpgl": lambda: HPGLTokenizer(split_coordinates=True), "gpgl": GPGLTokenizer})


def interpret(program: Program | str, device: DeviceProfile,
              sheet: tuple[float, float] | None = None) -> Interpretation:
    """Interpret ``program`` (a Program or bare text) as ``device`` would run it.

    ``sheet`` (w, h mm) fixes the sheet-to-device mapping; default: the profile's sheet.
    """
    from foldfab.programs.program import Program

    frame = device.frame(sheet or device.sheet)
    text = program.text if isinstance(program, Program) else program
    known = program if isinstance(program, Program) else None
    if known is not None and known.protocol != device.protocol:
        raise FoldfabError(f"a {known.protocol} program cannot run on {device.name} "
                           f"({device.protocol})")
    machine = readers()[0][device.protocol](device, frame, known)
    machine.position = device.park_units  # where the last job left the pen, as the optimizer assumes
    return machine.run(text)


def drawn(program: Program, device: DeviceProfile, sheet: tuple[float, float] | None = None,
          verify: bool = False) -> Drawn:
    """What ``program`` draws on ``device`` (``sheet`` as for :func:`interpret`): as its writer
    recorded it where it did (HP-GL, G-code), else read back.  ``verify`` reads it back anyway
    and refuses a program whose read-back differs from the record."""
    recorded = program.drawn(device.frame(sheet or device.sheet))
    if recorded is not None and not verify:
        return recorded
    from foldfab.programs.machine import from_interpretation

    read = from_interpretation(interpret(program, device, sheet))
    if recorded is not None:
        verify_drawn(recorded, read, f"{program.protocol} program for {device.name}")
    return read


def pen_states(text: str, protocol: str, device: DeviceProfile) -> Iterator[tuple[int, Machine]]:
    """(end offset, machine) after each step a plotter takes in program ``text``: an HP-GL
    coordinate pair or instruction, a GP-GL command, a G-code line (at least one, even in an
    empty text).  The machine is the same object, updated in place."""
    frame = device.frame(device.sheet)
    machines, tokenizers = readers()
    if protocol in tokenizers:
        machine = machines[protocol](device, frame, None)
        tokenizer = tokenizers[protocol]()
        commands = tokenizer.feed(text.encode("ascii")) + tokenizer.close()
        for command, end in zip(commands, [c.offset for c in commands[1:]] + [len(text)]):
            machine.at = command.offset
            machine.execute(command)
            yield end, machine
        return
    if protocol == "ebb":
        from foldfab.programs.read_ebb import ebb_commands

        machine = machines[protocol](device, frame, None)
        end = 0
        for command, end in ebb_commands(text):
            machine.at = command.offset
            machine.execute(command)
            yield end, machine
        if not end:
            yield len(text), machine
        return
    machine = machines["gcode"](device, frame, None)
    offset = 0
    for raw in text.split("\n"):
        end = min(offset + len(raw) + 1, len(text))
        machine.execute(raw, offset, end)
        yield end, machine
        offset = end
