"""Writing a design's files (FOLD, SVG, ORIPA, mesh) atomically, by kind."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from foldfab.atomic import write_files
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


def design_file_data(design: Design, kind: str, suffix: str = "") -> bytes:
    """The bytes of ``design`` as ``kind`` (fold, svg, cp, mesh; a mesh's format by ``suffix``)."""
    cp = design.crease_pattern
    if kind == "fold":
        from foldfab.formats import fold

        return fold.dumps(cp, design.job.name).encode()
    if kind == "svg":
        from foldfab.formats import svg

        return svg.dumps(cp, marks=design.marks).encode()
    if kind == "cp":
        from foldfab.formats import oripa

        return oripa.dumps(cp).encode()
    if kind == "mesh":
        from foldfab.formats.mesh import GLTF_FROM_FOLDFAB, to_trimesh

        mesh, file_type = to_trimesh(cp), suffix.lower().lstrip(".")
        if file_type == "glb":
            mesh.apply_transform(GLTF_FROM_FOLDFAB)
        data = mesh.export(file_type=file_type)
        return data.encode() if isinstance(data, str) else data
    raise ValueError(kind)  # pragma: no cover - the callers offer only the kinds above


def write_design_files(design: Design, outputs: Sequence[tuple[str, Path]],
                       pieces: Sequence[tuple[Design, Sequence[tuple[str, Path]]]] = ()) -> None:
    """Write ``design`` as each ``(kind, path)``, and each of a split design's ``pieces`` as its
    own: all of them, or none (see :mod:`foldfab.atomic`)."""
    write_files([(path, design_file_data(part, kind, path.suffix))
                 for part, files in [(design, outputs), *pieces] for kind, path in files])
