"""A template as PDF, drawn with reportlab.

reportlab is the PDF library chosen: pure-Python wheels on every platform (no system
library like cairo to install), vector paths with dash patterns and clipping, TrueType fonts
embedded as subsets (Bitstream Vera, which reportlab ships, so the text is selectable and
prints the same everywhere) and exact page boxes in points.  Its C accelerator rl_accel
(number formatting and stream encoding, half the PDF time of a 100,000-face pattern in pure
Python) is a dependency too.
"""

from __future__ import annotations

import functools
import io

from foldfab.printing.page import Lines, Page, Shape, Text

PT = 72.0 / 25.4
"""PDF points per mm."""
FONTS = {False: ("FoldfabVera", "Vera.ttf"), True: ("FoldfabVeraBd", "VeraBd.ttf")}


@functools.lru_cache(maxsize=4096)
def _color(text: str):
    """reportlab's colour of a ``#rrggbb`` string, parsed once."""
    from reportlab.lib.colors import HexColor

    return HexColor(text)


def _register_fonts() -> None:
    from reportlab.pdfbase import pdfmetrics
    from reportlab.pdfbase.ttfonts import TTFont

    for name, file in FONTS.values():
        if name not in pdfmetrics.getRegisteredFontNames():
            pdfmetrics.registerFont(TTFont(name, file))


def render_pdf(pages: list[Page], title: str) -> bytes:
    """The PDF of ``pages``, one PDF page each at its size."""
    from reportlab.pdfgen.canvas import Canvas

    _register_fonts()
    out = io.BytesIO()
    canvas = Canvas(out, pagesize=(pages[0].width * PT, pages[0].height * PT), pageCompression=1,
                    invariant=1, initialFontName=FONTS[False][0], initialFontSize=8)
    canvas.setTitle(title)
    canvas.setCreator("foldfab print")
    for page in pages:
        canvas.setPageSize((page.width * PT, page.height * PT))
        canvas.setLineCap(0)
        canvas.setLineJoin(1)
        for item in page.items:
            if isinstance(item, Lines):
                _lines(canvas, item)
            elif isinstance(item, Shape):
                _shape(canvas, item)
            else:
                _text(canvas, item)
        canvas.showPage()
    canvas.save()
    return out.getvalue()


def _lines(canvas, item: Lines) -> None:
    canvas.saveState()
    if item.clip is not None:
        x0, y0, x1, y1 = item.clip
        box = canvas.beginPath()
        box.rect(x0 * PT, y0 * PT, (x1 - x0) * PT, (y1 - y0) * PT)
        canvas.clipPath(box, stroke=0, fill=0)
    canvas.setStrokeColor(_color(item.color))
    canvas.setLineWidth(item.width * PT)
    canvas.setDash([d * PT for d in item.dash] if item.dash else [], 0)
    path = canvas.beginPath()
    for line in item.polylines:
        pts = (line * PT).tolist()
        path.moveTo(*pts[0])
        for x, y in pts[1:]:
            path.lineTo(x, y)
    canvas.drawPath(path, stroke=1, fill=0)
    canvas.restoreState()


def _shape(canvas, item: Shape) -> None:
    pts = (item.points * PT).tolist()
    path = canvas.beginPath()
    path.moveTo(*pts[0])
    for x, y in pts[1:]:
        path.lineTo(x, y)
    path.close()
    if item.fill:
        canvas.setFillColor(_color(item.fill))
    if item.stroke:
        canvas.setStrokeColor(_color(item.stroke))
        canvas.setLineWidth(item.width * PT)
    canvas.setDash([], 0)
    canvas.drawPath(path, stroke=1 if item.stroke else 0, fill=1 if item.fill else 0)


def _text(canvas, item: Text) -> None:
    canvas.setFillColor(_color("#000000"))
    canvas.setFont(FONTS[item.bold][0], item.size)
    draw = {"start": canvas.drawString, "middle": canvas.drawCentredString, "end": canvas.drawRightString}
    draw[item.anchor](item.x * PT, item.y * PT, item.text)
