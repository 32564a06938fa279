"""`foldfab design`: the summary, the four kinds of output files, and every kind of error.

Output files are read back with plain tools (json, ElementTree, text parsing,
trimesh) and checked against the conventions, not against foldfab's writers.
Errors must be one line on stderr with exit code 2 and leave no file behind.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.design import load_design
from helpers import JOBS, ROOT
from helpers.cli import run, write_job

SVG_NS = "{http://www.w3.org/2000/svg}"
COLOURS = {"M": "#ff0000", "V": "#0000ff", "B": "#000000", "F": "#ffff00"}
LABELS = {"M": "mountain", "V": "valley", "F": "flat", "B": "border"}


def outputs(folder: Path, mesh: str = "out.stl") -> tuple[list[str], dict[str, Path]]:
    paths = {"fold": folder / "out.fold", "svg": folder / "out.svg", "cp": folder / "out.cp", "mesh": folder / mesh}
    args = [a for kind, path in paths.items() for a in (f"--{kind}", str(path))]
    return args, paths


def assert_one_line_error(rc: int, out: str, err: str, *fragments: str) -> str:
    assert rc == 2, err
    assert out == ""
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("foldfab: error: ")
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


def no_files_left(folder: Path) -> None:
    left = sorted(p.name for p in folder.iterdir())
    assert left == [], f"files left behind: {left}"


def umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# --------------------------------------------------------------------------- readers and checks

def check_fold(data: dict) -> None:
    """The FOLD conventions: crease pattern on top, folded form in file_frames[0], isometric."""
    assert data["file_spec"] == 1.1
    assert data["frame_classes"] == ["creasePattern"]
    assert data["frame_unit"] == "mm"
    v2 = np.array(data["vertices_coords"], float)
    assert v2.ndim == 2 and v2.shape[1] == 2
    edges = np.array(data["edges_vertices"], int)
    assert edges.ndim == 2 and edges.shape[1] == 2 and edges.min() >= 0 and edges.max() < len(v2)
    assert np.all(edges[:, 0] != edges[:, 1])
    assert len({frozenset(e) for e in edges.tolist()}) == len(edges), "an edge is listed twice"
    assignment = np.array(data["edges_assignment"])
    angle = np.array(data["edges_foldAngle"], float)
    assert len(assignment) == len(angle) == len(edges)
    assert set(assignment.tolist()) <= set("BMVF")
    assert np.all(angle[assignment == "V"] > 0)
    assert np.all(angle[assignment == "M"] < 0)
    assert np.all(angle[assignment == "B"] == 0)
    assert np.all(angle[assignment == "F"] == 0)  # FOLD: zero for flat, unassigned and border edges
    assert np.all(np.abs(angle) <= 180)

    faces = data["faces_vertices"]
    assert faces and all(len(f) in (3, 4) and len(set(f)) == len(f) for f in faces)
    for f in faces:
        p = v2[f]
        area = 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
        assert area > 0, f"face {f} is not counter-clockwise"
    # Every face side is an edge; borders have one face beside them, creases two.
    count = {frozenset(e): 0 for e in edges.tolist()}
    for f in faces:
        for a, b in zip(f, f[1:] + f[:1]):
            assert frozenset((a, b)) in count, f"face side {a}-{b} is not an edge"
            count[frozenset((a, b))] += 1
    for e, kind in zip(edges.tolist(), assignment.tolist()):
        assert count[frozenset(e)] == (1 if kind == "B" else 2), (e, kind)

    assert len(data["file_frames"]) >= 1
    folded = data["file_frames"][0]
    assert folded["frame_inherit"] is True
    assert folded["frame_classes"] == ["foldedForm"]
    assert folded.get("frame_parent", 0) == 0
    v3 = np.array(folded["vertices_coords"], float)
    assert v3.shape == (len(v2), 3)
    # Isometric: every edge keeps its length (coordinates are written to 1e-9 mm).
    l2 = np.linalg.norm(v2[edges[:, 0]] - v2[edges[:, 1]], axis=1)
    l3 = np.linalg.norm(v3[edges[:, 0]] - v3[edges[:, 1]], axis=1)
    scale = float(np.ptp(v2, axis=0).max())
    assert np.all(np.abs(l3 - l2) <= 1e-9 * np.maximum(l2, scale))


def check_isometric_in_memory(design) -> None:
    cp = design.crease_pattern
    l2 = np.linalg.norm(cp.vertices[cp.edges[:, 0]] - cp.vertices[cp.edges[:, 1]], axis=1)
    l3 = np.linalg.norm(cp.vertices_3d[cp.edges[:, 0]] - cp.vertices_3d[cp.edges[:, 1]], axis=1)
    assert np.all(l2 > 0)
    assert np.all(np.abs(l3 - l2) <= 1e-9 * l2)


def fold_edge_points(data: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v2 = np.array(data["vertices_coords"], float)
    edges = np.array(data["edges_vertices"], int)
    return v2[edges], np.array(data["edges_assignment"]), np.array(data["edges_foldAngle"], float)


def match_edges(segments: np.ndarray, edge_points: np.ndarray, tol: float) -> np.ndarray:
    """Index of the FOLD edge each segment (S, 2, 2) lies on, either way round."""
    a, b = segments[:, None, 0], segments[:, None, 1]
    p, q = edge_points[None, :, 0], edge_points[None, :, 1]
    same = np.maximum(np.abs(a - p).max(-1), np.abs(b - q).max(-1))
    swapped = np.maximum(np.abs(a - q).max(-1), np.abs(b - p).max(-1))
    d = np.minimum(same, swapped)
    index = d.argmin(axis=1)
    assert np.all(d[np.arange(len(segments)), index] <= tol), "a segment matches no edge of the FOLD file"
    return index


def check_svg(path: Path, data: dict, design) -> None:
    root = ET.parse(path).getroot()
    assert root.tag == f"{SVG_NS}svg"
    width, height = root.get("width"), root.get("height")
    assert width.endswith("mm") and height.endswith("mm")
    view = [float(v) for v in root.get("viewBox").split()]
    assert view[:2] == [0, 0]
    unit = float(width[:-2]) / view[2]  # mm per user unit
    assert unit <= 0.1 * (1 + 1e-6) and view[3] * unit == pytest.approx(float(height[:-2]))
    children = list(root)
    assert children and all(c.tag == f"{SVG_NS}line" for c in children), "flat <line> elements only"
    for element in root.iter():
        assert element.get("transform") is None and element.get("style") is None and element.get("class") is None
    assert not root.findall(f".//{SVG_NS}g") and not root.findall(f".//{SVG_NS}style")

    points, assignment, angle = fold_edge_points(data)
    lo, hi = points.reshape(-1, 2).min(axis=0), points.reshape(-1, 2).max(axis=0)
    assert view[2] * unit == pytest.approx(hi[0] - lo[0], abs=1e-5)
    assert view[3] * unit == pytest.approx(hi[1] - lo[1], abs=1e-5)
    user = np.array([[float(c.get(k)) for k in ("x1", "y1", "x2", "y2")] for c in children]).reshape(-1, 2, 2)
    # Origami Simulator's default import merges vertices closer than 3 user units (issue 18: the
    # vase lost 363 - 186 vertices when they were written in mm): none may be that close.
    ends = np.unique(user.reshape(-1, 2), axis=0)
    assert len(ends) == len(design.crease_pattern.vertices), "every vertex, written once"
    gaps = np.linalg.norm(ends[:, None] - ends[None], axis=-1) + np.eye(len(ends)) * 1e9
    assert gaps.min() > 3, f"vertices {gaps.min():.3f} user units apart merge on import"
    coords = user * unit
    # SVG y runs down: the sheet's y is flipped about its top edge.
    sheet = np.stack([coords[..., 0] + lo[0], hi[1] - coords[..., 1]], axis=-1)
    index = match_edges(sheet, points, 2e-6)
    assert sorted(index.tolist()) == list(range(len(points))), "every edge exactly once"
    cp_angle = design.crease_pattern.fold_angle
    for element, i in zip(children, index.tolist()):
        kind = assignment[i]
        assert element.get("stroke") == COLOURS[kind]
        opacity = float(element.get("stroke-opacity"))
        assert 0 <= opacity <= 1
        if kind != "B":
            assert opacity == pytest.approx(abs(cp_angle[i]) / 180, abs=2e-6)
        if kind in "MV":
            assert opacity == pytest.approx(abs(angle[i]) / 180, abs=2e-6)


def check_oripa(path: Path, data: dict) -> None:
    rows = [line.split() for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]
    assert all(len(r) == 5 for r in rows)
    types = np.array([int(r[0]) for r in rows])
    segments = np.array([[float(c) for c in r[1:]] for r in rows]).reshape(-1, 2, 2)
    points, assignment, _ = fold_edge_points(data)
    kinds = {1: "B", 2: "M", 3: "V"}
    assert set(types.tolist()) <= set(kinds)
    for t, kind in kinds.items():
        assert int((types == t).sum()) == int((assignment == kind).sum()), kind
    index = match_edges(segments, points, 1e-8)
    assert len(set(index.tolist())) == len(rows)
    assert all(assignment[i] == kinds[t] for i, t in zip(index.tolist(), types.tolist()))


def check_mesh(path: Path, design) -> None:
    """The mesh is the folded sheet without its glue tab (which lies flat under the first
    panel), and a surface: no edge is shared by more than two triangles."""
    cp = design.crease_pattern
    mesh = trimesh.load(path, force="mesh")
    if path.suffix.lower() == ".glb":  # glTF is y-up in metres: back to foldfab's z-up millimetres
        mesh.vertices = np.column_stack([mesh.vertices[:, 0], -mesh.vertices[:, 2], mesh.vertices[:, 1]]) * 1000
    triangles, owner = cp.triangles()
    assert len(mesh.faces) == int((~cp.tab_faces[owner]).sum())
    expected = np.array([cp.vertices_3d.min(axis=0), cp.vertices_3d.max(axis=0)])
    np.testing.assert_allclose(mesh.bounds, expected, atol=1e-4)  # float32 in STL, PLY and glTF
    assert mesh.area == pytest.approx(design_area(cp, without_tab=True), rel=1e-5)
    mesh.merge_vertices()  # STL stores each triangle's corners on their own
    _, uses = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    assert uses.max() <= 2


def design_area(cp, without_tab: bool = False) -> float:
    """Area of the sheet (or of all but its glue tab) by the faces' 2D shoelace sum (faces are
    CCW, so it is positive)."""
    total = 0.0
    for f, tab in zip(cp.face_polygons(), cp.tab_faces if len(cp.tab_faces) else [False] * len(cp.faces)):
        if tab and without_tab:
            continue
        p = cp.vertices[f]
        total += 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    return total


# --------------------------------------------------------------------------- summary

def test_summary_of_hexagon(capsys):
    rc, out, err = run(capsys, "design", ROOT / "jobs" / "hexagon-fig8a.toml")
    assert rc == 0 and err == ""
    assert "closed, 6 corners" in out
    assert re.search(r"line elements 5, faces 32, vertices 45", out)
    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    cp = design.crease_pattern
    lengths = np.linalg.norm(cp.vertices[cp.edges[:, 0]] - cp.vertices[cp.edges[:, 1]], axis=1)
    for kind, label in LABELS.items():
        m = re.search(rf"^{label}\s+(\d+) edges\s+([\d.]+) mm$", out, re.M)
        assert m, label
        assert int(m.group(1)) == int((cp.assignment == kind).sum())
        assert float(m.group(2)) == pytest.approx(lengths[cp.assignment == kind].sum(), abs=0.051)
    m = re.search(r"^sheet\s+([\d.]+) x ([\d.]+) mm$", out, re.M)
    assert (float(m.group(1)), float(m.group(2))) == pytest.approx(tuple(np.ptp(cp.vertices, axis=0)), abs=0.051)
    assert re.search(r"^penetrations 0$", out, re.M)
    assert "wrote" not in out


@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_every_example_writes_every_format(capsys, tmp_path, job):
    args, paths = outputs(tmp_path, mesh="out.obj")
    rc, out, err = run(capsys, "design", job, *args, "--json")
    assert rc == 0, err
    info = json.loads(out)
    design = load_design(job)
    data = json.loads(paths["fold"].read_text(encoding="utf-8"))
    check_fold(data)
    check_isometric_in_memory(design)
    check_svg(paths["svg"], data, design)
    check_oripa(paths["cp"], data)
    check_mesh(paths["mesh"], design)

    # The summary agrees with the FOLD file.
    points, assignment, _ = fold_edge_points(data)
    lengths = np.linalg.norm(points[:, 0] - points[:, 1], axis=1)
    for kind, label in LABELS.items():
        assert info["creases"][label]["count"] == int((assignment == kind).sum())
        assert info["creases"][label]["length_mm"] == pytest.approx(lengths[assignment == kind].sum(), abs=1.1e-3)
    v2 = np.array(data["vertices_coords"])
    assert info["faces"] == len(data["faces_vertices"])
    assert info["vertices"] == len(v2)
    cp = design.crease_pattern   # a line element is a row of the sheet (a glue tab's chamfered corners are not)
    rows = v2[np.unique(cp.faces[~cp.tab_faces])] if len(cp.tab_faces) else v2
    assert info["line_elements"] == len(np.unique(rows[:, 1].round(6)))
    assert info["sheet_mm"] == pytest.approx(np.ptp(v2, axis=0).tolist(), abs=1.1e-3)
    assert info["penetrations"] == 0 and info["warnings"] == []
    assert info["written"][:len(paths)] == [str(p) for p in paths.values()]   # then a split job's pieces
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(Path(p).name for p in info["written"])


def test_json_and_text_agree(capsys):
    job = ROOT / "jobs" / "star.toml"
    _, text, _ = run(capsys, "design", job)
    _, raw, _ = run(capsys, "design", job, "--json")
    info = json.loads(raw)
    assert info["corners"] == 8 and info["closed"] is True
    assert f"closed, {info['corners']} corners" in text
    assert f"line elements {info['line_elements']}, faces {info['faces']}" in text
    for label in ("mountain", "valley", "flat"):
        c = info["creases"][label]
        assert re.search(rf"^{label}\s+{c['count']} edges\s+{c['length_mm']:.1f} mm$", text, re.M)


def test_open_trajectory_summary(capsys):
    rc, out, _ = run(capsys, "design", ROOT / "jobs" / "open-wave-fig11f.toml", "--json")
    info = json.loads(out)
    assert rc == 0 and info["closed"] is False and info["corners"] == 3


@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply", ".glb", ".STL"])
def test_mesh_formats(capsys, tmp_path, suffix):
    job = ROOT / "jobs" / "diamond-fig9.toml"
    target = tmp_path / f"model{suffix}"
    rc, out, err = run(capsys, "design", job, "--mesh", target)
    assert rc == 0, err
    assert f"wrote        {target}" in out
    check_mesh(target, load_design(job))
    assert [p.name for p in tmp_path.iterdir()] == [target.name]


def glb_positions(path: Path) -> np.ndarray:
    """The vertex positions of a one-mesh GLB, read from its chunks as any glTF viewer would."""
    import struct

    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<4sII", data)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_length, kind = struct.unpack_from("<I4s", data, 12)
    assert kind == b"JSON"
    gltf = json.loads(data[20:20 + json_length])
    binary = data[20 + json_length + 8:]
    accessor = gltf["accessors"][gltf["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    view = gltf["bufferViews"][accessor["bufferView"]]
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    assert accessor["componentType"] == 5126 and accessor["type"] == "VEC3"  # float32 triples
    points = np.frombuffer(binary, "<f4", accessor["count"] * 3, start).reshape(-1, 3)
    np.testing.assert_allclose(points.min(axis=0), accessor["min"], rtol=1e-6)
    assert all("matrix" not in node and "rotation" not in node and "scale" not in node for node in gltf.get("nodes", []))
    return points.astype(float)


@pytest.mark.parametrize("job", ["hexagon-fig8a", "helix-fig12"])
def test_glb_is_y_up_in_metres(capsys, tmp_path, job):
    """Issue 18: the GLB was z-up in mm, so glTF viewers showed the column on its side, 80 m wide.
    glTF is y-up in metres: the column stands along +y, as tall in metres as it is in mm / 1000."""
    design = load_design(ROOT / "jobs" / f"{job}.toml")
    for name in ("m.glb", "m.stl"):
        rc, _, err = run(capsys, "design", ROOT / "jobs" / f"{job}.toml", "--mesh", tmp_path / name)
        assert rc == 0, err
    points = glb_positions(tmp_path / "m.glb")
    folded = design.crease_pattern.vertices_3d
    np.testing.assert_allclose(points.min(axis=0), [folded[:, 0].min() / 1000, folded[:, 2].min() / 1000,
                                                    -folded[:, 1].max() / 1000], atol=1e-7)
    np.testing.assert_allclose(points.max(axis=0), [folded[:, 0].max() / 1000, folded[:, 2].max() / 1000,
                                                    -folded[:, 1].min() / 1000], atol=1e-7)
    stl = trimesh.load(tmp_path / "m.stl", force="mesh")  # the other formats keep z-up millimetres
    np.testing.assert_allclose(stl.bounds, [folded.min(axis=0), folded.max(axis=0)], atol=1e-4)


def test_relative_output_paths_and_file_mode(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, _, err = run(capsys, "design", ROOT / "jobs" / "hexagon-fig8b.toml", "--fold", "a.fold", "--cp", "a.cp")
    assert rc == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.cp", "a.fold"]  # no stray .part file
    for name in ("a.cp", "a.fold"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~umask()


def test_overwrites_an_existing_output(capsys, tmp_path):
    target = tmp_path / "x.fold"
    target.write_text("old")
    rc, _, _ = run(capsys, "design", ROOT / "jobs" / "star.toml", "--fold", target)
    assert rc == 0
    check_fold(json.loads(target.read_text(encoding="utf-8")))


def test_job_with_relative_svg_from_another_folder(capsys, tmp_path, monkeypatch):
    (tmp_path / "jobs").mkdir()
    (tmp_path / "jobs" / "p.svg").write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="10mm" height="40mm" viewBox="0 0 10 40">'
        '<path id="p" d="M 0 40 L 6 30 L 0 20 L 6 10"/></svg>')
    job = write_job(tmp_path / "jobs", """\
        [profile]
        svg = "p.svg"
        path = "p"
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    rc, out, err = run(capsys, "design", Path("../jobs/job.toml"), "--json")
    assert rc == 0, err
    assert json.loads(out)["line_elements"] == 4
    rc, out, err = run(capsys, "design", job, "--json")
    assert rc == 0 and json.loads(out)["line_elements"] == 4


