"""The checks of a device profile's values: a reader that names file and key in every error,
the value kinds, sheets, and the tool settings a profile or a job's layer gives."""

from __future__ import annotations

import math
import re
from typing import Any, Iterable

from foldfab.errors import FoldfabError, unknown_key

SHEETS = {"a4": (210.0, 297.0), "a3": (297.0, 420.0), "letter": (215.9, 279.4)}
SERVO_COMMAND = re.compile(r"M3 S\d+(\.\d{1,3})?|M5")
README_HINT = "see devices/README.md"


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
_LASER_KEYS = {
    "power": ("a share of the laser's full power (GRBL's $30) above 0 and at most 1", _number(0, 1, open_lo=True)),
}
"""Tool settings only a laser has (``[gcode] tool = "laser"``)."""
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


def _laser_power(device, reader: _Reader, default: Any = _MISSING) -> float | None:
    """The ``power`` of a layer: a laser's share of its full power; no other tool has one."""
    if not device.laser:
        if "power" in reader.data:
            raise reader.fail("power", f"no power ({device.lacks('power')})", reader.data["power"],
                              'remove it, or make the profile a laser ([gcode] tool = "laser")')
        return None
    return reader.take("power", *_LASER_KEYS["power"], default)
