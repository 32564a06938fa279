"""Job files: every key is checked, every error names the file and the key, paths resolve by the job."""

from __future__ import annotations

import datetime
import json
import math
import textwrap
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from foldfab.errors import FoldfabError, unknown_key
from foldfab.cli import main
from foldfab.fabrication.spec import job_spec
from foldfab.job import load_job, parse_job
from foldfab.limits import LENGTH_LIMIT
from helpers import JOBS


PROFILE = "[profile]\npoints = [[0, 0], [8, 10], [0, 20]]\n"
REGULAR = '[trajectory]\ntemplate = "regular"\ncorners = 6\nradius = 40\n'
STAR = '[trajectory]\ntemplate = "star"\npoints = 4\nouter_radius = 50\ninner_radius = 30\n'
POLYLINE = '[trajectory]\ntemplate = "polyline"\npoints = [[0, 0], [40, 20], [80, 0]]\n'


def error_of(text: str, path: str = "jobs/x.toml") -> str:
    """What every command says of a job text: the job read, its [fabrication] table checked."""
    with pytest.raises(FoldfabError) as info:
        job_spec(parse_job(textwrap.dedent(text), path))
    message = str(info.value)
    assert "\n" not in message, "an error is one line"
    assert message.startswith(f"{path}: "), "an error names the job file first"
    return message


# --------------------------------------------------------------------------- valid jobs

@pytest.mark.parametrize("path", JOBS, ids=[p.stem for p in JOBS])
def test_example_jobs_load(path):
    job = load_job(path)
    assert job.path == path
    assert job.name
    assert (job.profile.points is None) != (job.profile.svg is None)
    assert job.text == path.read_text(encoding="utf-8")


def test_defaults():
    job = parse_job(PROFILE + REGULAR, "some/folder/hexagon.toml")
    assert job.name == "hexagon"  # the file's stem
    assert job.profile.points == ((0.0, 0.0), (8.0, 10.0), (0.0, 20.0))
    assert job.profile.offset == (0.0, 0.0)
    assert job.trajectory.template == "regular"
    assert job.trajectory.params == {"corners": 6, "radius": 40.0}
    assert job.crease.flat_angle == 1.0 and job.crease.glue_tab == 0.0
    assert job.fabrication == {}


def test_every_key():
    job = parse_job(textwrap.dedent("""\
        [design]
        name = "full"
        [profile]
        points = [[0, 0], [3.5, 8], [0, 16]]
        offset = [-1.5, 2]
        [trajectory]
        template = "star"
        points = 5
        outer_radius = 50.5
        inner_radius = 30
        [crease]
        flat_angle = 0
        glue_tab = 4.25
        """), "j.toml")
    assert job.name == "full"
    assert job.profile.offset == (-1.5, 2.0)
    assert job.trajectory.params == {"points": 5, "outer_radius": 50.5, "inner_radius": 30.0}
    assert job.crease.flat_angle == 0.0 and job.crease.glue_tab == 4.25


def test_polyline_trajectory_2d_and_3d():
    job = parse_job(PROFILE + POLYLINE)
    assert job.trajectory.points == ((0.0, 0.0), (40.0, 20.0), (80.0, 0.0))
    job = parse_job(PROFILE + '[trajectory]\ntemplate = "polyline"\npoints = [[0, 0, 0], [10, 0, 5]]\n')
    assert job.trajectory.points == ((0.0, 0.0, 0.0), (10.0, 0.0, 5.0))


# --------------------------------------------------------------------------- tables

def test_unknown_table():
    message = error_of(PROFILE + REGULAR + "[creases]\nflat_angle = 2\n")
    assert "[creases]: unknown table" in message and "[crease]" in message


@pytest.mark.parametrize("missing, text", [("profile", REGULAR), ("trajectory", PROFILE)])
def test_missing_table(missing, text):
    assert f"[{missing}]: missing table" in error_of(text)


@pytest.mark.parametrize("table, text", [
    ("design", 'design = "x"\n' + PROFILE + REGULAR),
    ("profile", "profile = 5\n" + REGULAR),
    ("trajectory", 'trajectory = ["regular"]\n' + PROFILE),
    ("crease", "crease = 1.0\n" + PROFILE + REGULAR),
    ("fabrication", "fabrication = true\n" + PROFILE + REGULAR),
])
def test_table_that_is_not_a_table(table, text):
    message = error_of(text)
    assert f"[{table}]" in message and "expected a table" in message


