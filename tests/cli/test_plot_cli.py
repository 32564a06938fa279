"""``foldfab plot``: progress on stdout, one-line errors with exit code 2, Ctrl-C with 130."""

from __future__ import annotations

import json
import os
import pty
import queue
import select
import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from foldfab.cli import main
from foldfab.devices import load_device
from foldfab.plotting.resume import state_dir
from foldfab.plotting.transport import open_port
from helpers import ROOT
from helpers.processes import wait_for_handler

HELIX = str(ROOT / "jobs/helix-fig12.toml")
INSTANT = "sim://?time=instant"

pytestmark = pytest.mark.usefixtures("state_home")


def two_sided(tmp_path: Path, source: str = HELIX) -> str:
    """A copy of a job that scores valleys, waits for the flip, then the rest."""
    text = Path(source).read_text().split("[fabrication]")[0]
    job = tmp_path / Path(source).name
    job.write_text(text + '\n[fabrication]\nstrategy = "two-sided"\n')
    return str(job)


def plot(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["plot", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_progress_events_and_a_finished_job(capsys, tmp_path):
    preview = tmp_path / "preview.svg"
    code, out, err = plot(capsys, HELIX, "--device", "grbl", "--port", "sim://?time=fast", "--json",
                          "--preview", str(preview))
    assert code == 0, err
    events = [json.loads(line) for line in out.splitlines()][1:-1]  # without the report and the summary
    assert events[0]["event"] == "start" and events[-1]["event"] == "done"
    assert events[-1]["percent"] == 100.0 and events[-1]["strokes_done"] == events[-1]["strokes_total"] > 0
    assert {"acknowledged", "drawn", "drawn_total", "layer", "elapsed", "eta"} <= set(events[0])
    acked = [e["acknowledged"] for e in events]
    assert acked == sorted(acked)
    assert preview.read_text().startswith("<?xml") or "<svg" in preview.read_text()


def test_plain_progress_lines_when_stdout_is_not_a_terminal(capsys):
    code, out, err = plot(capsys, HELIX, "--device", "hp7475a", "--port", INSTANT)
    assert code == 0, err
    lines = out.split("\nestimate ")[1].splitlines()[1:-1]  # after the report, before the summary
    assert lines[0].strip().startswith("0.0%") and lines[-1].endswith("done")
    assert "\r" not in out  # no bar redrawn in place


def test_pauses_need_a_terminal_or_yes(capsys, tmp_path):
    job = two_sided(tmp_path)
    code, out, err = plot(capsys, job, "--device", "grbl", "--port", INSTANT)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "pauses 1 time(s) for the operator" in err and "--yes" in err
    code, out, err = plot(capsys, job, "--device", "grbl", "--port", INSTANT, "--yes", "--json")
    assert code == 0, err
    kinds = [json.loads(line)["event"] for line in out.splitlines()]
    assert kinds.count("pause") == 1 and kinds.index("pause") < kinds.index("resume")
    assert "Flip the sheet" in err  # the instruction, answered by --yes


def test_errors_are_one_line_with_exit_code_2(capsys):
    code, out, err = plot(capsys, HELIX, "--device", "grbl", "--port", "/dev/no-such-plotter")
    assert code == 2 and err.count("\n") == 1 and err.startswith("foldfab: error: cannot open port")
    code, out, err = plot(capsys, HELIX, "--device", "grbl", "--resume", "abcdef", "--port", INSTANT)
    assert code == 2 and err.count("\n") == 1 and "no saved plot with that token" in err
    code, out, err = plot(capsys, HELIX, "--device", "grbl", "--port", f"{INSTANT}&mute=1")
    assert code == 2 and err.count("\n") == 1 and "no GRBL banner" in err


def test_a_plotter_error_prints_how_to_resume_and_the_resume_finishes(capsys, tmp_path):
    job = str(tmp_path / "helix.toml")
    Path(job).write_text(Path(HELIX).read_text())
    code, out, err = plot(capsys, job, "--device", "grbl", "--port", f"{INSTANT}&error_at=30")
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("foldfab: error: GRBL error 20 at program line 30 (")
    assert "tool lifted" in err and "to finish the job run: foldfab plot" in err
    command = err.split("to finish the job run: ")[1].split()
    token = command[command.index("--resume") + 1]
    assert (state_dir() / f"{token}.json").exists()

    code, out, err = plot(capsys, job, "--device", "grbl", "--port", INSTANT, "--resume", token)
    assert code == 0, err
    assert not (state_dir() / f"{token}.json").exists()


def test_resume_refuses_a_changed_job(capsys, tmp_path):
    job = tmp_path / "helix.toml"
    job.write_text(Path(HELIX).read_text())
    code, out, err = plot(capsys, str(job), "--device", "grbl", "--port", f"{INSTANT}&error_at=30")
    token = err.split("--resume ")[1].split()[0]
    job.write_text(job.read_text() + '\n[fabrication]\nscale = 0.5\n')
    code, out, err = plot(capsys, str(job), "--device", "grbl", "--port", INSTANT, "--resume", token)
    assert code == 2 and err.count("\n") == 1
    assert "changed since the plot stopped" in err and "plot the whole job again" in err


def long_job(tmp_path: Path) -> Path:
    """The vase at 0.7: long enough on ``sim://?time=fast`` that a signal sent after its first
    acknowledged bytes comes while it still plots."""
    job = tmp_path / "vase.toml"
    job.write_text((ROOT / "jobs/vase-svg.toml").read_text().replace(
        "vase-profile.svg", str(ROOT / "jobs/vase-profile.svg")).replace('scale = "fit"', "scale = 0.7"))
    return job


def start_plot(tmp_path: Path, *args: str, **popen) -> subprocess.Popen:
    env = dict(os.environ, XDG_STATE_HOME=str(tmp_path / "state"))
    popen.setdefault("stdin", subprocess.DEVNULL)
    return subprocess.Popen([sys.executable, "-m", "foldfab", "plot", *args], cwd=ROOT, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **popen)


def resume_files(tmp_path: Path) -> list[Path]:
    folder = tmp_path / "state" / "foldfab" / "resume"
    return sorted(folder.glob("*.json")) if folder.is_dir() else []


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_while_starting_stops_before_anything_is_sent(sig, tmp_path):
    """A signal during the imports (the handlers are the first thing cmd_plot does) ends with the
    same clean stop as Ctrl-C: exit 130, one line, no traceback, nothing sent, nothing to resume."""
    proc = start_plot(tmp_path, str(long_job(tmp_path)), "--device", "hp7475a", "--port", "sim://?time=fast")
    wait_for_handler(proc, signal.SIGHUP)  # the last of the three installed
    proc.send_signal(getattr(signal, sig))
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and out == ""  # not even the report: it stopped at the next step
    assert err == "foldfab: stopped: stopped before anything was sent; nothing to resume\n"
    assert resume_files(tmp_path) == []


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_while_plotting_stops_safely_exits_130_and_prints_the_resume_command(sig, tmp_path):
    """Ctrl-C, a kill (SIGTERM) and a closed terminal (SIGHUP) all stop safely with a resume token;
    the signal comes once the plotter has acknowledged the first bytes (an event, not a time)."""
    proc = start_plot(tmp_path, str(long_job(tmp_path)), "--device", "hp7475a", "--port", "sim://?time=fast",
                      "--json")
    for line in proc.stdout:
        event = json.loads(line)
        if event["event"] == "progress" and event["acknowledged"] > 0:
            break
    else:
        pytest.fail(f"no progress event: {proc.stderr.read()}")
    proc.send_signal(getattr(signal, sig))
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("foldfab: stopped: stopped on request; tool lifted;")
    assert "--resume" in last
    token = last.split("--resume ")[1].split()[0]
    assert resume_files(tmp_path) == [tmp_path / "state" / "foldfab" / "resume" / f"{token}.json"]
    assert json.loads(out.splitlines()[-1])["event"] == "resume_token"


def test_plot_reports_the_job_before_and_sums_it_up_after(capsys, tmp_path):
    """The report export prints, then the progress, then time against the estimate, length drawn
    and pen lifts; --preview says it wrote the file."""
    preview = tmp_path / "preview.svg"
    code, out, err = plot(capsys, HELIX, "--device", "hp7475a", "--port", INSTANT, "--preview", str(preview))
    assert code == 0, err
    assert main(["export", HELIX, "--device", "hp7475a", "-o", str(tmp_path / "helix.hpgl")]) == 0
    report = capsys.readouterr().out.rsplit("\nwrote", 1)[0]
    assert out.startswith(report + f"\nwrote        {preview}\n")
    assert main(["export", HELIX, "--device", "hp7475a", "-o", str(tmp_path / "helix.hpgl"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    lifts = sum(layer["pen_lifts"] for layer in info["layers"].values())
    drawn = sum(layer["drawn_mm"] for layer in info["layers"].values())
    summary = out.splitlines()[-1]
    assert summary.startswith("plotted      ") and f"mm drawn, {lifts} pen lifts, in " in summary
    assert summary.endswith(f"(estimate {info['estimated_time_s']:.1f} s)")
    assert float(summary.split()[1]) == pytest.approx(drawn, abs=0.5)


def test_json_plot_reports_and_sums_up_as_events(capsys):
    code, out, err = plot(capsys, HELIX, "--device", "grbl", "--port", INSTANT, "--json")
    assert code == 0, err
    events = [json.loads(line) for line in out.splitlines()]
    assert events[0]["event"] == "report" and events[1]["event"] == "start"
    assert events[-2]["event"] == "done" and events[-1]["event"] == "summary"
    report, summary = events[0], events[-1]
    assert summary["pen_lifts"] == sum(layer["pen_lifts"] for layer in report["layers"].values())
    assert summary["estimated_time_s"] == report["estimated_time_s"]
    assert summary["drawn_mm"] == pytest.approx(events[-2]["drawn_total"], abs=0.1)


def test_the_printed_resume_command_keeps_the_link_settings_and_the_answers(capsys, tmp_path):
    """A stopped two-sided plot run with --yes, a baud rate and flow switches prints a command
    that resumes it the same way (without --yes it would refuse to run without a terminal)."""
    job = two_sided(tmp_path)
    code, out, err = plot(capsys, job, "--device", "grbl", "--port", f"{INSTANT}&error_at=30", "--yes",
                          "--baud", "57600", "--no-xonxoff", "--rtscts", "--json")
    assert code == 2
    command = shlex.split(err.split("to finish the job run: ")[1])
    token = command[command.index("--resume") + 1]
    assert command == ["foldfab", "plot", job, "--device", "grbl", "--port", f"{INSTANT}&error_at=30",
                       "--baud", "57600", "--no-xonxoff", "--rtscts", "--yes", "--json", "--resume", token]
    events = [json.loads(line) for line in out.splitlines()]
    assert events[-1] == {"event": "resume_token", "token": token, "stroke": events[-1]["stroke"],
                          "strokes": events[-1]["strokes"]}
    assert "resume" not in [e["event"] for e in events[:-1] if "token" in e]  # one name, one meaning
    code, out, err = plot(capsys, *command[2:command.index("--port") + 1], INSTANT,
                          *command[command.index("--port") + 2:])
    assert code == 0, err


def test_an_empty_resume_token_is_refused_not_a_whole_new_plot(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["plot", HELIX, "--device", "grbl", "--port", INSTANT, "--resume", ""])
    out, err = capsys.readouterr()
    assert exit_.value.code == 2 and out == ""
    assert "--resume: expected the resume token foldfab printed when the plot stopped" in err


def test_a_resume_that_cannot_start_keeps_its_token_and_says_how_to_finish(capsys, tmp_path):
    job = str(tmp_path / "helix.toml")
    Path(job).write_text(Path(HELIX).read_text())
    code, out, err = plot(capsys, job, "--device", "grbl", "--port", f"{INSTANT}&error_at=30")
    token = err.split("--resume ")[1].split()[0]
    board = f"{INSTANT}&session=alarmed&reset_on_open=0"
    open_port(board, load_device("grbl")).simulator.alarm = True  # e.g. reset while it moved: ALARM:3
    code, out, err = plot(capsys, job, "--device", "grbl", "--port", board, "--resume", token)
    assert code == 2 and err.count("\n") == 1
    assert "is in alarm state: home it ($H) or unlock it ($X)" in err
    assert "nothing was sent, and the resume token stays valid: " in err
    assert err.rstrip().endswith(f"--resume {token}")
    assert (state_dir() / f"{token}.json").exists()


@pytest.fixture
def pty_plotter():
    """A simulated GRBL board on a pseudo-terminal (served in a thread): a port that is not
    ``sim://``, so ``foldfab plot`` asks for the sheet as for real hardware."""
    from foldfab.sim import SimOptions, create_simulator
    from foldfab.sim.pty import serve_pty

    sim = create_simulator(load_device("grbl"), SimOptions(time="fast", speedup=200))
    stop, paths = threading.Event(), queue.Queue()
    thread = threading.Thread(target=serve_pty, args=(sim, paths.put, stop), daemon=True)
    thread.start()
    yield paths.get(timeout=20), sim
    stop.set()
    thread.join(20)


def read_until(fd: int, text: str, timeout: float = 120.0) -> str:
    """Read a pipe until ``text`` has come (an event, with a deadline)."""
    seen, deadline = b"", time.monotonic() + timeout
    while text.encode() not in seen:
        left = deadline - time.monotonic()
        assert left > 0, f"no {text!r} in {seen!r}"
        if select.select([fd], [], [], left)[0]:
            chunk = os.read(fd, 4096)
            assert chunk, f"closed before {text!r}: {seen!r}"
            seen += chunk
    return seen.decode()


@pytest.mark.parametrize("answer", ["enter", "SIGINT", "SIGTERM", "eof"])
def test_on_a_terminal_plot_asks_for_the_sheet_first(answer, tmp_path, pty_plotter):
    """On a terminal, without --yes, the operator loads the sheet and presses Enter before any
    byte goes to the plotter; Ctrl-C, a kill or the end of input there stops with nothing sent."""
    port, sim = pty_plotter
    typist, terminal = pty.openpty()  # plot's stdin is a terminal; the test types on the other side
    proc = start_plot(tmp_path, HELIX, "--device", "grbl", "--port", port, stdin=terminal)
    os.close(terminal)
    try:
        shown = read_until(proc.stderr.fileno(), "then press Enter to start")
        assert "Load a 210 x 297 mm sheet on the grbl" in shown
        assert sim.stats.bytes_received == 0  # it waits for the operator
        if answer == "enter":
            os.write(typist, b"\n")
        elif answer == "eof":
            os.write(typist, b"\x04")  # Ctrl-D: the end of input
        else:
            proc.send_signal(getattr(signal, answer))
        out, err = proc.communicate(timeout=120)
    finally:
        os.close(typist)
    assert "Traceback" not in err
    if answer == "enter":
        assert proc.returncode == 0, err
        assert out.splitlines()[-1].startswith("plotted      ")
        assert len(sim.strokes) == int(out.splitlines()[-1].split("pen lifts")[0].split()[-1]) > 0
    else:
        assert proc.returncode == 130
        assert err.endswith("foldfab: stopped: stopped before anything was sent; nothing to resume\n")
        assert sim.stats.bytes_received == 0 and resume_files(tmp_path) == []


def test_with_yes_or_on_sim_plot_does_not_ask(tmp_path, pty_plotter):
    port, sim = pty_plotter
    typist, terminal = pty.openpty()
    try:
        for where in ([port, "--yes"], ["sim://?time=instant"]):
            run = subprocess.run([sys.executable, "-m", "foldfab", "plot", HELIX, "--device", "grbl", "--port",
                                  *where], stdin=terminal, capture_output=True, text=True, timeout=300,
                                 env=dict(os.environ, XDG_STATE_HOME=str(tmp_path / "state")))
            assert run.returncode == 0 and "press Enter" not in run.stderr, run.stderr
    finally:
        os.close(typist)
        os.close(terminal)


def test_a_resume_stopped_at_the_prompt_keeps_its_token(capsys, tmp_path, pty_plotter, state_home):
    port, sim = pty_plotter
    job = str(tmp_path / "helix.toml")
    Path(job).write_text(Path(HELIX).read_text())
    code, out, err = plot(capsys, job, "--device", "grbl", "--port", f"{INSTANT}&error_at=30")
    token = err.split("--resume ")[1].split()[0]
    typist, terminal = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "foldfab", "plot", job, "--device", "grbl", "--port", port,
                             "--resume", token], cwd=ROOT, env=dict(os.environ, XDG_STATE_HOME=str(state_home)),
                            stdin=terminal, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    os.close(terminal)
    try:
        assert "Check the partly drawn sheet is still in place on the grbl" in \
            read_until(proc.stderr.fileno(), "then press Enter to start")
        os.write(typist, b"\x04")
        out, err = proc.communicate(timeout=120)
    finally:
        os.close(typist)
    assert proc.returncode == 130 and err.endswith(
        "foldfab: stopped: stopped before anything was sent; the resume token stays valid: "
        "run the same command again\n")
    assert sim.stats.bytes_received == 0 and (state_dir() / f"{token}.json").exists()
