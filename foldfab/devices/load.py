"""Device profiles: what a plotter speaks, where its origin is, and how it is reached.

A profile is a TOML file.  ``load_device(name_or_path)`` looks, in order, for a path
to a ``.toml`` file, for ``$XDG_CONFIG_HOME/foldfab/devices/NAME.toml`` (default
``~/.config``), then for a built-in profile (the repository's ``devices/`` folder,
installed as ``foldfab/builtin_devices``).  Every schema violation raises
:class:`~foldfab.errors.FoldfabError` naming the file and the key.

Schema (all lengths in mm, speeds in mm/s; ``devices/README.md`` has the long form)::

    name = "graphtec-ce6000"        # required
    model = "Graphtec CE6000"       # required, free text
    protocol = "hpgl"               # required: "hpgl" | "gcode" | "ebb" | "gpgl"
    dialect = "graphtec"            # hpgl: "hp" | "graphtec" | "roland" (required); gcode: "grbl";
                                    # ebb: "axidraw"; gpgl: "graphtec"
    units_per_mm = 40               # hpgl, default 40 (1016 per inch); gpgl, default 20; ebb: motor
                                    # steps per mm, default 80
    origin = "bottom-right"         # sheet corner at the device origin; must agree with the axes
    x_axis = "up"                   # direction of device +x on the sheet: right | left | up | down
    y_axis = "left"                 # direction of device +y; perpendicular to x_axis
    origin_offset = [0, 0]          # optional: device (0,0) measured from the origin corner
    plottable_area = [584, 1000]    # required: reach along device x and y from device (0,0)
    sheet = "A4"                    # A4 | A3 | Letter, optionally + " landscape", or [w, h]
    port = "/dev/ttyUSB0"           # optional: serial port or pyserial URL
    tool_changer = false            # optional: true if the device changes pens by itself
    firmware_blade_offset = false   # optional: true if the cutter compensates its drag knife itself

    [serial]   baudrate (required), bytesize = 8, parity = "none", stopbits = 1,
               xonxoff = false, rtscts = false, dsrdtr = false
    [buffer]   size (bytes, required), flow_control = "xonxoff" | "rtscts" | "escb" | "grbl" | "none"
    [motion]   draw_speed, travel_speed, acceleration (mm/s^2), pen_lift_time (s): required;
               park = [x, y] (device mm, default [0, 0]): where the head waits at pauses and the end;
               junction_deviation (mm > 0, G-code only): GRBL's $11; time estimates and the
               simulated GRBL then keep speed through corners as GRBL plans them (absent: every
               corner sharper than 1 degree is taken from rest);
               axis_limits (default false): travel_speed and acceleration limit each axis, as
               GRBL's $110/$111 and $120/$121 do, so a diagonal move gets up to 1.41 times both
    [limits]   optional ranges [lo, hi] for pen, force, speed
    [gcode]    gcode only: pen_up = Z height (number) or a servo command ("M3 S50");
               z_speed (mm/s, required with a Z height); or tool = "laser" (default "pen") with
               spindle_max (GRBL's $30, required) and spindle_min (GRBL's $31, default 0), no
               pen_up or z_speed: the beam is switched by M4/M5 and is off on G0 moves
    [ebb]      ebb only (required): pen_up, pen_down (servo height, percent), raise_rate,
               lower_rate (percent), servo_min, servo_max (pulse, 1/12 MHz units),
               servo_sweep_time (ms), microstepping (EM mode 1..5), time_slice (s)
    [layers.valley], [layers.mountain], [layers.cut] (required; other names allowed):
               pen (required), force, speed (default motion.draw_speed), passes = 1,
               pen_down (gcode only, required: Z height or servo command, same kind as pen_up);
               a laser's layers: power (share of $30's full power, 0 < power <= 1, required),
               speed, passes, pen (default 1), and no pen_down
               a drag knife on a layer that cuts (never valley or mountain, which score):
               blade_offset (mm, 0..5, default 0: none), swivel_angle (degrees, 0..179,
               default 5), overcut (mm, 0..50, default 0) -- see foldfab.fabrication.blade
    [gpgl]     gpgl only (required): blade_offset = [mm, ...], one per tool holder (FC; 0 for a
               pen or a scoring tool); layer pens are tool holders 1..len(blade_offset)
    [media.NAME]  optional presets a job picks with [fabrication] media = "NAME": description,
               score = {force, speed, passes} (valley and mountain), cut = {...} (the outline)

The profile's data model is :mod:`foldfab.devices.profile`, its value checks
:mod:`foldfab.devices.checks`.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import replace
from pathlib import Path
from types import MappingProxyType

from foldfab.devices.blade import BLADE_KEYS, profile_blade
from foldfab.devices.checks import (_MISSING, _PEN_POSITION, _TOOL_KEYS, README_HINT, _boolean, _check_tool, _choice,
                                    _choice_number, _integer, _laser_power, _number, _pair, _pen_position, _range,
                                    _Reader, _text, parse_sheet)
from foldfab.devices.profile import (DIALECTS, DIRECTIONS, FLOW_CONTROLS, PARITIES, REQUIRED_LAYERS, BufferSettings,
                                     DeviceProfile, EbbSettings, GcodeSettings, GPGLSettings, LayerDefaults, Limits,
                                     MediaPreset, Motion, SerialSettings, _origin_corner)
from foldfab.errors import FoldfabError
from foldfab.xdg import foldfab_dir


def load_device(name_or_path: str | os.PathLike) -> DeviceProfile:
    """Load and validate a profile by file path, user profile name or built-in name."""
    text = str(name_or_path)
    if text.endswith(".toml") or os.sep in text or "/" in text:
        path = Path(text)
        if not path.exists():  # anything else there is refused by name as it is read
            raise FoldfabError(f"{path}: no such device profile file; check the path")
        return _load_file(path)
    for folder in (_user_dir(), _builtin_dir()):
        path = folder / f"{text}.toml"
        if path.is_file():
            return _load_file(path)
    raise FoldfabError(
        f"unknown device '{text}'; known devices: {', '.join(list_devices()) or 'none'} "
        f"(or give the path of a .toml profile, or add {_user_dir() / (text + '.toml')})"
    )


def list_devices() -> list[str]:
    """Names of the user's and the built-in profiles, sorted (a user profile hides a built-in)."""
    names = set()
    for folder in (_user_dir(), _builtin_dir()):
        if folder.is_dir():
            names.update(p.stem for p in folder.glob("*.toml"))
    return sorted(names)


