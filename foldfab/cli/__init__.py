"""The ``foldfab`` command line: parses arguments, calls the library, prints.

Every command is a thin layer over library functions.  Heavy modules (numpy,
trimesh, vpype) are imported inside the command functions so ``foldfab --help``
stays fast.  A :class:`~foldfab.errors.FoldfabError` becomes one line on stderr
and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

def _design_outputs(args: argparse.Namespace) -> list[tuple[str, Path]]:
    outputs = [(kind, Path(path)) for kind, path in
               (("fold", args.fold), ("svg", args.svg), ("cp", args.cp), ("mesh", args.mesh)) if path]
    from foldfab.errors import FoldfabError
    from foldfab.formats.output import MESH_SUFFIXES

    for kind, path in outputs:
        if kind == "mesh" and path.suffix.lower() not in MESH_SUFFIXES:
            raise FoldfabError(f"--mesh {path}: unknown mesh format {path.suffix!r}; use one of {', '.join(MESH_SUFFIXES)}")
        _check_folder(path, f"--{kind}")
    return outputs


def cmd_design(args: argparse.Namespace) -> int:
    """Build a design; print its summary and write the requested files."""
    from foldfab.design import load_design, summary
    from foldfab.formats.output import write_design_files

    outputs = _design_outputs(args)
    design = load_design(args.job, allow_penetration=args.allow_penetration, max_faces=args.max_faces)
    try:
        write_design_files(design, outputs)
    except OSError as exc:  # e.g. the path is a folder or not writable: one line, and every file as it was
        from foldfab.errors import FoldfabError

        kind, path = next((k, p) for k, p in outputs if str(p) == exc.filename)
        raise FoldfabError(f"--{kind} {path}: cannot write: {exc.strerror or exc}") from None
    info = summary(design)
    info["written"] = [str(p) for _, p in outputs]
    for warning in design.warnings:
        print(f"foldfab: warning: {warning}", file=sys.stderr)
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        print(format_summary(info))
    return 0


def format_summary(info: dict) -> str:
    """Human-readable summary of a design."""
    lines = [
        f"design       {info['name']}  ({info['job']})",
        f"trajectory   {'closed' if info['closed'] else 'open'}, {info['corners']} corners",
        f"line elements {info['line_elements']}, faces {info['faces']}, vertices {info['vertices']}",
    ]
    for label in ("mountain", "valley", "flat", "border"):
        c = info["creases"][label]
        lines.append(f"{label:<12} {c['count']:>7} edges  {c['length_mm']:>12.1f} mm")
    w, h = info["sheet_mm"]
    lines.append(f"sheet        {w:.1f} x {h:.1f} mm")
    lines.append(f"penetrations {info['penetrations']}")
    for path in info.get("written", []):
        lines.append(f"wrote        {path}")
    return "\n".join(lines)


PROGRAM_SUFFIXES = {"hpgl": (".hpgl", ".plt", ".hpg"), "gcode": (".gcode", ".nc", ".gc", ".ngc")}


def _fabricate(args: argparse.Namespace):
    """Design, device profile and fabrication of the command's job."""
    from foldfab.design import load_design
    from foldfab.devices import load_device
    from foldfab.fabrication.spec import fabricate

    device = load_device(args.device)
    design = load_design(args.job, allow_penetration=args.allow_penetration, max_faces=args.max_faces)
    fab = fabricate(design, device, scale=getattr(args, "scale", None))
    for warning in (*design.warnings, *fab.warnings):
        print(f"foldfab: warning: {warning}", file=sys.stderr)
    return design, device, fab


def _check_output(path: Path, option: str, suffixes: tuple[str, ...]) -> None:
    from foldfab.errors import FoldfabError

    if path.suffix.lower() not in suffixes:
        raise FoldfabError(f"{option} {path}: expected a file ending in {', '.join(suffixes)}")
    _check_folder(path, option)


def _check_folder(path: Path, option: str) -> None:
    """An output path must name a file in a folder that exists: said before any work is done."""
    from foldfab.errors import FoldfabError

    if path.is_dir():
        raise FoldfabError(f"{option} {path}: is a folder; give the name of a file in it")
    if str(path.parent) and not path.parent.is_dir():
        what = "is a file, not a folder" if path.parent.exists() else "does not exist; create it first"
        raise FoldfabError(f"{option} {path}: folder {path.parent} {what}")


def fabrication_report(fab, device) -> dict:
    """Per-layer lengths, travel before/after optimization and the time estimate of a fabrication."""
    from foldfab.programs.estimate import estimate
    from foldfab.programs.interpret import interpret

    run = interpret(fab.program, device, fab.plan.sheet)
    times = estimate(run, device)
    return {
        "device": device.name,
        "strategy": fab.spec.strategy,
        "sheet_mm": list(fab.plan.sheet),
        "optimize": fab.spec.optimize,
        "scale": fab.placement.scale,
        "scale_fitted": fab.spec.scale == "fit",
        "rotated": fab.placement.rotated,
        "warnings": list(fab.warnings),
        "layers": {name: {"drawn_mm": round(t.drawn_length, 1), "pen_lifts": t.pen_lifts,
                          "travel_mm": round(t.travel_length, 1), "time_s": round(t.time, 1)}
                   for name, t in times.layers.items()},
        "travel_mm": {"before": {k: round(v, 1) for k, v in fab.travel_before["layers"].items()},
                      "after": {k: round(v, 1) for k, v in fab.travel_after["layers"].items()},
                      "total_before": round(fab.travel_before["total"], 1),
                      "total_after": round(fab.travel_after["total"], 1)},
        "pauses": [p.message for p in run.pauses],
        "estimated_time_s": round(times.total, 1),
        "lower_bound_s": round(times.lower_bound, 1),
        "program_bytes": len(fab.program.text),
    }


