"""A small single-stroke font: text as polylines a pen or a lightly scoring blade can draw.

Plotter text must be strokes, not outlines: HP-GL's ``LB`` exists on pen plotters only (GRBL,
G-code and the SVG and preview outputs have no text), and its font, size and direction vary by
machine.  Strokes drawn from this table come out the same on every device and in every
output.  Glyphs lie on a grid 4 wide and 6 high (baseline at 0); each is a list of polylines,
written as space-separated "xy" digit pairs.  Capital letters, digits and space only: match
marks need no more.  Pure geometry: no I/O.
"""

from __future__ import annotations

import numpy as np

GLYPHS: dict[str, tuple[str, ...]] = {
    "A": ("00 03 26 43 40", "03 43"), "B": ("00 06 36 45 44 33 03", "33 42 41 30 00"),
    "C": ("46 16 05 01 10 40",), "D": ("00 06 26 44 42 20 00",), "E": ("46 06 00 40", "03 33"),
    "F": ("46 06 00", "03 33"), "G": ("46 16 05 01 10 40 43 23",), "H": ("00 06", "40 46", "03 43"),
    "I": ("16 36", "26 20", "10 30"), "J": ("46 41 30 10 01",), "K": ("00 06", "46 03 40"),
    "L": ("06 00 40",), "M": ("00 06 23 46 40",), "N": ("00 06 40 46",),
    "O": ("10 01 05 16 36 45 41 30 10",), "P": ("00 06 36 45 44 33 03",),
    "Q": ("10 01 05 16 36 45 41 30 10", "22 40"), "R": ("00 06 36 45 44 33 03", "23 40"),
    "S": ("45 36 16 05 04 13 33 42 41 30 10 01",), "T": ("06 46", "26 20"), "U": ("06 01 10 30 41 46",),
    "V": ("06 20 46",), "W": ("06 00 23 40 46",), "X": ("06 40", "00 46"), "Y": ("06 23 46", "23 20"),
    "Z": ("06 46 00 40",),
    "0": ("10 01 05 16 36 45 41 30 10", "05 41"), "1": ("14 26 20", "10 30"), "2": ("05 16 36 45 44 00 40",),
    "3": ("05 16 36 45 44 33 13", "33 42 41 30 10 01"), "4": ("36 03 43", "46 40"),
    "5": ("46 06 04 34 43 41 30 00",), "6": ("45 36 16 05 01 10 30 41 42 33 03",), "7": ("06 46 20",),
    "8": ("13 04 05 16 36 45 44 33 13 02 01 10 30 41 42 33",), "9": ("01 10 30 41 45 36 16 05 04 13 43",),
    " ": (),
}
ADVANCE = 6
"""Grid units from one character to the next (4 wide, 2 apart)."""


def text_strokes(text: str, height: float) -> list[np.ndarray]:
    """The strokes (N, 2) writing ``text`` with capitals ``height`` mm tall, from (0, 0) along +x.
    Characters the font lacks are drawn as a box, so nothing is silently dropped."""
    unit = height / 6.0
    strokes = []
    for index, char in enumerate(text.upper()):
        glyph = GLYPHS.get(char, ("00 06 46 40 00",))
        for stroke in glyph:
            points = np.array([[int(p[0]), int(p[1])] for p in stroke.split()], float)
            strokes.append((points + [index * ADVANCE, 0.0]) * unit)
    return strokes