# --------------------------------------------------------------------------- penetration

PENETRATING = """\
    [profile]
    points = [[0, 0], [6, 10], [6, 0], [0, 10]]
    [trajectory]
    template = "regular"
    corners = 6
    radius = 40
    """


def named_face_pairs(message: str) -> list[tuple[int, int]]:
    """(profile segment, profile segment) of every face pair a penetration message names."""
    pairs = re.findall(r"face \d+ \(profile segment (\d+), trajectory segment \d+\) and "
                       r"face \d+ \(profile segment (\d+), trajectory segment \d+\)", message)
    return [(int(a), int(b)) for a, b in pairs]


def test_penetration_is_an_error(capsys, tmp_path):
    job = write_job(tmp_path / "jobs", PENETRATING)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    args, _ = outputs(out_dir)
    line = assert_one_line_error(*run(capsys, "design", job, *args), str(job), "penetration", "--allow-penetration")
    # The self-crossing profile's segments 0 and 2 cross at (3, 5): those strips meet everywhere.
    pairs = named_face_pairs(line)
    assert pairs and all(sorted(p) == [0, 2] for p in pairs)
    no_files_left(out_dir)


def test_allow_penetration_builds_with_a_warning(capsys, tmp_path):
    job = write_job(tmp_path / "jobs", PENETRATING)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    args, paths = outputs(out_dir)
    rc, out, err = run(capsys, "design", job, *args, "--allow-penetration", "--json")
    assert rc == 0
    warnings = err.splitlines()
    assert len(warnings) == 1 and warnings[0].startswith("foldfab: warning: penetration")
    assert named_face_pairs(warnings[0])
    info = json.loads(out)
    assert info["penetrations"] > 0
    assert len(info["warnings"]) == 1 and "face" in info["warnings"][0]
    check_fold(json.loads(paths["fold"].read_text(encoding="utf-8")))
    assert all(p.exists() for p in paths.values())
    rc, text, _ = run(capsys, "design", job, "--allow-penetration")
    assert rc == 0 and re.search(rf"^penetrations {info['penetrations']}$", text, re.M)