def format_report(info: dict) -> str:
    """Human-readable fabrication report."""
    from foldfab.fabrication.spec import placement_text

    lines = [f"device       {info['device']}  strategy {info['strategy']}  sheet {info['sheet_mm'][0]:g} x {info['sheet_mm'][1]:g} mm",
             f"placement    {placement_text(info['scale'], info['scale_fitted'], info['rotated'])}"]
    for name, layer in info["layers"].items():
        lines.append(f"{name:<12} {layer['drawn_mm']:>9.1f} mm drawn {layer['pen_lifts']:>6} pen lifts "
                     f"{layer['travel_mm']:>9.1f} mm travel {layer['time_s']:>8.1f} s")
    before, after = info["travel_mm"]["before"], info["travel_mm"]["after"]
    lines.append(f"pen-up travel ({info['optimize']}): {info['travel_mm']['total_before']:.1f} mm -> "
                 f"{info['travel_mm']['total_after']:.1f} mm")
    for key in after:
        lines.append(f"  {key:<16} {before.get(key, 0.0):>10.1f} -> {after[key]:>10.1f} mm")
    for message in info["pauses"]:
        lines.append(f"pause        {message}")
    lines.append(f"estimate     {info['estimated_time_s']:.1f} s (lower bound {info['lower_bound_s']:.1f} s)")
    return "\n".join(lines)


def cmd_export(args: argparse.Namespace) -> int:
    """Write the plotter program of a job for a device."""
    from foldfab.atomic import write_text
    from foldfab.devices import load_device

    output = Path(args.output)
    device = load_device(args.device)
    _check_output(output, "-o", PROGRAM_SUFFIXES[device.protocol])
    design, device, fab = _fabricate(args)
    info = fabrication_report(fab, device)
    write_text(output, fab.program.text)
    info["written"] = str(output)
    print(json.dumps(info, indent=2) if args.json else format_report(info) + f"\nwrote        {output}")
    return 0


def cmd_preview(args: argparse.Namespace) -> int:
    """Render the dry run: the program read back and drawn as the machine would move."""
    output = Path(args.output)
    _check_output(output, "-o", (".svg",))
    design, device, fab = _fabricate(args)
    _write_preview(fab, device, output)
    info = fabrication_report(fab, device)
    info["written"] = str(output)
    print(json.dumps(info, indent=2) if args.json else format_report(info) + f"\nwrote        {output}")
    return 0


def _add_fabrication_args(parser: argparse.ArgumentParser, output_help: str) -> None:
    parser.add_argument("job", help="job file (TOML)")
    parser.add_argument("--device", required=True, metavar="NAME",
                        help="device profile: a built-in name, a profile in your config folder, or a .toml path")
    parser.add_argument("-o", "--output", required=True, metavar="OUT", help=output_help)
    parser.add_argument("--allow-penetration", action="store_true", help="fabricate a design whose faces intersect")
    _add_max_faces(parser)
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    _add_scale_arg(parser)


def _add_scale_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scale", type=_scale, metavar="S|fit",
                        help="scale of the design on the sheet instead of the job's [fabrication].scale: a number "
                             "> 0, or fit: the largest that fits the sheet and the device's reach")


def _scale(text: str) -> float | str:
    """An argparse type: ``fit`` or a finite number > 0."""
    import math

    if text == "fit":
        return text
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0 or fit, got {text!r}")
    return value


def _add_max_faces(parser: argparse.ArgumentParser) -> None:
    from foldfab.limits import MAX_FACES

    parser.add_argument("--max-faces", type=_positive_int, metavar="N",
                        help=f"build a design of up to N faces (default: the job's [design].max_faces, "
                             f"else {MAX_FACES:,})")



# --- foldfab plot ----------------------------------------------------------------------------


def _operator(args: argparse.Namespace, prompting: list[bool]):
    """Answers the program's pauses: a prompt on a terminal, yes with --yes, else None."""
    if sys.stdin.isatty():
        def ask(message: str) -> bool:
            print(f"\npause: {message}", file=sys.stderr)
            answer = _ask(prompting, "Press Enter to continue, or type q and Enter to stop: ")
            return answer is not None and answer.strip().lower() not in ("q", "quit", "stop")
        return ask
    if args.yes:
        def scripted(message: str) -> bool:
            print(f"foldfab: pause (answered by --yes): {message}", file=sys.stderr)
            return True
        return scripted
    return None


class _NotStarted(Exception):
    """A stop (a signal, or no at the prompt) before the first byte was sent."""


def _chooser(args: argparse.Namespace, prompting: list[bool]):
    """Asks, on a terminal (not with --json), where a resume starts when the plotter's position is
    doubtful proof (:class:`foldfab.plotting.resume.Location`); None elsewhere: the resume then stops."""
    if args.json or not sys.stdin.isatty():
        return None

    def choose(location) -> int | None:
        left = location.strokes - location.acknowledged
        trusted = (f"resume at stroke {location.stroke + 1}, where its position places it" if
                   location.stroke < location.strokes else "the job is finished: end it (the token is deleted)")
        print(f"\nfoldfab: where the plot stopped is uncertain: {location.doubt}.\n"
              f"  a  resume at stroke {location.acknowledged + 1} of {location.strokes}, the last acknowledged "
              f"({left} strokes; those the plotter drew since are drawn again)\n"
              f"  p  trust the plotter: {trusted}\n"
              "  q  stop here; the resume token stays valid", file=sys.stderr)
        while True:
            answer = _ask(prompting, "Look at the sheet, then type a, p or q and Enter: ")
            if answer is None:
                return None
            answer = answer.strip().lower()
            if answer in ("a", "p", "q"):
                return {"a": location.acknowledged, "p": location.stroke, "q": None}[answer]
    return choose


