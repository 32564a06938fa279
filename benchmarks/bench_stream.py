"""Streaming: link use, plotter starvation, host CPU, on the simulated plotters.

Run by hand:  python benchmarks/bench_stream.py   (about three minutes)
              python benchmarks/bench_stream.py --load 2 --part link   (link-bound only, with two
              CPU-bound processes running throughout: a loaded host, both cores busy)

1. Link-bound: every device at 9600 baud with motion made instant (a profile copy with
   huge speeds and no pen-lift time), so the wire is the only limit; ``time=real``
   simulator, so the host's own turnaround counts.  foldfab's sender side by side with
   send-and-wait (one command, wait for its reply: ``ok`` for GRBL, the answer to an
   ``OE;`` sent after each HP-GL command).  Throughput = program bytes / plot time,
   as a share of the line rate (baud / 10 for 8N1).  foldfab's figure includes its checks:
   HP-GL ``OE`` checkpoints with an ``OA`` position check every 2048 bytes and at the end,
   GRBL's status position at the end.
2. Motion-bound: the real profiles (and the Silhouette Cameo 4 in GP-GL), ``time=instant``:
   the plotter's idle time while more of the job was still to come (``starved``) as a share
   of its plot time.
3. Host CPU while the plotter works: ``foldfab sim NAME --pty`` at real speed in another
   process, foldfab streaming for a fixed time; process CPU over wall time.
4. The USB transports: the Roland GX-24 (HP-GL, no handshake) with motion made instant,
   through ``lp://`` (a simulated printer device on a pty, served by a thread) and ``usb://``
   (a simulated cutter behind a pyusb backend), both ``time=real``, beside the same job over
   serial at 9600 baud; then with the profile's own motion (``time=instant``), its starvation.
   ``python benchmarks/bench_stream.py --usb`` runs this part only.

``--load N`` runs N CPU-bound processes (each a busy loop, at normal priority) from before the
first measurement to after the last: the sender must keep the link full when the host is busy
(the plotter, not the host, sets the pace).  ``--part`` runs one part (link, motion, cpu, usb).
"""

from __future__ import annotations

import argparse
import contextlib
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate
from foldfab.fabrication.spec import parse_fabrication
from foldfab.plotting.engines.base import StreamStopped
from foldfab.plotting.stream import stream
from foldfab.plotting.transport import open_port

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from helpers.streams import instant_motion  # noqa: E402  (a profile copy whose motion takes no time)

DEVICES = ["hp7475a", "graphtec-ce6000", "roland-gx24", "grbl"]
GPGL = ["silhouette-cameo-4"]
"""Motion-bound only: GP-GL has no reply per command for a send-and-wait to compare with."""
SPEC = {"sheet": "A3", "margin": 5, "scale": 0.4}
BAUD = 9600


def program_for(device, job: str = "vase-svg", strategy: str = "force"):
    spec = parse_fabrication({**SPEC, "strategy": strategy}, job)
    return fabricate(load_design(ROOT / "jobs" / f"{job}.toml"), device, spec).program


def send_and_wait(port, program, device) -> None:
    """One command, then wait for the plotter's reply to it."""
    port.timeout = 5.0
    if device.protocol == "gcode":
        while b"Grbl" not in port.read_until(b"]\r\n"):
            pass
        for line in program.text.split("\n")[:-1]:
            port.write(line.encode() + b"\n")
            while (reply := port.read_until(b"\r\n").strip()).startswith(b"["):
                pass  # [MSG:...]
            assert reply == b"ok", reply
        return
    for command in re.findall(r"[^;]*;", program.text):
        port.write(command.encode() + b"OE;")
        assert port.read_until(b"\r").strip() == b"0"


def link_bound() -> None:
    print(f"1. link-bound: {BAUD} baud, motion instant (time=real simulator, vase-svg job)")
    print(f"{'device':<18}{'flow control':<14}{'bytes':>7}{'foldfab':>10}{'send-and-wait':>15}")
    with tempfile.TemporaryDirectory() as folder:
        for name in DEVICES:
            device = load_device(instant_motion(name, Path(folder)))
            program = program_for(device)
            shares = []
            for sender in (stream, send_and_wait):
                port = open_port("sim://?time=real&sheet=A3", device, baudrate=BAUD)
                sender(port, program, device)
                stats = port.simulator.stats
                port.close()
                assert stats.bytes_lost == 0
                shares.append(len(program.text) / stats.plot_time / (BAUD / 10))
            print(f"{name:<18}{device.buffer.flow_control:<14}{len(program.text):>7}"
                  f"{shares[0]:>10.1%}{shares[1]:>15.1%}")


