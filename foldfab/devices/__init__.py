"""Device profiles: what a plotter speaks, where its origin is, and how it is reached.

A profile is a TOML file.  ``load_device(name_or_path)`` looks, in order, for a path
to a ``.toml`` file, for ``$XDG_CONFIG_HOME/foldfab/devices/NAME.toml`` (default
``~/.config``), then for a built-in profile (the repository's ``devices/`` folder,
installed as ``foldfab/builtin_devices``).  Every schema violation raises
:class:`~foldfab.errors.FoldfabError` naming the file and the key.

Schema (all lengths in mm, speeds in mm/s; ``devices/README.md`` has the long form)::

    name = "graphtec-ce6000"        # required
    model = "Graphtec CE6000"       # required, free text
    protocol = "hpgl"               # required: "hpgl" | "gcode"
    dialect = "graphtec"            # hpgl: "hp" | "graphtec" | "roland" (required); gcode: "grbl"
    units_per_mm = 40               # hpgl only, default 40 (1016 per inch)
    origin = "bottom-right"         # sheet corner at the device origin; must agree with the axes
    x_axis = "up"                   # direction of device +x on the sheet: right | left | up | down
    y_axis = "left"                 # direction of device +y; perpendicular to x_axis
    origin_offset = [0, 0]          # optional: device (0,0) measured from the origin corner
    plottable_area = [584, 1000]    # required: reach along device x and y from device (0,0)
    sheet = "A4"                    # A4 | A3 | Letter, optionally + " landscape", or [w, h]
    port = "/dev/ttyUSB0"           # optional: serial port or pyserial URL
    tool_changer = false            # optional: true if the device changes pens by itself

    [serial]   baudrate (required), bytesize = 8, parity = "none", stopbits = 1,
               xonxoff = false, rtscts = false, dsrdtr = false
    [buffer]   size (bytes, required), flow_control = "xonxoff" | "rtscts" | "escb" | "grbl" | "none"
    [motion]   draw_speed, travel_speed, acceleration (mm/s^2), pen_lift_time (s): required;
               park = [x, y] (device mm, default [0, 0]): where the head waits at pauses and the end;
               junction_deviation (mm > 0, G-code only): GRBL's $11; time estimates and the
               simulated GRBL then keep speed through corners as GRBL plans them (absent: every
               corner sharper than 1 degree is taken from rest);
               axis_limits (default false): travel_speed and acceleration limit each axis, as
               GRBL's $110/$111 and $120/$121 do, so a diagonal move gets up to 1.41 times both
    [limits]   optional ranges [lo, hi] for pen, force, speed
    [gcode]    gcode only: pen_up = Z height (number) or a servo command ("M3 S50");
               z_speed (mm/s, required with a Z height)
    [layers.valley], [layers.mountain], [layers.cut] (required; other names allowed):
               pen (required), force, speed (default motion.draw_speed), passes = 1,
               pen_down (gcode only, required: Z height or servo command, same kind as pen_up)

This module is imported by the command line's fast path: no numpy or vpype at module
level (the :class:`Frame` methods import numpy when called).
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Iterable, Mapping

from foldfab.errors import FoldfabError, unknown_key
from foldfab.fabrication.plan import Tool
from foldfab.xdg import foldfab_dir

GCODE_DECIMALS = 3
"""Decimals of the millimetre coordinates in G-code (GRBL takes more; a micrometre is plenty)."""

if TYPE_CHECKING:
    import numpy as np

REQUIRED_LAYERS = ("valley", "mountain", "cut")
DIRECTIONS = {"right": (1, 0), "left": (-1, 0), "down": (0, 1), "up": (0, -1)}
SHEETS = {"a4": (210.0, 297.0), "a3": (297.0, 420.0), "letter": (215.9, 279.4)}
PARITIES = {"none": "N", "even": "E", "odd": "O", "mark": "M", "space": "S"}
FLOW_CONTROLS = ("xonxoff", "rtscts", "escb", "grbl", "none")
SERVO_COMMAND = re.compile(r"M3 S\d+(\.\d{1,3})?|M5")
README_HINT = "see devices/README.md"


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
}


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
    """How a G-code device lifts its tool: a Z height or a servo command."""

    pen_up: float | str
    z_speed: float | None


@dataclass(frozen=True)
class LayerDefaults:
    """Profile defaults for one layer name."""

    pen: int
    force: float | None
    speed: float
    passes: int
    pen_down: float | str | None


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
        return (rel @ np.asarray(self.matrix, dtype=float).T - self.offset) * self.units_per_mm

    def to_sheet(self, points: np.ndarray) -> np.ndarray:
        """Device units (N, 2) -> sheet mm, float (N, 2)."""
        import numpy as np

        dev = np.asarray(points, dtype=float).reshape(-1, 2) / self.units_per_mm + self.offset
        return dev @ np.asarray(self.matrix, dtype=float) + self.corner

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

    @property
    def resolution(self) -> float:
        """The smallest step a program for this device expresses, mm: one plotter unit in
        HP-GL, the last of the :data:`GCODE_DECIMALS` decimals G-code coordinates are written with.
        Optimization merges and simplifies within it, so the program moves nothing further."""
        return 1.0 / self.units_per_mm if self.protocol == "hpgl" else 10.0 ** -GCODE_DECIMALS

    @property
    def park_units(self) -> tuple[float, float]:
        """The park position in device units as programs write it (whole plotter units in
        HP-GL): where the pen waits at pauses and at the end, and so where a job starts."""
        x, y = (v * self.units_per_mm for v in self.motion.park)
        return (round(x), round(y)) if self.protocol == "hpgl" else (x, y)

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
        reader = _Reader(dict(overrides or {}), source, f"layers.{layer_name}.", _TOOL_KEYS)
        values.update({key: reader.take(key, *_TOOL_KEYS[key]) for key in _TOOL_KEYS
                       if key in reader.data})
        reader.done()
        _check_tool(self, reader, **values)
        return Tool(**values, pen_down=base.pen_down if like != layer_name else None)

    def lacks(self, key: str) -> str | None:
        """Why this device has no ``key`` tool setting (None: it has it)."""
        if key == "force" and not self.language.force:
            return "its language has no force command"
        return None

    def supported(self, overrides: Mapping[str, Any], where: str) -> tuple[dict[str, Any], list[str]]:
        """A job's tool ``overrides`` less the settings this device does not have, and one warning
        line for each left out (``where`` names the job's table).  A job describes the sheet and
        the creases, not one machine: a setting another device has is no mistake on this one.
        A malformed value is kept, for :meth:`tool_for` to refuse."""
        kept, warnings = dict(overrides), []
        for key in [key for key, value in kept.items()
                    if key in _TOOL_KEYS and self.lacks(key) and _TOOL_KEYS[key][1](value) is not None]:
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


def load_device(name_or_path: str | os.PathLike) -> DeviceProfile:
    """Load and validate a profile by file path, user profile name or built-in name."""
    text = str(name_or_path)
    if text.endswith(".toml") or os.sep in text or "/" in text:
        path = Path(text)
        if not path.exists():  # anything else there is refused by name as it is read
            raise FoldfabError(f"{path}: no such device profile file; check the path")
        return _load_file(path)
    for folder in (_user_dir(), _builtin_dir()):
        path = folder / f"{text}.toml"
        if path.is_file():
            return _load_file(path)
    raise FoldfabError(
        f"unknown device '{text}'; known devices: {', '.join(list_devices()) or 'none'} "
        f"(or give the path of a .toml profile, or add {_user_dir() / (text + '.toml')})"
    )


def list_devices() -> list[str]:
    """Names of the user's and the built-in profiles, sorted (a user profile hides a built-in)."""
    names = set()
    for folder in (_user_dir(), _builtin_dir()):
        if folder.is_dir():
            names.update(p.stem for p in folder.glob("*.toml"))
    return sorted(names)


def _user_dir() -> Path:
    return foldfab_dir("XDG_CONFIG_HOME") / "devices"


def _builtin_dir() -> Path:
    """``foldfab/builtin_devices`` when installed, the repository's ``devices/`` in a checkout."""
    here = Path(__file__).resolve().parent.parent  # foldfab/
    installed = here / "builtin_devices"
    return installed if installed.is_dir() else here.parent / "devices"


def _load_file(path: Path) -> DeviceProfile:
    from foldfab.files import SMALL_LIMIT, read_text

    text = read_text(path, "device profile", SMALL_LIMIT)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FoldfabError(f"{path}: not valid TOML ({exc}); fix the syntax") from None
    return _parse(_Reader(data, str(path), keys=_ROOT_KEYS))


# --- validation ----------------------------------------------------------------------

_MISSING = object()


class _Reader:
    """Takes keys out of one TOML table, naming file and dotted key in every error."""

    def __init__(self, data: dict, file: str, prefix: str = "", keys: Iterable[str] | None = None):
        """``keys``: every key the table may hold.  A key outside them is reported at once,
        before a missing key it may be the misspelling of; None leaves the table open."""
        self.data, self.file, self.prefix = data, file, prefix
        self.keys = keys
        if keys is not None:
            self.done()

    def fail(self, key: str, expected: str, value: Any, fix: str = README_HINT) -> FoldfabError:
        return FoldfabError(
            f"{self.file}: key '{self.prefix}{key}': expected {expected}, got {value!r}; {fix}"
        )

    def take(self, key: str, expected: str, check, default: Any = _MISSING) -> Any:
        if key not in self.data:
            if default is _MISSING:
                raise FoldfabError(
                    f"{self.file}: missing key '{self.prefix}{key}' ({expected}); "
                    f"add it, {README_HINT}"
                )
            return default
        value = self.data.pop(key)
        result = check(value)
        if result is None:
            raise self.fail(key, expected, value)
        return result

    def table(self, key: str, required: bool = True, keys: Iterable[str] | None = None) -> _Reader | None:
        if key not in self.data:
            if required:
                raise FoldfabError(
                    f"{self.file}: missing table '[{self.prefix}{key}]'; add it, {README_HINT}"
                )
            return None
        value = self.data.pop(key)
        if not isinstance(value, dict):
            raise self.fail(key, "a table", value)
        return _Reader(value, self.file, f"{self.prefix}{key}.", keys)

    def done(self) -> None:
        """Fail on a key left over (once all are taken) or outside the declared keys."""
        found = unknown_key(self.data, self.keys or ())
        if found:
            raise FoldfabError(
                f"{self.file}: unknown key '{self.prefix}{found[0]}'; remove it or fix its spelling: "
                f"{found[1]} ({README_HINT})"
            )


def _number(lo: float = -math.inf, hi: float = math.inf, open_lo: bool = False):
    def check(value):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return None
        if value < lo or value > hi or (open_lo and value == lo):
            return None
        return float(value)

    return check


def _integer(lo: int, hi: int = 2**31):
    def check(value):
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            return None
        return value

    return check


def _choice(options):
    return lambda value: value if isinstance(value, str) and value in options else None


def _choice_number(options):
    return lambda value: float(value) if _number()(value) in options else None


def _text(value):
    return value if isinstance(value, str) and value.strip() else None


def _boolean(value):
    return value if isinstance(value, bool) else None


def _pair(check):
    def pair(value):
        if not isinstance(value, list) or len(value) != 2:
            return None
        items = [check(v) for v in value]
        return None if None in items else tuple(items)

    return pair


def _range(value):
    pair = _pair(_number())(value)
    return pair if pair is not None and pair[0] <= pair[1] else None


def parse_sheet(value: Any) -> tuple[float, float] | None:
    """Sheet size (w, h mm) from "A4", "A3", "Letter" (+ " landscape") or [w, h]; None if invalid."""
    if isinstance(value, str):
        words = value.lower().split()
        if len(words) in (1, 2) and words[0] in SHEETS and words[1:] in ([], ["landscape"]):
            w, h = SHEETS[words[0]]
            return (h, w) if words[1:] else (w, h)
        return None
    return _pair(_number(0, open_lo=True))(value)


def _pen_position(value):
    if isinstance(value, str):
        return value if SERVO_COMMAND.fullmatch(value) else None
    return _number()(value)


_TOOL_KEYS = {
    "pen": ("an integer pen/tool number >= 0", _integer(0)),
    "force": ("a number >= 0 (device force units)", _number(0)),
    "speed": ("a speed in mm/s > 0", _number(0, open_lo=True)),
    "passes": ("an integer from 1 to 100", _integer(1, 100)),
}
_PEN_POSITION = 'a Z height in mm (number) or a servo command like "M3 S30" or "M5"'


def _check_tool(device, reader: _Reader, pen, force, speed, passes) -> None:
    """Check tool values against what the device's language and limits accept."""
    language = device.language
    if force is not None and device.lacks("force"):
        raise reader.fail("force", f"no force ({device.lacks('force')})", force,
                          "remove it" + ("; set the depth with pen_down" if device.protocol == "gcode" else ""))
    for key, value, step, unit in (
        ("force", force, language.force_step, "force units"),
        ("speed", speed, language.speed_step, "mm/s"),
    ):
        if value is not None and step is not None and abs(value / step - round(value / step)) > 1e-9:
            lower, upper = math.floor(value / step) * step, math.ceil(value / step) * step
            raise reader.fail(
                key, f"a multiple of {step:g} {unit} ({device.dialect} dialect)", value,
                f"use {lower:g} or {upper:g}: the device cannot be told {value:g} exactly",
            )
    for key, value in (("pen", pen), ("force", force), ("speed", speed)):
        bounds = getattr(device.limits, key)
        if value is not None and bounds is not None and not bounds[0] <= value <= bounds[1]:
            raise reader.fail(
                key, f"a value in [{bounds[0]:g}, {bounds[1]:g}] ([limits] of {device.name})",
                value, "use a value inside the device's range",
            )


def _origin_corner(ex, ey, sheet) -> tuple[float, float]:
    """The sheet corner from which both device axes point into the sheet."""
    x = 0.0 if (ex[0] > 0 or ey[0] > 0) else float(sheet[0])
    y = 0.0 if (ex[1] > 0 or ey[1] > 0) else float(sheet[1])
    return x, y


def _corner_name(ex, ey) -> str:
    x, y = _origin_corner(ex, ey, (1, 1))
    return f"{'top' if y == 0 else 'bottom'}-{'left' if x == 0 else 'right'}"


_ROOT_KEYS = ("name", "model", "protocol", "dialect", "units_per_mm", "x_axis", "y_axis", "origin", "origin_offset",
              "plottable_area", "sheet", "port", "tool_changer", "serial", "buffer", "motion", "limits", "gcode",
              "layers")
"""Every key at the top of a device profile."""


def _parse(root: _Reader) -> DeviceProfile:
    name = root.take("name", "a device name", _text)
    model = root.take("model", "a model description", _text)
    protocol = root.take("protocol", '"hpgl" or "gcode"', _choice(DIALECTS))
    dialects = DIALECTS[protocol]
    default_dialect = "grbl" if protocol == "gcode" else _MISSING
    dialect = root.take(
        "dialect", " or ".join(f'"{d}"' for d in dialects), _choice(dialects), default_dialect
    )
    if protocol == "hpgl":
        units = root.take("units_per_mm", "plotter units per mm > 0", _number(0, open_lo=True), 40.0)
    elif "units_per_mm" in root.data:
        raise root.fail("units_per_mm", "no units_per_mm (G-code is in mm)", root.data["units_per_mm"],
                        "remove it")
    else:
        units = 1.0
    axes = {}
    for key in ("x_axis", "y_axis"):
        axes[key] = root.take(key, "right, left, up or down", _choice(DIRECTIONS))
    ex, ey = DIRECTIONS[axes["x_axis"]], DIRECTIONS[axes["y_axis"]]
    if ex[0] * ey[0] + ex[1] * ey[1] != 0:
        raise root.fail("y_axis", f"a direction perpendicular to x_axis '{axes['x_axis']}'",
                        axes["y_axis"], "one axis runs along the top edge, the other along the side")
    corners = ("top-left", "top-right", "bottom-left", "bottom-right")
    origin = root.take("origin", "top-left, top-right, bottom-left or bottom-right", _choice(corners))
    if origin != _corner_name(ex, ey):
        raise root.fail(
            "origin", f"'{_corner_name(ex, ey)}' (the corner x_axis '{axes['x_axis']}' and "
            f"y_axis '{axes['y_axis']}' point away from)", origin, "fix origin or the axes",
        )
    offset = root.take("origin_offset", "[x, y] in mm", _pair(_number()), (0.0, 0.0))
    area = root.take("plottable_area", "[width, height] in mm > 0", _pair(_number(0, open_lo=True)))
    sheet = root.take("sheet", 'A4, A3, Letter (optionally + " landscape") or [w, h] in mm', parse_sheet)
    port = root.take("port", "a serial port or pyserial URL", _text, None)
    tool_changer = root.take("tool_changer", "true or false", _boolean, False)

    ser = root.table("serial", keys=("baudrate", "bytesize", "parity", "stopbits", "xonxoff", "rtscts", "dsrdtr"))
    serial = SerialSettings(
        baudrate=ser.take("baudrate", "a baud rate", _integer(50)),
        bytesize=ser.take("bytesize", "5, 6, 7 or 8", _integer(5, 8), 8),
        parity=PARITIES[ser.take("parity", "none, even, odd, mark or space", _choice(PARITIES), "none")],
        stopbits=ser.take("stopbits", "1, 1.5 or 2", _choice_number((1, 1.5, 2)), 1.0),
        xonxoff=ser.take("xonxoff", "true or false", _boolean, False),
        rtscts=ser.take("rtscts", "true or false", _boolean, False),
        dsrdtr=ser.take("dsrdtr", "true or false", _boolean, False),
    )
    ser.done()

    buf = root.table("buffer", keys=("size", "flow_control"))
    buffer = BufferSettings(
        size=buf.take("size", "the receive buffer size in bytes", _integer(1)),
        flow_control=buf.take("flow_control", ", ".join(FLOW_CONTROLS), _choice(FLOW_CONTROLS)),
    )
    needs = {"xonxoff": ("serial.xonxoff", serial.xonxoff), "rtscts": ("serial.rtscts", serial.rtscts)}
    if buffer.flow_control in needs and not needs[buffer.flow_control][1]:
        raise buf.fail("flow_control", f"a flow control enabled in [serial] "
                       f"({needs[buffer.flow_control][0]} = true)", buffer.flow_control,
                       f"set {needs[buffer.flow_control][0]} = true")
    native = {"grbl": "gcode", "escb": "hpgl"}
    if native.get(buffer.flow_control, protocol) != protocol:
        raise buf.fail("flow_control", f"a flow control for {protocol}", buffer.flow_control,
                       "grbl is for G-code devices, escb for HPGL ones")
    buf.done()

    mot = root.table("motion", keys=("draw_speed", "travel_speed", "acceleration", "pen_lift_time", "park",
                                        "junction_deviation", "axis_limits"))
    positive = _number(0, open_lo=True)
    motion = Motion(
        draw_speed=mot.take("draw_speed", "mm/s > 0", positive),
        travel_speed=mot.take("travel_speed", "mm/s > 0", positive),
        acceleration=mot.take("acceleration", "mm/s^2 > 0", positive),
        pen_lift_time=mot.take("pen_lift_time", "seconds >= 0", _number(0)),
        park=mot.take("park", "[x, y] in device mm", _pair(_number()), (0.0, 0.0)),
        junction_deviation=mot.take("junction_deviation", "mm > 0 (GRBL's $11)", positive, None),
        axis_limits=mot.take("axis_limits", "true or false", _boolean, False),
    )
    if protocol == "hpgl" and motion.junction_deviation is not None:
        raise mot.fail("junction_deviation", "no junction_deviation in an HPGL profile (GRBL's $11; "
                       "HPGL plotters are modelled stopping at corners)", motion.junction_deviation,
                       "remove it")
    if not all(0 <= motion.park[i] <= area[i] for i in (0, 1)):
        raise mot.fail("park", f"a point inside plottable_area {list(area)}", list(motion.park),
                       "move the park position into the plottable area")
    mot.done()

    lim = root.table("limits", required=False, keys=("pen", "force", "speed"))
    limits = Limits()
    if lim is not None:
        limits = Limits(**{k: lim.take(k, "[lo, hi] with lo <= hi", _range, None)
                           for k in ("pen", "force", "speed")})
        lim.done()

    gcode = None
    gc = root.table("gcode", required=protocol == "gcode", keys=("pen_up", "z_speed"))
    if gc is not None and protocol != "gcode":
        raise root.fail("gcode", "no [gcode] table in an HPGL profile", "[gcode]", "remove it")
    if gc is not None:
        pen_up = gc.take("pen_up", _PEN_POSITION, _pen_position)
        z_speed = gc.take("z_speed", "mm/s > 0", positive, None)
        if isinstance(pen_up, float) and z_speed is None:
            raise FoldfabError(f"{gc.file}: missing key 'gcode.z_speed' (mm/s > 0, the speed of "
                               f"pen-down Z moves); add it, {README_HINT}")
        gcode = GcodeSettings(pen_up=pen_up, z_speed=z_speed)
        gc.done()

    profile = DeviceProfile(
        name=name, model=model, protocol=protocol, dialect=dialect, units_per_mm=units,
        origin=origin, x_axis=axes["x_axis"], y_axis=axes["y_axis"], origin_offset=offset,
        plottable_area=area, sheet=sheet, port=port, tool_changer=tool_changer, serial=serial,
        buffer=buffer, motion=motion, limits=limits, gcode=gcode, layers=MappingProxyType({}),
        source=root.file,
    )
    layers_reader = root.table("layers")
    layers = {}
    for layer in REQUIRED_LAYERS:
        if layer not in layers_reader.data:
            raise FoldfabError(f"{root.file}: missing table '[layers.{layer}]'; add it, {README_HINT}")
    for layer in list(layers_reader.data):
        layers[layer] = _parse_layer(profile, layers_reader.table(layer, keys=(*_TOOL_KEYS, "pen_down")))
    root.done()
    return replace(profile, layers=MappingProxyType(layers))


def _parse_layer(profile: DeviceProfile, reader: _Reader) -> LayerDefaults:
    values = {
        "pen": reader.take("pen", *_TOOL_KEYS["pen"]),
        "force": reader.take("force", *_TOOL_KEYS["force"], None),
        "speed": reader.take("speed", *_TOOL_KEYS["speed"], profile.motion.draw_speed),
        "passes": reader.take("passes", *_TOOL_KEYS["passes"], 1),
    }
    _check_tool(profile, reader, **values)
    pen_down = None
    if profile.gcode is not None:
        pen_up = profile.gcode.pen_up
        pen_down = reader.take("pen_down", _PEN_POSITION, _pen_position)
        if isinstance(pen_down, str) != isinstance(pen_up, str):
            raise reader.fail("pen_down", "the same kind as gcode.pen_up "
                              f"({'a servo command' if isinstance(pen_up, str) else 'a Z height'})",
                              pen_down, "use Z heights or servo commands throughout")
        if pen_down == pen_up or (isinstance(pen_up, float) and pen_down >= pen_up):
            raise reader.fail("pen_down", f"a pen-down position below/unlike gcode.pen_up ({pen_up!r})",
                              pen_down, "lower pen_down or raise pen_up")
    reader.done()
    return LayerDefaults(pen_down=pen_down, **values)
