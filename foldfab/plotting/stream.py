"""Stream a program to a plotter without losing a byte, and stop it safely.

Plotters have small receive buffers: a sender that writes faster than the plotter
draws overruns the buffer and commands are lost silently.  :func:`stream` sends a
:class:`~foldfab.programs.program.Program` over an open pyserial port with the handshake the
device profile's ``[buffer] flow_control`` names.  The engine is the protocol's sender in
:mod:`foldfab.plotting.engines` (HP-GL: :mod:`~foldfab.plotting.engines.hpgl`, GRBL 1.1:
:mod:`~foldfab.plotting.engines.grbl`, GP-GL: :mod:`~foldfab.plotting.engines.gpgl`), chosen by the
profile's ``protocol``.

Stopping (the ``cancel`` event, KeyboardInterrupt, a serial fault, a plotter error or a
stall) stops sending, lifts the tool (HP-GL: the command being sent is finished, or
after a plotter error ``ESC.K`` discards what the plotter holds, then ``PU;`` and a
checkpoint; GRBL: feed hold ``!``, soft reset 0x18, ``$X`` if the reset left an alarm,
then the program's own preamble, which lifts the tool; GP-GL: ``M`` to where the program has
brought the tool, after what the cutter holds, or ``ESC 0x04`` once its tray is empty) and raises
:class:`~foldfab.plotting.engines.base.StreamStopped` with the executed byte count a resume
can start from.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Callable

from foldfab.errors import FoldfabError
from foldfab.plotting.engines import SENDERS

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.plotting.engines.base import Operator, PenPosition, StreamResult
    from foldfab.plotting.progress import JobProgress, ProgressEvent
    from foldfab.programs.program import Program


def stream(port, program: Program, device: DeviceProfile, *,
           events: Callable[[ProgressEvent], None] | None = None,
           cancel: threading.Event | None = None, operator: Operator | None = None,
           stall_timeout: float = 30.0, progress: JobProgress | None = None,
           note: str = "") -> StreamResult:
    """Send ``program`` to the plotter on ``port`` (open, with the profile's settings).

    ``events`` receives :class:`~foldfab.plotting.progress.ProgressEvent` objects; setting
    ``cancel`` (or a KeyboardInterrupt) stops the job safely; ``operator`` answers the
    program's pauses (without one, a pause stops the job).  ``stall_timeout``: seconds
    without a sign of progress, beyond the time the estimate expects the plotter to
    need, before the job is stopped as stalled.  Raises :class:`StreamStopped` if the
    job did not finish.
    """
    if program.protocol != device.protocol:
        raise FoldfabError(f"a {program.protocol} program cannot run on {device.name} ({device.protocol})")
    sender = SENDERS[device.protocol]
    return sender(port, program, device, events, cancel, operator, stall_timeout, progress).run(note)


def locate_pen(port, device: DeviceProfile, timeout: float = 10.0) -> PenPosition | None:
    """Ask a plotter where its pen stopped after a job lost its host; None if it cannot know.

    HP-GL: ``ESC.K`` (abort graphics), sent twice, first discards what the plotter still
    holds from the lost connection, including an instruction a pulled cable cut in two,
    which would otherwise run together with the next one; ``OI`` waits for the move in
    progress and skips answers meant for the lost host; ``OS`` says whether the plotter
    was initialized since (switched off and on, or another program's ``IN``: its position
    then says nothing about the job; the engine reads ``OS`` at its first checkpoint,
    which clears the job's own ``IN``); ``OA`` gives the pen.

    GRBL: a board that greets on opening has just rebooted (an Arduino's DTR reset) and
    lost its position: None.  Otherwise, once the status says ``Idle`` (the lines it held
    are done), a soft reset clears a line the cable cut in two (GRBL keeps its position
    when reset at rest) and the status report gives the position; a Z tool stays where it
    was, a servo pen's state is lost with the reset (None).
    """
    from foldfab.programs.program import Program

    empty = Program("", device.protocol, device.name, (), ())
    sender = SENDERS[device.protocol]
    return sender(port, empty, device, None, None, None, timeout, None).locate()
