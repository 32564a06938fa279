"""``foldfab plot``: a job streamed to a plotter, with the operator's questions (load the sheet,
the program's pauses, where a doubtful resume starts), a safe stop on a signal, and the command
that resumes a stopped plot."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from foldfab.cli.common import (_add_max_faces, _add_scale_arg, _add_split_args, _check_output, _fabricate, _int_from,
                                _positive_int, _write_preview, fabrication_report, format_report)


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
                   location.stroke < location.strokes else "every stroke is drawn: send the closing (tool up, head parked)")
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
    _, device, fab = _fabricate(args)
    if args.json:
        for warning in fab.warnings:
            print(json.dumps({"event": "warning", "message": warning}), flush=True)
    checkpoint()
    port = args.port or device.port
    if not port:
        raise FoldfabError(f"{device.name} has no port: give --port PORT (a serial port such as /dev/ttyUSB0, "
                           f"or the simulated plotter sim://), or set port in {device.source}")
    info = fabrication_report(fab, device, verify=True)   # what is sent is what was planned
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


def add_commands(sub) -> None:
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
    _add_split_args(plot, one_program=False)   # a split design's sheets: one program, a pause before each
    _add_max_faces(plot)
    plot.set_defaults(func=cmd_plot)


def _token(text: str) -> str:
    """An argparse type: a resume token, not empty (``--resume "$TOKEN"`` with TOKEN unset must not
    plot the whole job again)."""
    from foldfab.plotting.resume import TOKEN_PATTERN

    if not TOKEN_PATTERN.fullmatch(text):
        raise argparse.ArgumentTypeError("expected the resume token foldfab printed when the plot stopped "
                                         f"(6 to 32 characters 0-9 and a-f), got {text!r}")
    return text