def test_same_profile_without_the_crossing_builds(capsys, tmp_path):
    job = write_job(tmp_path, PENETRATING.replace("[6, 0], [0, 10]", "[0, 20], [6, 30]"))
    rc, out, err = run(capsys, "design", job)
    assert rc == 0 and err == "" and re.search(r"^penetrations 0$", out, re.M)


# --------------------------------------------------------------------------- errors from the job

HEXAGON_CORNER_START = ("[[40, 0], [20, 34.64101615137754], [-20, 34.64101615137754], [-40, 0], "
                        "[-20, -34.64101615137754], [20, -34.64101615137754], [40, 0]]")
SHAPE_SVG = ('<svg xmlns="http://www.w3.org/2000/svg" width="10mm" height="40mm" viewBox="0 0 10 40">'
             '<path id="wave" d="M 0 40 L 6 30 L 0 20"/><path id="dot" d="M 5 5 L 5 5"/>'
             '<path id="split" d="M 0 40 L 6 30 M 0 20 L 6 10"/></svg>')

# name: (job text, fragments the one-line message must contain)
JOB_ERRORS = {
    "odd corners": ("""\
        [profile]
        points = [[0, 0], [6, 10], [0, 20]]
        [trajectory]
        template = "regular"
        corners = 5
        radius = 40
        """, ["even number of corners", "has 5"]),
    "negative length between two mirrors": (f"""\
        [profile]
        points = [[0, 0], [20, 10], [0, 20]]
        [trajectory]
        template = "polyline"
        points = {HEXAGON_CORNER_START}
        """, ["line element 1", "meets the mirror at trajectory point 1", "before the seam mirror at trajectory point 0",
              "reduce u of profile point 1", "[profile].offset[0]", "at most 11.55 mm"]),
    "negative length from the offset": ("""\
        [profile]
        points = [[0, 0], [6, 10], [0, 20]]
        offset = [14, 0]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["line element ", "meets the mirror at trajectory point", "reduce u of profile point",
              "[profile].offset[0]"]),
    "negative length inwards": ("""\
        [profile]
        points = [[0, 0], [-20, 10], [0, 20]]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["line element 1", "meets the mirror at trajectory point 2", "before the mirror at trajectory point 1",
              "increase u of profile point 1", "at least -11.55 mm"]),
    "fewer than two profile points": ("""\
        [profile]
        points = [[0, 0]]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["[profile].points", "at least 2 points, got 1"]),
    "fewer than two trajectory points": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        [trajectory]
        template = "polyline"
        points = [[0, 0]]
        """, ["[trajectory].points", "at least 2 points"]),
    "fewer than two points from SVG": ("""\
        [profile]
        svg = "shape.svg"
        path = "dot"
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["profile", "at least 2 points, got 1"]),
    "repeated profile points": ("""\
        [profile]
        points = [[0, 0], [6, 10], [6, 10], [0, 20]]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["profile", "points 1 and 2 are the same point", "remove the repeated point"]),
    "repeated trajectory points": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        [trajectory]
        template = "polyline"
        points = [[0, 0], [40, 20], [40, 20], [80, 0]]
        """, ["trajectory", "points 1 and 2 are the same point"]),
    "nan in profile": ("""\
        [profile]
        points = [[0, 0], [nan, 10]]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["[profile].points[1]", "finite"]),
    "inf radius": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        [trajectory]
        template = "regular"
        corners = 6
        radius = inf
        """, ["[trajectory].radius", "finite"]),
    "-inf offset": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        offset = [-inf, 0]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["[profile].offset", "finite"]),
    "unknown key": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        radus = 3
        """, ["[trajectory].radus: unknown key"]),
    "unknown table": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        [crease_pattern]
        flat_angle = 2
        """, ["[crease_pattern]: unknown table"]),
    "missing key": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        [trajectory]
        template = "regular"
        corners = 6
        """, ["[trajectory].radius: missing"]),
    "missing table": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        """, ["[trajectory]: missing table"]),
    "wrong type": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        [trajectory]
        template = "regular"
        corners = "six"
        radius = 40
        """, ["[trajectory].corners: expected a whole number"]),
    "out of range": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        [crease]
        flat_angle = 270
        """, ["[crease].flat_angle: must be at most 180"]),
    "invalid TOML": ("""\
        [profile]
        points = [[0, 0], [6, 10]
        """, ["not valid TOML"]),
    "glue tab on an open trajectory": ("""\
        [profile]
        points = [[0, 0], [6, 10]]
        [trajectory]
        template = "polyline"
        points = [[0, 0], [40, 20], [80, 0]]
        [crease]
        glue_tab = 5
        """, ["[crease].glue_tab", "open"]),
    "SVG id not found": ("""\
        [profile]
        svg = "shape.svg"
        path = "profile"
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["[profile].svg", "no path with id 'profile'", "wave, dot, split"]),
    "SVG index out of range": ("""\
        [profile]
        svg = "shape.svg"
        path = 3
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["[profile].svg", "path index 3 out of range", "3 drawable path"]),
    "SVG path with subpaths": ("""\
        [profile]
        svg = "shape.svg"
        path = "split"
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["[profile].svg", "subpaths"]),
    "SVG file missing": ("""\
        [profile]
        svg = "missing.svg"
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """, ["[profile].svg: file not found"]),
}


