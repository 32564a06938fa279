"""A template page as SVG: the same drawing as the PDF, one SVG file per page, sized in mm
(user units are mm, y flipped to point down)."""

from __future__ import annotations

from xml.sax.saxutils import escape, quoteattr

from foldfab.printing.page import Lines, Page, Shape

FONT = "Bitstream Vera Sans, DejaVu Sans, Verdana, sans-serif"
PT_MM = 25.4 / 72.0


def render_svg(page: Page) -> str:
    """SVG text of one page."""
    h = page.height
    out = [f'<?xml version="1.0" encoding="UTF-8"?>\n<svg xmlns="http://www.w3.org/2000/svg" version="1.1" '
           f'width="{page.width:g}mm" height="{h:g}mm" viewBox="0 0 {page.width:g} {h:g}">']
    clips: dict[tuple[float, float, float, float], str] = {}
    for item in page.items:
        if isinstance(item, Lines):
            clip = ""
            if item.clip is not None:
                if item.clip not in clips:
                    x0, y0, x1, y1 = item.clip
                    clips[item.clip] = f"clip{len(clips)}"
                    out.append(f'<clipPath id="{clips[item.clip]}"><rect x="{x0:.3f}" y="{h - y1:.3f}" '
                               f'width="{x1 - x0:.3f}" height="{y1 - y0:.3f}"/></clipPath>')
                clip = f' clip-path="url(#{clips[item.clip]})"'
            dash = f' stroke-dasharray="{" ".join(f"{d:g}" for d in item.dash)}"' if item.dash else ""
            d = " ".join("M" + " L".join(f"{x:.3f},{h - y:.3f}" for x, y in line.tolist()) for line in item.polylines)
            out.append(f'<path d="{d}" fill="none" stroke="{item.color}" stroke-width="{item.width:g}"{dash} '
                       f'stroke-linecap="butt" stroke-linejoin="round"{clip}/>')
        elif isinstance(item, Shape):
            pts = " ".join(f"{x:.3f},{h - y:.3f}" for x, y in item.points.tolist())
            stroke = f'stroke="{item.stroke}" stroke-width="{item.width:g}"' if item.stroke else 'stroke="none"'
            out.append(f'<polygon points="{pts}" fill="{item.fill or "none"}" {stroke}/>')
        else:
            anchor = f' text-anchor="{item.anchor}"' if item.anchor != "start" else ""
            weight = ' font-weight="bold"' if item.bold else ""
            out.append(f'<text x="{item.x:.3f}" y="{h - item.y:.3f}" font-family={quoteattr(FONT)} '
                       f'font-size="{item.size * PT_MM:.3f}"{anchor}{weight}>{escape(item.text)}</text>')
    out.append("</svg>\n")
    return "\n".join(out)
