"""EBB writer: programs for the EiBotBoard of AxiDraw pen plotters.

The program is the EBB commands themselves, each ended by ``\\r``: ``EM`` enables the motors at the
profile's microstepping, four ``SC`` set the pen-lift servo's up and down positions and rates,
``SP,1``/``SP,0`` raise and lower the pen (with the profile's ``pen_lift_time`` as the move's
delay), and ``SM,<ms>,<steps1>,<steps2>`` moves the two motors (motor 1 turns by x + y, motor 2
by x - y, in motor steps: device units are steps, so a program moves by whole steps).

Every straight move starts and ends at rest: a trapezoid at the profile's acceleration and the
layer's speed (pen down) or the travel speed (pen up), cut into ``SM`` moves of at most the
profile's ``time_slice``, as AxiDraw's own software does.  Each position comes from the motors'
absolute step counts, so rounding never accumulates and every vertex is reached exactly.  A drawn
vertex is followed by ``SM,1,0,0`` (the head at rest for one millisecond): the mark by which
:mod:`~foldfab.programs.read_ebb` finds the drawn polyline's vertices among the time slices.

Pauses exist only as offsets (:attr:`Program.pauses`), as in HP-GL: the pen is raised and parked
there, and the sender waits until the motors are idle before prompting.  The end raises the pen
and parks; the motors stay enabled so the carriage keeps its place.

The command text comes from Evil Mad Scientist's ``plotink`` (``ebb_motion``: ``EM``, ``SC``,
``SP``, ``SM`` as AxiDraw sends them), driven against a recorder instead of a serial port; the
peak speed of a short move comes from ``plot_utils.vFinal_Vi_A_Dx``.  foldfab writes the slicing
of each trapezoid itself (plotink has no planner; AxiDraw's lives in its own ``motion.py``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from foldfab.programs.estimate import move_times
from foldfab.programs.program import Program, ProgramBuilder, Sink, Stop, Sweep, sweeps

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.fabrication.plan import PlotPlan

VERTEX_MARK = "SM,1,0,0\r"
"""One millisecond at rest after a drawn vertex (how the reader tells vertices from slices)."""


def write_ebb(plan: PlotPlan, device: DeviceProfile, sink: Sink | None = None) -> Program:
    """The EBB program drawing ``plan`` on ``device``;
    ``sink``: see :class:`~foldfab.programs.program.ProgramBuilder` (the text streamed, not kept)."""
    items = sweeps(plan, device)
    out = _EbbWriter(device, sink=sink)
    park = np.asarray(device.park_units, dtype=float)
    for item in items:
        if isinstance(item, Stop):
            out.pen_up()
            out.move(park, device.motion.travel_speed)
            out.builder.pause(item)
        else:
            out.sweep(item)
    out.pen_up()
    out.move(park, device.motion.travel_speed)
    return out.builder.build()


def homing(device: DeviceProfile) -> str:
    """Commands that raise the pen and send the carriage home (``HM``: to the step counts of
    ``EM``, where a program starts) wherever a stop left it: how a stop ends and a resume begins."""
    from plotink import ebb_motion

    builder = ProgramBuilder("ebb", device)
    port = _Recorder(builder)
    ebb_motion.sendPenUp(port, int(round(device.motion.pen_lift_time * 1000)), verbose=False)
    ebb_motion.doAbsMove(port, home_rate(device), verbose=False)
    return builder.build().text


def home_rate(device: DeviceProfile) -> int:
    """``HM``'s step rate (steps/s of the faster motor): the travel speed, within the board's limit."""
    return int(min(device.motion.travel_speed * device.units_per_mm, 25000))


def travel(device: DeviceProfile, target: np.ndarray) -> str:
    """A pen-up move from home (the park position) to ``target`` (device units)."""
    writer = _EbbWriter(device, setup=False)
    writer.move(np.asarray(target, dtype=float), device.motion.travel_speed)
    return writer.builder.build().text   # every block: a long move is thousands of commands


class _Recorder:
    """Stands in for plotink's serial port: keeps what it writes, answers every command OK."""

    def __init__(self, builder: ProgramBuilder):
        self.builder = builder

    def write(self, data: bytes) -> int:
        self.builder.write(data.decode("ascii"))
        return len(data)

    def readline(self) -> bytes:
        return b"OK\r\n"


