"""The studio's API: small JSON requests, answered by foldfab's own core.

Every request is a JSON object (at most :data:`MAX_BODY` bytes) whose fields are
checked by type; a :class:`~foldfab.errors.FoldfabError` becomes HTTP 400 with
its message, and where it points (a view, a key, a point) as ``cause``.  A
design travels as the tables of its job file (``job``: ``design``, ``profile``,
``trajectory``, ``crease``, ``fabrication``) and is built from exactly the TOML
text the studio would save, so a saved job builds identically with
``foldfab design``.  A built design is answered in binary (:func:`pack`): a JSON
header, then flat little-endian arrays the browser reads without parsing.

**Files.**  The studio reads and writes only the paths the user types.  A
relative path is taken from the folder the studio was started in and must stay
inside that folder or the folder of the job the studio was started with (symbolic
links resolved; never a folder a request names); an absolute path (or ``~/...``)
is the user's explicit choice and is used as given.  An existing file is replaced
only when the request says ``overwrite``, and two requests creating the same new
file do not both succeed: the second is told it exists (409).  Every file is
written atomically.
"""

from __future__ import annotations

import json
import re
import threading
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from foldfab.errors import FoldfabError
from foldfab.studio.wire import ApiError, Response, field_of, number_of, pack

MAX_BODY = 16 * 2**20
STUDIO_MAX_FACES = 200_000
"""The most faces the studio builds and sends to the browser (a server answering every edit:
a larger design is built with ``foldfab design``, up to :data:`foldfab.limits.MAX_FACES`)."""
STUDIO_LIMIT_ADVICE = (f"the studio builds at most {STUDIO_MAX_FACES:,} faces: use fewer points, or build "
                       "the saved job with 'foldfab design' or 'foldfab export' (their limit is higher)")
EDGE_GROUPS = ("F", "V", "M", "B")  # drawn in this order: outline on top
VIEWS = {"design": "file", "profile": "profile", "trajectory": "trajectory", "crease": "creases",
         "fabrication": "creases"}
NEW_JOB = {
    "design": {"name": "untitled"},
    "profile": {"points": [[0.0, 0.0], [8.0, 10.0], [0.0, 20.0], [8.0, 30.0], [0.0, 40.0]], "offset": [0.0, 0.0]},
    "trajectory": {"template": "regular", "corners": 6, "radius": 40.0},
    "crease": {"flat_angle": 1.0, "glue_tab": 0.0},
}


def _checked(job):
    """``job``, its ``[fabrication]`` table validated too (:func:`~foldfab.fabrication.spec.job_spec`):
    the studio saves and shows only jobs every command reads."""
    from foldfab.fabrication.spec import job_spec

    job_spec(job)
    return job


def refusal_comment(reason: str | None) -> str:
    """TOML comment lines at the top of a job saved although ``foldfab design`` refuses it
    ("" when it does not): the reason, control characters replaced (a comment cannot hold them)."""
    if reason is None:
        return ""
    clean = re.sub(r"[\x00-\x08\x0a-\x1f\x7f]", " ", reason)
    return f"# saved by foldfab studio although 'foldfab design' refuses it:\n# {clean}\n\n"


def error_cause(message: str) -> dict[str, Any]:
    """Where an error points: the view (profile, trajectory, creases, model, file), key and point."""
    if "penetration" in message:
        return {"view": "model"}
    element = re.search(r"line element (\d+) \(profile point", message)
    if element:
        return {"view": "profile", "point": int(element.group(1))}
    tool = re.search(r"\[fabrication\.layers\]: (?:unknown )?key 'layers\.(\w+)\.(\w+)'", message)
    if tool:
        return {"view": "creases", "field": f"fabrication.layers.{tool.group(1)}.{tool.group(2)}"}
    setting = re.search(r"\[fabrication\] (\w+):|\[fabrication\.(\w+)\](?:\.(\w+))?", message)
    if setting:
        return {"view": "creases", "field": ".".join(["fabrication", *filter(None, setting.groups())])}
    key = re.search(r"\[(design|profile|trajectory|crease|fabrication)\](?:\.(\w+))?(?:\[(\d+)\])?", message)
    if key:
        table, name, index = key.groups()
        cause: dict[str, Any] = {"view": VIEWS[table]}
        if name:
            cause["field"] = f"{table}.{name}"
        if index is not None:
            cause["point"] = int(index)
        return cause
    if "even number of corners" in message:
        return {"view": "trajectory", "field": "trajectory.corners"}
    point = re.search(r"(profile|trajectory) (?:point|segment) (\d+)|\b(profile|trajectory): points? (\d+)", message)
    if point:
        return {"view": point.group(1) or point.group(3), "point": int(point.group(2) or point.group(4))}
    for word in ("profile", "trajectory"):
        if re.search(rf"\b{word}\b", message):
            return {"view": word}
    return {"view": "file"}