def cmd_plot(args: argparse.Namespace) -> int:
    """Build the job's program as ``export`` does, report it, and stream it to the plotter.

    The signal handlers come first, before the heavy imports, so that Ctrl-C, SIGTERM or
    SIGHUP at any moment ends the same clean way: before the first byte a signal only sets
    the cancel event, looked at before each step, and the plot stops with nothing sent; once
    sending, the engine stops safely on it (a second signal stops waiting for that)."""
    import signal
    import threading

    cancel, sending, prompting = threading.Event(), [False], [False]

    def interrupt(signum, frame):
        if prompting[0] or (sending[0] and cancel.is_set()):
            raise KeyboardInterrupt
        first = not cancel.is_set()
        cancel.set()
        if sending[0] and first:
            try:
                print("\nfoldfab: stopping: finishing the current command and lifting the tool "
                      "(Ctrl-C again to stop waiting)", file=sys.stderr)
            except OSError:  # the terminal was closed (SIGHUP)
                pass

    stops = [s for s in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, s)]
    previous = {name: signal.signal(getattr(signal, name), interrupt) for name in stops}
    try:
        return _plot(args, cancel, sending, prompting)
    except _NotStarted:
        after = ("the resume token stays valid: run the same command again" if args.resume else
                 "nothing to resume")
        try:
            print(f"foldfab: stopped: stopped before anything was sent; {after}", file=sys.stderr)
        except OSError:
            pass
        return 130
    finally:
        for name, handler in previous.items():
            signal.signal(getattr(signal, name), handler)


def _plot(args: argparse.Namespace, cancel, sending: list[bool], prompting: list[bool]) -> int:
    """:func:`cmd_plot` once its signal handlers are in place."""
    import shlex

    from foldfab.errors import FoldfabError
    from foldfab.plotting.progress import reporter
    from foldfab.plotting.resume import PlotStopped, ResumeAmbiguous, ResumeNotStarted, plot

    def checkpoint() -> None:
        if cancel.is_set():
            raise _NotStarted

    checkpoint()
    if args.preview:
        _check_output(Path(args.preview), "--preview", (".svg",))
    design, device, fab = _fabricate(args)
    if args.json:
        for warning in fab.warnings:
            print(json.dumps({"event": "warning", "message": warning}), flush=True)
    checkpoint()
    port = args.port or device.port
    if not port:
        raise FoldfabError(f"{device.name} has no port: give --port PORT (a serial port such as /dev/ttyUSB0, "
                           f"or the simulated plotter sim://), or set port in {device.source}")
    info = fabrication_report(fab, device)
    if args.preview:
        _write_preview(fab, device, Path(args.preview))
        info["written"] = args.preview
    operator = _operator(args, prompting)
    if fab.program.pauses and operator is None:
        raise FoldfabError(f"this job pauses {len(fab.program.pauses)} time(s) for the operator "
                           f"({fab.program.pauses[0].message}); run it on a terminal, or pass --yes "
                           "to continue at every pause without asking")
    print(json.dumps({"event": "report", **info}) if args.json else
          format_report(info) + (f"\nwrote        {args.preview}" if args.preview else ""), flush=True)
    _load_sheet(args, port, fab.plan.sheet, device.name, cancel, prompting)
    checkpoint()
    seen: dict = {}
    show = reporter(sys.stdout, args.json)

    def events(event) -> None:
        seen.setdefault(event.kind, event)
        seen["last"] = event
        show(event)

    sending[0] = True
    try:
        result = plot(fab.program, device, job=args.job, port=port, resume=args.resume, baudrate=args.baud,
                      xonxoff=args.xonxoff, rtscts=args.rtscts, events=events, cancel=cancel, operator=operator,
                      choose=_chooser(args, prompting),
                      from_stroke=None if args.from_stroke is None else args.from_stroke - 1)
    except PlotStopped as stop:
        message = str(stop)
        if stop.token:
            if args.json:
                print(json.dumps({"event": "resume_token", "token": stop.token, "stroke": stop.stroke,
                                  "strokes": stop.strokes}), flush=True)
            message += f"; to finish the job run: {shlex.join(_resume_command(args, port, stop.token))}"
        kind = "stopped" if stop.exit_code == 130 else "error"
        print(f"foldfab: {kind}: {message}", file=sys.stderr)
        return stop.exit_code
    except ResumeAmbiguous as exc:
        where = exc.location
        command = _resume_command(args, port, exc.token)
        if args.json:
            print(json.dumps({"event": "resume_ambiguous", "token": exc.token, "acknowledged": where.acknowledged + 1,
                              "located": where.stroke + 1, "strokes": where.strokes, "reason": where.doubt}),
                  flush=True)
        trusted = shlex.join(command + ["--from-stroke", str(where.stroke + 1)]) + (
            " (if the plotter did draw them)" if where.stroke < where.strokes else
            " (if every stroke is on the sheet: ends the job, deleting the token)")
        raise FoldfabError(f"{exc}; nothing was sent and the resume token stays valid; look at the sheet, then run "
                           f"{shlex.join(command + ['--from-stroke', str(where.acknowledged + 1)])} (from the last "
                           f"acknowledged stroke) or {trusted}") from None
    except ResumeNotStarted as exc:  # once the fault is mended, the same command finishes the job
        chosen = ["--from-stroke", str(args.from_stroke)] if args.from_stroke else []  # (a stop saves a new state)
        raise FoldfabError(f"{exc}; nothing was sent, and the resume token stays valid: "
                           f"{shlex.join(_resume_command(args, port, exc.token) + chosen)}") from None
    from foldfab.plotting.progress import plot_summary

    summary = plot_summary(seen.get("start"), seen["last"], result.waited)
    print(json.dumps({"event": "summary", **summary}) if args.json else format_plot_summary(summary), flush=True)
    return 0


def _load_sheet(args: argparse.Namespace, port: str, sheet, device: str, cancel, prompting: list[bool]) -> None:
    """On a terminal, without --yes and on a real plotter (not ``sim://``): the operator loads
    the sheet and presses Enter; Ctrl-C, end of input or a signal there stop with nothing sent."""
    if args.yes or port.startswith("sim://") or not sys.stdin.isatty():
        return
    what = ("Check the partly drawn sheet is still in place" if args.resume else
            f"Load a {sheet[0]:g} x {sheet[1]:g} mm sheet")
    print(f"{what} on the {device}, then press Enter to start (Ctrl-C: stop): ", end="", file=sys.stderr,
          flush=True)
    if _ask(prompting, cancel=cancel) is None:
        raise _NotStarted