def _user_dir() -> Path:
    return foldfab_dir("XDG_CONFIG_HOME") / "devices"


def _builtin_dir() -> Path:
    """``foldfab/builtin_devices`` when installed, the repository's ``devices/`` in a checkout."""
    here = Path(__file__).resolve().parent.parent  # foldfab/
    installed = here / "builtin_devices"
    return installed if installed.is_dir() else here.parent / "devices"


def _load_file(path: Path) -> DeviceProfile:
    from foldfab.files import SMALL_LIMIT, read_text

    text = read_text(path, "device profile", SMALL_LIMIT)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FoldfabError(f"{path}: not valid TOML ({exc}); fix the syntax") from None
    return _parse(_Reader(data, str(path), keys=_ROOT_KEYS))


# --- validation ----------------------------------------------------------------------


def _corner_name(ex, ey) -> str:
    x, y = _origin_corner(ex, ey, (1, 1))
    return f"{'top' if y == 0 else 'bottom'}-{'left' if x == 0 else 'right'}"


_ROOT_KEYS = ("name", "model", "protocol", "dialect", "units_per_mm", "x_axis", "y_axis", "origin", "origin_offset",
              "plottable_area", "sheet", "port", "tool_changer", "serial", "buffer", "motion", "limits", "gcode",
              "layers", "ebb", "firmware_blade_offset", "gpgl", "media")
"""Every key at the top of a device profile."""