def feasible_band(profile: np.ndarray, trajectory: np.ndarray) -> list[list[float]] | None:
    """The region where profile points (offset included) may go, as a polygon reaching far beyond the
    design (:class:`~foldfab.geometry.feasible.Feasible`), or None when the trajectory has none."""
    from foldfab.geometry.feasible import Feasible

    try:
        region = Feasible.of(trajectory)
    except FoldfabError:
        return None
    size = max(float(np.ptp(profile, axis=0).max()), float(np.ptp(trajectory, axis=0).max()), 1.0)
    (u, v), reach = profile.mean(axis=0), 20 * size
    return region.polygon((u - reach, v - reach, u + reach, v + reach)).round(6).tolist()


@dataclass
class Studio:
    """One studio session: the folder it was started in, the device profiles it has read."""

    start_dir: Path
    job_path: Path | None = None
    _devices: dict = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _write_lock: threading.Lock = field(default_factory=threading.Lock)

    def __post_init__(self) -> None:
        from foldfab.job import load_job

        self.start_dir = Path(self.start_dir).resolve()
        if self.job_path is not None:
            self.job_path = Path(self.job_path).resolve()
            if self.job_path.exists():
                _checked(load_job(self.job_path))  # a job file that does not read is an error before the server starts

    # -- dispatch

    def routes(self) -> dict[tuple[str, str], Callable[[dict], Response | dict]]:
        """(method, path) -> handler."""
        return {("GET", "/api/state"): self.state, ("POST", "/api/design"): self.design,
                ("POST", "/api/open"): self.open, ("POST", "/api/files"): self.files,
                ("POST", "/api/save"): self.save, ("POST", "/api/export"): self.export,
                ("POST", "/api/preview"): self.preview, ("POST", "/api/queue"): self.queue,
                ("POST", "/api/device"): self.device_settings, ("POST", "/api/fabrication"): self.fabrication,
                ("POST", "/api/print"): self.print_template,
                ("POST", "/api/fit-template"): self.fit_template, ("POST", "/api/fold"): self.fold,
                ("POST", "/api/generate-profile"): self.generate_profile}

    def handle(self, method: str, path: str, body: bytes = b"") -> Response:
        """Answer one API request; user mistakes are 4xx JSON, never an exception."""
        handler = self.routes().get((method, path))
        if handler is None:
            known = any(p == path for _, p in self.routes())
            return Response.json({"error": f"{method} {path}: " + ("method not allowed" if known else "no such API")},
                                 405 if known else 404)
        try:
            request = self._decode(body) if method == "POST" else {}
            result = handler(request)
            return result if isinstance(result, Response) else Response.json(result)
        except ApiError as exc:
            return Response.json({"error": str(exc), **exc.extra}, exc.status)
        except FoldfabError as exc:
            return Response.json({"error": str(exc), "cause": error_cause(str(exc))}, 400)
        except RecursionError:
            return Response.json({"error": "request: nested too deeply"}, 400)
        except Exception as exc:  # a bug: report it, keep the session alive
            traceback.print_exc()
            return Response.json({"error": f"internal error in the studio: {type(exc).__name__}: {exc}"}, 500)

    @staticmethod
    def _decode(body: bytes) -> dict:
        if len(body) > MAX_BODY:
            raise ApiError(f"request too large ({len(body)} bytes; at most {MAX_BODY})", 413)

        def no_constants(name: str):
            raise ApiError(f"request: {name} is not a number JSON allows")

        try:
            data = json.loads(body.decode("utf-8"), parse_constant=no_constants)
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
            raise ApiError(f"request: not valid JSON: {exc}") from None
        if not isinstance(data, dict):
            raise ApiError("request: expected a JSON object")
        return data

    # -- paths

    def _job_path(self, request: dict) -> Path:
        """The job file the design belongs to (where its relative SVG paths start)."""
        text = field_of(request, "path", str, "")
        if not text:
            return self.start_dir / "untitled.toml"
        path = Path(text).expanduser()
        return path if path.is_absolute() else self.start_dir / path

    def user_path(self, text: str) -> Path:
        """A path the user typed, under the module docstring's file rule."""
        if not text.strip():
            raise ApiError("type a file name first")
        typed = Path(text).expanduser()
        if typed.is_absolute():
            return typed
        resolved = (self.start_dir / typed).resolve()
        job_dir = (self.job_path or self.start_dir / "untitled.toml").parent.resolve()
        if not any(resolved.is_relative_to(folder) for folder in (self.start_dir, job_dir)):
            raise ApiError(f"{text}: a relative path must stay inside the folder the studio was started in "
                           f"({self.start_dir}) or the job's folder ({job_dir}); type an absolute path "
                           "to use another folder", cause={"view": "file"})
        return resolved

    def display(self, path: Path) -> str:
        """``path`` relative to the start folder when inside it, else absolute."""
        path = path.resolve()
        return str(path.relative_to(self.start_dir)) if path.is_relative_to(self.start_dir) else str(path)

    def _target(self, request: dict, suffixes: tuple[str, ...] | None) -> Path:
        """Where to write; call it holding ``_write_lock`` so that the exists check and the write are one step."""
        target = self.user_path(field_of(request, "target", str))
        if suffixes and target.suffix.lower() not in suffixes:
            raise ApiError(f"{target}: expected a file name ending in {', '.join(suffixes)}", cause={"view": "file"})
        if not target.parent.is_dir():
            raise ApiError(f"{target}: folder {target.parent} does not exist; create it first", cause={"view": "file"})
        if target.is_dir():
            raise ApiError(f"{target}: is a folder; type a file name", cause={"view": "file"})
        if target.exists() and not field_of(request, "overwrite", bool, False):
            raise ApiError(f"{target} exists; replace it?", 409, exists=True, target=str(target))
        return target

    # -- jobs and designs

    def _job(self, request: dict):
        """The request's job, validated as its TOML would be; ``text`` is that TOML.

        The tables are checked as they are (reading the text back gives the same tables, a
        tested property of :func:`~foldfab.job.toml_text`), which saves parsing TOML on every edit.
        """
        from foldfab.job import job_from_data, toml_text

        data = field_of(request, "job", dict)
        return _checked(job_from_data(data, self._job_path(request), toml_text(data)))

    def _device(self, name: str):
        from foldfab.devices import load_device

        if not name:
            raise ApiError("choose a device first", cause={"view": "creases", "field": "device"})
        with self._lock:
            if name not in self._devices:
                self._devices[name] = load_device(name)
            return self._devices[name]

    def _build(self, request: dict):
        """The request's design; penetration is an error unless ``allow_penetration``."""
        from foldfab.design import LIMIT_ADVICE, build_design

        allow = field_of(request, "allow_penetration", bool, False)
        job = self._job(request)
        studio_bound = job.max_faces is None or job.max_faces > STUDIO_MAX_FACES  # else the job's own limit
        try:
            design = build_design(job, allow_penetration=True,
                                  max_faces=STUDIO_MAX_FACES if studio_bound else job.max_faces,
                                  limit_advice=STUDIO_LIMIT_ADVICE if studio_bound else LIMIT_ADVICE)
        except FoldfabError as exc:
            raise self._failure(job, str(exc)) from None
        if len(design.penetrations) and not allow:
            from foldfab.design import penetration_message

            cp = design.crease_pattern
            quads = cp.vertices_3d[cp.faces[np.unique(design.penetrations)[:4000]]]
            message = (f"{job.path}: {penetration_message(cp, design.penetrations)}; change the design, "
                       "or tick 'allow penetration' to keep it")
            raise self._failure(job, message, penetrating=quads.astype(np.float32).ravel().round(4).tolist())
        return design

    @staticmethod
    def _failure(job, message: str, **extra: Any) -> ApiError:
        """An invalid design: the message, its cause, and the polylines as given (when they can be read)."""
        from foldfab.design import profile_points, trajectory_points

        try:
            profile, trajectory = profile_points(job), trajectory_points(job)
            extra["polylines"] = {"profile": (profile - np.array(job.profile.offset)).tolist(),
                                  "trajectory": trajectory.tolist()}
            extra["feasible"] = feasible_band(profile, trajectory)
        except FoldfabError:
            pass
        return ApiError(message, cause=error_cause(message.removeprefix(f"{job.path}: ")), **extra)

    def _fit(self, design, device_name: str) -> dict | None:
        """Does the design fit the device's sheet (the job's [fabrication] settings)?"""
        from foldfab.fabrication.layout import place
        from foldfab.fabrication.spec import job_spec

        if not device_name:
            return None
        try:
            device = self._device(device_name)
            spec = job_spec(design.job)
            if spec.split or spec.split_height:
                from foldfab.fabrication.layout import reachable
                from foldfab.fabrication.pieces import design_pieces

                sheet, area, reach = reachable(design, device, spec)
                pieces = len(design_pieces(design, spec, sheet, area, reach))
                if pieces:
                    return {"device": device_name, "ok": True, "sheet": list(sheet), "margin": spec.margin,
                            "pieces": pieces, "message": f"split into {pieces} pieces for {device.name}: one "
                                                         f"{sheet[0]:g} x {sheet[1]:g} mm sheet each"}
            placement, sheet = place(design, device, spec)
        except FoldfabError as exc:
            return {"device": device_name, "ok": False, "message": str(exc).removeprefix(f"{design.job.path}: ")}
        from foldfab.studio.fabrication import sheet_outline

        w, h = placement.size
        return {"device": device_name, "ok": True, "margin": spec.margin, **sheet_outline(placement, sheet, spec.margin),
                "scale": placement.scale, "rotated": placement.rotated, "placed": [w, h],
                "message": f"fits {device.name}: {w:.1f} x {h:.1f} mm on a {sheet[0]:g} x {sheet[1]:g} mm sheet"
                           f"{' (turned 90 degrees)' if placement.rotated else ''}, margin {spec.margin:g} mm"}

    # -- handlers

    def state(self, request: dict) -> dict:
        """The session: the first job, its path, the devices and whether the queue is there."""
        from foldfab.devices import list_devices
        from foldfab.job import job_data, load_job
        from foldfab.queue.location import shown_location

        path = self.job_path or self.start_dir / "untitled.toml"
        job = job_data(_checked(load_job(path))) if self.job_path and self.job_path.is_file() else \
            {**NEW_JOB, "design": {"name": path.stem}}
        return {"job": job, "path": str(path), "display": self.display(path), "start_dir": str(self.start_dir),
                "devices": list_devices(), "queue": {"available": True, "location": shown_location()},
                "max_body": MAX_BODY}

    def design(self, request: dict) -> Response:
        """Build the design; binary answer (:func:`pack`)."""
        import time

        from foldfab.design import summary, trajectory_points

        start = time.perf_counter()
        device, seq = field_of(request, "device", str, ""), field_of(request, "seq", int, 0)
        design = self._build(request)
        built = time.perf_counter()
        fit = self._fit(design, device)
        cp, grid = design.crease_pattern, design.grid
        rank = np.zeros(len(cp.edges), np.uint8)
        for i, kind in enumerate(EDGE_GROUPS):
            rank[cp.assignment == kind] = i
        order = np.argsort(rank, kind="stable")
        counts = np.bincount(rank, minlength=len(EDGE_GROUPS)).tolist()
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).tolist()
        arrays = {
            "profile": grid.profile - np.array(design.job.profile.offset),
            "trajectory": trajectory_points(design.job),
            "planes": np.column_stack([grid.trajectory, grid.mirror_normals]),
            "paths": grid.points.astype(np.float32),
            "cp_vertices": cp.vertices.astype(np.float32),
            "model_vertices": cp.vertices_3d.astype(np.float32),
            "edges": cp.edges[order].astype(np.uint32),
            "triangles": cp.triangles()[0].astype(np.uint32),
            "penetrating": cp.faces[np.unique(design.penetrations)].astype(np.uint32),
        }
        header = {"summary": summary(design), "fit": fit, "closed": grid.closed,
                  "feasible": feasible_band(grid.profile, grid.trajectory),
                  "corner_seam": grid.corner_seam,
                  "edge_groups": {k: [s, c] for k, s, c in zip(EDGE_GROUPS, starts, counts)},
                  "seq": seq}
        header["server_ms"] = {"build": round(1000 * (built - start), 2),
                               "total": round(1000 * (time.perf_counter() - start), 2)}
        return Response(200, "application/octet-stream", pack(header, arrays))

    def open(self, request: dict) -> dict:
        """Read a job file: its tables for the views."""
        from foldfab.job import job_data, load_job

        path = self.user_path(field_of(request, "target", str))
        job = _checked(load_job(path))
        return {"job": job_data(job), "path": str(path), "display": self.display(path)}

    def files(self, request: dict) -> dict:
        """Job files in the start folder, its subfolders and the job's folder, for the open field."""
        job_dir = self._job_path(request).parent
        found: set[Path] = set()
        for pattern, folder in (("*.toml", self.start_dir), ("*/*.toml", self.start_dir), ("*.toml", job_dir)):
            if folder.is_dir():
                found.update(p.resolve() for p in sorted(folder.glob(pattern))[:200] if p.is_file())
        return {"files": sorted(self.display(p) for p in found)[:400]}

    def save(self, request: dict) -> dict:
        """Write the job file; SVG paths are rewritten relative to its new folder.

        A design ``foldfab design`` refuses is not saved (400 with ``refused``: the reason), unless
        the request says ``anyway``: then the reason is written as a comment at the top.  A design
        too large for the studio to build is saved unchecked (the command line's limit is higher)."""
        job = self._job(request)
        refused = None
        try:
            self._build(request)
        except ApiError as exc:
            if STUDIO_LIMIT_ADVICE in str(exc):
                return self._write_job(request, job, None)
            refused = str(exc).removeprefix(f"{job.path}: ")
            if not field_of(request, "anyway", bool, False):
                raise ApiError(f"not saved: 'foldfab design' refuses this job: {refused}", refused=refused,
                               cause=exc.extra.get("cause", {"view": "file"})) from None
        return self._write_job(request, job, refused)

    def _write_job(self, request: dict, job, refused: str | None) -> dict:
        """Write ``job`` to the request's target, ``refused`` (the reason) as a comment at the top."""
        from foldfab.atomic import write_text
        from foldfab.job import job_data, job_to_toml, parse_job

        with self._write_lock:
            target = self._target(request, (".toml",))
            text = refusal_comment(refused) + job_to_toml(job, target.parent)
            saved = _checked(parse_job(text, target))
            write_text(target, text)
        return {"written": str(target), "path": str(target), "display": self.display(target),
                "job": job_data(saved), "refused": refused}

    def export(self, request: dict) -> dict:
        """Write the crease pattern or model: FOLD, SVG, ORIPA .cp or a mesh, by the file's suffix."""
        from foldfab.formats.output import SUFFIX_KINDS, kind_of, write_design_files

        design = self._build(request)
        with self._write_lock:
            target = self._target(request, tuple(SUFFIX_KINDS))
            kind = kind_of(target)
            try:
                write_design_files(design, [(kind, target)])
            except OSError as exc:
                raise ApiError(f"{target}: cannot write: {exc.strerror or exc}", cause={"view": "file"}) from None
        return {"written": str(target), "kind": kind}

    def _fabricate(self, request: dict):
        """Design, device and program; a split design's sheets in one program, with a pause to
        load each new sheet (as ``foldfab plot`` makes it)."""
        from foldfab.fabricate import fabricate_sheets

        device_name = field_of(request, "device", str, "")
        design = self._build(request)
        device = self._device(device_name)
        return design, device, fabricate_sheets(design, device, one_program=True)[0]

    def preview(self, request: dict) -> dict:
        """The dry run: the program read back and drawn as the device would move."""
        from foldfab.programs.interpret import interpret
        from foldfab.programs.preview import render_preview
        from foldfab.studio.fabrication import dry_run_strokes

        design, device, fab = self._fabricate(request)
        run = interpret(fab.program, device, fab.plan.sheet)
        svg = render_preview(run, device, fab.plan)
        return {"svg": svg, "device": device.name, "strategy": fab.spec.strategy, "sheet": list(fab.plan.sheet),
                "program_bytes": len(fab.program.text), "strokes": dry_run_strokes(run)}

    def device_settings(self, request: dict) -> dict:
        """The fabrication panel's fields for a device: defaults, ranges, media presets."""
        from foldfab.studio.fabrication import device_settings

        return device_settings(self._device(field_of(request, "device", str, "")))

    def fabrication(self, request: dict) -> dict:
        """The fabrication panel: the design on the device's sheets (pieces when split), the estimate."""
        from foldfab.studio.fabrication import fabrication_answer

        design = self._build(request)
        return fabrication_answer(design, self._device(field_of(request, "device", str, "")))

    def print_template(self, request: dict) -> dict:
        """Write the printable template (``foldfab print``): PDF, or SVG pages."""
        from foldfab.printing.output import SUFFIXES
        from foldfab.studio.fabrication import print_options, write_print

        design = self._build(request)
        options = print_options(design, field_of(request, "paper", str, "A4"))
        with self._write_lock:
            return write_print(design, self._target(request, SUFFIXES), options)

    def queue(self, request: dict) -> dict:
        """Build the program now and add a snapshot of it to the plot queue."""
        from foldfab.queue.limits import MAX_COPIES, PRIORITIES
        from foldfab.queue.records import NewJob
        from foldfab.queue.snapshot import make_snapshot
        from foldfab.queue.location import open_queue

        design, device, fab = self._fabricate(request)
        copies = number_of(request, "copies", 1, 1, MAX_COPIES)
        priority = number_of(request, "priority", 0, *PRIORITIES)
        snapshot = make_snapshot(design.job.path, design.job.text, design.job.name, device, fab.program)
        job = NewJob.targeted(snapshot, field_of(request, "port", str, ""), None, device.port, priority, copies)
        store = open_queue()
        try:
            ids = store.add([job])
        finally:
            store.close()
        return {"ids": ids, "queue": str(store.location), "device": device.name, "port": job.port,
                "where": job.where(), "program_bytes": len(fab.program.text)}

    def fit_template(self, request: dict) -> dict:
        """The request's template with sizes that leave its profile room (:func:`~foldfab.geometry.feasible.fit_template`):
        ``changed`` is what the user moved (a parameter or "template"), ``previous`` its last value."""
        from foldfab.design import profile_points
        from foldfab.geometry.feasible import fit_template

        job = self._job(request)
        spec = job.trajectory
        changed = field_of(request, "changed", str, "template")
        previous = field_of(request, "previous", (int, float), None)
        params, note = fit_template(spec.template, dict(spec.params), profile_points(job), changed, previous)
        return {"trajectory": {**request["job"]["trajectory"], **params}, "note": note}

    def fold(self, request: dict) -> Response:
        """The design part-way folded (``t`` from 0, flat, to 1, folded) with its strain per vertex; binary
        answer (:func:`pack`) on the model's vertex indices (:func:`~foldfab.geometry.fold.fold_state`)."""
        from foldfab.geometry.fold import fold_state

        t = field_of(request, "t", (int, float))
        if not 0 <= t <= 1:
            raise ApiError(f"request: 't' must be from 0 to 1, got {t}")
        state = fold_state(self._build(request).crease_pattern, t)
        header = {"t": t, "max_strain": round(float(state.face_strain.max(initial=0.0)), 6),
                  "seq": field_of(request, "seq", int, 0)}
        return Response(200, "application/octet-stream", pack(header, {
            "vertices": state.vertices.astype(np.float32), "strain": state.vertex_strain.astype(np.float32)}))

    def generate_profile(self, request: dict) -> dict:
        """New profile points from a generator (:func:`~foldfab.geometry.profiles.generate`), clamped to where
        the request's trajectory leaves them room; the job's other tables are only read."""
        from foldfab.design import generated_profile
        from foldfab.geometry.profiles import MAX_POINTS

        number = (int, float)
        points = generated_profile(self._job(request), field_of(request, "kind", str),
                                   amplitude=field_of(request, "amplitude", number, 5.0),
                                   period=field_of(request, "period", number, 20.0),
                                   count=number_of(request, "points", 41, 2, MAX_POINTS),
                                   height=field_of(request, "height", number, None),
                                   passes=number_of(request, "passes", 3, 1, 1000))
        return {"points": points.round(6).tolist()}