def _ask(prompting: list[bool], prompt: str = "", cancel=None) -> str | None:
    """A line the operator types; None at end of input or on a signal: while ``prompting``,
    :func:`cmd_plot`'s handler raises KeyboardInterrupt, which ends the question, not the plot
    (``cancel``: a stop already asked for before the question)."""
    prompting[0] = True
    try:
        return None if cancel is not None and cancel.is_set() else input(prompt)
    except (EOFError, KeyboardInterrupt):
        return None
    finally:
        prompting[0] = False


def format_plot_summary(summary: dict) -> str:
    """The line ``foldfab plot`` prints when the job is done."""
    waited = f", {summary['waited_s']:.1f} s waiting for the operator" if summary["waited_s"] else ""
    return (f"plotted      {summary['drawn_mm']:.1f} mm drawn, {summary['pen_lifts']} pen lifts, in "
            f"{summary['time_s']:.1f} s (estimate {summary['estimated_time_s']:.1f} s){waited}")


def _resume_command(args: argparse.Namespace, port: str, token: str) -> list[str]:
    """The ``foldfab plot`` command that finishes a stopped plot: this one's job, device, port,
    link settings and answers to pauses, with ``--resume``."""
    command = ["foldfab", "plot", args.job, "--device", args.device, "--port", port]
    if args.baud:
        command += ["--baud", str(args.baud)]
    for switch in ("xonxoff", "rtscts"):
        if getattr(args, switch) is not None:
            command.append(f"--{switch}" if getattr(args, switch) else f"--no-{switch}")
    if args.max_faces:
        command += ["--max-faces", str(args.max_faces)]
    command += [f"--{flag.replace('_', '-')}" for flag in ("yes", "json", "allow_penetration") if getattr(args, flag)]
    if args.scale is not None:  # the same scale makes the same program, which the token is for
        command += ["--scale", str(args.scale)]
    return command + ["--resume", token]


def _write_preview(fab, device, output: Path) -> None:
    """The dry-run SVG of a fabrication (``foldfab preview``, ``foldfab plot --preview``)."""
    from foldfab.atomic import write_text
    from foldfab.programs.interpret import interpret
    from foldfab.programs.preview import render_preview

    write_text(output, render_preview(interpret(fab.program, device, fab.plan.sheet), device, fab.plan,
                                      notes=[fab.placement_summary]))


def _add_plot_parser(sub) -> None:
    plot = sub.add_parser("plot", help="send a job to a plotter, with progress, safe stop and resume",
                          description="Build the job's program as 'foldfab export' does and stream it to "
                                      "the plotter with its handshake.  Ctrl-C stops safely (tool up) and "
                                      "prints how to resume.")
    plot.add_argument("job", help="job file (TOML)")
    plot.add_argument("--device", required=True, metavar="NAME",
                      help="device profile: a built-in name, a profile in your config folder, or a .toml path")
    plot.add_argument("--port", metavar="PORT",
                      help="serial port or pyserial URL (default: the profile's port); sim:// for the "
                           "simulated plotter of the device (options: sim://?time=fast)")
    plot.add_argument("--preview", metavar="OUT.svg", help="also write the dry-run preview SVG")
    plot.add_argument("--baud", type=_positive_int, metavar="N", help="baud rate instead of the profile's")
    plot.add_argument("--xonxoff", action=argparse.BooleanOptionalAction, default=None,
                      help="software flow control on the port (default: the profile's)")
    plot.add_argument("--rtscts", action=argparse.BooleanOptionalAction, default=None,
                      help="hardware flow control on the port (default: the profile's)")
    plot.add_argument("--resume", type=_token, metavar="TOKEN", help="finish a stopped plot (foldfab printed the token)")
    plot.add_argument("--from-stroke", type=_int_from(1, None, "expected a stroke number, 1 or more"), metavar="N",
                      help="with --resume: resume at stroke N (as foldfab numbers them; one past the last: the "
                           "job is done) instead of where the plotter says it stopped; foldfab asks for this "
                           "when that is uncertain")
    plot.add_argument("--yes", action="store_true", help="start without asking to load the sheet; without a "
                      "terminal, continue at every pause")
    plot.add_argument("--json", action="store_true", help="progress as JSON lines on stdout")
    plot.add_argument("--allow-penetration", action="store_true", help="fabricate a design whose faces intersect")
    _add_scale_arg(plot)
    _add_max_faces(plot)
    plot.set_defaults(func=cmd_plot)

# --- foldfab queue ---------------------------------------------------------------------------


def _queue_store(args: argparse.Namespace):
    from foldfab.queue.sqlite import SqliteQueueStore, default_queue_path

    return SqliteQueueStore(args.queue or default_queue_path(), wait=args.wait)


def _when(seconds: float) -> str:
    import time

    return time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(seconds))


def cmd_queue_add(args: argparse.Namespace) -> int:
    """Build every job now (a bad job fails here, nothing is added) and queue the snapshots."""
    from foldfab.errors import FoldfabError
    from foldfab.queue.records import NewJob
    from foldfab.queue.snapshot import make_snapshot

    new = []
    for job in args.jobs:
        design, device, fab = _fabricate(argparse.Namespace(job=job, device=args.device, scale=args.scale,
                                                            allow_penetration=args.allow_penetration,
                                                            max_faces=args.max_faces))
        port = args.port or device.port
        if not port:
            raise FoldfabError(f"{device.name} has no port: give --port PORT (a serial port such as /dev/ttyUSB0, "
                               f"or a simulated plotter such as sim://{device.name}), or set port in {device.source}")
        snapshot = make_snapshot(design.job.path, design.job.text, design.job.name, device, fab.program)
        new.append(NewJob(snapshot, port, args.priority, args.copies))
    store = _queue_store(args)
    ids = iter(store.add(new))
    for item in new:
        numbers = [next(ids) for _ in range(item.copies)]
        label = f"job {numbers[0]}" if len(numbers) == 1 else f"jobs {numbers[0]}-{numbers[-1]}"
        print(f"queued {label}: {item.snapshot.name} on {item.snapshot.device} at {item.port}, "
              f"{len(item.snapshot.program.text)} bytes, priority {item.priority} ({store.location})")
    return 0


