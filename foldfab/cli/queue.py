"""``foldfab queue ...``: jobs added to the persistent queue, listed, shown, cancelled, retried,
continued after a pause, removed, and plotted by a worker (``queue run``) on its terminal."""

from __future__ import annotations

import argparse
import json
import sys
import threading

from foldfab.cli.common import _add_max_faces, _add_scale_arg, _add_split_args, _fabricate, _int_from


_OPENED = threading.local()
"""``stores``: the queue stores the command running in this thread opened (:func:`_closing`
closes them when it ends; a thread's own, since tests run commands side by side in threads)."""


def _queue_store(args: argparse.Namespace):
    from foldfab.queue.location import open_queue

    store = open_queue(args.queue, wait=args.wait)
    _OPENED.__dict__.setdefault("stores", []).append(store)
    return store


def _closing(command):
    """``command``, then every queue store it opened closed: a server's pool of connections at
    once, never whenever it is collected (from whichever thread that happens in)."""
    import functools

    @functools.wraps(command)
    def run(args: argparse.Namespace) -> int:
        try:
            return command(args)
        finally:
            stores = _OPENED.__dict__.get("stores", [])
            while stores:
                stores.pop().close()

    return run


def _when(seconds: float) -> str:
    import time

    return time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(seconds))


def cmd_queue_add(args: argparse.Namespace) -> int:
    """Build every job now (a bad job fails here, nothing is added) and queue the snapshots."""
    from foldfab.queue.records import NewJob
    from foldfab.queue.snapshot import make_snapshot

    new = []
    for path in args.jobs:
        job, device, fab = _fabricate(argparse.Namespace(job=path, device=args.device, scale=args.scale,
                                                         allow_penetration=args.allow_penetration,
                                                         max_faces=args.max_faces, split=args.split))
        snapshot = make_snapshot(job.path, job.text, job.name, device, fab.program)
        new.append(NewJob.targeted(snapshot, args.port, args.plotter, device.port, args.priority, args.copies))
    store = _queue_store(args)
    ids = iter(store.add(new))
    for item in new:
        numbers = [next(ids) for _ in range(item.copies)]
        label = f"job {numbers[0]}" if len(numbers) == 1 else f"jobs {numbers[0]}-{numbers[-1]}"
        print(f"queued {label}: {item.snapshot.name} on {item.snapshot.device} {item.where()}, "
              f"{len(item.snapshot.program.text)} bytes, priority {item.priority} ({store.location})")
    return 0


def format_job_line(job) -> str:
    """One row of ``foldfab queue list``."""
    name = job.name if job.copies == 1 else f"{job.name} ({job.copy}/{job.copies})"
    state = job.state + ("*" if job.cancel_requested else "")
    port = job.target if len(job.target) <= 24 else job.target[:23] + "~"
    return f"{job.id:>5} {state:<12} {job.priority:>4} {job.percent:>5.1f}%  {job.device:<16} {port:<24} {name}"


LIST_LIMIT = 100
"""Jobs ``foldfab queue list`` shows at once (a page); the JSON listing has them all unless told."""


def cmd_queue_list(args: argparse.Namespace) -> int:
    """List jobs in the queue, oldest first, a page at a time (``--after``, ``--limit``)."""
    store = _queue_store(args)
    limit = args.limit if args.limit is not None else 0 if args.json else LIST_LIMIT
    page = store.page(args.state, args.after, limit or None)
    jobs = page.jobs
    if args.json:
        print(json.dumps([job.as_dict() for job in jobs], indent=1))
    elif not jobs:
        print(f"no {args.state + ' ' if args.state else ''}jobs {f'after job {args.after} ' if args.after else ''}"
              f"in {store.location}")
    else:
        lines = [f"{'ID':>5} {'STATE':<12} {'PRI':>4} {'DONE':>6}  {'DEVICE':<16} {'PLOTTER/PORT':<24} NAME"]
        lines.extend(format_job_line(job) for job in jobs)
        if any(job.cancel_requested for job in jobs):
            lines.append("* cancel requested: the worker stops the plotter")
        if any(len(job.target) > 24 for job in jobs):
            lines.append("~ plotter or port shortened: foldfab queue show ID has it whole")
        if page.more:
            lines.append(more_line(page.more, jobs[-1].id, args))
        print("\n".join(lines))
    return 0


def more_line(more: int, last: int, args: argparse.Namespace) -> str:
    """The last line of a page that is not the last: how many more, and the command for the next page."""
    options = "".join(f" --{name} {getattr(args, name)}" for name in ("state", "limit") if getattr(args, name))
    return (f"... {more} more {args.state + ' ' if args.state else ''}job{'s' * (more != 1)}: foldfab queue list "
            f"--after {last}{options} (--limit 0 lists all)")


