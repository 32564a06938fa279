"""The queue worker: claim a job, plot it through the streaming engine, keep the queue true.

:class:`Worker` takes jobs from a :class:`~foldfab.queue.store.QueueStore` in claim order and
plots each one with a :data:`Runner` (by default :func:`stream_runner`: the port is
opened and :func:`foldfab.plotting.stream.stream` sends the program).  While a job runs, a
heartbeat thread renews the worker's lease and persists the acknowledged position
whenever a stroke has been completed, at least every ``heartbeat`` seconds; it also
picks up cancel requests (the engine then stops the plotter safely) and notices when
the job is no longer this worker's (the plotter is stopped at once).

A job that was interrupted before (its worker died, the cable was pulled) is resumed
with :func:`foldfab.plotting.resume.resume_program` from the first stroke not drawn: the first
not acknowledged, moved on past those the plotter says it drew after its worker lost
it (:func:`foldfab.plotting.resume.locate_resume`).  No stroke is lost; drawn twice is the
interrupted stroke (on a GRBL board that resets when its port opens, also the lines it
still held when the worker died: better twice than lost).  Pauses (the flip of a
two-sided job) set the job ``waiting``; the :class:`WorkerUI` may answer on a terminal,
and ``foldfab queue continue ID`` answers from anywhere.

How a job ends: the engine finished -> ``done``; the queue's cancel (or the operator at
the worker's terminal) -> ``cancelled``; the port could not be opened, the link or the
plotter was lost (the tool could not be lifted) or Ctrl-C on the worker ->
``interrupted``; the plotter reported an error or stalled (the tool was lifted), or the
job cannot start (its stored program no longer matches its SHA-256, or its stored device
profile no longer loads) -> ``failed``.  A progress save that fails for anything but another
writer's lock (the disk is full, the queue file became read-only) stops the plotter at once,
tool lifted: the queue keeps the last saved position, so a retry draws again at most the
stroke whose save failed.
A worker does not resume a job it saw interrupted itself, or lost (its lease expired), until
``retry_after`` seconds have passed (``--follow``), or not at all in this run
(``--until-empty``, ``--once``): someone has to plug the cable back in, or the worker was too
slow to renew its lease and would lose the job again.
"""

from __future__ import annotations

import bisect
import socket
import threading
import time
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Callable, Protocol, TypeVar

from foldfab.errors import FoldfabError
from foldfab.queue.limits import DEFAULT_HEARTBEAT, DEFAULT_LEASE, LEASE_HEARTBEATS
from foldfab.queue.records import Claim, JobRecord, WorkerId, default_plotter_name, plotter_name
from foldfab.queue.snapshot import load_snapshot_device
from foldfab.queue.store import QueueBusy, QueueStore

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.plotting.progress import ProgressEvent
    from foldfab.programs.program import Program
    from foldfab.plotting.engines.base import StreamStopped

MODES = ("until-empty", "once", "follow")
MAX_BACKOFF = 30.0
"""Longest wait (s) between two tries to reach a queue server that is out of reach."""
FINISH_PATIENCE = 3600.0
"""How long (s) a worker tries to record a job's end on a queue server that is out of reach."""
DRY_RUN_PORT = "sim://?time=instant"
"""``--dry-run``: the simulated plotter of the job's device, as fast as it can go."""


class PortUnavailable(FoldfabError):
    """The plotter's port cannot be opened (unplugged, switched off, in use): nothing was sent."""


class Runner(Protocol):
    """Plots ``program`` on ``port``; returns when it is done, raises
    :class:`foldfab.plotting.engines.base.StreamStopped` when it stopped early and :class:`PortUnavailable`
    when it could not start."""

    def __call__(self, program: Program, device: DeviceProfile, port: str, *,
                 events: Callable[[ProgressEvent], None], cancel: threading.Event,
                 operator: Callable[[str], bool]) -> None: ...