def _parse(root: _Reader) -> DeviceProfile:
    name = root.take("name", "a device name", _text)
    model = root.take("model", "a model description", _text)
    protocol = root.take("protocol", '"hpgl", "gcode", "ebb" or "gpgl"', _choice(DIALECTS))
    dialects = DIALECTS[protocol]
    default_dialect = {"gcode": "grbl", "ebb": "axidraw", "gpgl": "graphtec"}.get(protocol, _MISSING)
    dialect = root.take(
        "dialect", " or ".join(f'"{d}"' for d in dialects), _choice(dialects), default_dialect
    )
    if protocol != "gcode":
        units = root.take("units_per_mm", "plotter units per mm > 0", _number(0, open_lo=True),
                          {"hpgl": 40.0, "gpgl": 20.0, "ebb": EBB_STEPS_PER_MM}[protocol])
    elif "units_per_mm" in root.data:
        raise root.fail("units_per_mm", "no units_per_mm (G-code is in mm)", root.data["units_per_mm"],
                        "remove it")
    else:
        units = 1.0
    axes = {}
    for key in ("x_axis", "y_axis"):
        axes[key] = root.take(key, "right, left, up or down", _choice(DIRECTIONS))
    ex, ey = DIRECTIONS[axes["x_axis"]], DIRECTIONS[axes["y_axis"]]
    if ex[0] * ey[0] + ex[1] * ey[1] != 0:
        raise root.fail("y_axis", f"a direction perpendicular to x_axis '{axes['x_axis']}'",
                        axes["y_axis"], "one axis runs along the top edge, the other along the side")
    corners = ("top-left", "top-right", "bottom-left", "bottom-right")
    origin = root.take("origin", "top-left, top-right, bottom-left or bottom-right", _choice(corners))
    if origin != _corner_name(ex, ey):
        raise root.fail(
            "origin", f"'{_corner_name(ex, ey)}' (the corner x_axis '{axes['x_axis']}' and "
            f"y_axis '{axes['y_axis']}' point away from)", origin, "fix origin or the axes",
        )
    offset = root.take("origin_offset", "[x, y] in mm", _pair(_number()), (0.0, 0.0))
    area = root.take("plottable_area", "[width, height] in mm > 0", _pair(_number(0, open_lo=True)))
    sheet = root.take("sheet", 'A4, A3, Letter (optionally + " landscape") or [w, h] in mm', parse_sheet)
    port = root.take("port", "a serial port or pyserial URL", _text, None)
    tool_changer = root.take("tool_changer", "true or false", _boolean, False)

    ser = root.table("serial", keys=("baudrate", "bytesize", "parity", "stopbits", "xonxoff", "rtscts", "dsrdtr"))
    serial = SerialSettings(
        baudrate=ser.take("baudrate", "a baud rate", _integer(50)),
        bytesize=ser.take("bytesize", "5, 6, 7 or 8", _integer(5, 8), 8),
        parity=PARITIES[ser.take("parity", "none, even, odd, mark or space", _choice(PARITIES), "none")],
        stopbits=ser.take("stopbits", "1, 1.5 or 2", _choice_number((1, 1.5, 2)), 1.0),
        xonxoff=ser.take("xonxoff", "true or false", _boolean, False),
        rtscts=ser.take("rtscts", "true or false", _boolean, False),
        dsrdtr=ser.take("dsrdtr", "true or false", _boolean, False),
    )
    ser.done()

    buf = root.table("buffer", keys=("size", "flow_control"))
    buffer = BufferSettings(
        size=buf.take("size", "the receive buffer size in bytes", _integer(1)),
        flow_control=buf.take("flow_control", ", ".join(FLOW_CONTROLS), _choice(FLOW_CONTROLS)),
    )
    needs = {"xonxoff": ("serial.xonxoff", serial.xonxoff), "rtscts": ("serial.rtscts", serial.rtscts)}
    if buffer.flow_control in needs and not needs[buffer.flow_control][1]:
        raise buf.fail("flow_control", f"a flow control enabled in [serial] "
                       f"({needs[buffer.flow_control][0]} = true)", buffer.flow_control,
                       f"set {needs[buffer.flow_control][0]} = true")
    native = {"grbl": "gcode", "escb": "hpgl", "ebb": "ebb", "status": "gpgl"}
    if native.get(buffer.flow_control, protocol) != protocol or (protocol == "gpgl") != (buffer.flow_control == "status"):
        raise buf.fail("flow_control", f"a flow control for {protocol}", buffer.flow_control,
                       "grbl is for G-code devices, escb for HPGL ones, status for (and only for) GP-GL ones")
    buf.done()

    mot = root.table("motion", keys=("draw_speed", "travel_speed", "acceleration", "pen_lift_time", "park",
                                        "junction_deviation", "axis_limits"))
    positive = _number(0, open_lo=True)
    motion = Motion(
        draw_speed=mot.take("draw_speed", "mm/s > 0", positive),
        travel_speed=mot.take("travel_speed", "mm/s > 0", positive),
        acceleration=mot.take("acceleration", "mm/s^2 > 0", positive),
        pen_lift_time=mot.take("pen_lift_time", "seconds >= 0", _number(0)),
        park=mot.take("park", "[x, y] in device mm", _pair(_number()), (0.0, 0.0)),
        junction_deviation=mot.take("junction_deviation", "mm > 0 (GRBL's $11)", positive, None),
        axis_limits=mot.take("axis_limits", "true or false", _boolean, False),
    )
    if protocol != "gcode" and motion.junction_deviation is not None:
        raise mot.fail("junction_deviation", "no junction_deviation in an HPGL profile (GRBL's $11; "
                       "HPGL plotters are modelled stopping at corners)", motion.junction_deviation,
                       "remove it")
    if not all(0 <= motion.park[i] <= area[i] for i in (0, 1)):
        raise mot.fail("park", f"a point inside plottable_area {list(area)}", list(motion.park),
                       "move the park position into the plottable area")
    mot.done()

    lim = root.table("limits", required=False, keys=("pen", "force", "speed"))
    limits = Limits()
    if lim is not None:
        limits = Limits(**{k: lim.take(k, "[lo, hi] with lo <= hi", _range, None)
                           for k in ("pen", "force", "speed")})
        lim.done()

    gcode = None
    gc = root.table("gcode", required=protocol == "gcode",
                    keys=("pen_up", "z_speed", "tool", "spindle_max", "spindle_min"))
    if gc is not None and protocol != "gcode":
        raise root.fail("gcode", "no [gcode] table in an HPGL profile", "[gcode]", "remove it")
    if gc is not None and gc.data.get("tool") == "laser":
        gcode = _parse_laser(gc)
    elif gc is not None:
        gc.take("tool", '"pen" or "laser"', _choice(("pen", "laser")), "pen")
        for key in ("spindle_max", "spindle_min"):
            if key in gc.data:
                raise gc.fail(key, f'no {key} but for a laser (tool = "laser")', gc.data[key], "remove it")
        pen_up = gc.take("pen_up", _PEN_POSITION, _pen_position)
        z_speed = gc.take("z_speed", "mm/s > 0", positive, None)
        if isinstance(pen_up, float) and z_speed is None:
            raise FoldfabError(f"{gc.file}: missing key 'gcode.z_speed' (mm/s > 0, the speed of "
                               f"pen-down Z moves); add it, {README_HINT}")
        gcode = GcodeSettings(pen_up=pen_up, z_speed=z_speed)
        gc.done()

    profile = DeviceProfile(
        name=name, model=model, protocol=protocol, dialect=dialect, units_per_mm=units,
        origin=origin, x_axis=axes["x_axis"], y_axis=axes["y_axis"], origin_offset=offset,
        plottable_area=area, sheet=sheet, port=port, tool_changer=tool_changer, serial=serial,
        buffer=buffer, motion=motion, limits=limits, gcode=gcode, layers=MappingProxyType({}),
        source=root.file, ebb=_parse_ebb(root, protocol, buffer, motion, units),
    )
    # a GP-GL cutter compensates with FC, its [gpgl] blade_offset: foldfab then moves no path
    firmware = root.take("firmware_blade_offset", "true or false", _boolean, protocol == "gpgl")
    layers_reader = root.table("layers")
    layers, blades = {}, {}
    for layer in REQUIRED_LAYERS:
        if layer not in layers_reader.data:
            raise FoldfabError(f"{root.file}: missing table '[layers.{layer}]'; add it, {README_HINT}")
    for layer in list(layers_reader.data):
        reader = layers_reader.table(layer, keys=(*_TOOL_KEYS, "pen_down", "power", *BLADE_KEYS))
        blade = profile_blade(reader, layer, firmware)
        if blade is not None:
            blades[layer] = blade
        layers[layer] = _parse_layer(profile, reader)
    profile = replace(profile, layers=MappingProxyType(layers), firmware_blade_offset=firmware,
                      blades=MappingProxyType(blades))
    profile = replace(profile, gpgl=_parse_gpgl(root, profile))
    profile = replace(profile, media=_parse_media(root, profile))
    root.done()
    return profile