# --------------------------------------------------------------------------- keys

@pytest.mark.parametrize("text, key", [
    ("[design]\nname = 'a'\ntitle = 'b'\n" + PROFILE + REGULAR, "[design].title"),
    (PROFILE + "offest = [0, 1]\n" + REGULAR, "[profile].offest"),
    (PROFILE + REGULAR + "radus = 4\n", "[trajectory].radus"),
    (PROFILE + REGULAR + "points = [[0, 0], [1, 1]]\n", "[trajectory].points"),  # not a key of "regular"
    (PROFILE + STAR + "radius = 4\n", "[trajectory].radius"),
    (PROFILE + POLYLINE + "corners = 4\n", "[trajectory].corners"),
    (PROFILE + REGULAR + "[crease]\nflat_angel = 2\n", "[crease].flat_angel"),
])
def test_unknown_key(text, key):
    message = error_of(text)
    assert f"{key}: unknown key" in message
    assert "expected one of" in message


@pytest.mark.parametrize("text, key", [
    (PROFILE + '[trajectory]\ncorners = 6\nradius = 40\n', "[trajectory].template"),
    (PROFILE + '[trajectory]\ntemplate = "regular"\nradius = 40\n', "[trajectory].corners"),
    (PROFILE + '[trajectory]\ntemplate = "regular"\ncorners = 6\n', "[trajectory].radius"),
    (PROFILE + '[trajectory]\ntemplate = "star"\nouter_radius = 5\ninner_radius = 3\n', "[trajectory].points"),
    (PROFILE + '[trajectory]\ntemplate = "star"\npoints = 5\ninner_radius = 3\n', "[trajectory].outer_radius"),
    (PROFILE + '[trajectory]\ntemplate = "star"\npoints = 5\nouter_radius = 3\n', "[trajectory].inner_radius"),
    (PROFILE + '[trajectory]\ntemplate = "polyline"\n', "[trajectory].points"),
])
def test_missing_key(text, key):
    assert f"{key}: missing" in error_of(text)


def test_profile_needs_points_or_svg_exactly():
    assert "[profile]: give either points" in error_of("[profile]\noffset = [0, 1]\n" + REGULAR)
    assert "[profile]: give either points" in error_of(PROFILE + 'svg = "a.svg"\n' + REGULAR)


# (job text with {value} in place of the tested value, key named by the error)
TYPED = {
    "name": ("[design]\nname = {value}\n" + PROFILE + REGULAR, "[design].name"),
    "template": (PROFILE + "[trajectory]\ntemplate = {value}\ncorners = 6\nradius = 40\n", "[trajectory].template"),
    "corners": (PROFILE + '[trajectory]\ntemplate = "regular"\ncorners = {value}\nradius = 40\n', "[trajectory].corners"),
    "radius": (PROFILE + '[trajectory]\ntemplate = "regular"\ncorners = 6\nradius = {value}\n', "[trajectory].radius"),
    "star points": (PROFILE + '[trajectory]\ntemplate = "star"\npoints = {value}\nouter_radius = 5\ninner_radius = 3\n',
                    "[trajectory].points"),
    "outer_radius": (PROFILE + '[trajectory]\ntemplate = "star"\npoints = 5\nouter_radius = {value}\ninner_radius = 3\n',
                     "[trajectory].outer_radius"),
    "inner_radius": (PROFILE + '[trajectory]\ntemplate = "star"\npoints = 5\nouter_radius = 5\ninner_radius = {value}\n',
                     "[trajectory].inner_radius"),
    "profile points": ("[profile]\npoints = {value}\n" + REGULAR, "[profile].points"),
    "trajectory points": (PROFILE + '[trajectory]\ntemplate = "polyline"\npoints = {value}\n', "[trajectory].points"),
    "offset": (PROFILE + "offset = {value}\n" + REGULAR, "[profile].offset"),
    "flat_angle": (PROFILE + REGULAR + "[crease]\nflat_angle = {value}\n", "[crease].flat_angle"),
    "glue_tab": (PROFILE + REGULAR + "[crease]\nglue_tab = {value}\n", "[crease].glue_tab"),
}