def stream_runner(program: Program, device: DeviceProfile, port: str, *,
                  events: Callable[[ProgressEvent], None], cancel: threading.Event,
                  operator: Callable[[str], bool]) -> None:
    """Open ``port`` with the device's serial settings and stream ``program`` to it."""
    from foldfab.plotting.stream import stream
    from foldfab.plotting.transport import open_port

    try:
        link = open_port(port, device)
    except FoldfabError as exc:
        raise PortUnavailable(str(exc)) from None
    try:
        _discard_stale_replies(link)
        stream(link, program, device, events=events, cancel=cancel, operator=operator)
    finally:
        link.close()


def _discard_stale_replies(link, quiet: float = 0.1, limit: float = 5.0) -> None:
    """Drop what the plotter still answers to a previous host (a worker that died mid-job):
    read until the line has been quiet for ``quiet`` s, at most ``limit`` s."""
    deadline = time.monotonic() + limit
    link.reset_input_buffer()
    while time.monotonic() < deadline:
        time.sleep(quiet)
        if not link.in_waiting:
            return
        link.reset_input_buffer()


Locator = Callable[[int], "tuple[int, str]"]
"""Given the first stroke not acknowledged, the first stroke not drawn and how it was found."""
T = TypeVar("T")


class WorkerUI(Protocol):
    """What the worker shows and asks; the command line implements it on a terminal."""

    def job_started(self, job: JobRecord, note: str) -> None:
        """A job begins (``note``: started, or where it resumes)."""

    def progress(self, event: ProgressEvent) -> None:
        """The engine's progress events."""

    def paused(self, job: JobRecord, message: str) -> None:
        """The job waits for the operator at a pause."""

    def answer(self, timeout: float) -> str | None:
        """The operator's answer within ``timeout`` s: "continue", "cancel", or None (none yet, or no terminal)."""

    def job_ended(self, job: JobRecord, state: str, message: str) -> None:
        """A job left this worker in ``state``."""


@dataclass(frozen=True)
class WorkerOptions:
    """How ``foldfab queue run`` works."""

    device: str | None = None
    """Only jobs for this device profile."""
    port: str | None = None
    """Only jobs for this port."""
    mode: str = "until-empty"
    """until-empty: stop when nothing is runnable; once: one job at most; follow: wait for jobs."""
    lease: float = DEFAULT_LEASE
    """Seconds a job stays this worker's without a heartbeat; at least ``LEASE_HEARTBEATS`` heartbeats."""
    heartbeat: float = DEFAULT_HEARTBEAT
    """Longest time between two heartbeats (progress is also saved when a stroke is done)."""
    poll: float = 2.0
    """follow: most seconds between looks at an empty queue (a PostgreSQL queue wakes the worker at
    once when a job may have become runnable); also how often a pause checks the queue."""
    retry_after: float = 60.0
    """follow: seconds before this worker resumes a job it saw interrupted."""
    name: str | None = None
    """The name of the plotter at ``port``, registered in the queue (default ``host:port``)."""

    @property
    def plotter(self) -> str | None:
        """The plotter's name: a worker with a port registers its plotter; one without runs every
        job at the job's own port, and registers none."""
        if self.port is None:
            if self.name is not None:
                raise FoldfabError(f"plotter {self.name}: a named plotter needs its port: give --port PORT")
            return None
        return plotter_name(self.name or default_plotter_name(socket.gethostname(), self.port))


@dataclass
class WorkerSummary:
    """Jobs this worker ended, by state."""

    ended: dict[str, list[int]] = field(default_factory=dict)

    def add(self, job_id: int, state: str) -> None:
        self.ended.setdefault(state, []).append(job_id)


