"""Device profiles: what a plotter speaks, where its origin is, and how it is reached.

Takes a profile name or a TOML file (:mod:`~foldfab.devices.load`, schema and search path
there) and gives a :class:`~foldfab.devices.profile.DeviceProfile`, every value checked
(:mod:`~foldfab.devices.checks`); the fabrication and later stages read only the profile.
"""

from foldfab.devices.checks import parse_sheet
from foldfab.devices.load import list_devices, load_device
from foldfab.devices.profile import (FLOW_CONTROLS, GCODE_DECIMALS, BufferSettings, DeviceProfile, Frame, Motion,
                                     Tool)
from foldfab.devices.profile import Blade

__all__ = ["FLOW_CONTROLS", "GCODE_DECIMALS", "BufferSettings", "DeviceProfile", "Frame", "Motion", "Tool",
           "list_devices", "load_device", "parse_sheet", "Blade"]