@pytest.mark.parametrize("name", JOB_ERRORS)
def test_job_errors(capsys, tmp_path, name):
    text, fragments = JOB_ERRORS[name]
    folder = tmp_path / "jobs"
    job = write_job(folder, text)
    (folder / "shape.svg").write_text(SHAPE_SVG, encoding="utf-8")
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    args, _ = outputs(out_dir, mesh="out.glb")
    line = assert_one_line_error(*run(capsys, "design", job, *args), *fragments)
    assert line.startswith(f"foldfab: error: {job}: ")
    no_files_left(out_dir)


def test_error_keeps_an_existing_output_untouched(capsys, tmp_path):
    job = write_job(tmp_path / "jobs", JOB_ERRORS["odd corners"][0])
    target = tmp_path / "out.fold"
    target.write_text("previous design")
    assert_one_line_error(*run(capsys, "design", job, "--fold", target), "even number of corners")
    assert target.read_text() == "previous design"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["jobs", "out.fold"]


# --------------------------------------------------------------------------- errors from the command line

def test_missing_job_file(capsys, tmp_path):
    args, _ = outputs(tmp_path)
    assert_one_line_error(*run(capsys, "design", tmp_path / "nope.toml", *args), "nope.toml", "job file not found")
    no_files_left(tmp_path)


