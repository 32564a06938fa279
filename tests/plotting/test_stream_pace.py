"""The plotter sets the pace: the sender never leaves the link idle while it has bytes to send.

On a plotter whose motion takes no time the link is the only limit, so the device waits for
every byte; what must never happen is that the wire carries nothing while the device waits
and the sender still has bytes for it (a checkpoint's round trip it sits out, a write it is
late for).  The simulator counts exactly that on its own clock (``link_starvations``);
``time=instant`` moves the clock only when the host blocks, so a host that is never late is
the case the sender alone decides.  And ``sim://`` in real time keeps a driver's transmit
buffer: bytes written go out on the plotter's clock while the host does something else.
"""

from __future__ import annotations

import pytest

from foldfab.devices import load_device
from foldfab.plotting.stream import stream
from foldfab.plotting.transport import open_port
from foldfab.plotting.urlhandler.protocol_sim import DRIVER_BUFFER
from helpers import ROOT
from helpers.streams import FAST_BAUD, SIM, fabricated, instant_motion

VASE = str(ROOT / "jobs" / "vase-svg.toml")


def port_char_time(device) -> float:
    """Seconds a byte takes on the wire at FAST_BAUD with the profile's framing."""
    serial = device.serial
    return (1 + serial.bytesize + (serial.parity != "N") + serial.stopbits) / FAST_BAUD


@pytest.mark.parametrize("name", ["hp7475a", "graphtec-ce6000", "roland-gx24", "grbl", "xonxoff"])
def test_link_bound_sender_never_leaves_the_device_waiting(name, tmp_path, xonxoff_device):
    profile = str(instant_motion(xonxoff_device if name == "xonxoff" else name, tmp_path))
    device = load_device(profile)
    program = fabricated(VASE, profile).program
    port = open_port(SIM, device, baudrate=FAST_BAUD)
    stream(port, program, device)
    stats = port.simulator.stats
    port.close()
    assert stats.bytes_lost == 0 and stats.bytes_received >= len(program.encode())
    assert stats.starved_time > 0  # the device did wait: for bytes on their way
    # the sender let it wait for no byte at all only at round trips it cannot skip: HP-GL's first
    # checkpoint, and where the pen comes back to a state the plotter may still hold (see
    # HPGLSender.repeats_allow), a few times per job, each for less than a millisecond here
    assert stats.link_starved_time <= 0.01 * stats.plot_time
    working = stats.plot_time - stats.paused_time  # the pen parked at the end (SP0) waits for nothing
    assert stats.bytes_received * port_char_time(device) >= 0.95 * working


def held_bytes(tmp_path):
    """A port to a plotter that takes every byte at once (motion instant), in fast time, and a
    driver buffer's worth of program bytes."""
    profile = str(instant_motion("hp7475a", tmp_path))
    device = load_device(profile)
    data = fabricated(VASE, profile).program.encode()[:DRIVER_BUFFER]
    return open_port("sim://?time=fast&speedup=20&sheet=A3", device, baudrate=FAST_BAUD), data


def test_sim_port_holds_written_bytes_like_a_driver(tmp_path):
    """A write in real or fast time returns before its bytes are through; ``flush`` waits for
    the last one, and they all arrive."""
    port, data = held_bytes(tmp_path)
    assert port.write(data) == len(data)
    assert port.out_waiting > 0  # 4 KiB take the wire 0.36 s (18 ms of wall time at speedup 20)
    port.flush()
    assert port.out_waiting == 0
    stats = port.simulator.stats
    assert stats.bytes_received == len(data) and stats.bytes_lost == 0
    port.close()


def test_sim_port_close_lets_the_held_bytes_go(tmp_path):
    port, data = held_bytes(tmp_path)
    port.write(data)
    port.close()
    stats = port.simulator.stats
    assert stats.bytes_received == len(data) and stats.bytes_lost == 0


@pytest.mark.parametrize("name, link_bound", [("graphtec-ce6000", True), ("grbl", True), ("graphtec-ce6000", False),
                                              ("hp7475a", False)])
def test_estimate_within_a_tenth_of_the_plotters_clock(name, link_bound, tmp_path):
    """The estimate counts the serial line where it, not motion, sets the pace: within 10% of
    the simulated plotter's clock on a link-bound profile (motion instant: 9600 baud on the
    Graphtec, 115200 on GRBL) as on a motion-bound one (the profiles' own)."""
    from foldfab.programs.estimate import estimate, estimate_drawn
    from foldfab.programs.interpret import interpret

    profile = str(instant_motion(name, tmp_path)) if link_bound else name
    device = load_device(profile)
    fab = fabricated(VASE, profile)
    times = estimate(interpret(fab.program, device, fab.plan.sheet), device)
    recorded = estimate_drawn(fab.program.drawn(device.frame(fab.plan.sheet)), device)  # export's route
    assert recorded.link_wait == pytest.approx(times.link_wait, rel=1e-9, abs=1e-9)
    port = open_port(SIM, device)  # at the profile's own baud rate
    stream(port, fab.program, device)
    stats = port.simulator.stats
    port.close()
    assert (times.link_wait > times.total / 2) == link_bound
    assert abs(times.total - (stats.plot_time - stats.paused_time)) <= 0.1 * times.total
