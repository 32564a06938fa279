"""The device profile's data model: what a plotter speaks, where its origin is, its motion,
limits and layer tools, and the frame that maps sheet millimetres to device units.

Imported by the command line's fast path: no numpy or vpype at module level (the
:class:`Frame` methods import numpy when called).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Mapping

from foldfab.devices.checks import _LASER_KEYS, _TOOL_KEYS, _laser_power, _Reader, _check_tool
from foldfab.errors import FoldfabError

GCODE_DECIMALS = 3
"""Decimals of the millimetre coordinates in G-code (GRBL takes more; a micrometre is plenty)."""

if TYPE_CHECKING:
    import numpy as np
REQUIRED_LAYERS = ("valley", "mountain", "cut")
DIRECTIONS = {"right": (1, 0), "left": (-1, 0), "down": (0, 1), "up": (0, -1)}
PARITIES = {"none": "N", "even": "E", "odd": "O", "mark": "M", "space": "S"}
FLOW_CONTROLS = ("xonxoff", "rtscts", "escb", "grbl", "none", "ebb", "status")


@dataclass(frozen=True)
class Dialect:
    """What one plotter language can express about a tool."""

    force: bool
    """The language has a force command (HPGL ``FS``)."""
    force_step: float | None
    """Resolution of the force value (None: no force)."""
    speed_step: float | None
    """Resolution of the speed in mm/s (None: practically continuous)."""


DIALECTS = {
    "hpgl": {
        # VS in cm/s with two decimals
        "hp": Dialect(force=False, force_step=None, speed_step=0.1),
        # FS in whole force steps, VS in whole cm/s
        "graphtec": Dialect(force=True, force_step=1.0, speed_step=10.0),
        # FS in whole grams-force, VS in whole cm/s
        "roland": Dialect(force=True, force_step=1.0, speed_step=10.0),
    },
    "gcode": {"grbl": Dialect(force=False, force_step=None, speed_step=None)},
    # EiBotBoard: speeds are step rates over time slices, practically continuous
    "ebb": {"axidraw": Dialect(force=False, force_step=None, speed_step=None)},
    # GP-GL (Graphtec, Silhouette): FX in whole force steps, "!" in whole cm/s
    "gpgl": {"graphtec": Dialect(force=True, force_step=1.0, speed_step=10.0)},
}
INTEGER_UNITS = ("hpgl", "gpgl", "ebb")
"""The languages whose coordinates are whole device units (G-code writes millimetres)."""


@dataclass(frozen=True)
class Tool:
    """Resolved settings for one pass."""

    pen: int
    """HPGL pen / tool number (``SP n``); for G-code, the tool named in tool-change messages."""
    force: float | None
    """Device force units (see the device profile's ``[limits] force``); None = do not set."""
    speed: float
    """Drawing speed in mm/s."""
    passes: int = 1
    """Each line of the layer is drawn this many times (the whole layer is repeated)."""
    pen_down: float | str | None = None
    """G-code: the depth of the profile layer this pass borrows its tool from (perforation dashes
    cut at the cut's depth); None: the depth of the pass's own layer."""
    power: float | None = None
    """A laser's power, as a share of its full power (GRBL's ``$30``); None for other tools."""


SWIVEL_ANGLE = 5.0
"""Degrees: a drag knife swivels round corners turning more than this (Inkcut's blade-offset
filter's default cutoff); gentler corners are joined straight."""


@dataclass(frozen=True)
class Blade:
    """A drag knife's compensation for one layer (:mod:`foldfab.fabrication.blade`)."""

    offset: float = 0.0
    """mm: how far the blade's tip trails the knife's axis (``blade_offset``); 0: none."""
    swivel_angle: float = SWIVEL_ANGLE
    """Degrees: corners turning more than this get a swivel arc."""
    overcut: float = 0.0
    """mm: closed loops are cut this far past their start."""


@dataclass(frozen=True)
class SerialSettings:
    """pyserial settings (``parity`` is a pyserial letter N/E/O/M/S)."""

    baudrate: int
    bytesize: int = 8
    parity: str = "N"
    stopbits: float = 1
    xonxoff: bool = False
    rtscts: bool = False
    dsrdtr: bool = False


@dataclass(frozen=True)
class BufferSettings:
    """The device's receive buffer and how a sender keeps from overrunning it."""

    size: int
    flow_control: str

    @property
    def instruction_limit(self) -> int:
        """HP-GL: bytes an instruction may have (the writer splits longer ``PD`` lists).  A
        sender waits for room for a whole instruction, and with no handshake it cannot send
        more than a buffer between two checks, so an instruction must fit with room to spare:
        half the buffer (the plotter reads the next while drawing one), at least 24 bytes
        (a coordinate pair) where the buffer holds that and a 3-byte ``OE;`` marker."""
        return max(self.size // 2, min(24, self.size - 3))


@dataclass(frozen=True)
class Motion:
    """Kinematics for time estimates, and the park position (device mm)."""

    draw_speed: float
    travel_speed: float
    acceleration: float
    pen_lift_time: float
    park: tuple[float, float] = (0.0, 0.0)
    junction_deviation: float | None = None
    """GRBL's ``$11`` (mm): corners are planned with junction speeds; None: taken from rest."""
    axis_limits: bool = False
    """``travel_speed`` and ``acceleration`` limit each axis (GRBL's ``$110``/``$111``,
    ``$120``/``$121``), not the head's path: see :func:`foldfab.programs.estimate.axis_factors`."""


@dataclass(frozen=True)
class Limits:
    """Accepted ranges, inclusive; None = unchecked."""

    pen: tuple[float, float] | None = None
    force: tuple[float, float] | None = None
    speed: tuple[float, float] | None = None


@dataclass(frozen=True)
class GcodeSettings:
    """How a G-code device lifts its tool: a Z height or a servo command; or a laser's beam."""

    pen_up: float | str | None
    """None for a laser (its beam is off on G0 moves and after M5)."""
    z_speed: float | None
    tool: str = "pen"
    """``"pen"`` (a pen, drag knife or stylus lowered by Z or a servo) or ``"laser"``."""
    spindle_max: float | None = None
    """A laser: GRBL's ``$30``, the ``S`` value of full power."""
    spindle_min: float = 0.0
    """A laser: GRBL's ``$31``, the ``S`` value of the lowest power above off."""


@dataclass(frozen=True)
class EbbSettings:
    """An EiBotBoard's pen-lift servo and stepper settings (AxiDraw's own names and units)."""

    pen_up: float
    """Pen-up height, percent of the servo's range (AxiDraw ``pen_pos_up``)."""
    pen_down: float
    """Pen-down height, percent (AxiDraw ``pen_pos_down``)."""
    raise_rate: float
    """Raising speed, percent (AxiDraw ``pen_rate_raise``)."""
    lower_rate: float
    """Lowering speed, percent (AxiDraw ``pen_rate_lower``)."""
    servo_min: int = 9855
    """Servo pulse at 0 %, in 1/12 MHz units (AxiDraw ``servo_min``)."""
    servo_max: int = 27831
    """Servo pulse at 100 % (AxiDraw ``servo_max``)."""
    servo_sweep_time: float = 200.0
    """ms the servo signal takes over the whole range at 100 % rate (AxiDraw ``servo_sweep_time``)."""
    microstepping: int = 1
    """``EM`` mode: 1 = 16x (AxiDraw's high resolution), 2 = 8x, ... 5 = full steps."""
    time_slice: float = 0.025
    """Seconds per ``SM`` move while accelerating (AxiDraw ``time_slice``)."""

    def position(self, percent: float) -> int:
        """The ``SC,4``/``SC,5`` servo pulse for a height in percent (as AxiDraw computes it)."""
        return int(round(self.servo_min + (self.servo_max - self.servo_min) * percent / 100.0))

    def rate(self, percent: float) -> int:
        """The ``SC,11``/``SC,12`` servo rate for a rate in percent: the pulse change per 24 ms
        servo cycle that sweeps the whole range in ``servo_sweep_time`` at 100 %."""
        return int(round((self.servo_max - self.servo_min) * 0.24 / self.servo_sweep_time * percent))


@dataclass(frozen=True)
class LayerDefaults:
    """Profile defaults for one layer name."""

    pen: int
    force: float | None
    speed: float
    passes: int
    pen_down: float | str | None
    power: float | None = None
    """A laser's power (a share of ``$30``); None for other tools."""


@dataclass(frozen=True)
class GPGLSettings:
    """A GP-GL cutter's tool holders: the blade offset of each (``FC``), tool 1 first."""

    blade_offset: tuple[float, ...]
    """mm from the tool's axis to its tip (0 for a pen, a scoring or an embossing tool)."""

    @property
    def tools(self) -> int:
        """How many tool holders the carriage has (more than one: ``J`` selects, and each
        setting names its tool)."""
        return len(self.blade_offset)


@dataclass(frozen=True)
class MediaPreset:
    """Tool settings for one material: ``score`` for the valley and mountain layers, ``cut``
    for the outline (job overrides of ``pen``, ``force``, ``speed``, ``passes``)."""

    description: str
    score: Mapping[str, Any]
    cut: Mapping[str, Any]


@dataclass(frozen=True)
class Frame:
    """Sheet millimetres <-> device units, for one device and one sheet size.

    ``device = units_per_mm * (M (sheet - corner) - offset)`` where the rows of ``M``
    are the sheet directions of device +x and +y.  Writers use :meth:`to_device`,
    interpreters :meth:`to_sheet`, so a round trip is exact up to the writer's rounding.
    """

    matrix: tuple[tuple[int, int], tuple[int, int]]
    corner: tuple[float, float]
    offset: tuple[float, float]
    units_per_mm: float

    def to_device(self, points: np.ndarray) -> np.ndarray:
        """Sheet mm (complex array or (N, 2)) -> device units, float (N, 2)."""
        import numpy as np

        pts = np.asarray(points)
        if np.iscomplexobj(pts):
            pts = np.column_stack([pts.real, pts.imag])
        rel = pts.reshape(-1, 2) - np.asarray(self.corner)
        dev = rel @ np.asarray(self.matrix, dtype=float).T
        dev -= self.offset   # in place, as :meth:`to_sheet`
        dev *= self.units_per_mm
        return dev

    def to_sheet(self, points: np.ndarray) -> np.ndarray:
        """Device units (N, 2) -> sheet mm, float (N, 2)."""
        import numpy as np

        dev = np.asarray(points, dtype=float).reshape(-1, 2) / self.units_per_mm
        dev += self.offset   # in place: a million strokes' points are 50 MB an array
        sheet = dev @ np.asarray(self.matrix, dtype=float)
        sheet += self.corner
        return sheet

    def device_rect_on_sheet(self, width: float, height: float) -> tuple[float, float, float, float]:
        """The device rectangle [0, width] x [0, height] (mm) as (x0, y0, x1, y1) on the sheet."""
        (a, b), (c, d) = self.matrix
        xs, ys = [], []
        for u, v in ((0.0, 0.0), (width, height)):
            u, v = u + self.offset[0], v + self.offset[1]
            xs.append(self.corner[0] + a * u + c * v)
            ys.append(self.corner[1] + b * u + d * v)
        return min(xs), min(ys), max(xs), max(ys)


@dataclass(frozen=True)
class DeviceProfile:
    """A validated device profile (see the module docstring for the schema)."""

    name: str
    model: str
    protocol: str
    dialect: str
    units_per_mm: float
    origin: str
    x_axis: str
    y_axis: str
    origin_offset: tuple[float, float]
    plottable_area: tuple[float, float]
    sheet: tuple[float, float]
    port: str | None
    tool_changer: bool
    serial: SerialSettings
    buffer: BufferSettings
    motion: Motion
    limits: Limits
    gcode: GcodeSettings | None
    layers: Mapping[str, LayerDefaults]
    source: str
    ebb: EbbSettings | None = None
    """EiBotBoard settings (``protocol = "ebb"`` only)."""
    firmware_blade_offset: bool = False
    """The device compensates its drag knife's offset itself (a cutter's own offset setting):
    foldfab moves no path and ignores a job's blade settings."""
    blades: Mapping[str, Blade] = field(default_factory=lambda: MappingProxyType({}))
    """The drag-knife compensation of each profile layer that sets one."""
    gpgl: GPGLSettings | None = None
    media: Mapping[str, MediaPreset] = field(default_factory=lambda: MappingProxyType({}))

    @property
    def resolution(self) -> float:
        """The smallest step a program for this device expresses, mm: one plotter unit in
        HP-GL, one motor step on an EiBotBoard, the last of the :data:`GCODE_DECIMALS` decimals
        G-code coordinates are written with.
        Optimization merges and simplifies within it, so the program moves nothing further."""
        return 1.0 / self.units_per_mm if self.protocol in INTEGER_UNITS else 10.0 ** -GCODE_DECIMALS

    @property
    def park_units(self) -> tuple[float, float]:
        """The park position in device units as programs write it (whole plotter units in
        HP-GL): where the pen waits at pauses and at the end, and so where a job starts."""
        x, y = (v * self.units_per_mm for v in self.motion.park)
        return (round(x), round(y)) if self.protocol in INTEGER_UNITS else (x, y)

    @property
    def laser(self) -> bool:
        """A G-code laser (``[gcode] tool = "laser"``): power per layer, no Z, beam off on G0."""
        return self.gcode is not None and self.gcode.tool == "laser"

    @property
    def language(self) -> Dialect:
        """What this device's plotter language can express."""
        return DIALECTS[self.protocol][self.dialect]

    def frame(self, sheet: tuple[float, float]) -> Frame:
        """The sheet <-> device mapping for a sheet of this size (w, h mm)."""
        ex, ey = DIRECTIONS[self.x_axis], DIRECTIONS[self.y_axis]
        corner = _origin_corner(ex, ey, sheet)
        return Frame((ex, ey), corner, self.origin_offset, self.units_per_mm)

    def tool_for(
        self, layer_name: str, overrides: Mapping[str, Any] | None = None, source: str = "job",
        like: str | None = None,
    ) -> Tool:
        """The profile's tool for ``layer_name`` with job ``overrides`` (pen, force, speed, passes).

        ``like`` names the profile layer whose settings the overrides start from (default
        ``layer_name``: perforation dashes start from the cut's); ``source`` names where the
        overrides come from (a job file) in error messages.
        """
        like = like or layer_name
        if like not in self.layers:
            raise FoldfabError(
                f"{self.source}: no [layers.{like}] table; known layers: "
                f"{', '.join(self.layers)}; add one to the profile or rename the layer"
            )
        base = self.layers[like]
        values = {key: getattr(base, key) for key in _TOOL_KEYS}
        overrides = dict(overrides or {})
        power = base.power
        if "power" in overrides:
            power = _laser_power(self, _Reader({"power": overrides.pop("power")}, source,
                                               f"layers.{layer_name}."))
        reader = _Reader(overrides, source, f"layers.{layer_name}.", _TOOL_KEYS)
        values.update({key: reader.take(key, *_TOOL_KEYS[key]) for key in _TOOL_KEYS
                       if key in reader.data})
        reader.done()
        _check_tool(self, reader, **values)
        return Tool(**values, pen_down=base.pen_down if like != layer_name else None, power=power)

    def media_overrides(self, media: str | None, where: str) -> dict[str, dict[str, Any]]:
        """The tool overrides of the media preset ``media`` by layer (valley and mountain get its
        ``score``, cut its ``cut``); {} for None.  ``where`` names the job key in the error."""
        if media is None:
            return {}
        if media not in self.media:
            known = ", ".join(self.media) if self.media else "none (add [media.NAME] tables to the profile)"
            raise FoldfabError(f"{where}: expected a media preset of {self.name}, got {media!r}; "
                               f"its presets: {known}")
        preset = self.media[media]
        return {"valley": dict(preset.score), "mountain": dict(preset.score), "cut": dict(preset.cut)}

    def lacks(self, key: str) -> str | None:
        """Why this device has no ``key`` tool setting (None: it has it)."""
        if key == "force" and not self.language.force:
            return "its language has no force command"
        if key == "power" and not self.laser:
            return "it is no laser"
        return None

    def supported(self, overrides: Mapping[str, Any], where: str) -> tuple[dict[str, Any], list[str]]:
        """A job's tool ``overrides`` less the settings this device does not have, and one warning
        line for each left out (``where`` names the job's table).  A job describes the sheet and
        the creases, not one machine: a setting another device has is no mistake on this one.
        A malformed value is kept, for :meth:`tool_for` to refuse."""
        kept, warnings, known = dict(overrides), [], {**_TOOL_KEYS, **_LASER_KEYS}
        for key in [key for key, value in kept.items()
                    if key in known and self.lacks(key) and known[key][1](value) is not None]:
            value = kept.pop(key)
            warnings.append(f"{where}.{key} = {value!r} ignored: {self.name} has no {key} setting "
                            f"({self.lacks(key)})")
        return kept, warnings

    def check_tool(self, tool: Tool, where: str) -> None:
        """Raise FoldfabError unless this device can use ``tool`` (``where`` names the step)."""
        reader = _Reader({key: getattr(tool, key) for key in _TOOL_KEYS
                          if getattr(tool, key) is not None}, where, "tool.")
        values = {key: reader.take(key, *_TOOL_KEYS[key], None) for key in _TOOL_KEYS}
        _check_tool(self, reader, **values)


# --- loading -------------------------------------------------------------------------


def _origin_corner(ex, ey, sheet) -> tuple[float, float]:
    """The sheet corner from which both device axes point into the sheet."""
    x = 0.0 if (ex[0] > 0 or ey[0] > 0) else float(sheet[0])
    y = 0.0 if (ex[1] > 0 or ey[1] > 0) else float(sheet[1])
    return x, y