def format_job_line(job) -> str:
    """One row of ``foldfab queue list``."""
    name = job.name if job.copies == 1 else f"{job.name} ({job.copy}/{job.copies})"
    state = job.state + ("*" if job.cancel_requested else "")
    port = job.port if len(job.port) <= 24 else job.port[:23] + "~"
    return f"{job.id:>5} {state:<12} {job.priority:>4} {job.percent:>5.1f}%  {job.device:<16} {port:<24} {name}"


def cmd_queue_list(args: argparse.Namespace) -> int:
    """List jobs in the queue, oldest first."""
    store = _queue_store(args)
    jobs = store.jobs(args.state)
    if args.json:
        print(json.dumps([job.as_dict() for job in jobs], indent=1))
    elif not jobs:
        print(f"no {args.state + ' ' if args.state else ''}jobs in {store.location}")
    else:
        lines = [f"{'ID':>5} {'STATE':<12} {'PRI':>4} {'DONE':>6}  {'DEVICE':<16} {'PORT':<24} NAME"]
        lines.extend(format_job_line(job) for job in jobs)
        if any(job.cancel_requested for job in jobs):
            lines.append("* cancel requested: the worker stops the plotter")
        if any(len(job.port) > 24 for job in jobs):
            lines.append("~ port shortened: foldfab queue show ID has it whole")
        print("\n".join(lines))
    return 0


def format_job(job, events) -> str:
    """``foldfab queue show``: the job and its event log."""
    copy = f" (copy {job.copy} of {job.copies})" if job.copies > 1 else ""
    lines = [f"job {job.id}    {job.name}{copy}",
             f"state        {job.state}" + (" (cancel requested)" if job.cancel_requested else "")
             + (f": {job.reason}" if job.reason else ""),
             f"device       {job.device} at {job.port}",
             f"priority     {job.priority}",
             f"job file     {job.job_path} (as it was when queued)",
             f"progress     {job.percent:.1f}% done"
             + (f" ({job.drawn_mm:.1f} of {job.drawn_total_mm:.1f} mm drawn)" if job.drawn_total_mm else "")
             + (f", {job.progress}" if job.progress else "")
             + f"; {job.acked_bytes} of {job.program_bytes} bytes acknowledged",
             f"attempts     {job.attempts}"]
    if job.worker:
        lines.append(f"worker       {job.worker}, lease until {_when(job.lease_expires)}")
    lines.append("events")
    lines.extend(f"  {_when(e.time)}  {e.kind:<11} {e.message}" for e in events)
    return "\n".join(lines)


def cmd_queue_show(args: argparse.Namespace) -> int:
    """Show one job with its event log."""
    store = _queue_store(args)
    job, events = store.job(args.id), store.events(args.id)
    if args.json:
        print(json.dumps({"job": job.as_dict(), "events": [e.__dict__ for e in events]}, indent=1))
    else:
        print(format_job(job, events))
    return 0


def cmd_queue_cancel(args: argparse.Namespace) -> int:
    """Cancel a job; a running one is stopped safely by its worker."""
    job = _queue_store(args).cancel(args.id)
    print(f"job {job.id}: cancel requested; worker {job.worker} stops the plotter (pen up, parked)"
          if job.cancel_requested else f"job {job.id} cancelled")
    return 0


def cmd_queue_retry(args: argparse.Namespace) -> int:
    """Queue a failed, cancelled or interrupted job again."""
    job = _queue_store(args).retry(args.id, restart=args.restart, port=args.port)
    where = (f"resumes at byte {job.acked_bytes} of {job.program_bytes}, before any other job at {job.port} "
             "(--restart: from the start, new sheet)" if job.acked_bytes else "runs from the start")
    print(f"job {job.id} queued again: {where}")
    return 0


def cmd_queue_continue(args: argparse.Namespace) -> int:
    """The operator has acted at the pause (flipped the sheet): let the worker go on."""
    job = _queue_store(args).continue_job(args.id, "foldfab queue continue")
    print(f"job {job.id} continues on worker {job.worker}")
    return 0


def cmd_queue_remove(args: argparse.Namespace) -> int:
    """Delete a job and its log."""
    _queue_store(args).remove(args.id)
    print(f"job {args.id} removed")
    return 0


def cmd_queue_clear(args: argparse.Namespace) -> int:
    """Delete finished jobs."""
    count = _queue_store(args).clear(["done"])
    print(f"removed {count} done job{'s' if count != 1 else ''}")
    return 0


class QueueConsole:
    """The worker's terminal: job lines, the progress display of ``foldfab plot``, and pauses
    answered with Enter (without a terminal: ``foldfab queue continue ID``); ``rehearsal``: the
    dry run answers pauses itself, so nothing is asked."""

    def __init__(self, rehearsal: bool = False):
        from foldfab.plotting.progress import reporter

        self.report = reporter(sys.stdout)
        self.terminal = sys.stdin.isatty()
        self.rehearsal = rehearsal

    def job_started(self, job, note: str) -> None:
        print(f"job {job.id}: {job.name} on {job.device} at {job.port}: {note}", flush=True)

    def progress(self, event) -> None:
        self.report(event)

    def paused(self, job, message: str) -> None:
        if self.rehearsal:
            print(f"job {job.id} pauses: {message}", flush=True)
            return
        how = ("press Enter to continue, or type c and Enter to cancel the job" if self.terminal
               else f"when done, run: foldfab queue continue {job.id}")
        print(f"job {job.id} waits: {message}\n{how}", flush=True)

    def answer(self, timeout: float) -> str | None:
        import select
        import time

        if not self.terminal:
            time.sleep(timeout)
            return None
        if not select.select([sys.stdin], [], [], timeout)[0]:
            return None
        line = sys.stdin.readline()
        if not line:  # end of input: from now on only foldfab queue continue answers
            self.terminal = False
            return None
        return "cancel" if line.strip().lower() in ("c", "cancel") else "continue"

    def job_ended(self, job, state: str, message: str) -> None:
        print(f"job {job.id} {state}: {message}", flush=True)


