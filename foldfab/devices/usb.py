"""USB cutters foldfab knows by their vendor and product id, and the profile that fits each.

The ids are those the open Silhouette drivers use (inkscape-silhouette's
``silhouette/Graphtec.py``, taken from robocut's ``Plotter.h``; see devices/README.md).  A
profile name is given where foldfab ships one for that model (the GP-GL profiles); the
others are listed by model so that ``foldfab ports`` can say what is connected.
"""

from __future__ import annotations

from dataclasses import dataclass

SILHOUETTE_VENDOR = 0x0B4D
"""Graphtec's USB vendor id: every Silhouette and the Graphtec craft cutters."""


@dataclass(frozen=True)
class UsbCutter:
    """A cutter model on USB."""

    vendor: int
    product: int
    model: str
    profile: str | None
    """The built-in profile that fits (None: none ships)."""

    @property
    def id(self) -> str:
        return f"{self.vendor:04x}:{self.product:04x}"


KNOWN_CUTTERS = {(c.vendor, c.product): c for c in (
    UsbCutter(SILHOUETTE_VENDOR, 0x110A, "Graphtec Craft ROBO CC200-20", None),
    UsbCutter(SILHOUETTE_VENDOR, 0x111A, "Graphtec Craft ROBO CC300-20", None),
    UsbCutter(SILHOUETTE_VENDOR, 0x111C, "Silhouette SD 1", None),
    UsbCutter(SILHOUETTE_VENDOR, 0x111D, "Silhouette SD 2", None),
    UsbCutter(SILHOUETTE_VENDOR, 0x1121, "Silhouette Cameo", None),
    UsbCutter(SILHOUETTE_VENDOR, 0x112B, "Silhouette Cameo 2", None),
    UsbCutter(SILHOUETTE_VENDOR, 0x112F, "Silhouette Cameo 3", None),
    UsbCutter(SILHOUETTE_VENDOR, 0x1137, "Silhouette Cameo 4", "silhouette-cameo-4"),
    UsbCutter(SILHOUETTE_VENDOR, 0x1138, "Silhouette Cameo 4 Plus", "silhouette-cameo-4"),
    UsbCutter(SILHOUETTE_VENDOR, 0x1139, "Silhouette Cameo 4 Pro", "silhouette-cameo-4"),
    UsbCutter(SILHOUETTE_VENDOR, 0x1123, "Silhouette Portrait", None),
    UsbCutter(SILHOUETTE_VENDOR, 0x1132, "Silhouette Portrait 2", None),
    UsbCutter(SILHOUETTE_VENDOR, 0x113A, "Silhouette Portrait 3", "silhouette-portrait-3"),
)}
"""Known USB cutters by (vendor id, product id)."""


def usb_cutter(vendor: int, product: int) -> UsbCutter | None:
    """The known cutter with these ids; a Silhouette-vendor device not in the table is still
    named as one (None: not a cutter foldfab knows)."""
    found = KNOWN_CUTTERS.get((vendor, product))
    if found is None and vendor == SILHOUETTE_VENDOR:
        return UsbCutter(vendor, product, f"Silhouette or Graphtec cutter {product:04x}", None)
    return found