def format_job(job, events) -> str:
    """``foldfab queue show``: the job and its event log."""
    copy = f" (copy {job.copy} of {job.copies})" if job.copies > 1 else ""
    lines = [f"job {job.id}    {job.name}{copy}",
             f"state        {job.state}" + (" (cancel requested)" if job.cancel_requested else "")
             + (f": {job.reason}" if job.reason else ""),
             f"device       {job.device} at {job.port}"
             + (f" (plotter {job.plotter})" if job.plotter else " (or any plotter of it)" if job.any_plotter else ""),
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
    job = _queue_store(args).retry(args.id, restart=args.restart, port=args.port, plotter=args.plotter)
    where = (f"resumes at byte {job.acked_bytes} of {job.program_bytes}, before any other job at {job.target} "
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


def cmd_queue_migrate(args: argparse.Namespace) -> int:
    """Move every job of another queue (an SQLite file) into this one (a PostgreSQL server)."""
    from foldfab.queue.location import open_queue
    from foldfab.queue.migrate import move_jobs

    source, target = open_queue(args.source, wait=args.wait), _queue_store(args)
    moved = move_jobs(source, target)
    if not moved:
        print(f"nothing to move: {source.location} has no jobs")
        return 0
    first, last = min(moved.values()), max(moved.values())
    print(f"moved {len(moved)} job{'s' if len(moved) != 1 else ''} from {source.location} to {target.location} "
          f"(now jobs {first}-{last})")
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

        options = WorkerOptions(device=args.device, port=args.port, mode=args.mode, lease=args.lease, name=args.name)
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


def format_plotter_state(plotter) -> str:
    """What a plotter does, as ``foldfab queue plotters`` says it."""
    job = plotter.job
    if plotter.state == "offline":
        why = "its worker stopped" if plotter.stopped is not None else "its last heartbeat: the worker is gone"
        return f"offline since {_when(plotter.offline_since)} ({why})"
    if job is None:
        return "idle"
    if plotter.state == "paused":
        return (f"paused in job {job.id} at {job.percent:.0f}%: waits for the operator (a flip, a tool or the "
                f"next sheet; foldfab queue continue {job.id})")
    return f"drawing job {job.id} at {job.percent:.0f}%"


def cmd_queue_plotters(args: argparse.Namespace) -> int:
    """The registered plotters and what each does now (read from the queue only)."""
    store = _queue_store(args)
    plotters = store.plotters()
    if args.json:
        print(json.dumps([plotter.as_dict() for plotter in plotters], indent=1))
        return 0
    if not plotters:
        print(f"no plotters registered in {store.location} (a worker registers its plotter when it starts: "
              "foldfab queue run --port PORT --name NAME --device PROFILE)")
        return 0
    rows = [("NAME", "HOST", "PROFILE", "PORT", "STATE")]
    for plotter in plotters:
        rows.append(tuple(_shown(text) for text in (plotter.name, plotter.host, plotter.device or "-", plotter.port))
                    + (format_plotter_state(plotter),))
    widths = [min(max(len(row[i]) for row in rows), 40) for i in range(4)]
    print("\n".join("  ".join(cell.ljust(width) for cell, width in zip(row, widths)) + "  " + row[4]
                    for row in rows))
    return 0


def _shown(text: str) -> str:
    """A name from the queue as it can be shown on a terminal: control characters escaped."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _plotter(text: str) -> str:
    from foldfab.errors import FoldfabError
    from foldfab.queue.records import plotter_name

    try:
        return plotter_name(text)
    except FoldfabError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _port(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a serial port or pyserial URL (such as /dev/ttyUSB0 or "
                                         "sim://grbl), got an empty one")
    return text


def add_commands(sub) -> None:
    """``foldfab queue ...``: the persistent job queue."""
    from foldfab.queue.limits import (DEFAULT_HEARTBEAT, DEFAULT_LEASE, DEFAULT_WAIT, LEASE_HEARTBEATS, MAX_COPIES,
                                      MAX_JOB_ID, MIN_LEASE, PRIORITIES, STATES)

    job_id = _int_from(1, MAX_JOB_ID, "expected a job id")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--queue", metavar="PATH|URL", help="queue: an SQLite file, or a PostgreSQL server "
                        "postgresql://user@host/db shared by several hosts (default: $FOLDFAB_QUEUE, else "
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
    target = add.add_mutually_exclusive_group()
    target.add_argument("--port", type=_port, metavar="PORT",
                        help="only the plotter at this serial port or pyserial URL (default: any plotter of the "
                             "profile; a worker without --port runs it at the profile's port)")
    target.add_argument("--plotter", type=_plotter, metavar="NAME",
                        help="only this registered plotter (foldfab queue plotters lists them)")
    add.add_argument("--copies", type=_int_from(1, MAX_COPIES, "expected copies"), default=1, metavar="N",
                     help=f"sheets of each job, up to {MAX_COPIES} (default 1)")
    add.add_argument("--priority", type=_int_from(*PRIORITIES, "expected a priority"), default=0, metavar="P",
                     help=f"higher runs first, {PRIORITIES[0]} to {PRIORITIES[1]} (default 0)")
    add.add_argument("--allow-penetration", action="store_true", help="queue a design whose faces intersect")
    _add_scale_arg(add)
    _add_split_args(add, one_program=False)   # a split design: one job, a pause to load each sheet
    _add_max_faces(add)
    add.set_defaults(func=_closing(cmd_queue_add))

    listing = commands.add_parser("list", parents=[common], help="list jobs")
    listing.add_argument("--state", choices=STATES, help="only jobs in this state")
    listing.add_argument("--json", action="store_true", help="print JSON")
    listing.add_argument("--after", type=_int_from(0, MAX_JOB_ID, "expected a job id"), default=0, metavar="ID",
                         help="only jobs with higher ids (the next page starts after the last job shown)")
    listing.add_argument("--limit", type=_int_from(0, MAX_JOB_ID, "expected a number of jobs"), metavar="N",
                         help=f"show at most N jobs, 0 for all (default {LIST_LIMIT}; --json: all)")
    listing.set_defaults(func=_closing(cmd_queue_list))

    show = commands.add_parser("show", parents=[common], help="one job and its event log")
    show.add_argument("id", type=job_id, metavar="ID")
    show.add_argument("--json", action="store_true", help="print JSON")
    show.set_defaults(func=_closing(cmd_queue_show))

    for name, func, text in (("cancel", cmd_queue_cancel, "cancel a job (a running one stops safely)"),
                             ("retry", cmd_queue_retry, "queue a failed, cancelled or interrupted job again"),
                             ("move", cmd_queue_retry, "queue an interrupted (failed, cancelled) job again on "
                                                       "another plotter: the operator moved its sheet there"),
                             ("continue", cmd_queue_continue, "go on after a pause (the sheet is flipped)"),
                             ("remove", cmd_queue_remove, "delete a job that is not running")):
        action = commands.add_parser(name, parents=[common], help=text)
        action.add_argument("id", type=job_id, metavar="ID")
        action.set_defaults(func=_closing(func))
        if name in ("retry", "move"):
            action.add_argument("--restart", action="store_true",
                                help="from the start on a new sheet, not from the last acknowledged stroke")
            target = action.add_mutually_exclusive_group(required=name == "move")
            target.add_argument("--port", type=_port, metavar="PORT",
                                help="on this port from now on (the plotter's new device path, or another "
                                     "plotter of the same model)")
            target.add_argument("--plotter", type=_plotter, metavar="NAME",
                                help="on this registered plotter of the job's profile from now on")

    clear = commands.add_parser("clear", parents=[common], help="delete finished jobs")
    clear.add_argument("--done", action="store_true", required=True, help="delete every done job")
    clear.set_defaults(func=_closing(cmd_queue_clear))

    plotters = commands.add_parser("plotters", parents=[common], help="list the plotters and what each does",
                                   description="The plotters the workers registered (foldfab queue run --port PORT "
                                               "--name NAME): name, host, profile, port, and state: idle, drawing "
                                               "a job, paused in a job, or offline since when.")
    plotters.add_argument("--json", action="store_true", help="print JSON")
    plotters.set_defaults(func=_closing(cmd_queue_plotters))

    migrate = commands.add_parser("migrate", parents=[common], help="move every job of another queue into this one",
                                  description="Move the jobs of another queue (such as the SQLite file of one "
                                              "machine) into this one (--queue or $FOLDFAB_QUEUE, such as a "
                                              "PostgreSQL server), with their progress and logs, under new ids.  "
                                              "Stop the other queue's workers first.")
    migrate.add_argument("source", metavar="FROM", help="the queue the jobs leave: an SQLite file (or a URL)")
    migrate.set_defaults(func=_closing(cmd_queue_migrate))

    run = commands.add_parser("run", parents=[common], help="plot queued jobs (a worker)",
                              description="Plot jobs in priority and arrival order, one at a time, with the "
                                          "progress display of foldfab plot.  Run one worker per plotter (or "
                                          "several on one queue: they never run the same job).  A job whose "
                                          "worker died is resumed from its last acknowledged stroke.")
    run.add_argument("--device", metavar="PROFILE", help="only jobs for this device profile (the plotter's)")
    run.add_argument("--port", type=_port, metavar="PORT",
                     help="the plotter's port: registers the plotter and takes the jobs at this port, for it by "
                          "name, and for any plotter of its --device (without: every job, each at its own port)")
    run.add_argument("--name", type=_plotter, metavar="NAME",
                     help="the plotter's name, unique in the queue (default HOST:PORT; needs --port)")
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
    run.set_defaults(func=_closing(cmd_queue_run))