def cmd_queue_run(args: argparse.Namespace) -> int:
    """Plot queued jobs (or rehearse them on simulated plotters with --dry-run).  SIGTERM (a service
    manager's stop) and SIGHUP (a closed terminal) act as Ctrl-C: the tool is lifted and the job is
    left interrupted, to resume; the handlers come first, so a signal while starting ends as cleanly."""
    import signal

    worker = []  # the Worker once it exists: a signal then stops it through events, never lost
    signalled, rehearsing = [], [False]

    def interrupt(signum, frame) -> None:
        if worker and not worker[0].interrupting:
            worker[0].interrupt()
        elif signalled or rehearsing[0] or worker:  # a second signal: stop waiting for the safe stop
            raise KeyboardInterrupt
        else:  # while starting: noted, and acted on once the worker exists (never raised inside an import)
            signalled.append(signum)

    stops = [getattr(signal, s) for s in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, s)]
    previous = {sig: signal.signal(sig, interrupt) for sig in stops}
    try:
        from foldfab.errors import FoldfabError
        from foldfab.queue.worker import Worker, WorkerOptions, rehearse

        options = WorkerOptions(device=args.device, port=args.port, mode=args.mode, lease=args.lease)
        store, console = _queue_store(args), QueueConsole(rehearsal=args.dry_run)
        if args.dry_run:
            rehearsing[0] = True
            if signalled:
                raise KeyboardInterrupt
        else:
            worker.append(Worker(store, console, options))
            if signalled:
                worker[0].interrupt()  # its run ends before claiming anything
        summary = rehearse(store, console, options) if args.dry_run else worker[0].run()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if not summary.ended:
        print(f"nothing to run in {store.location}" + (" for these filters" if args.device or args.port else ""))
        return 0
    print("; ".join(f"{len(ids)} {state} ({', '.join(map(str, ids))})" for state, ids in summary.ended.items()))
    trouble = {state: ids for state, ids in summary.ended.items() if state not in ("done", "cancelled")}
    if trouble:
        raise FoldfabError(", ".join(f"{len(ids)} job(s) {state}" for state, ids in trouble.items())
                           + ": foldfab queue show ID says why" + ("" if args.dry_run else
                           "; run again to resume interrupted jobs, foldfab queue retry ID a failed one"))
    return 0


def _positive_int(text: str) -> int:
    """An argparse type: a whole number, 1 or more."""
    return _int_from(1, None, "expected a whole number")(text)


def _token(text: str) -> str:
    """An argparse type: a resume token, not empty (``--resume "$TOKEN"`` with TOKEN unset must not
    plot the whole job again)."""
    from foldfab.plotting.resume import TOKEN_PATTERN

    if not TOKEN_PATTERN.fullmatch(text):
        raise argparse.ArgumentTypeError("expected the resume token foldfab printed when the plot stopped "
                                         f"(6 to 32 characters 0-9 and a-f), got {text!r}")
    return text