@pytest.mark.parametrize("name", ["out.dxf", "out", "out.stl.bak"])
def test_bad_mesh_extension(capsys, tmp_path, name):
    rc, out, err = run(capsys, "design", ROOT / "jobs" / "star.toml", "--fold", tmp_path / "a.fold",
                       "--mesh", tmp_path / name)
    assert_one_line_error(rc, out, err, "--mesh", "unknown mesh format", ".stl, .obj, .ply, .glb")
    no_files_left(tmp_path)


@pytest.mark.parametrize("kind", ["fold", "svg", "cp", "mesh"])
def test_output_folder_missing(capsys, tmp_path, kind):
    args, paths = outputs(tmp_path)
    missing = tmp_path / "no" / "such"
    i = args.index(f"--{kind}")
    args[i + 1] = str(missing / paths[kind].name)
    line = assert_one_line_error(*run(capsys, "design", ROOT / "jobs" / "star.toml", *args), f"--{kind}", "does not exist")
    assert str(missing) in line
    no_files_left(tmp_path)


def test_output_path_is_a_folder(capsys, tmp_path):
    # The first files are written before the third fails: none of them may stay.
    (tmp_path / "taken.cp").mkdir()
    rc, out, err = run(capsys, "design", ROOT / "jobs" / "star.toml", "--fold", tmp_path / "a.fold",
                       "--svg", tmp_path / "a.svg", "--cp", tmp_path / "taken.cp")
    assert_one_line_error(rc, out, err, "--cp", "taken.cp", "is a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.cp"]
    assert list((tmp_path / "taken.cp").iterdir()) == []