def _parse_gpgl(root: _Reader, profile: DeviceProfile) -> GPGLSettings | None:
    """The ``[gpgl]`` table: required in a GP-GL profile, refused elsewhere; every layer's pen
    must be one of its tool holders."""
    table = root.table("gpgl", required=profile.protocol == "gpgl", keys=("blade_offset",))
    if table is None:
        return None
    if profile.protocol != "gpgl":
        raise root.fail("gpgl", f"no [gpgl] table in a {profile.protocol} profile", "[gpgl]", "remove it")
    offsets = table.take("blade_offset", "a list of 1 to 8 blade offsets in mm from 0 to 2.35 (FC, "
                         "one per tool holder)", _offsets)
    table.done()
    for name, layer in profile.layers.items():
        if not 1 <= layer.pen <= len(offsets):
            raise FoldfabError(f"{root.file}: key 'layers.{name}.pen': expected a tool holder from 1 to "
                               f"{len(offsets)} (one per [gpgl] blade_offset), got {layer.pen}; {README_HINT}")
    return GPGLSettings(offsets)


def _offsets(value):
    if not isinstance(value, list) or not 1 <= len(value) <= 8:
        return None
    items = [_number(0, 2.35)(v) for v in value]  # FC takes at most 47 units of 0.05 mm
    return None if None in items else tuple(items)