def motion_bound() -> None:
    print("\n2. motion-bound: the profiles' own speeds (time=instant simulator); starved = idle "
          "with more to come")
    print(f"{'device':<18}{'job':<22}{'plot time s':>12}{'starved s':>11}{'starved':>9}")
    for name in DEVICES + GPGL:
        device = load_device(name)
        for job, strategy in (("vase-svg", "force"), ("star", "perforate")):
            program = program_for(device, job, strategy)
            port = open_port("sim://?time=instant&sheet=A3", device)
            stream(port, program, device)
            stats = port.simulator.stats
            port.close()
            assert stats.bytes_lost == 0
            print(f"{name:<18}{job + ' ' + strategy:<22}{stats.plot_time:>12.1f}{stats.starved_time:>11.2f}"
                  f"{stats.starved_time / stats.plot_time:>9.2%}")


def host_cpu(seconds: float = 10.0) -> None:
    print(f"\n3. host CPU while the plotter works: pty simulator at real speed, {seconds:g} s of plotting")
    print(f"{'device':<18}{'flow control':<14}{'CPU / wall':>11}")
    for name in DEVICES:
        device = load_device(name)
        program = program_for(device)
        proc = subprocess.Popen([sys.executable, "-m", "foldfab", "sim", name, "--pty", "-o", "sheet=A3"],
                                stdout=subprocess.PIPE, text=True, cwd=ROOT)
        port = open_port(proc.stdout.readline().strip(), device)
        cancel = threading.Event()
        timer = threading.Timer(seconds, cancel.set)
        wall, cpu = time.monotonic(), time.process_time()
        timer.start()
        try:
            stream(port, program, device, cancel=cancel)
        except StreamStopped:
            pass
        share = (time.process_time() - cpu) / (time.monotonic() - wall)
        port.close()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=30)
        print(f"{name:<18}{device.buffer.flow_control:<14}{share:>11.2%}")


def usb_transports() -> None:
    from foldfab.plotting.urlhandler import protocol_usb
    from foldfab.sim import create_simulator, parse_options
    from foldfab.sim.printer import printer_thread
    from foldfab.sim.usb import SimulatedUsbBackend, SimulatedUsbDevice
    from foldfab.sim.usblink import UsbLink

    def opened(transport, device, time_mode):
        sim = create_simulator(device, parse_options([("time", time_mode), ("sheet", "A3")]))
        if transport == "lp://":
            path, _, stop, thread = printer_thread(sim)
            return open_port(f"lp://{path}", device), sim, lambda: (stop.set(), thread.join())
        if transport == "usb://":
            protocol_usb.BACKEND = SimulatedUsbBackend([SimulatedUsbDevice(UsbLink(sim), 0x0B4D, 0x1137)])
            return open_port("usb://0b4d:1137", device), sim, lambda: None
        port = open_port(f"sim://?time={time_mode}&sheet=A3", device, baudrate=BAUD)
        return port, port.simulator, lambda: None

    print("\n4. USB transports: roland-gx24 (HP-GL, flow none), vase-svg job")
    print(f"{'transport':<16}{'motion':<10}{'bytes':>7}{'plot time s':>12}{'bytes/s':>10}{'starved':>9}")
    with tempfile.TemporaryDirectory() as folder:
        for motion, device, time_mode in (("instant", load_device(instant_motion("roland-gx24", Path(folder))), "real"),
                                          ("profile", load_device("roland-gx24"), "instant")):
            program = program_for(device)
            for transport in ("lp://", "usb://", f"serial {BAUD}"):
                port, sim, close = opened(transport, device, time_mode)
                try:
                    stream(port, program, device)
                finally:
                    port.close()
                    close()
                stats = sim.stats
                assert stats.bytes_lost == 0
                print(f"{transport:<16}{motion:<10}{len(program.text):>7}{stats.plot_time:>12.2f}"
                      f"{len(program.text) / stats.plot_time:>10.0f}{stats.starved_time / stats.plot_time:>9.2%}")


@contextlib.contextmanager
def cpu_load(processes: int):
    """``processes`` busy loops in other processes while the block runs (a loaded host)."""
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(processes)]
    try:
        yield
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()


PARTS = {"link": link_bound, "motion": motion_bound, "cpu": host_cpu, "usb": usb_transports}

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--load", type=int, default=0, metavar="N",
                        help="run N CPU-bound processes during the measurement (2: both cores of this machine)")
    parser.add_argument("--part", choices=sorted(PARTS), action="append",
                        help="run only this part (repeatable); default: all")
    parser.add_argument("--usb", action="store_true", help="the USB transports only (as --part usb)")
    args = parser.parse_args()
    parts = ["usb"] if args.usb else args.part or list(PARTS)
    if args.load:
        print(f"host loaded: {args.load} CPU-bound processes running")
    with cpu_load(args.load):
        for part in parts:
            PARTS[part]()