@dataclass(frozen=True)
class StartPoint:
    """What to stream for a job: the whole program, or a resume program and how its byte
    offsets and pauses map back to the stored program."""

    program: Program
    note: str
    confirmed: tuple[int, ...]
    """For each pause of the streamed program: stored pauses confirmed once it is answered."""
    cut: int = 0
    """Offset in the stored program where the streamed text continues it."""
    prelude: int = 0
    """Bytes of the streamed program before that point (tool state, travel)."""
    stroke: int = 0
    """Strokes of the stored program already drawn."""
    drawn: tuple[float, float] | None = None
    """Length (mm) of those strokes and of all the stored program's; None when the streamed
    program is the stored one (its own progress says)."""

    def original(self, offset: int) -> int:
        """Stored-program offset of streamed-program byte ``offset``."""
        return self.cut + max(offset - self.prelude, 0)


def start_point(program: Program, device: DeviceProfile, acked: int, pauses_done: int,
                locate: Locator | None = None) -> StartPoint:
    """Where a job starts: from the beginning, or from the first stroke not acknowledged,
    moved on by ``locate`` (``(stroke) -> (stroke, note)``: what the plotter drew since)."""
    if not acked:
        return StartPoint(program, "started", tuple(range(1, len(program.pauses) + 1)))
    from foldfab.programs.interpret import interpret
    from foldfab.plotting.resume import resume_cut, resume_program

    strokes = interpret(program, device).strokes
    stroke = bisect.bisect_right([s.end for s in strokes], acked)
    found = ""
    if locate is not None and stroke < len(strokes):
        stroke, found = locate(stroke)
    found = f"; {found}" if found else ""
    lengths = [s.length for s in strokes]
    drawn = (sum(lengths[:stroke]), sum(lengths))
    resumed = resume_program(program, device, stroke, pauses_done)
    cut = resume_cut(program, strokes, stroke)
    prelude = len(resumed.text) - (len(program.text) - cut)
    originals = [p.offset for p in program.pauses]
    counts = tuple(bisect.bisect_right(originals, cut + max(p.offset - prelude, 0)) for p in resumed.pauses)
    note = (f"resumed at stroke {stroke + 1} of {len(strokes)} (byte {cut})" if stroke < len(strokes) else
            f"all {len(strokes)} strokes were drawn before the interruption: sending the closing "
            "(tool up, head parked)")
    return StartPoint(resumed, note + found, counts, cut, prelude, stroke, drawn)


class _Heartbeat(threading.Thread):
    """Renews the lease and saves progress; sets ``cancel`` on a cancel request or a lost job."""

    def __init__(self, store: QueueStore, worker: WorkerId, job_id: int, options: WorkerOptions,
                 cancel: threading.Event):
        super().__init__(name=f"foldfab-heartbeat-{job_id}", daemon=True)
        self.store, self.worker, self.job_id, self.options, self.cancel = store, worker, job_id, options, cancel
        self.acked: int | None = None
        self.progress: str | None = None
        self.pauses_done: int | None = None
        self.drawn: tuple[float, float] | None = None
        self.cancel_requested = False
        self.lost: str | None = None
        self.renewed = time.monotonic()
        self.offline: str | None = None  # why the queue could not be reached, while it cannot
        self.delay = options.heartbeat
        self._poke = threading.Event()
        self._stopped = threading.Event()
        self._saving = threading.Lock()  # one save at a time, so an older one never lands after a newer one

    def poke(self) -> None:
        """Save soon (a pause was answered)."""
        self._poke.set()

    def run(self) -> None:
        while not self._stopped.is_set():
            self._poke.wait(self.delay)
            self._poke.clear()
            if not self._stopped.is_set():
                self.beat()

    def beat(self) -> None:
        """One heartbeat; gives the job up if the lease could not be renewed in time.

        Called from this thread and from the plotting thread (before a pause): the lock makes
        each save read the progress when it is its turn, so a save started earlier can never
        write older progress over a later one."""
        try:
            with self._saving:
                control = self.store.heartbeat(self.job_id, self.worker, self.options.lease, self.acked,
                                               self.progress, self.pauses_done, self.drawn)
        except QueueBusy as exc:
            if self.store.survives_outages:  # a server out of reach: plot on, the progress kept here
                self.offline = str(exc)
                self.delay = min(2 * self.delay, MAX_BACKOFF)
                return
            # another writer holds the queue: again at the next beat, while the lease lasts
            if time.monotonic() - self.renewed > 0.8 * self.options.lease:
                self.give_up(f"the lease could not be renewed for {self.options.lease:g} s ({exc})")
            return
        except FoldfabError as exc:  # a full disk, a read-only file: plotting on would draw what is never saved
            self.give_up(f"the progress could not be saved: {exc}")
            return
        self.renewed, self.delay = time.monotonic(), self.options.heartbeat
        if control.lost:
            self.give_up("the job is no longer this worker's (its lease expired and it was taken, retried, "
                         "cancelled or removed" + (f" while the queue was out of reach: {self.offline})"
                                                   if self.offline else ")"))
        elif control.cancel_requested and not self.cancel_requested:
            self.cancel_requested = True
            self.cancel.set()
        self.offline = None

    def give_up(self, reason: str) -> None:
        self.lost = reason
        self.cancel.set()

    def finish(self) -> None:
        self._stopped.set()
        self._poke.set()
        self.join()