@pytest.mark.parametrize("name, value, expected", [
    ("name", "3", "expected a string"),
    ("template", "6", "expected a string"),
    ("template", '"hexagon"', "expected one of 'regular', 'star', 'polyline'"),
    ("corners", "6.0", "expected a whole number"),
    ("corners", '"6"', "expected a whole number"),
    ("corners", "true", "expected a whole number"),
    ("radius", '"40mm"', "expected a number"),
    ("radius", "false", "expected a number"),
    ("radius", "[40]", "expected a number"),
    ("star points", "4.5", "expected a whole number"),
    ("outer_radius", "{ r = 5 }", "expected a number"),
    ("profile points", '"0,0 8,10"', "expected a list of points"),
    ("profile points", "[[0, 0], [8, 10, 3]]", "[profile].points[1]: expected a point [u, v]"),
    ("profile points", "[[0, 0], [8, true]]", "[profile].points[1]: expected a point"),
    ("profile points", '[[0, 0], ["8", 10]]', "[profile].points[1]: expected a point"),
    ("profile points", "[[0, 0], 5]", "[profile].points[1]: expected a point"),
    ("trajectory points", "[[0, 0], [1, 1, 1]]", "[trajectory].points[1]: has 3 coordinates but point 0 has 2"),
    ("trajectory points", "[[0], [1]]", "[trajectory].points[0]: expected a point [x, y] or [x, y, z]"),
    ("offset", "[1]", "expected a pair"),
    ("offset", "[1, 2, 3]", "expected a pair"),
    ("offset", '["a", 2]', "expected a pair"),
    ("offset", "4", "expected a pair"),
    ("flat_angle", '"1"', "expected a number"),
    ("glue_tab", "[]", "expected a number"),
    ("glue_tab", "1979-05-27", "expected a number"),
])
def test_wrong_type(name, value, expected):
    template, key = TYPED[name]
    message = error_of(template.format(value=value))
    assert key in message and expected in message


@pytest.mark.parametrize("name, value, expected", [
    ("corners", "2", "must be at least 3, got 2"),
    ("corners", "-6", "must be at least 3"),
    ("corners", "100001", "must be at most 100000"),
    ("radius", "0", "must be greater than 0"),
    ("radius", "-40", "must be greater than 0"),
    ("star points", "1", "must be at least 2"),
    ("outer_radius", "0.0", "must be greater than 0"),
    ("inner_radius", "-3", "must be greater than 0"),
    ("inner_radius", "5", "must differ from outer_radius"),
    ("flat_angle", "-0.5", "must be at least 0"),
    ("flat_angle", "180.5", "must be at most 180"),
    ("glue_tab", "-1", "must be at least 0"),
    ("profile points", "[[0, 0]]", "expected at least 2 points, got 1"),
    ("profile points", "[]", "expected at least 2 points, got 0"),
    ("trajectory points", "[[3, 4]]", "expected at least 2 points, got 1"),
])
def test_out_of_range(name, value, expected):
    template, key = TYPED[name]
    message = error_of(template.format(value=value))
    assert key in message and expected in message


@pytest.mark.parametrize("name, value, key", [
    ("radius", "inf", "[trajectory].radius"),
    ("radius", "nan", "[trajectory].radius"),
    ("outer_radius", "+inf", "[trajectory].outer_radius"),
    ("flat_angle", "nan", "[crease].flat_angle"),
    ("glue_tab", "inf", "[crease].glue_tab"),
    ("profile points", "[[0, 0], [nan, 10]]", "[profile].points[1]"),
    ("profile points", "[[-inf, 0], [1, 10]]", "[profile].points[0]"),
    ("trajectory points", "[[0, 0, 0], [1, 1, inf]]", "[trajectory].points[1]"),
    ("offset", "[nan, 0]", "[profile].offset"),
    ("offset", "[0, -inf]", "[profile].offset"),
])
def test_non_finite_numbers(name, value, key):
    template, _ = TYPED[name]
    message = error_of(template.format(value=value))
    assert key in message and "finite" in message


HUGE = "1" + "0" * 400  # TOML's reader takes it; no float holds it