def _int_from(low: int, high: int | None, what: str):
    """An argparse type: a whole number from ``low`` to ``high`` (None: no upper bound)."""
    def whole(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < low or (high is not None and value > high):
            bounds = f"from {low} to {high}" if high is not None else f"of {low} or more"
            raise argparse.ArgumentTypeError(f"{what} {bounds}, got {value}")
        return value
    return whole


def _seconds_from(low: float, what: str):
    """An argparse type: a finite number of seconds, ``low`` or more."""
    def seconds(text: str) -> float:
        import math

        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
        if not (math.isfinite(value) and value >= low):
            raise argparse.ArgumentTypeError(f"{what}, got {text}")
        return value
    return seconds


def _port(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a serial port or pyserial URL (such as /dev/ttyUSB0 or "
                                         "sim://grbl), got an empty one")
    return text


def _add_queue_parser(sub) -> None:
    """``foldfab queue ...``: the persistent job queue."""
    from foldfab.queue.records import (DEFAULT_HEARTBEAT, DEFAULT_LEASE, LEASE_HEARTBEATS, MAX_COPIES, MIN_LEASE,
                                       PRIORITIES, STATES)
    from foldfab.queue.sqlite import MAX_JOB_ID
    from foldfab.queue.store import DEFAULT_WAIT

    job_id = _int_from(1, MAX_JOB_ID, "expected a job id")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--queue", metavar="PATH", help="queue file (default: $FOLDFAB_QUEUE, else "
                        "$XDG_DATA_HOME/foldfab/queue.sqlite3, default ~/.local/share)")
    common.add_argument("--wait", type=_seconds_from(0, "expected 0 seconds or more"), default=DEFAULT_WAIT,
                        metavar="SECONDS",
                        help=f"how long to wait while another foldfab writes the queue (default {DEFAULT_WAIT:g})")
    queue = sub.add_parser("queue", help="a persistent job queue for one or several plotters",
                           description="Line up sheets and let workers plot them; survives crashes and "
                                       "pulled cables without losing or duplicating a sheet.")
    commands = queue.add_subparsers(dest="queue_command", metavar="ACTION", required=True)

    add = commands.add_parser("add", parents=[common], help="build jobs now and queue them",
                              description="Build each job's program now (a bad job is an error here and nothing "
                                          "is added) and queue a snapshot: later edits of the files change nothing.")
    add.add_argument("jobs", nargs="+", metavar="JOB.toml", help="job files")
    add.add_argument("--device", required=True, metavar="NAME", help="device profile (name or .toml path)")
    add.add_argument("--port", type=_port, metavar="PORT",
                     help="serial port or pyserial URL (default: the profile's port)")
    add.add_argument("--copies", type=_int_from(1, MAX_COPIES, "expected copies"), default=1, metavar="N",
                     help=f"sheets of each job, up to {MAX_COPIES} (default 1)")
    add.add_argument("--priority", type=_int_from(*PRIORITIES, "expected a priority"), default=0, metavar="P",
                     help=f"higher runs first, {PRIORITIES[0]} to {PRIORITIES[1]} (default 0)")
    add.add_argument("--allow-penetration", action="store_true", help="queue a design whose faces intersect")
    _add_scale_arg(add)
    _add_max_faces(add)
    add.set_defaults(func=cmd_queue_add)

    listing = commands.add_parser("list", parents=[common], help="list jobs")
    listing.add_argument("--state", choices=STATES, help="only jobs in this state")
    listing.add_argument("--json", action="store_true", help="print JSON")
    listing.set_defaults(func=cmd_queue_list)

    show = commands.add_parser("show", parents=[common], help="one job and its event log")
    show.add_argument("id", type=job_id, metavar="ID")
    show.add_argument("--json", action="store_true", help="print JSON")
    show.set_defaults(func=cmd_queue_show)

    for name, func, text in (("cancel", cmd_queue_cancel, "cancel a job (a running one stops safely)"),
                             ("retry", cmd_queue_retry, "queue a failed, cancelled or interrupted job again"),
                             ("continue", cmd_queue_continue, "go on after a pause (the sheet is flipped)"),
                             ("remove", cmd_queue_remove, "delete a job that is not running")):
        action = commands.add_parser(name, parents=[common], help=text)
        action.add_argument("id", type=job_id, metavar="ID")
        action.set_defaults(func=func)
        if name == "retry":
            action.add_argument("--restart", action="store_true",
                                help="from the start on a new sheet, not from the last acknowledged stroke")
            action.add_argument("--port", type=_port, metavar="PORT", help="on this port from now on (the "
                                "plotter's new device path, or another plotter of the same model)")

    clear = commands.add_parser("clear", parents=[common], help="delete finished jobs")
    clear.add_argument("--done", action="store_true", required=True, help="delete every done job")
    clear.set_defaults(func=cmd_queue_clear)

    run = commands.add_parser("run", parents=[common], help="plot queued jobs (a worker)",
                              description="Plot jobs in priority and arrival order, one at a time, with the "
                                          "progress display of foldfab plot.  Run one worker per plotter (or "
                                          "several on one queue: they never run the same job).  A job whose "
                                          "worker died is resumed from its last acknowledged stroke.")
    run.add_argument("--device", metavar="NAME", help="only jobs for this device profile")
    run.add_argument("--port", type=_port, metavar="PORT", help="only jobs for this port")
    modes = run.add_mutually_exclusive_group()
    modes.add_argument("--until-empty", dest="mode", action="store_const", const="until-empty",
                       help="stop when no job is runnable (the default)")
    modes.add_argument("--once", dest="mode", action="store_const", const="once", help="run one job at most")
    modes.add_argument("--follow", dest="mode", action="store_const", const="follow",
                       help="keep running, waiting for new jobs")
    run.set_defaults(mode="until-empty")
    run.add_argument("--dry-run", action="store_true",
                     help="stream every runnable job (one with --once) to a simulated plotter of its device; the queue "
                          "is not changed")
    lease = _seconds_from(MIN_LEASE, f"expected at least {MIN_LEASE:g} seconds ({LEASE_HEARTBEATS} of the "
                                     f"worker's heartbeats, one every {DEFAULT_HEARTBEAT:g} s)")
    run.add_argument("--lease", type=lease, default=DEFAULT_LEASE, metavar="SECONDS",
                     help=f"a job whose worker is silent this long is interrupted (default {DEFAULT_LEASE:g}, "
                          f"at least {MIN_LEASE:g})")
    run.set_defaults(func=cmd_queue_run)


def cmd_sim(args: argparse.Namespace) -> int:
    """Serve a simulated plotter on a pseudo-terminal until SIGINT/SIGTERM; report what it did."""
    import signal
    import threading

    from foldfab.devices import load_device
    from foldfab.errors import FoldfabError
    from foldfab.sim import create_simulator, parse_options
    from foldfab.sim.pty import serve_pty

    device = load_device(args.device)
    pairs = [("time", args.time)]
    for item in args.option:
        key, sep, value = item.partition("=")
        if not sep:
            raise FoldfabError(f"--option {item!r}: expected KEY=VALUE, e.g. noise=0.001")
        pairs.append((key.strip(), value))
    options = parse_options(pairs, "foldfab sim")
    outputs = [(path, kind) for path, kind in ((args.record, "json"), (args.svg, "svg")) if path]
    for path, kind in outputs:
        _check_output(Path(path), "--record" if kind == "json" else "--svg", (f".{kind}",))
    sim = create_simulator(device, options)
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        serve_pty(sim, lambda path: print(path, flush=True), stop, lambda job: print(job.line(), flush=True))
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    for path, kind in outputs:
        {"json": sim.write_json, "svg": sim.write_svg}[kind](path)
    strokes = sim.strokes
    print(f"strokes      {len(strokes)} drawn, {sum(s.length for s in strokes):.1f} mm")
    print(sim.stats.summary())
    for path, _ in outputs:
        print(f"wrote        {path}")
    return 0


def _add_sim_parser(sub) -> None:
    sim = sub.add_parser("sim", help="run a simulated plotter on a pseudo-terminal",
                         description="Serve a simulated plotter of a device profile on a pseudo-terminal: "
                                     "the first line printed is its path (e.g. /dev/pts/5), which any "
                                     "program opens like the real port.  Prints a line per job it served "
                                     "(bytes received, length drawn, time on its clock); runs until "
                                     "interrupted, then writes the recordings and prints the statistics.")
    sim.add_argument("device", metavar="NAME", help="device profile: a built-in name, a profile in your "
                                                    "config folder, or a .toml path")
    sim.add_argument("--pty", action="store_true", help="serve on a pseudo-terminal (the default and only mode)")
    sim.add_argument("--time", default="real", metavar="MODE",
                     help="real: at the plotter's own speed; fast: 50 times faster (-o speedup=N); instant: as "
                          "fast as it can be simulated; the statistics stay true (as sim://?time=)")
    sim.add_argument("-o", "--option", action="append", default=[], metavar="KEY=VALUE",
                     help="simulator option, as in sim:// URLs (noise=0.001, stall=5, flow=xonxoff, ...); repeatable")
    sim.add_argument("--record", metavar="OUT.json", help="write the statistics and drawn strokes as JSON")
    sim.add_argument("--svg", metavar="OUT.svg", help="write the drawn strokes as a preview SVG")
    sim.set_defaults(func=cmd_sim)


def cmd_studio(args: argparse.Namespace) -> int:
    """Serve the four-view designer on 127.0.0.1 and open a browser on it."""
    from foldfab.studio.api import Studio
    from foldfab.studio.server import serve

    studio = Studio(Path.cwd(), Path(args.job) if args.job else None)
    if args.job and not Path(args.job).exists():
        print(f"foldfab studio: {args.job} does not exist yet: a new design, saved there when you save")
    try:
        serve(studio, args.port, not args.no_browser,
              announce=lambda url: print(f"foldfab studio: {url}  (Ctrl-C stops)", flush=True))
    except KeyboardInterrupt:
        print("\nfoldfab studio: stopped")
    return 0


def _port_number(text: str) -> int:
    value = int(text)
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"expected 0 to 65535, got {value}")
    return value


def _add_studio_parser(sub) -> None:
    studio = sub.add_parser("studio", help="the four-view designer in the browser",
                            description="Design interactively: profile, trajectory (top view), crease pattern "
                                        "and 3D model, updated while you drag; open and save job files, export, "
                                        "dry-run preview and queue.  Serves on 127.0.0.1 only.  A relative file "
                                        "path typed in the studio starts in the current folder and must stay "
                                        "inside it or the job's folder; an absolute path may go anywhere.")
    studio.add_argument("job", nargs="?", metavar="JOB.toml", help="job file to open (a new design if it does not exist)")
    studio.add_argument("--port", type=_port_number, default=0, metavar="N", help="port (default 0: a free one)")
    studio.add_argument("--no-browser", action="store_true", help="only print the address; do not open a browser")
    studio.set_defaults(func=cmd_studio)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every command."""
    from foldfab import __version__

    parser = argparse.ArgumentParser(
        prog="foldfab",
        description="Mirror-reflection column origami: from a profile and a trajectory to a crease pattern, "
                    "a 3D model and a plotter program.")
    parser.add_argument("--version", action="version", version=f"foldfab {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    design = sub.add_parser("design", help="build a design: summary, FOLD, SVG, ORIPA .cp, mesh",
                            description="Build the crease pattern and 3D model of a job file.")
    design.add_argument("job", help="job file (TOML)")
    design.add_argument("--fold", metavar="OUT.fold", help="write the crease pattern and folded form as FOLD")
    design.add_argument("--svg", metavar="OUT.svg", help="write the crease pattern as SVG (Origami Simulator colours)")
    design.add_argument("--cp", metavar="OUT.cp", help="write the crease pattern as ORIPA .cp")
    design.add_argument("--mesh", metavar="OUT", help="write the 3D model (.stl, .obj, .ply or .glb)")
    design.add_argument("--allow-penetration", action="store_true",
                        help="build a design whose faces intersect, with a warning instead of an error")
    _add_max_faces(design)
    design.add_argument("--json", action="store_true", help="print the summary as JSON")
    design.set_defaults(func=cmd_design)

    export = sub.add_parser("export", help="write the plotter program (HPGL or G-code) for a device",
                            description="Score and cut a design: write the program a plotter receives.")
    _add_fabrication_args(export, "program file (.hpgl/.plt for HPGL devices, .gcode/.nc for G-code)")
    export.set_defaults(func=cmd_export)

    preview = sub.add_parser("preview", help="dry run: render what the plotter would do as SVG",
                             description="Read the program back and draw it: strokes per layer, travel, "
                                         "sheet, plottable area, pauses, and the time estimate.")
    _add_fabrication_args(preview, "preview SVG file")
    preview.set_defaults(func=cmd_preview)
    _add_plot_parser(sub)
    _add_queue_parser(sub)
    _add_sim_parser(sub)
    _add_studio_parser(sub)
    return parser


def run() -> int:
    """The ``foldfab`` console script and ``python -m foldfab``: :func:`main` on ``sys.argv``.

    On the way out the interpreter would run one last garbage collection over every
    object still alive (numpy, scipy and vpype's modules included: 30-60 ms, more after
    a large job) only to free memory the process is handing back anyway.  ``gc.freeze``
    exempts them; every file foldfab writes is closed (and atomically renamed) before
    ``main`` returns, so no finalizer is waited for.
    """
    import gc

    code = main()
    gc.freeze()
    return code


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default ``sys.argv``), run the command; the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from foldfab.errors import FoldfabError

    try:
        return args.func(args)
    except FoldfabError as exc:
        print(f"foldfab: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("foldfab: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (``foldfab queue list | head``): not an error of ours.
        # Point stdout at /dev/null so the interpreter's final flush stays quiet.
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # the system refused (no room, no permission): one line, as for a mistake
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"foldfab: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