class Worker:
    """Runs queued jobs on their plotters (see the module docstring)."""

    def __init__(self, store: QueueStore, ui: WorkerUI, options: WorkerOptions = WorkerOptions(),
                 runner: Runner = stream_runner, locate: bool = True):
        """``locate``: before resuming a job, ask its plotter how far it got
        (:func:`foldfab.plotting.resume.locate_resume`)."""
        if options.mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}")
        if not options.heartbeat > 0 or not options.lease >= LEASE_HEARTBEATS * options.heartbeat:
            raise ValueError(f"the lease ({options.lease:g} s) must last at least {LEASE_HEARTBEATS} heartbeats "
                             f"({LEASE_HEARTBEATS * options.heartbeat:g} s), else the worker loses its jobs")
        self.store, self.ui, self.options, self.runner = store, ui, options, runner
        self.locate = locate
        self.id = WorkerId.current()
        self.plotter = options.plotter
        self._alive_at = time.monotonic()  # when the plotter's heartbeat was last renewed
        self.interrupted: dict[int, float] = {}  # jobs this worker saw interrupted or lost, and when
        self.stopping = threading.Event()
        self.interrupting = False
        self._cancel: threading.Event | None = None  # the running job's

    def stop(self) -> None:
        """Claim no more jobs (the one running goes on to its end)."""
        self.stopping.set()

    def interrupt(self) -> None:
        """Stop as Ctrl-C does, safe to call from a signal handler: the running job stops safely
        (tool lifted) and is left interrupted, and :meth:`run` then raises KeyboardInterrupt.
        Setting events, unlike raising in the handler, cannot be lost inside a library call
        (an exception raised in SQLite's callback becomes a database error)."""
        self.interrupting = True
        self.stopping.set()
        if self._cancel is not None:
            self._cancel.set()

    def run(self) -> WorkerSummary:
        """Register the plotter, claim and plot jobs until the mode says stop, sign the plotter off;
        Ctrl-C interrupts the job and stops."""
        if self.plotter is None:
            return self._run()
        self.store.register_plotter(self.plotter, self.options.port, self.options.device, self.id, self.options.lease)
        try:
            return self._run()
        finally:
            try:
                self.store.unregister_plotter(self.plotter, self.id)
            except FoldfabError:  # the queue is out of reach: the plotter shows offline once its lease is over
                pass

    def _run(self) -> WorkerSummary:
        summary = WorkerSummary()
        while not self.stopping.is_set():
            self._keep_plotter()
            claim = self._patiently(lambda: self.store.claim(self.id, self.options.lease, self.options.device,
                                                             self.options.port, exclude=self._skipped(),
                                                             plotter=self.plotter), True)
            if claim is None:
                if self.options.mode != "follow":
                    return self._ended(summary)
                poll = self.options.poll if self.plotter is None else min(self.options.poll, self.options.lease / 2)
                self.store.wait_for_work(poll, self.stopping)
                continue
            state = self.run_job(claim)
            summary.add(claim.job.id, state)
            if state in ("interrupted", "lost"):  # not again at once: the same would happen
                self.interrupted[claim.job.id] = time.monotonic()
            if self.options.mode == "once":
                return self._ended(summary)
        return self._ended(summary)

    def _keep_plotter(self) -> None:
        """The heartbeat of the plotter while no job runs (a job's heartbeats renew it while it does).
        A plotter taken over meanwhile (its lease had run out) is registered again, which fails if
        the other worker is online: the error stops this worker, never two on one plotter."""
        if self.plotter is None or time.monotonic() - self._alive_at < self.options.heartbeat:
            return
        try:
            if not self.store.plotter_alive(self.plotter, self.id):
                self.store.register_plotter(self.plotter, self.options.port, self.options.device, self.id,
                                            self.options.lease)
        except QueueBusy:
            return  # the claim that follows meets the same
        self._alive_at = time.monotonic()

    def _ended(self, summary: WorkerSummary) -> WorkerSummary:
        if self.interrupting:
            raise KeyboardInterrupt
        return summary

    def _skipped(self) -> list[int]:
        if self.options.mode != "follow":
            return list(self.interrupted)
        now = time.monotonic()
        return [job for job, when in self.interrupted.items() if now - when < self.options.retry_after]

    def run_job(self, claim: Claim) -> str:
        """Plot one claimed job to its end; return the state it ended in."""
        job = claim.job
        cancel = self._cancel = threading.Event()
        if self.interrupting:
            cancel.set()
        heartbeat = _Heartbeat(self.store, self.id, job.id, self.options, cancel)
        try:
            device = load_snapshot_device(claim.snapshot)
            program = claim.snapshot.program
            from foldfab.plotting.resume import locate_resume

            locate = partial(locate_resume, program, device, job.port, pauses_done=job.pauses_done)
            start = start_point(program, device, job.acked_bytes, job.pauses_done,
                                locate if self.locate and not _failed_last(self._patiently(
                                    lambda: self.store.events(job.id))) else None)
        except FoldfabError as exc:
            return self._end(job, heartbeat, "failed", f"cannot start: {exc}")
        self.ui.job_started(job, start.note)
        heartbeat.drawn = start.drawn
        heartbeat.start()
        tracker = _Tracker(self, job, start, heartbeat)
        try:
            self.runner(start.program, device, job.port, events=tracker.event, cancel=cancel,
                        operator=tracker.pause)
        except KeyboardInterrupt:
            self._end(job, heartbeat, "interrupted", "the worker was stopped (Ctrl-C)", tracker.acked)
            raise
        except PortUnavailable as exc:
            return self._end(job, heartbeat, "interrupted", f"{exc}; then run again", tracker.acked)
        except FoldfabError as exc:
            from foldfab.plotting.engines.base import StreamStopped

            if not isinstance(exc, StreamStopped):
                return self._end(job, heartbeat, "failed", str(exc), tracker.acked)
            acked = start.original(exc.acknowledged)
            where = f"at byte {acked} of {job.program_bytes} ({tracker.describe()})"
            if heartbeat.lost:
                return self._end(job, heartbeat, "lost", f"{heartbeat.lost}; the plotter was stopped {where}",
                                 acked)
            if tracker.cancelled_by or heartbeat.cancel_requested:
                who = tracker.cancelled_by or "foldfab queue cancel"
                return self._end(job, heartbeat, "cancelled", f"cancelled ({who}): {exc}; stopped {where}", acked)
            if exc.cancelled:  # Ctrl-C, caught by the engine, which lifted the tool
                self._end(job, heartbeat, "interrupted", f"the worker was stopped: {exc}; {where}", acked)
                raise KeyboardInterrupt from None
            return self._end(job, heartbeat, stopped_state(exc), f"{exc}; stopped {where}", acked)
        resumed = f" ({start.note})" if start.stroke else ""
        return self._end(job, heartbeat, "done", f"finished: {tracker.describe()}{resumed}", job.program_bytes)

    def _end(self, job: JobRecord, heartbeat: _Heartbeat, state: str, message: str,
             acked: int | None = None) -> str:
        """Stop the heartbeat, record the end in the queue, tell the UI."""
        if heartbeat.is_alive():
            heartbeat.finish()
        if state != "lost" and not self._finish(job.id, state, message, acked, heartbeat):
            state, message = "lost", f"{message}; but the job was no longer this worker's, so the queue keeps " \
                                     "what the next writer decided"
        self.ui.job_ended(job, state, message)
        return state


    def _finish(self, job_id: int, state: str, message: str, acked: int | None, heartbeat: _Heartbeat) -> bool:
        """Record the end; a store that survives outages is tried again, backing off, until it is
        back (at most ``FINISH_PATIENCE`` s): the end of a sheet drawn offline is not lost."""
        return self._patiently(lambda: self.store.finish(job_id, self.id, state, message, acked,
                                                         heartbeat.pauses_done, heartbeat.progress, heartbeat.drawn))

    def _patiently(self, call: Callable[[], T], stoppable: bool = False) -> T | None:
        """``call()``, a store operation; on a store that survives outages, tried again backing off
        while its server is out of reach, at most ``FINISH_PATIENCE`` s (``stoppable``: None once
        the worker is stopped meanwhile).  A host of a farm waits out a server restart."""
        delay, deadline = self.options.heartbeat, time.monotonic() + FINISH_PATIENCE
        while True:
            try:
                return call()
            except QueueBusy:
                if not self.store.survives_outages or time.monotonic() + delay > deadline:
                    raise
            stopped = self.stopping.wait(delay) if stoppable else time.sleep(delay)  # backing off
            if stopped:
                return None
            delay = min(2 * delay, MAX_BACKOFF)


