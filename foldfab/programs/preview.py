"""Dry-run preview: an SVG of what the interpreted program would do to the sheet.

Drawn from the *interpreted program*, not from the plan, so it shows what the device
will receive: the sheet, the device's reachable area, pen-down strokes coloured by
layer (mountain red, valley blue, cut black, others grey), pen-up travel as thin
dashed grey lines, numbered pause markers with the operator's instructions, and a
legend with drawn length, pen lifts, travel and estimated time per layer.
Units are millimetres (``viewBox`` in mm); the output is deterministic.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from typing import TYPE_CHECKING
from xml.sax.saxutils import escape, quoteattr

from foldfab.programs.estimate import estimate
from foldfab.fabrication.plan import PlotPlan
from foldfab.programs.program import fmt_number

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.programs.machine import Interpretation

COLORS = {"mountain": "#ff0000", "valley": "#0000ff", "cut": "#000000"}
OTHER_COLOR = "#808080"
MARGIN, FONT, LINE = 10.0, 4.0, 6.0


def render_preview(interpretation: Interpretation, device: DeviceProfile,
                   plan_or_sheet: PlotPlan | tuple[float, float], notes: Sequence[str] = ()) -> str:
    """SVG text previewing ``interpretation`` on ``device`` for this plan's (or size's) sheet;
    ``notes`` are more legend lines after the device's (the scale the design is drawn at)."""
    sheet = plan_or_sheet.sheet if isinstance(plan_or_sheet, PlotPlan) else plan_or_sheet
    width, height = sheet
    times = estimate(interpretation, device)
    wrap = max(20, int((width + 2 * MARGIN) / (FONT * 0.55)))
    legend: list[tuple[str | None, str]] = [(None, f"{device.name}: {device.model}")]
    legend += [(None, note) for note in notes]
    for name, stats in times.layers.items():
        legend.append((layer_color(name),
                       f"{name}: {stats.drawn_length:.0f} mm drawn, {stats.pen_lifts} pen lift{'' if stats.pen_lifts == 1 else 's'}, "
                       f"{stats.travel_length:.0f} mm travel, {_duration(stats.time)}"))
    legend.append((None, f"total: {_duration(times.total)} (lower bound "
                         f"{_duration(times.lower_bound)})"))
    for number, pause in enumerate(interpretation.pauses, 1):
        for k, text in enumerate(textwrap.wrap(f"pause {number}: {pause.message}", wrap) or [""]):
            legend.append((None, text if k == 0 else "    " + text))

    view_w = width + 2 * MARGIN
    view_h = height + 2 * MARGIN + LINE * len(legend)
    f = _f
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{f(view_w)}mm" height="{f(view_h)}mm" '
        f'viewBox="{f(-MARGIN)} {f(-MARGIN)} {f(view_w)} {f(view_h)}">',
        f'<rect id="sheet" x="0" y="0" width="{f(width)}" height="{f(height)}" fill="#ffffff" '
        'stroke="#000000" stroke-width="0.2"/>',
    ]
    x0, y0, x1, y1 = device.frame(sheet).device_rect_on_sheet(*device.plottable_area)
    out.append(f'<rect id="plottable-area" x="{f(x0)}" y="{f(y0)}" width="{f(x1 - x0)}" '
               f'height="{f(y1 - y0)}" fill="none" stroke="#00a000" stroke-width="0.2" '
               'stroke-dasharray="2,1"/>')
    if interpretation.travels:
        path = " ".join(f"M{f(t.start[0])},{f(t.start[1])}L{f(t.end[0])},{f(t.end[1])}"
                        for t in interpretation.travels)
        out.append(f'<path id="travel" d="{path}" fill="none" stroke="#a0a0a0" '
                   'stroke-width="0.15" stroke-dasharray="1,1"/>')
    groups: dict[str, list[str]] = {}
    for stroke in interpretation.strokes:
        color = layer_color(stroke.layer)
        points = stroke.points.tolist()
        if len(points) == 1:
            element = f'<circle cx="{f(points[0][0])}" cy="{f(points[0][1])}" r="0.3" fill="{color}"/>'
        else:
            element = '<polyline points="' + " ".join(f"{f(x)},{f(y)}" for x, y in points) + '"/>'
        groups.setdefault(stroke.layer, []).append(element)
    for index, (name, elements) in enumerate(groups.items()):
        color = layer_color(name)
        out.append(f'<g id="layer-{index + 1}" data-layer={quoteattr(name)} fill="none" '
                   f'stroke="{color}" stroke-width="0.3" stroke-linejoin="round">')
        out.extend(elements)
        out.append("</g>")
    for number, pause in enumerate(interpretation.pauses, 1):
        x, y = pause.position
        out.append(f'<g class="pause"><circle cx="{f(x)}" cy="{f(y)}" r="2.5" fill="#ffcc00" '
                   f'stroke="#000000" stroke-width="0.2"/><text x="{f(x)}" y="{f(y + 1.4)}" '
                   f'font-size="{f(FONT)}" text-anchor="middle" font-family="sans-serif">'
                   f'{number}</text></g>')
    out.append(f'<g id="legend" font-family="sans-serif" font-size="{f(FONT)}">')
    for row, (color, text) in enumerate(legend):
        y = height + MARGIN + row * LINE
        if color is not None:
            out.append(f'<rect x="0" y="{f(y - FONT)}" width="{f(FONT)}" height="{f(FONT)}" '
                       f'fill="{color}"/>')
        out.append(f'<text x="{f(FONT * 1.5 if color else 0)}" y="{f(y)}">{escape(text)}</text>')
    out.append("</g>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


def layer_color(name: str) -> str:
    """A layer's colour; layers drawn with one tool ("valley+mountain") take the first one's."""
    return COLORS.get(name.split("+")[0], OTHER_COLOR)


def _f(value: float) -> str:
    return fmt_number(value, 3)


def _duration(seconds: float) -> str:
    """Human-readable duration: "12.3 s", "4 min 05 s", "1 h 02 min"."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, secs = divmod(round(seconds), 60)
    if minutes < 60:
        return f"{minutes} min {secs:02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"