class _EbbWriter:
    """Tracks the motors' step counts and the pen, and writes EBB commands through plotink."""

    def __init__(self, device: DeviceProfile, setup: bool = True, sink: Sink | None = None):
        from plotink import ebb_motion

        self.device, self.ebb, self.commands = device, device.ebb, ebb_motion
        self.builder = ProgramBuilder("ebb", device, sink=sink)
        self.port = _Recorder(self.builder)
        park = np.asarray(device.park_units, dtype=float)
        self.steps = _motor_steps(park)  # where the last job left the carriage
        self.delay = int(round(device.motion.pen_lift_time * 1000))
        self.down = False
        if not setup:
            return
        settings, port = self.ebb, self.port
        ebb_motion.sendEnableMotors(port, settings.microstepping, False)
        ebb_motion.setPenUpPos(port, settings.position(settings.pen_up), False)
        ebb_motion.setPenDownPos(port, settings.position(settings.pen_down), False)
        ebb_motion.setPenUpRate(port, settings.rate(settings.raise_rate), False)
        ebb_motion.setPenDownRate(port, settings.rate(settings.lower_rate), False)
        self.down = True  # unknown at the start: raise it
        self.pen_up()

    def pen_up(self) -> None:
        if self.down:
            self.commands.sendPenUp(self.port, self.delay, verbose=False)
            self.down = False

    def sweep(self, item: Sweep) -> None:
        self.builder.start(item)
        travel, speed = self.device.motion.travel_speed, item.tool.speed
        for line in item.lines:
            self.pen_up()
            self.move(line[0], travel)
            self.commands.sendPenDown(self.port, self.delay, verbose=False)
            self.down = True
            for point in line[1:]:
                self.move(point, speed)
                self.builder.write(VERTEX_MARK)

    def move(self, target: np.ndarray, speed: float) -> None:
        """A straight move to ``target`` (device units) from rest to rest at ``speed`` mm/s."""
        goal = _motor_steps(target)
        delta = goal - self.steps
        if not delta.any():
            return
        units = self.device.units_per_mm
        length = math.hypot((delta[0] + delta[1]) / 2, (delta[0] - delta[1]) / 2) / units  # mm
        acceleration = self.device.motion.acceleration
        total = float(move_times(np.asarray(length), speed, acceleration))
        count = max(1, math.ceil(total / self.ebb.time_slice - 1e-9))
        times = np.linspace(0.0, total, count + 1)
        done = _trapezoid_distance(times, length, speed, acceleration, total) / length
        positions = self.steps + np.rint(np.outer(done, delta)).astype(np.int64)
        positions[-1] = goal
        millis = np.rint(times * 1000).astype(np.int64)
        waited = 0
        for (s1, s2), ms in zip(np.diff(positions, axis=0).tolist(), np.diff(millis).tolist()):
            waited += ms
            if s1 or s2:
                # plotink's doXYMove writes "SM,duration,delta_y,delta_x": motor 1 goes second
                self.commands.doXYMove(self.port, s2, s1, max(waited, 1), verbose=False)
                waited = 0
        self.steps = goal


def _motor_steps(point: np.ndarray) -> np.ndarray:
    """Motor step counts (x + y, x - y) of a point in device units, rounded to whole steps."""
    x, y = float(point[0]), float(point[1])
    return np.rint([x + y, x - y]).astype(np.int64)


def _trapezoid_distance(times: np.ndarray, length: float, speed: float, acceleration: float,
                        total: float) -> np.ndarray:
    """mm covered at ``times`` by a rest-to-rest move of ``length`` lasting ``total`` seconds."""
    from plotink import plot_utils

    peak = min(speed, plot_utils.vFinal_Vi_A_Dx(0.0, acceleration, length / 2))
    ramp = peak / acceleration
    rising = 0.5 * acceleration * np.square(np.minimum(times, ramp))
    cruising = peak * np.clip(times - ramp, 0.0, max(total - 2 * ramp, 0.0))
    falling = 0.5 * acceleration * (ramp * ramp - np.square(np.clip(total - times, 0.0, ramp)))
    return np.minimum(rising + cruising + falling, length)