def test_a_failed_write_keeps_the_files_that_were_there(capsys, tmp_path):
    # Outputs that existed before stay as they were, not replaced and then deleted.
    (tmp_path / "keep.fold").write_text("previous fold")
    (tmp_path / "keep.cp").write_text("previous cp")
    (tmp_path / "full.svg").symlink_to("/dev/full")  # a device, written in place: no room on it
    rc, out, err = run(capsys, "design", ROOT / "jobs" / "star.toml", "--fold", tmp_path / "keep.fold",
                       "--svg", tmp_path / "full.svg", "--cp", tmp_path / "keep.cp")
    assert_one_line_error(rc, out, err, "--svg", "full.svg", "cannot write: No space left on device")
    assert (tmp_path / "keep.fold").read_text() == "previous fold"
    assert (tmp_path / "keep.cp").read_text() == "previous cp"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full.svg", "keep.cp", "keep.fold"]


# --------------------------------------------------------------------------- a real process

def test_real_process_error(tmp_path):
    job = write_job(tmp_path, JOB_ERRORS["odd corners"][0])
    result = subprocess.run([sys.executable, "-m", "foldfab", "design", str(job), "--fold", str(tmp_path / "x.fold")],
                            capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert result.returncode == 2
    assert result.stdout == ""
    assert "Traceback" not in result.stderr
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("foldfab: error: ")
    assert "even number of corners" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["job.toml"]


def test_real_process_write_error(tmp_path):
    (tmp_path / "dir.svg").mkdir()
    result = subprocess.run([sys.executable, "-m", "foldfab", "design", str(ROOT / "jobs" / "star.toml"),
                             "--fold", "a.fold", "--svg", "dir.svg"],
                            capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr and result.stderr.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.svg"]


def test_real_process_success(tmp_path):
    result = subprocess.run([sys.executable, "-m", "foldfab", "design", str(ROOT / "jobs" / "hexagon-fig8a.toml"),
                             "--fold", "h.fold", "--json"],
                            capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    info = json.loads(result.stdout)
    assert info["written"] == ["h.fold"] and info["corners"] == 6
    check_fold(json.loads((tmp_path / "h.fold").read_text(encoding="utf-8")))


@settings(max_examples=60, deadline=None)
@given(shortest=st.floats(1e-6, 1e3), count=st.integers(2, 12), seed=st.integers(0, 2**16))
def test_svg_user_unit_keeps_every_vertex_apart_on_import(shortest, count, seed):
    """The SVG's user unit puts the closest two distinct vertices at least 10 units apart (Origami
    Simulator merges under 3) and is the coarsest power of ten up to 0.1 mm that does."""
    from foldfab.formats.svg import user_unit

    rng = np.random.default_rng(seed)
    points = np.concatenate([[[0.0, 0.0], [shortest, 0.0]], rng.uniform(2 * shortest, 3 * shortest + 100, (count, 2))])
    gaps = np.linalg.norm(points[:, None] - points[None], axis=-1) + np.eye(len(points)) * 1e18
    unit = user_unit(np.concatenate([points, points[:1]]))  # a repeated vertex is one vertex
    exponent = np.log10(unit)
    assert unit <= 0.1 and exponent == pytest.approx(round(exponent))
    assert gaps.min() / unit >= 10 * (1 - 1e-12)
    assert unit == 0.1 or gaps.min() / (10 * unit) < 10