@pytest.mark.parametrize("name, value, key, expected", [
    ("radius", HUGE, "[trajectory].radius", "expected a finite number of a sensible size, got 1000"),
    ("radius", "1e12", "[trajectory].radius", "must be at most 1000000, got 1e+12"),
    ("outer_radius", "1000000.5", "[trajectory].outer_radius", "must be at most 1000000, got 1000000.5"),
    ("glue_tab", "2e6", "[crease].glue_tab", "must be at most 1000000"),
    ("profile points", f"[[0, 0], [-{HUGE}, 10]]", "[profile].points[1]", "within ±1,000,000 mm, got [-1000"),
    ("profile points", "[[0, 0], [1e200, 10]]", "[profile].points[1]", "within ±1,000,000 mm, got [1e+200, 10]"),
    ("trajectory points", "[[0, 0], [0, 1000001]]", "[trajectory].points[1]", "within ±1,000,000 mm"),
    ("offset", f"[{HUGE}, 0]", "[profile].offset", "within ±1,000,000 mm, got [1000"),
])
def test_lengths_beyond_a_kilometre(name, value, key, expected):
    template, _ = TYPED[name]
    message = error_of(template.format(value=value))
    assert message.startswith(f"jobs/x.toml: {key}:") and expected in message
    assert len(message) < 300  # a 400-digit number is cut short
    if name in ("radius", "outer_radius", "glue_tab"):  # the limit itself is allowed
        parse_job(template.format(value="1e6"), "jobs/x.toml")


