"""Device profiles: the shipped ones, lookup order, schema errors, tools, frames, packaging."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from foldfab.devices import list_devices, load_device, parse_sheet
from foldfab.errors import FoldfabError
from foldfab.devices import Tool
from helpers import ROOT
from helpers.devices import broken

SHIPPED = ["graphtec-ce6000", "grbl", "hp7475a", "roland-gx24"]


def test_shipped_profiles_load():
    assert set(SHIPPED) <= set(list_devices())
    for name in SHIPPED:
        device = load_device(name)
        assert device.name == name and Path(device.source).name == f"{name}.toml"
        assert {"valley", "mountain", "cut"} <= set(device.layers)
    hp, grbl = load_device("hp7475a"), load_device("grbl")
    assert (hp.protocol, hp.dialect, hp.units_per_mm, hp.sheet) == ("hpgl", "hp", 40.0, (297.0, 210.0))
    assert (grbl.protocol, grbl.units_per_mm, grbl.buffer.size, grbl.buffer.flow_control) == \
        ("gcode", 1.0, 128, "grbl")
    assert load_device("graphtec-ce6000").serial.rtscts


def test_device_module_imports_without_numpy_or_vpype():
    code = ("import sys, foldfab.devices as d; d.load_device('grbl'); "
            "assert not {'numpy', 'vpype'} & set(sys.modules), sorted(sys.modules)")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def test_lookup_order_path_user_builtin(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    user = tmp_path / "foldfab" / "devices"
    user.mkdir(parents=True)
    text = Path(load_device("grbl").source).read_text()
    (user / "grbl.toml").write_text(text.replace('model = "', 'model = "mine: '))
    (user / "bench.toml").write_text(text.replace('name = "grbl"', 'name = "bench"'))
    assert load_device("grbl").model.startswith("mine: ")
    assert load_device("bench").name == "bench" and "bench" in list_devices()
    elsewhere = tmp_path / "other.toml"
    elsewhere.write_text(text.replace('model = "', 'model = "path: '))
    assert load_device(str(elsewhere)).model.startswith("path: ")
    assert load_device("hp7475a").source.endswith("hp7475a.toml")  # built-in still found


def test_unknown_device_lists_the_known_ones():
    with pytest.raises(FoldfabError) as error:
        load_device("plotomatic")
    message = str(error.value)
    assert "unknown device 'plotomatic'" in message
    assert all(name in message for name in SHIPPED)
    with pytest.raises(FoldfabError, match="no such device profile file"):
        load_device("missing/profile.toml")


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace('protocol = "gcode"\n', ""), ["missing key 'protocol'", "add it"]),
    (lambda t: t.replace("baudrate = 115200", 'baudrate = "fast"'),
     ["key 'serial.baudrate'", "expected a baud rate", "'fast'"]),
    (lambda t: t.replace("[serial]", "colour = \"red\"\n[serial]"),
     ["unknown key 'colour'", "remove it"]),
    (lambda t: t.replace("speed = 15", "speed = 15\nsped = 3"), ["unknown key 'layers.cut.sped'"]),
    (lambda t: t.replace("[layers.cut]", "[layers.cut_]"), ["missing table '[layers.cut]'"]),
    (lambda t: t.replace('origin = "bottom-left"', 'origin = "top-left"'),
     ["key 'origin'", "'bottom-left'"]),
    (lambda t: t.replace('y_axis = "up"', 'y_axis = "left"'), ["key 'y_axis'", "perpendicular"]),
    (lambda t: t.replace("pen_down = -1.0", 'pen_down = "M3 S20"'),
     ["key 'layers.cut.pen_down'", "same kind as gcode.pen_up"]),
    (lambda t: t.replace("pen_down = -1.0", "pen_down = 4"), ["key 'layers.cut.pen_down'"]),
    (lambda t: t.replace("speed = 15", "speed = 15\nforce = 3"), ["key 'layers.cut.force'"]),
    (lambda t: t.replace('flow_control = "grbl"', 'flow_control = "xonxoff"'),
     ["key 'buffer.flow_control'", "serial.xonxoff = true"]),
    (lambda t: t.replace("park = [0, 0]", "park = [400, 0]"), ["key 'motion.park'"]),
    (lambda t: t.replace("axis_limits = true", 'axis_limits = "yes"'),
     ["key 'motion.axis_limits'", "true or false", "'yes'"]),
    (lambda t: t.replace('sheet = "A4"', 'sheet = "B5"'), ["key 'sheet'", "'B5'"]),
    (lambda t: t.replace("z_speed = 10", ""), ["missing key 'gcode.z_speed'"]),
    (lambda t: t + "\n[unused]\nx = 1\n", ["unknown key 'unused'"]),
    # a typo in a required key is named as a typo, with the closest key, not as the key missing
    (lambda t: t.replace("baudrate =", "baudrat ="), ["unknown key 'serial.baudrat'", "did you mean 'baudrate'?"]),
    (lambda t: t.replace("protocol =", "protocl ="), ["unknown key 'protocl'", "did you mean 'protocol'?"]),
    (lambda t: t.replace("draw_speed =", "draw_sped ="), ["unknown key 'motion.draw_sped'", "did you mean 'draw_speed'?"]),
    (lambda t: t.replace("pen_down = -1.0", "pen_dwn = -1.0", 1), ["did you mean 'pen_down'?"]),
    (lambda t: t.replace("name =", "name = [", 1), ["not valid TOML"]),
])
def test_schema_errors_name_file_and_key(tmp_path, edit, words):
    message = broken(tmp_path, edit)
    for word in words:
        assert word in message, message


def test_hpgl_only_and_gcode_only_keys(tmp_path):
    message = broken(tmp_path, lambda t: t.replace('dialect = "grbl"', 'dialect = "grbl"\nunits_per_mm = 40'))
    assert "key 'units_per_mm'" in message and "remove it" in message
    path = tmp_path / "hp.toml"
    path.write_text(Path(load_device("hp7475a").source).read_text() + "\n[gcode]\npen_up = 3\n")
    with pytest.raises(FoldfabError, match=r"key 'gcode'.*no \[gcode\] table in an HPGL profile"):
        load_device(str(path))
    path.write_text(Path(load_device("hp7475a").source).read_text().replace(
        "[layers.valley]", "[layers.valley]\nforce = 20"))
    with pytest.raises(FoldfabError, match="layers.valley.force.*no force"):
        load_device(str(path))


def test_tool_for_merges_and_validates_overrides():
    device = load_device("graphtec-ce6000")
    assert device.tool_for("cut") == Tool(pen=1, force=18.0, speed=100.0, passes=1)
    assert device.tool_for("cut", {"force": 20, "passes": 2}) == Tool(1, 20.0, 100.0, 2)
    for overrides, words in [
        ({"speed": "fast"}, "key 'layers.cut.speed': expected a speed in mm/s > 0, got 'fast'"),
        ({"speed": 25}, "key 'layers.cut.speed': expected a multiple of 10 mm/s"),
        ({"force": 99}, "key 'layers.cut.force': expected a value in [1, 38]"),
        ({"passes": 0}, "key 'layers.cut.passes': expected an integer from 1 to 100"),
        ({"passes": 1000}, "key 'layers.cut.passes': expected an integer from 1 to 100, got 1000"),
        ({"pen": True}, "key 'layers.cut.pen'"),
        ({"depth": 1}, "unknown key 'layers.cut.depth'"),
    ]:
        with pytest.raises(FoldfabError) as error:
            device.tool_for("cut", overrides, source="jobs/box.toml")
        assert str(error.value).startswith("jobs/box.toml: ") and words in str(error.value)
    with pytest.raises(FoldfabError, match=r"no \[layers.score\] table; known layers: valley"):
        device.tool_for("score")


def test_parse_sheet():
    assert parse_sheet("A4") == (210.0, 297.0)
    assert parse_sheet("a3 landscape") == (420.0, 297.0)
    assert parse_sheet("Letter") == (215.9, 279.4)
    assert parse_sheet([100, 50.5]) == (100.0, 50.5)
    assert parse_sheet("A4 portrait") is None and parse_sheet([0, 10]) is None


@pytest.mark.parametrize("name", SHIPPED)
@given(st.lists(st.tuples(st.floats(-500, 500), st.floats(-500, 500)), min_size=1, max_size=20),
       st.sampled_from([(210.0, 297.0), (297.0, 210.0), (420.0, 297.0)]))
def test_frame_round_trip(name, points, sheet):
    frame = load_device(name).frame(sheet)
    points = np.array(points)
    assert np.allclose(frame.to_sheet(frame.to_device(points)), points, atol=1e-9)
    complex_points = points[:, 0] + 1j * points[:, 1]
    assert np.array_equal(frame.to_device(complex_points), frame.to_device(points))


def test_frames_put_the_origin_where_the_profile_says():
    hp = load_device("hp7475a").frame((297.0, 210.0))  # bottom-left, 10 mm right, 4 mm up
    assert hp.to_device(np.array([10 + 206j])).tolist() == [[0.0, 0.0]]
    assert hp.to_device(np.array([20 + 196j])).tolist() == [[400.0, 400.0]]
    cutter = load_device("roland-gx24").frame((210.0, 297.0))  # bottom-right, x up, y left
    assert cutter.to_device(np.array([200 + 287j])).tolist() == [[400.0, 400.0]]
    assert cutter.device_rect_on_sheet(100, 50) == (160.0, 197.0, 210.0, 297.0)


def test_wheel_contains_builtin_profiles_and_every_module(tmp_path):
    """A non-editable build installs devices/ as foldfab/builtin_devices (pyproject package-dir)."""
    source = tmp_path / "src"  # a copy, so that setuptools' build/ stays out of the checkout
    shutil.copytree(ROOT, source, ignore=shutil.ignore_patterns(
        ".*", "__pycache__", "build", "dist", "*.egg-info", "out", "tests", "benchmarks"))
    pip = [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
           "-w", str(tmp_path), str(source)]
    run = subprocess.run(pip, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"building a wheel failed (needs setuptools>=68 from an index): {run.stderr[-400:]}"
    (wheel,) = tmp_path.glob("foldfab-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {f"foldfab/builtin_devices/{n}.toml" for n in SHIPPED} <= names
    assert "foldfab/builtin_devices/README.md" in names
    modules = {p.relative_to(ROOT).as_posix() for p in (ROOT / "foldfab").rglob("*.py")}
    assert modules <= names  # automatic discovery still finds every subpackage


def test_a_profile_that_is_not_utf8_is_a_clear_error(tmp_path):
    path = tmp_path / "latin.toml"
    path.write_bytes(Path(load_device("grbl").source).read_bytes().replace(b'model = "', b'model = "\xff\xfe'))
    with pytest.raises(FoldfabError, match=r"latin\.toml: not UTF-8 text \(invalid start byte at byte \d+\); "
                                           r"save the device profile as UTF-8"):
        load_device(str(path))
    path.write_bytes(b"\xef\xbb\xbf" + Path(load_device("grbl").source).read_bytes())  # a byte-order mark is fine
    assert load_device(str(path)).name == "grbl"


@pytest.mark.parametrize("name", ["hp7475a", "grbl", "graphtec-ce6000"])
def test_a_job_setting_the_device_lacks_is_left_out_with_a_warning(name):
    """A job's [fabrication.layers] describes the creases, not one machine: force on a device
    without a force command is dropped with one line naming the setting and the device."""
    device = load_device(name)
    where = "jobs/box.toml: [fabrication.layers.valley]"
    kept, warnings = device.supported({"force": 18, "speed": 20}, where)
    if device.language.force:
        assert (kept, warnings) == ({"force": 18, "speed": 20}, [])
    else:
        assert kept == {"speed": 20}
        assert warnings == [f"{where}.force = 18 ignored: {name} has no force setting "
                            "(its language has no force command)"]
    kept, warnings = device.supported({"force": "hard"}, where)  # malformed: left for tool_for to refuse
    assert kept == {"force": "hard"} and warnings == []
    with pytest.raises(FoldfabError, match="layers.valley.force': expected a number"):
        device.tool_for("valley", kept, where)


def test_a_tool_can_start_from_another_layer():
    """Perforation dashes start from the cut's settings (G-code: its depth too)."""
    graphtec = load_device("graphtec-ce6000")
    assert graphtec.tool_for("valley", like="cut") == graphtec.tool_for("cut")
    assert graphtec.tool_for("valley", {"speed": 20}, like="cut") == Tool(1, 18.0, 20.0, 1)
    grbl = load_device("grbl")
    assert grbl.tool_for("valley", like="cut").pen_down == grbl.layers["cut"].pen_down == -1.0
    assert grbl.tool_for("valley").pen_down is None  # its own layer's depth
