"""Make the README's pictures from the example jobs: python docs/pictures.py

Writes docs/img/*.svg: crease patterns (foldfab's own SVG writer) and shaded 3D
views of the folded models (orthographic, painter's algorithm, one colour per
paper side), plus the dry-run plotter preview of the Figure 8 (a) job on the Graphtec profile.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate
from foldfab.formats import svg
from foldfab.programs.interpret import interpret
from foldfab.programs.preview import render_preview

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "img"
FRONT, BACK = np.array([236, 226, 200]), np.array([150, 180, 215])


def render_3d(cp, azimuth: float = 35.0, elevation: float = 28.0, size: float = 480.0) -> str:
    """SVG of the folded model seen from (azimuth, elevation) degrees."""
    a, e = np.radians(azimuth), np.radians(elevation)
    view = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    right = np.array([-np.sin(a), np.cos(a), 0.0])
    up = np.cross(view, right)
    p = cp.vertices_3d
    xy = np.column_stack([p @ right, p @ up])
    depth = p @ view
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    scale = (size - 20) / max(hi - lo)
    xy = (xy - lo) * scale + 10
    xy[:, 1] = size - xy[:, 1]
    faces = cp.faces
    q = p[faces]
    normal = np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    facing = normal @ view
    light = np.abs(normal @ (view + up * 0.5) / np.linalg.norm(view + up * 0.5))
    shade = 0.45 + 0.55 * light
    order = np.argsort(depth[faces].mean(axis=1))
    polys = []
    for f in order:
        colour = (FRONT if facing[f] >= 0 else BACK) * shade[f]
        pts = " ".join(f"{x:.2f},{y:.2f}" for x, y in xy[faces[f]])
        polys.append(f'<polygon points="{pts}" fill="rgb({int(colour[0])},{int(colour[1])},{int(colour[2])})" '
                     f'stroke="#333" stroke-width="0.3" stroke-linejoin="round"/>')
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{size:.0f}" height="{size:.0f}" '
            f'viewBox="0 0 {size:.0f} {size:.0f}">\n<rect width="100%" height="100%" fill="white"/>\n'
            + "\n".join(polys) + "\n</svg>\n")


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for job in ("hexagon-fig8a", "diamond-fig9", "vase-svg", "star"):
        design = load_design(ROOT / "jobs" / f"{job}.toml")
        text = svg.dumps(design.crease_pattern, stroke_width=0.4)
        text = text.replace('viewBox', 'style="background:white" viewBox', 1)
        (OUT / f"{job}-cp.svg").write_text(text)
        (OUT / f"{job}-3d.svg").write_text(render_3d(design.crease_pattern))
        print("wrote", OUT / f"{job}-cp.svg", OUT / f"{job}-3d.svg", file=sys.stderr)
    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    device = load_device("graphtec-ce6000")
    fab = fabricate(design, device)
    preview = render_preview(interpret(fab.program, device, fab.plan.sheet), device, fab.plan)
    (OUT / "hexagon-fig8a-preview.svg").write_text(preview)
    print("wrote", OUT / "hexagon-fig8a-preview.svg", file=sys.stderr)


if __name__ == "__main__":
    main()