def _failed_last(events) -> bool:
    """Did the job's last run end ``failed``?  (The plotter reported an error or stalled: an
    error means it skipped an instruction, so its position is not used to resume.)"""
    ends = [e.kind for e in events if e.kind in ("failed", "interrupted", "cancelled", "done")]
    return bool(ends) and ends[-1] == "failed"


def stopped_state(stop: StreamStopped) -> str:
    """The state of a job the engine stopped by itself: ``interrupted`` if the link failed (the
    engine stops inside its ``except OSError``) or the tool could not be lifted, else ``failed``
    (the plotter reported an error or stalled)."""
    return "interrupted" if isinstance(stop.__context__, OSError) or not stop.lifted else "failed"


def rehearse(store: QueueStore, ui: WorkerUI, options: WorkerOptions = WorkerOptions(),
             runner: Runner = stream_runner) -> WorkerSummary:
    """``--dry-run``: every runnable job (the first only in mode ``once``, as a run would claim
    one), in claim order, streamed to a simulated plotter of its device (resumed where a run
    would resume it; pauses answered at once).  A job that a run could not start (a damaged
    snapshot) or that the simulated plotter stops is reported and the next one rehearsed.  The
    queue is not changed."""
    summary = WorkerSummary()
    for job in store.runnable(options.device, options.port, plotter=options.plotter):
        summary.add(job.id, _rehearse_job(store, ui, job, runner))
        if options.mode == "once":
            break
    return summary


