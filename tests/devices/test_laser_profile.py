"""Laser profiles (``[gcode] tool = "laser"``): power per layer, GRBL's $30/$31, no Z or servo keys."""

from __future__ import annotations

import pytest

from foldfab.devices import Tool, list_devices, load_device
from foldfab.errors import FoldfabError
from helpers.devices import broken


def test_the_grbl_laser_profile_loads():
    assert "grbl-laser" in list_devices()
    laser = load_device("grbl-laser")
    assert laser.laser and not load_device("grbl").laser
    assert (laser.gcode.tool, laser.gcode.spindle_max, laser.gcode.spindle_min) == ("laser", 1000.0, 0.0)
    assert laser.gcode.pen_up is None and laser.gcode.z_speed is None
    assert laser.tool_for("cut") == Tool(pen=1, force=None, speed=10.0, passes=1, power=0.6)
    assert laser.tool_for("valley").power == 0.15
    assert all(layer.pen_down is None for layer in laser.layers.values())


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace('tool = "laser"', 'tool = "laser"\npen_up = 3.0'),
     ["key 'gcode.pen_up'", "no pen_up for a laser", "remove it"]),
    (lambda t: t.replace('tool = "laser"', 'tool = "laser"\nz_speed = 10'), ["key 'gcode.z_speed'", "remove it"]),
    (lambda t: t.replace("power = 0.6", 'power = 0.6\npen_down = "M3 S20"'),
     ["key 'layers.cut.pen_down'", "no pen_down for a laser"]),
    (lambda t: t.replace("power = 0.6", "power = 0.6\npen_down = -1"), ["key 'layers.cut.pen_down'"]),
    (lambda t: t.replace("power = 0.6", ""), ["missing key 'layers.cut.power'", "$30"]),
    (lambda t: t.replace("power = 0.6", "power = 1.5"), ["key 'layers.cut.power'", "at most 1", "1.5"]),
    (lambda t: t.replace("power = 0.6", "power = 0"), ["key 'layers.cut.power'"]),
    (lambda t: t.replace("power = 0.6", 'power = "high"'), ["key 'layers.cut.power'"]),
    (lambda t: t.replace("spindle_max = 1000", ""), ["missing key 'gcode.spindle_max'", "$30"]),
    (lambda t: t.replace("spindle_min = 0", "spindle_min = 1000"), ["key 'gcode.spindle_min'", "below spindle_max"]),
    (lambda t: t.replace("power = 0.6", "power = 0.6\nforce = 3"), ["key 'layers.cut.force'", "no force"]),
    (lambda t: t.replace('tool = "laser"', 'tool = "lazer"'), ["key 'gcode.tool'", '"pen" or "laser"']),
])
def test_laser_profile_errors_name_file_and_key(tmp_path, edit, words):
    message = broken(tmp_path, edit, base="grbl-laser")
    for word in words:
        assert word in message, message


def test_power_and_spindle_keys_belong_to_lasers_only(tmp_path):
    message = broken(tmp_path, lambda t: t.replace("speed = 15", "speed = 15\npower = 0.5"), base="grbl")
    assert "key 'layers.cut.power'" in message and "no laser" in message
    message = broken(tmp_path, lambda t: t.replace("z_speed = 10", "z_speed = 10\nspindle_max = 1000"), base="grbl")
    assert "key 'gcode.spindle_max'" in message and "remove it" in message
    message = broken(tmp_path, lambda t: t.replace("[layers.valley]", "[layers.valley]\npower = 0.5"),
                     base="hp7475a")
    assert "key 'layers.valley.power'" in message


def test_a_job_sets_a_layers_power_on_a_laser_and_is_warned_elsewhere():
    where = "jobs/box.toml: [fabrication.layers.valley]"
    laser = load_device("grbl-laser")
    assert laser.supported({"power": 0.3, "speed": 20}, where) == ({"power": 0.3, "speed": 20}, [])
    assert laser.tool_for("valley", {"power": 0.3, "speed": 20}, where).power == 0.3
    assert laser.tool_for("valley", {"speed": 20}, where, like="cut").power == 0.6  # dashes cut
    with pytest.raises(FoldfabError, match=r"jobs/box.toml.*'layers.valley.power': expected .* at most 1"):
        laser.tool_for("valley", {"power": 2}, where)
    grbl = load_device("grbl")
    kept, warnings = grbl.supported({"power": 0.3, "speed": 20}, where)
    assert kept == {"speed": 20}
    assert warnings == [f"{where}.power = 0.3 ignored: grbl has no power setting (it is no laser)"]
    with pytest.raises(FoldfabError, match="'layers.valley.power': expected no power"):
        grbl.tool_for("valley", {"power": 0.3}, where)
