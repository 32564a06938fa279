"""A drag knife's keys in a profile's ``[layers.NAME]`` and a job's ``[fabrication.layers.NAME]``:
``blade_offset``, ``swivel_angle`` and ``overcut`` (:class:`~foldfab.devices.profile.Blade`)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Mapping

from foldfab.devices.checks import _number, _Reader
from foldfab.devices.profile import Blade

MAX_OFFSET = 5.0
"""mm: the largest blade offset (drag knives trail by 0.25 to 1 mm; more is a unit mistake)."""
MAX_OVERCUT = 50.0
"""mm: the longest overcut."""
BLADE_KEYS = {
    "blade_offset": (f"mm from 0 to {MAX_OFFSET:g}: how far the blade's tip trails the knife's axis",
                     _number(0, MAX_OFFSET)),
    "swivel_angle": ("degrees from 0 to 179: corners turning more than this get a swivel arc", _number(0, 179)),
    "overcut": (f"mm from 0 to {MAX_OVERCUT:g}: how far closed loops are cut past their start",
                _number(0, MAX_OVERCUT)),
}
FIELDS = {"blade_offset": "offset", "swivel_angle": "swivel_angle", "overcut": "overcut"}
SCORING_LAYERS = ("valley", "mountain")
"""Profile layers that score: a blade there presses, it does not cut, so no compensation."""


def take_blade(reader: _Reader, base: Blade = Blade()) -> Blade | None:
    """The blade keys of ``reader``'s table taken out of it over ``base``; None if it has none."""
    given = {key: reader.take(key, *BLADE_KEYS[key]) for key in BLADE_KEYS if key in reader.data}
    if not given:
        return None
    return replace(base, **{FIELDS[key]: value for key, value in given.items()})


def blade_keys(table: Mapping[str, Any]) -> dict[str, Any]:
    """The blade keys of a layer table."""
    return {key: value for key, value in table.items() if key in BLADE_KEYS}


def without_blade_keys(table: Mapping[str, Any]) -> dict[str, Any]:
    """A layer table less its blade keys (the tool settings)."""
    return {key: value for key, value in table.items() if key not in BLADE_KEYS}


def profile_blade(reader: _Reader, layer: str, firmware: bool) -> Blade | None:
    """A profile layer's blade keys: refused on a scoring layer and where the firmware compensates."""
    for key in BLADE_KEYS:
        if key in reader.data and layer in SCORING_LAYERS:
            raise reader.fail(key, f"no {key} on the {layer} layer (it scores: only cut layers are compensated)",
                              reader.data[key], "remove it")
        if key in reader.data and firmware:
            raise reader.fail(key, f"no {key} where firmware_blade_offset = true (the cutter compensates)",
                              reader.data[key], "set the offset on the cutter, or set firmware_blade_offset = false")
    return take_blade(reader)
