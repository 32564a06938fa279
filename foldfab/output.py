"""Writing a design's files (FOLD, SVG, ORIPA, mesh) atomically, by kind."""

from __future__ import annotations

from pathlib import Path

from foldfab.atomic import write_bytes, write_text
from foldfab.design import Design
from foldfab.errors import FoldfabError

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".glb")
SUFFIX_KINDS = {".fold": "fold", ".svg": "svg", ".cp": "cp", **dict.fromkeys(MESH_SUFFIXES, "mesh")}


def kind_of(path: Path) -> str:
    """The kind of design file (fold, svg, cp, mesh) a file name asks for, by its suffix."""
    try:
        return SUFFIX_KINDS[path.suffix.lower()]
    except KeyError:
        raise FoldfabError(f"{path}: unknown design file type {path.suffix!r}; "
                           f"use one of {', '.join(SUFFIX_KINDS)}") from None


def write_design_file(design: Design, kind: str, path: Path) -> None:
    """Write ``design`` as ``kind`` (fold, svg, cp, mesh) to ``path``, all or nothing."""
    cp = design.crease_pattern
    if kind == "fold":
        from foldfab.formats import fold

        write_text(path, fold.dumps(cp, design.job.name))
    elif kind == "svg":
        from foldfab.formats import svg

        write_text(path, svg.dumps(cp))
    elif kind == "cp":
        from foldfab.formats import oripa

        write_text(path, oripa.dumps(cp))
    elif kind == "mesh":
        from foldfab.mesh import to_trimesh

        data = to_trimesh(cp).export(file_type=path.suffix.lower().lstrip("."))
        write_bytes(path, data.encode() if isinstance(data, str) else data)
    else:  # pragma: no cover - the CLI offers only the kinds above
        raise ValueError(kind)