def test_svg_trajectory_only_as_polyline(tmp_path):
    (tmp_path / "t.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0 L 9 9"/></svg>')
    job = tmp_path / "j.toml"
    job.write_text(PROFILE + '[trajectory]\ntemplate = "regular"\nsvg = "t.svg"\n')
    with pytest.raises(FoldfabError, match=r"\[trajectory\]\.template: expected one of 'polyline'"):
        load_job(job)


# --------------------------------------------------------------------------- the file itself

def test_invalid_toml():
    message = error_of(PROFILE + "[trajectory\n")
    assert "not valid TOML" in message and "line" in message


def test_duplicate_key_is_invalid_toml():
    assert "not valid TOML" in error_of(PROFILE + REGULAR + "radius = 50\n")


def test_a_byte_order_mark_is_read_past(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + (PROFILE + REGULAR).encode())
    assert load_job(path).trajectory.params == {"corners": 6, "radius": 40.0}


@pytest.mark.parametrize("table, expected", [
    ("[fabrication]\nbogus = 1\n", "[fabrication].bogus: unknown key"),
    ("[fabrication]\nstrategy = 5\n", "[fabrication].strategy: expected a string"),
    ("[fabrication.perforate]\nvalley = [1]\n", "[fabrication.perforate].valley: expected an even-length list"),
])
def test_a_mistake_in_the_fabrication_table_is_the_jobs(table, expected, tmp_path, capsys):
    # Every command that reads the job refuses it, not only the ones that fabricate: the job stage
    # reads the table, the fabrication stage (which owns it) checks it, and `foldfab design` asks it.
    assert expected in error_of(PROFILE + REGULAR + table)
    path = tmp_path / "x.toml"
    path.write_text(PROFILE + REGULAR + table)
    assert main(["design", str(path)]) == 2
    assert f"{path}: {expected}" in capsys.readouterr().err


def test_missing_job_file(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(FoldfabError, match="job file not found") as info:
        load_job(path)
    assert str(path) in str(info.value)


def test_unreadable_job_file(tmp_path):
    path = tmp_path / "binary.toml"
    path.write_bytes(b"\xff\xfe\x00 not utf-8")
    with pytest.raises(FoldfabError, match="not UTF-8 text|is a folder, not a job file"):
        load_job(path)
    with pytest.raises(FoldfabError, match="not UTF-8 text|is a folder, not a job file"):
        load_job(tmp_path)  # a folder


# --------------------------------------------------------------------------- relative paths

def test_relative_paths_resolve_against_the_job_folder(tmp_path, monkeypatch):
    folder = tmp_path / "a" / "b"
    folder.mkdir(parents=True)
    (folder / "p.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0 L 9 9"/></svg>')
    (tmp_path / "a" / "t.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0 L 9 9"/></svg>')
    job = folder / "job.toml"
    job.write_text('[profile]\nsvg = "p.svg"\n[trajectory]\nsvg = "../t.svg"\npath = 0\n')
    monkeypatch.chdir(tmp_path)
    for given_path in (job, Path("a/b/job.toml")):
        loaded = load_job(given_path)
        assert loaded.profile.svg.file == (folder / "p.svg").resolve()
        assert loaded.trajectory.svg.file == (tmp_path / "a" / "t.svg").resolve()
    # the working folder does not matter, and a file there of the same name is not picked up
    (tmp_path / "p.svg").write_text("decoy")
    other = tmp_path / "other"
    other.mkdir()
    monkeypatch.chdir(other)
    assert load_job(job).profile.svg.file == (folder / "p.svg").resolve()
    # an absolute path is kept
    job.write_text(f'[profile]\nsvg = {json.dumps(str(tmp_path / "p.svg"))}\n' + REGULAR)
    assert load_job(job).profile.svg.file == (tmp_path / "p.svg").resolve()


def test_missing_svg_names_key_and_resolved_path(tmp_path, monkeypatch):
    folder = tmp_path / "jobs"
    folder.mkdir()
    (tmp_path / "shape.svg").write_text("<svg/>")  # beside the working folder, not the job
    job = folder / "job.toml"
    job.write_text('[profile]\nsvg = "shape.svg"\n' + REGULAR)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(FoldfabError) as info:
        load_job(job)
    message = str(info.value)
    assert "[profile].svg: file not found" in message and str((folder / "shape.svg").resolve()) in message


# --------------------------------------------------------------------------- property tests

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
positive = st.floats(1e-6, 1e6, allow_nan=False, allow_infinity=False)


def toml_string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    out = []
    for c in text:
        if c in '"\\':
            out.append("\\" + c)
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\u{ord(c):04X}")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'


def toml_float(x: float) -> str:
    text = repr(float(x))
    return text if any(c in text for c in ".en") else text + ".0"


@settings(max_examples=150, deadline=None)
@given(points=st.lists(st.tuples(finite, finite), min_size=2, max_size=8),
       offset=st.tuples(finite, finite), corners=st.integers(3, 100000), radius=positive,
       flat_angle=st.floats(0, 180), glue_tab=st.floats(0, 1e6), name=st.text(max_size=20))
def test_valid_numbers_round_trip(points, offset, corners, radius, flat_angle, glue_tab, name):
    pts = ", ".join(f"[{toml_float(u)}, {toml_float(v)}]" for u, v in points)
    text = (f"[design]\nname = {toml_string(name)}\n"
            f"[profile]\npoints = [{pts}]\noffset = [{toml_float(offset[0])}, {toml_float(offset[1])}]\n"
            f'[trajectory]\ntemplate = "regular"\ncorners = {corners}\nradius = {toml_float(radius)}\n'
            f"[crease]\nflat_angle = {toml_float(flat_angle)}\nglue_tab = {toml_float(glue_tab)}\n")
    job = parse_job(text, "r.toml")
    assert job.name == name
    assert job.profile.points == tuple((float(u), float(v)) for u, v in points)
    assert job.profile.offset == (float(offset[0]), float(offset[1]))
    assert job.trajectory.params == {"corners": corners, "radius": float(radius)}
    assert job.crease.flat_angle == float(flat_angle) and job.crease.glue_tab == float(glue_tab)


@settings(max_examples=60, deadline=None)
@given(points=st.lists(st.tuples(finite, finite, finite), min_size=2, max_size=6),
       star=st.tuples(st.integers(2, 1000), positive, positive).filter(lambda s: s[1] != s[2]))
def test_3d_polyline_and_star_round_trip(points, star):
    pts = ", ".join("[" + ", ".join(toml_float(c) for c in p) + "]" for p in points)
    job = parse_job(PROFILE + f'[trajectory]\ntemplate = "polyline"\npoints = [{pts}]\n')
    assert job.trajectory.points == tuple(tuple(float(c) for c in p) for p in points)
    n, outer, inner = star
    job = parse_job(PROFILE + f'[trajectory]\ntemplate = "star"\npoints = {n}\n'
                    f"outer_radius = {toml_float(outer)}\ninner_radius = {toml_float(inner)}\n")
    assert job.trajectory.params == {"points": n, "outer_radius": float(outer), "inner_radius": float(inner)}


def toml_value(value) -> str:
    """A TOML literal of ``value`` (strings, booleans, numbers, dates, lists and inline tables)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else toml_float(value)
    if isinstance(value, datetime.date):
        return value.isoformat()
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(value)


text_junk = st.text(st.characters(codec="ascii", exclude_categories=("Cc",)), max_size=8)
scalar_junk = st.one_of(text_junk, st.booleans(), st.dates(),
                        st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6),
                        st.sampled_from([10**400, -10**400, 2**63]))  # TOML's reader takes any whole number
junk = st.one_of(scalar_junk, st.lists(scalar_junk, max_size=3),
                 st.dictionaries(st.sampled_from(["a", "b", "u"]), scalar_junk, max_size=2))


def is_valid(name: str, value) -> bool:
    """Whether ``value`` is a valid setting of the TYPED key ``name`` (then it is not junk)."""
    number = isinstance(value, (int, float)) and not isinstance(value, bool) and abs(value) < math.inf
    integer = isinstance(value, int) and not isinstance(value, bool)
    length = number and value <= LENGTH_LIMIT
    return {
        "name": isinstance(value, str),
        "template": value in ("regular",),
        "corners": integer and 3 <= value <= 100000,
        "radius": length and value > 0,
        "star points": integer and 2 <= value <= 100000,
        "outer_radius": length and value > 0 and value != 3,
        "inner_radius": length and value > 0 and value != 5,
        "profile points": False,  # no junk value is a list of two or more [u, v] pairs
        "trajectory points": False,
        "offset": isinstance(value, list) and len(value) == 2 and all(
            isinstance(c, (int, float)) and not isinstance(c, bool) and abs(c) <= LENGTH_LIMIT for c in value),
        "flat_angle": number and 0 <= value <= 180,
        "glue_tab": length and value >= 0,
    }[name]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(name=st.sampled_from(sorted(TYPED)), value=junk)
def test_junk_values_give_an_error_naming_the_key(name, value):
    # another template name is valid, but then that template's own keys are missing
    assume(not (name == "template" and value in ("star", "polyline")))
    # an outer radius equal to the inner one (3) is the equal-radii error, which names
    # inner_radius (tested with the other star errors)
    assume(not (name == "outer_radius" and type(value) in (int, float) and value == 3))
    template, key = TYPED[name]
    text = template.format(value=toml_value(value))
    if is_valid(name, value):
        parse_job(text, "junk.toml")
        return
    with pytest.raises(FoldfabError) as info:
        parse_job(text, "junk.toml")
    message = str(info.value)
    assert message.startswith(f"junk.toml: {key}"), message
    assert "\n" not in message


@pytest.mark.parametrize("text, key, suggestion", [
    ("[profile]\npionts = [[0, 0], [8, 10]]\n" + REGULAR, "[profile].pionts", "points"),  # issue 18: not "give either"
    (PROFILE + '[trajectory]\ntemplate = "regular"\ncorners = 6\nradus = 40\n', "[trajectory].radus", "radius"),
    (PROFILE + '[trajectory]\ntemplate = "star"\npionts = 4\nouter_radius = 5\ninner_radius = 3\n',
     "[trajectory].pionts", "points"),
    (PROFILE + '[trajectory]\ntempalte = "regular"\ncorners = 6\nradius = 40\n', "[trajectory].tempalte", "template"),
    (PROFILE + REGULAR + "[fabrication]\nsheet = 'A9'\nmargn = 3\n", "[fabrication].margn", "margin"),
    ("[desing]\nname = 'x'\n" + PROFILE + REGULAR, "[desing]", "[design]"),
])
def test_a_misspelt_key_is_named_before_the_key_it_hides(text, key, suggestion):
    """A typo in a required key is reported as the unknown key with the closest known one, not as
    the missing key (or a bad value read before the typo was noticed)."""
    message = error_of(text)
    assert f"{key}: unknown" in message and f"did you mean '{suggestion}'?" in message, message


def test_unknown_key_suggests_only_close_matches():
    assert unknown_key(["points"], ["points", "svg"]) is None
    key, hint = unknown_key(["zzz", "pionts"], ["points", "svg"])
    assert key == "pionts" and hint == "did you mean 'points'? expected one of: points, svg"
    assert unknown_key(["colour"], ["points", "svg"]) == ("colour", "expected one of: points, svg")