MEDIA_TOOL_KEYS = ("force", "speed", "passes")
"""What a media preset sets for scoring and for cutting."""


def _parse_media(root: _Reader, profile: DeviceProfile) -> MappingProxyType:
    """The ``[media.NAME]`` presets, each checked against the layers' tools and the limits."""
    tables = root.table("media", required=False)
    presets = {}
    for name in list(tables.data) if tables is not None else []:
        preset = tables.table(name, keys=("description", "score", "cut"))
        description = preset.take("description", "a description of the material", _text, name)
        parts = {}
        for part, layer in (("score", "valley"), ("cut", "cut")):
            reader = preset.table(part, keys=MEDIA_TOOL_KEYS)
            values = dict(reader.data)
            base = profile.layers[layer]
            tool = {key: reader.take(key, *_TOOL_KEYS[key], getattr(base, key)) for key in MEDIA_TOOL_KEYS}
            _check_tool(profile, reader, pen=base.pen, **tool)
            reader.done()
            parts[part] = MappingProxyType(values)
        preset.done()
        presets[name] = MediaPreset(description, parts["score"], parts["cut"])
    return MappingProxyType(presets)


def _parse_layer(profile: DeviceProfile, reader: _Reader) -> LayerDefaults:
    values = {
        "pen": reader.take("pen", *_TOOL_KEYS["pen"], *((1,) if profile.laser else ())),
        "force": reader.take("force", *_TOOL_KEYS["force"], None),
        "speed": reader.take("speed", *_TOOL_KEYS["speed"], profile.motion.draw_speed),
        "passes": reader.take("passes", *_TOOL_KEYS["passes"], 1),
    }
    _check_tool(profile, reader, **values)
    power = _laser_power(profile, reader)
    pen_down = None
    if profile.laser and "pen_down" in reader.data:
        raise reader.fail("pen_down", "no pen_down for a laser (its beam is set by power)", reader.data["pen_down"],
                          "remove it and give the layer a power")
    if profile.gcode is not None and not profile.laser:
        pen_up = profile.gcode.pen_up
        pen_down = reader.take("pen_down", _PEN_POSITION, _pen_position)
        if isinstance(pen_down, str) != isinstance(pen_up, str):
            raise reader.fail("pen_down", "the same kind as gcode.pen_up "
                              f"({'a servo command' if isinstance(pen_up, str) else 'a Z height'})",
                              pen_down, "use Z heights or servo commands throughout")
        if pen_down == pen_up or (isinstance(pen_up, float) and pen_down >= pen_up):
            raise reader.fail("pen_down", f"a pen-down position below/unlike gcode.pen_up ({pen_up!r})",
                              pen_down, "lower pen_down or raise pen_up")
    reader.done()
    return LayerDefaults(pen_down=pen_down, power=power, **values)