def _rehearse_job(store: QueueStore, ui: WorkerUI, job: JobRecord, runner: Runner) -> str:
    """Rehearse one job (see :func:`rehearse`); the state it would end in."""
    from foldfab.plotting.engines.base import StreamStopped

    try:
        snapshot = store.snapshot(job.id)
        device = load_snapshot_device(snapshot)
        start = start_point(snapshot.program, device, job.acked_bytes, job.pauses_done)
    except FoldfabError as exc:
        ui.job_ended(job, "failed", f"cannot start: {exc}")
        return "failed"
    ui.job_started(job, f"dry run on {DRY_RUN_PORT} instead of {job.port}: {start.note}")
    state, message = "done", "the simulated plotter finished it"
    try:
        runner(start.program, device, DRY_RUN_PORT, events=ui.progress, cancel=threading.Event(),
               operator=lambda text: ui.paused(job, f"{text} (answered by the dry run)") or True)
    except StreamStopped as exc:
        state, message = stopped_state(exc), str(exc)
    except FoldfabError as exc:  # the simulated plotter could not be opened
        state, message = "failed", str(exc)
    ui.job_ended(job, state, message)
    return state


class _Tracker:
    """The engine's callbacks for one job: progress into the heartbeat, pauses into the queue."""

    def __init__(self, worker: Worker, job: JobRecord, start: StartPoint, heartbeat: _Heartbeat):
        self.worker, self.job, self.start, self.heartbeat = worker, job, start, heartbeat
        self.acked: int | None = None
        self.done = self.total = start.stroke
        self.pauses_seen = 0
        self.cancelled_by: str | None = None

    def describe(self) -> str:
        """Strokes done, in the stored program's numbering."""
        return f"{self.done} of {self.total} strokes done"

    def event(self, event: ProgressEvent) -> None:
        """Record the position; when a stroke was completed, save it before the engine goes on
        (it lets the plotter hold repeats of a pen state only past the reported stroke, so the
        saved one must not lag: see :meth:`foldfab.plotting.engines.hpgl.HPGLSender.repeats_allow`)."""
        self.acked = self.start.original(event.acknowledged)
        done, self.total = self.start.stroke + event.strokes_done, self.start.stroke + event.strokes_total
        self.heartbeat.acked = self.acked
        self.heartbeat.progress = f"stroke {done} of {self.total} done, {event.layer}"
        before, total = self.start.drawn or (0.0, event.drawn_total)
        self.heartbeat.drawn = (before + event.drawn, total)
        if done != self.done:
            self.done = done
            self.heartbeat.beat()
        self.worker.ui.progress(event)

    def pause(self, message: str) -> bool:
        """The engine is at a pause: wait in state ``waiting`` for an answer."""
        store, worker, options = self.worker.store, self.worker.id, self.worker.options
        confirmed = self.start.confirmed[self.pauses_seen] if self.pauses_seen < len(self.start.confirmed) else None
        self.pauses_seen += 1
        self.heartbeat.beat()  # everything before the pause is done: save it before waiting
        control = store.wait_at_pause(self.job.id, worker, message)
        self.worker.ui.paused(self.job, message)
        while not control.lost:
            if control.cancel_requested:
                self.heartbeat.cancel_requested = True
                return False
            if self.worker.interrupting:
                return False
            if control.state == "running":  # continued: here or with foldfab queue continue
                if confirmed is not None:
                    self.heartbeat.pauses_done = confirmed
                    self.heartbeat.poke()
                return True
            answer = self.worker.ui.answer(min(options.poll, options.heartbeat))
            if answer == "cancel":
                self.cancelled_by = "the operator at the worker's terminal"
                return False
            if answer == "continue":
                try:
                    store.continue_job(self.job.id, "on the worker's terminal")
                except FoldfabError:
                    pass  # continued or cancelled meanwhile; the heartbeat tells
            control = store.heartbeat(self.job.id, worker, options.lease)
        self.heartbeat.give_up("the job is no longer this worker's (its lease expired, or it was removed)")
        return False
