"""Reading PDFs back with Debian's poppler-utils (pdfinfo, pdftotext, pdftoppm): a reader
independent of the library that wrote them."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np

DPI = 600
PT = 72.0 / 25.4


def pdfinfo(path: Path) -> tuple[int, list[tuple[float, float]]]:
    """The page count pdfinfo reads and every page's size in mm."""
    out = subprocess.run(["pdfinfo", "-f", "1", "-l", "100000", str(path)], check=True, capture_output=True,
                         text=True).stdout
    pages = int(re.search(r"^Pages:\s+(\d+)$", out, re.M)[1])
    sizes = [(float(w) / PT, float(h) / PT) for w, h in re.findall(r"^Page\s+\d+ size:\s+([\d.]+) x ([\d.]+) pts", out, re.M)]
    return pages, sizes


def pdftotext(path: Path, page: int) -> str:
    return subprocess.run(["pdftotext", "-f", str(page), "-l", str(page), "-layout", str(path), "-"], check=True,
                          capture_output=True, text=True).stdout


def render(path: Path, page: int, box_mm: tuple[float, float, float, float], page_height_mm: float,
           dpi: int = DPI) -> np.ndarray:
    """Pixels (rows, cols, 3) of the page region ``box_mm`` (x0, y0, x1, y1 in page mm, y up)
    rendered by pdftoppm at ``dpi``, as read from its binary PPM; row 0 is the top."""
    px = dpi / 25.4
    x0, y0, x1, y1 = box_mm
    args = ["pdftoppm", "-r", str(dpi), "-f", str(page), "-l", str(page), "-x", str(round(x0 * px)),
            "-y", str(round((page_height_mm - y1) * px)), "-W", str(round((x1 - x0) * px)),
            "-H", str(round((y1 - y0) * px)), "-aaVector", "no", str(path)]
    data = subprocess.run(args, check=True, capture_output=True).stdout
    header = re.match(rb"P6\s+(\d+)\s+(\d+)\s+(\d+)\s", data)
    width, height = int(header[1]), int(header[2])
    return np.frombuffer(data[header.end():], np.uint8)[: width * height * 3].reshape(height, width, 3)


def pixel(box_mm: tuple[float, float, float, float], x: float, y: float, dpi: int = DPI) -> tuple[int, int]:
    """The (row, col) in a :func:`render` of ``box_mm`` of the page point (x, y) mm."""
    px = dpi / 25.4
    return int((box_mm[3] - y) * px), int((x - box_mm[0]) * px)


def runs(ink: np.ndarray) -> list[tuple[bool, int]]:
    """Runs of equal values along a 1D boolean array: (value, length)."""
    out: list[tuple[bool, int]] = []
    for value in ink.tolist():
        if out and out[-1][0] == value:
            out[-1] = (value, out[-1][1] + 1)
        else:
            out.append((value, 1))
    return out