def _parse_laser(gc: _Reader) -> GcodeSettings:
    """A laser's ``[gcode]`` table: GRBL's ``$30`` and ``$31``, and no pen keys."""
    gc.take("tool", '"laser"', _choice(("laser",)))
    for key in ("pen_up", "z_speed"):
        if key in gc.data:
            raise gc.fail(key, f"no {key} for a laser (its beam is switched by M4/M5 and is off on G0 moves)",
                          gc.data[key], "remove it")
    top = gc.take("spindle_max", "the S value of full power > 0 (GRBL's $30)", _number(0, open_lo=True))
    low = gc.take("spindle_min", "the S value of the lowest power >= 0 (GRBL's $31)", _number(0), 0.0)
    if low >= top:
        raise gc.fail("spindle_min", f"a value below spindle_max ({top:g})", low, "lower spindle_min")
    gc.done()
    return GcodeSettings(pen_up=None, z_speed=None, tool="laser", spindle_max=top, spindle_min=low)


EBB_STEPS_PER_MM = 80.0
"""AxiDraw's 2032 steps per inch along a belt at 16x microstepping (``native_res_factor`` x 2)."""
EBB_MAX_STEP_RATE = 25000.0
"""The EiBotBoard's highest step rate per motor, steps/s."""


def _parse_ebb(root: _Reader, protocol: str, buffer: BufferSettings, motion: Motion,
               units: float) -> EbbSettings | None:
    """The ``[ebb]`` table: required in an EBB profile, refused in any other."""
    table = root.table("ebb", required=protocol == "ebb",
                       keys=("pen_up", "pen_down", "raise_rate", "lower_rate", "servo_min", "servo_max",
                             "servo_sweep_time", "microstepping", "time_slice"))
    if table is None:
        return None
    if protocol != "ebb":
        raise root.fail("ebb", f"no [ebb] table in a {protocol} profile", "[ebb]", "remove it")
    if buffer.flow_control != "ebb":
        raise FoldfabError(f"{root.file}: key 'buffer.flow_control': expected \"ebb\" (an EiBotBoard "
                           f"answers every command), got {buffer.flow_control!r}; set it to \"ebb\"")
    if motion.junction_deviation is not None:
        raise FoldfabError(f"{root.file}: key 'motion.junction_deviation': expected none in an EBB "
                           "profile (foldfab's EBB programs stop at every corner); remove it")
    # a diagonal move turns one motor sqrt(2) times as fast as the head moves
    fastest = EBB_MAX_STEP_RATE / (units * 2 ** 0.5)
    if motion.travel_speed > fastest:
        raise FoldfabError(f"{root.file}: key 'motion.travel_speed': expected at most {fastest:.1f} mm/s "
                           f"(25,000 steps/s per motor at {units:g} steps/mm), got {motion.travel_speed:g}; "
                           "lower it")
    percent, positive = _number(0, 100), _number(0, open_lo=True)
    settings = EbbSettings(
        pen_up=table.take("pen_up", "a height in percent, 0..100", percent),
        pen_down=table.take("pen_down", "a height in percent, 0..100", percent),
        raise_rate=table.take("raise_rate", "a rate in percent, 1..200", _number(1, 200)),
        lower_rate=table.take("lower_rate", "a rate in percent, 1..200", _number(1, 200)),
        servo_min=table.take("servo_min", "a servo pulse 1..65535", _integer(1, 65535), 9855),
        servo_max=table.take("servo_max", "a servo pulse 1..65535", _integer(1, 65535), 27831),
        servo_sweep_time=table.take("servo_sweep_time", "ms > 0", positive, 200.0),
        microstepping=table.take("microstepping", "an EM mode 1..5", _integer(1, 5), 1),
        time_slice=table.take("time_slice", "seconds, 0.005..0.5", _number(0.005, 0.5), 0.025),
    )
    if settings.pen_down == settings.pen_up:
        raise table.fail("pen_down", f"a height other than pen_up ({settings.pen_up:g})", settings.pen_down,
                         "lower pen_down or raise pen_up")
    table.done()
    return settings


def profile_origin(device: DeviceProfile) -> str:
    """``built-in`` or ``user``: where ``device``'s profile comes from (``foldfab devices``)."""
    builtin = _builtin_dir().resolve()
    return "built-in" if builtin in Path(device.source).resolve().parents else "user"
