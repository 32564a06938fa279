"""Job files: the TOML that names a design (profile, trajectory, crease settings).

Reading a job validates every key and returns plain data; it does no geometry.
Every error names the file and the key (``jobs/x.toml: [trajectory].radius: ...``)
and says what was expected.  Unknown keys are errors too, so a typo never
silently falls back to a default.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

from foldfab.errors import FoldfabError, unknown_key
from foldfab.limits import LENGTH_LIMIT

TEMPLATES = ("regular", "star", "polyline")


@dataclass(frozen=True)
class SvgSource:
    """A polyline to be read from a path of an SVG file."""

    file: Path
    path: str | int = 0
    samples: int | None = None
    tolerance: float | None = None


@dataclass(frozen=True)
class ProfileSpec:
    """The profile polyline: points (u, v) in mm, or an SVG source, plus an offset."""

    points: tuple[tuple[float, float], ...] | None
    svg: SvgSource | None
    offset: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class TrajectorySpec:
    """The trajectory: a template with its parameters, a polyline, or an SVG source."""

    template: str
    params: dict[str, float] = field(default_factory=dict)
    points: tuple[tuple[float, ...], ...] | None = None
    svg: SvgSource | None = None


@dataclass(frozen=True)
class CreaseSpec:
    """Crease-pattern settings."""

    flat_angle: float = 1.0
    glue_tab: float = 0.0


@dataclass(frozen=True)
class Job:
    """A validated job file."""

    path: Path
    name: str
    profile: ProfileSpec
    trajectory: TrajectorySpec
    crease: CreaseSpec
    fabrication: dict[str, Any] = field(default_factory=dict)
    text: str = ""
    max_faces: int | None = None  # [design].max_faces: None for foldfab.design.MAX_FACES


class TomlTable:
    """A TOML table that remembers where it came from, for error messages."""

    def __init__(self, source: str, name: str, data: Any, keys: Iterable[str] | None = None):
        """``keys``: every key the table may hold in any of its forms.  A key outside them is
        reported at once, before a missing key it may be the misspelling of."""
        self.source = source
        self.name = name
        if not isinstance(data, dict):
            self.fail(None, f"expected a table, got {_type_name(data)}")
        self.data = data
        self.used: set[str] = set()
        if keys is not None:
            self.check_unknown(set(keys))

    def where(self, key: str | None) -> str:
        return f"{self.source}: [{self.name}]" + (f".{key}" if key else "")

    def fail(self, key: str | None, message: str):
        raise FoldfabError(f"{self.where(key)}: {message}")

    def has(self, key: str) -> bool:
        """Is ``key`` given?  (Either way it is a key this table knows: see :meth:`check_unknown`.)"""
        self.used.add(key)
        return key in self.data

    def get(self, key: str, default: Any = None, *, required: bool = False) -> Any:
        self.used.add(key)
        if key not in self.data:
            if required:
                self.fail(key, "missing; add it to the job file")
            return default
        return self.data[key]

    def number(self, key: str, default: float | None = None, *, required: bool = False,
               minimum: float | None = None, exclusive_minimum: float | None = None,
               maximum: float | None = None) -> float | None:
        value = self.get(key, default, required=required)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f"expected a number, got {_type_name(value)} {value!r}")
        given, value = value, _float(value)
        if not math.isfinite(value):
            self.fail(key, f"expected a finite number{' of a sensible size' if isinstance(given, int) else ''}, "
                           f"got {_shown(given)}")
        if minimum is not None and value < minimum:
            self.fail(key, f"must be at least {minimum:.10g}, got {value:.10g}")
        if exclusive_minimum is not None and value <= exclusive_minimum:
            self.fail(key, f"must be greater than {exclusive_minimum:.10g}, got {value:.10g}")
        if maximum is not None and value > maximum:
            self.fail(key, f"must be at most {maximum:.10g}, got {value:.10g}")
        return value

    def integer(self, key: str, default: int | None = None, *, required: bool = False,
                minimum: int | None = None, maximum: int | None = None) -> int | None:
        value = self.get(key, default, required=required)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"expected a whole number, got {_type_name(value)} {value!r}")
        if minimum is not None and value < minimum:
            self.fail(key, f"must be at least {minimum}, got {value}")
        if maximum is not None and value > maximum:
            self.fail(key, f"must be at most {maximum}, got {value}")
        return value

    def string(self, key: str, default: str | None = None, *, required: bool = False,
               choices: tuple[str, ...] | None = None) -> str | None:
        value = self.get(key, default, required=required)
        if value is None:
            return None
        if not isinstance(value, str):
            self.fail(key, f"expected a string, got {_type_name(value)} {value!r}")
        if choices is not None and value not in choices:
            self.fail(key, f"expected one of {', '.join(map(repr, choices))}, got {value!r}")
        return value

    def points(self, key: str, dims: tuple[int, ...], *, minimum: int = 2) -> tuple[tuple[float, ...], ...]:
        value = self.get(key, required=True)
        names = ("u", "v") if self.name == "profile" else ("x", "y", "z")
        shape = " or ".join(f"[{', '.join(names[:d])}]" for d in dims)
        if not isinstance(value, list):
            self.fail(key, f"expected a list of points {shape}, got {_type_name(value)}")
        if len(value) < minimum:
            self.fail(key, f"expected at least {minimum} points, got {len(value)}")
        out = []
        width = None
        for i, point in enumerate(value):
            if (not isinstance(point, list) or len(point) not in dims
                    or any(isinstance(c, bool) or not isinstance(c, (int, float)) for c in point)):
                self.fail(f"{key}[{i}]", f"expected a point {shape} of numbers, got {point!r}")
            if width is None:
                width = len(point)
            elif len(point) != width:
                self.fail(f"{key}[{i}]", f"has {len(point)} coordinates but point 0 has {width}; use one form for all points")
            coordinates = tuple(_float(c) for c in point)
            if not all(abs(c) <= LENGTH_LIMIT for c in coordinates):  # NaN too
                self.fail(f"{key}[{i}]", f"coordinates must be finite numbers within ±{LENGTH_LIMIT:,.0f} mm, "
                                         f"got {_shown(point)}")
            out.append(coordinates)
        return tuple(out)

    def pair(self, key: str, default: tuple[float, float]) -> tuple[float, float]:
        value = self.get(key, None)
        if value is None:
            return default
        if (not isinstance(value, list) or len(value) != 2
                or any(isinstance(c, bool) or not isinstance(c, (int, float)) for c in value)
                or not all(abs(_float(c)) <= LENGTH_LIMIT for c in value)):
            self.fail(key, f"expected a pair of finite numbers [a, b] within ±{LENGTH_LIMIT:,.0f} mm, "
                           f"got {_shown(value)}")
        return (_float(value[0]), _float(value[1]))

    def check_unknown(self, allowed: set[str] | None = None) -> None:
        """Fail on the first key not in ``allowed`` (default: the keys read so far)."""
        found = unknown_key(self.data, self.used if allowed is None else allowed)
        if found:
            self.fail(found[0], f"unknown key; {found[1]}")


def _float(value: int | float) -> float:
    """``value`` as a float; a whole number too large for one (TOML allows 400 digits) is infinite."""
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def _shown(value: Any) -> str:
    """``value`` for an error message, a runaway number cut short."""
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _type_name(value: Any) -> str:
    return {dict: "a table", list: "a list", str: "a string", bool: "a boolean",
            int: "an integer", float: "a number"}.get(type(value), type(value).__name__)


SVG_SAMPLES_LIMIT = 100_000
"""Most points an SVG path may be sampled into (as many as a trajectory may have corners)."""
SVG_TOLERANCE_FLOOR = 0.001
"""mm: the finest chord error an SVG curve is sampled to (a plotter's step is 0.025 mm)."""


SVG_KEYS = ("svg", "path", "samples", "tolerance")
PROFILE_KEYS = ("points", "offset", *SVG_KEYS)
TRAJECTORY_KEYS = ("template", "corners", "radius", "points", "outer_radius", "inner_radius", *SVG_KEYS)
"""Every key [profile] and [trajectory] may hold, in any form: what a typo is checked against
before the form's own keys are read (which then reject a key of another form)."""


def _svg_source(table: TomlTable, base: Path) -> SvgSource:
    file = table.string("svg", required=True)
    path_value = table.get("path", 0)
    if isinstance(path_value, bool) or not isinstance(path_value, (str, int)):
        table.fail("path", f"expected a path id (string) or index (whole number), got {path_value!r}")
    if isinstance(path_value, int) and path_value < 0:
        table.fail("path", f"a path index must be 0 or more, got {path_value}")
    samples = table.integer("samples", None, minimum=2, maximum=SVG_SAMPLES_LIMIT)
    tolerance = table.number("tolerance", None, minimum=SVG_TOLERANCE_FLOOR)
    if samples is not None and tolerance is not None:
        table.fail("samples", "give either samples or tolerance, not both")
    resolved = (base / file).resolve()
    if not resolved.exists():  # read (a regular file, bounded) when the design is built
        table.fail("svg", f"file not found: {resolved}")
    return SvgSource(resolved, path_value, samples, tolerance)


def _parse_profile(table: TomlTable, base: Path) -> ProfileSpec:
    if table.has("points") == table.has("svg"):
        table.fail(None, "give either points = [[u, v], ...] or svg = \"file.svg\" (exactly one)")
    offset = table.pair("offset", (0.0, 0.0))
    if table.has("points"):
        spec = ProfileSpec(table.points("points", (2,)), None, offset)
    else:
        spec = ProfileSpec(None, _svg_source(table, base), offset)
    table.check_unknown()
    return spec


def _parse_trajectory(table: TomlTable, base: Path) -> TrajectorySpec:
    if table.has("svg"):
        template = table.string("template", "polyline", choices=("polyline",))
        spec = TrajectorySpec(template, svg=_svg_source(table, base))
    else:
        template = table.string("template", required=True, choices=TEMPLATES)
        if template == "regular":
            params = {"corners": table.integer("corners", required=True, minimum=3, maximum=100000),
                      "radius": table.number("radius", required=True, exclusive_minimum=0.0, maximum=LENGTH_LIMIT)}
            spec = TrajectorySpec(template, params)
        elif template == "star":
            params = {"points": table.integer("points", required=True, minimum=2, maximum=100000),
                      "outer_radius": table.number("outer_radius", required=True, exclusive_minimum=0.0, maximum=LENGTH_LIMIT),
                      "inner_radius": table.number("inner_radius", required=True, exclusive_minimum=0.0, maximum=LENGTH_LIMIT)}
            if params["inner_radius"] == params["outer_radius"]:
                table.fail("inner_radius", "must differ from outer_radius (equal radii give a regular polygon: use template = \"regular\")")
            spec = TrajectorySpec(template, params)
        else:
            spec = TrajectorySpec(template, points=table.points("points", (2, 3)))
    table.check_unknown()
    return spec


def _parse_crease(table: TomlTable) -> CreaseSpec:
    spec = CreaseSpec(flat_angle=table.number("flat_angle", 1.0, minimum=0.0, maximum=180.0),
                      glue_tab=table.number("glue_tab", 0.0, minimum=0.0, maximum=LENGTH_LIMIT))
    return spec


def parse_job(text: str, path: str | Path = "<job>") -> Job:
    """Validate the TOML text of a job; relative paths resolve against ``path``'s folder."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FoldfabError(f"{path}: not valid TOML: {exc}") from None
    return job_from_data(data, path, text)


def job_from_data(data: dict[str, Any], path: str | Path = "<job>", text: str = "") -> Job:
    """Validate a job's tables (what its TOML text holds), as :func:`parse_job` does."""
    path = Path(path)
    source = str(path)
    found = unknown_key(data, ("design", "profile", "trajectory", "crease", "fabrication"), "[{}]")
    if found:
        raise FoldfabError(f"{source}: [{found[0]}]: unknown table; {found[1]}")
    base = path.parent
    design = TomlTable(source, "design", data.get("design", {}), ("name", "max_faces"))
    name = design.string("name", path.stem)
    max_faces = design.integer("max_faces", None, minimum=1)
    for required in ("profile", "trajectory"):
        if required not in data:
            raise FoldfabError(f"{source}: [{required}]: missing table; every job needs [profile] and [trajectory]")
    profile = _parse_profile(TomlTable(source, "profile", data["profile"], PROFILE_KEYS), base)
    trajectory = _parse_trajectory(TomlTable(source, "trajectory", data["trajectory"], TRAJECTORY_KEYS), base)
    crease = _parse_crease(TomlTable(source, "crease", data.get("crease", {}), ("flat_angle", "glue_tab")))
    fabrication = data.get("fabrication", {})
    if not isinstance(fabrication, dict):
        raise FoldfabError(f"{source}: [fabrication]: expected a table")
    # Its keys are checked by the fabrication stage that owns them (foldfab.fabrication.spec.job_spec),
    # for every command that reads a job.
    return Job(path, name, profile, trajectory, crease, fabrication, text, max_faces)


def load_job(path: str | Path) -> Job:
    """Read and validate a job file."""
    from foldfab.files import JOB_LIMIT, read_text

    path = Path(path)
    return parse_job(read_text(path, "job file", JOB_LIMIT), path)


# --- writing -------------------------------------------------------------------------------

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")
TABLE_ORDER = ("design", "profile", "trajectory", "crease", "fabrication")


def job_data(job: Job, folder: str | Path | None = None) -> dict[str, Any]:
    """The job as the plain tables of its TOML; SVG paths relative to ``folder`` (default: the job's)."""
    folder = Path(folder) if folder is not None else job.path.parent

    def svg(source: SvgSource) -> dict[str, Any]:
        out: dict[str, Any] = {"svg": Path(os.path.relpath(source.file, folder.resolve())).as_posix(),
                               "path": source.path}
        if source.samples is not None:
            out["samples"] = source.samples
        if source.tolerance is not None:
            out["tolerance"] = source.tolerance
        return out

    profile = ({"points": [list(p) for p in job.profile.points]} if job.profile.points is not None
               else svg(job.profile.svg))
    profile["offset"] = list(job.profile.offset)
    spec = job.trajectory
    if spec.svg is not None:
        trajectory = {"template": "polyline", **svg(spec.svg)}
    elif spec.template == "polyline":
        trajectory = {"template": "polyline", "points": [list(p) for p in spec.points]}
    else:
        trajectory = {"template": spec.template, **spec.params}
    design = {"name": job.name} if job.max_faces is None else {"name": job.name, "max_faces": job.max_faces}
    data = {"design": design, "profile": profile, "trajectory": trajectory,
            "crease": {"flat_angle": job.crease.flat_angle, "glue_tab": job.crease.glue_tab}}
    if job.fabrication:
        data["fabrication"] = copy.deepcopy(job.fabrication)
    return data


def job_to_toml(job: Job, folder: str | Path | None = None) -> str:
    """TOML text that :func:`parse_job` reads back as ``job`` (comments are not kept)."""
    return toml_text(job_data(job, folder))


def toml_text(data: Mapping[str, Any]) -> str:
    """TOML of nested tables of strings, numbers, booleans, lists and tables; job tables first."""
    if not isinstance(data, Mapping):
        raise FoldfabError(f"a job is a table of tables, got {_type_name(data)}")
    order = [k for k in TABLE_ORDER if k in data] + [k for k in data if k not in TABLE_ORDER]
    lines: list[str] = []
    for key in order:
        if not isinstance(data[key], Mapping):
            raise FoldfabError(f"[{key}]: expected a table, got {_type_name(data[key])}")
        _table_lines(lines, [key], data[key])
    return "\n".join(lines).lstrip("\n") + "\n"


def _table_lines(lines: list[str], name: list[str], table: Mapping[str, Any]) -> None:
    lines.extend(["", "[" + ".".join(map(_key, name)) + "]"])
    for key, value in table.items():
        if not isinstance(value, Mapping):
            lines.append(f"{_key(key)} = {_value(value, '.'.join(name + [key]))}")
    for key, value in table.items():
        if isinstance(value, Mapping):
            _table_lines(lines, name + [key], value)


def _key(key: Any) -> str:
    if not isinstance(key, str):
        raise FoldfabError(f"a key must be a string, got {_type_name(key)} {key!r}")
    return key if _BARE_KEY.fullmatch(key) else _string(key)


def _string(text: str) -> str:
    if any(0xD800 <= ord(c) <= 0xDFFF for c in text):
        raise FoldfabError(f"{text!r}: a lone surrogate cannot be written to a TOML file")
    return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007f")


def _value(value: Any, where: str) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, (list, tuple)):
        items = [_value(item, f"{where}[{i}]") for i, item in enumerate(value)]
        if len(items) > 4 and all(isinstance(item, (list, tuple)) for item in value):
            return "[\n" + "".join(f"  {item},\n" for item in items) + "]"  # one point per line
        return "[" + ", ".join(items) + "]"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{_key(k)} = {_value(v, f'{where}.{k}')}" for k, v in value.items()) + "}"
    raise FoldfabError(f"{where}: cannot be written to TOML: {_type_name(value)} {value!r}")
