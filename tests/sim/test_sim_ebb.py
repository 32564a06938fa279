"""The simulated EiBotBoard: its replies as the firmware and plotink have them, the motion FIFO
that paces OK replies on the simulator's clock, the emergency stop, the fault options, and
plotink's own ebb_serial and ebb_motion talking to it."""

from __future__ import annotations

import pytest

from foldfab.devices import load_device
from foldfab.plotting.transport import open_port
from foldfab.sim import create_simulator, parse_options


@pytest.fixture
def board():
    device = load_device("axidraw-v3")
    return open_port("sim://?time=instant", device, timeout=1.0)


def ask(port, command: str, lines: int = 1) -> list[bytes]:
    port.write(command.encode("ascii") + b"\r")
    return [port.readline() for _ in range(lines)]


def test_registered_as_sim_axidraw():
    for name in ("axidraw-v3", "axidraw-se-a3"):
        device = load_device(name)
        assert type(create_simulator(device, parse_options({}))).__name__ == "EbbBoard"
        port = open_port(f"sim://{name}?time=instant", None)
        assert ask(port, "V") == [b"EBBv13_and_above EB Firmware Version 2.8.1\r\n"]


def test_replies_as_the_firmware(board):
    assert ask(board, "EM,1,1") == [b"OK\r\n"]
    assert ask(board, "SC,4,20641") == [b"OK\r\n"]
    assert ask(board, "QP", 2) == [b"1\r\n", b"OK\r\n"]  # pen up
    assert ask(board, "QM") == [b"QM,0,0,0,0\r\n"]  # no OK after QM, QG, V
    assert ask(board, "QG") == [b"10\r\n"]  # pen up, nothing moving
    assert ask(board, "QS", 2) == [b"0,0\r\n", b"OK\r\n"]
    assert ask(board, "XX,1") == [b"!8 Err: Unknown command 'XX'\r\n"]
    assert ask(board, "SM,0,10,10") == [b"!8 Err: bad parameter 'SM'\r\n"]
    assert ask(board, "SM,a") == [b"!8 Err: bad parameter 'SM'\r\n"]
    assert ask(board, "SP,0,100") == [b"OK\r\n"]
    assert ask(board, "QP", 2) == [b"0\r\n", b"OK\r\n"]
    assert ask(board, "SM,200,800,0") == [b"OK\r\n"]
    assert ask(board, "QM") == [b"QM,1,1,1,1\r\n"]
    assert int(ask(board, "QG")[0], 16) & 15 != 0
    board.simulator.run_until_idle()
    assert ask(board, "QM") == [b"QM,0,0,0,0\r\n"]
    assert ask(board, "QS", 2) == [b"800,0\r\n", b"OK\r\n"]


def test_the_fifo_paces_the_ok_replies(board):
    """A motion command is answered once the FIFO has room: the third 100 ms move's OK comes
    when the first has ended."""
    sim = board.simulator
    times = []
    for _ in range(3):
        assert ask(board, "SM,100,80,80") == [b"OK\r\n"]
        times.append(sim.t)
    assert times[1] < 0.01 and times[2] == pytest.approx(0.1, abs=0.005)
    sim.run_until_idle()
    assert sim.t == pytest.approx(0.3, abs=0.005)
    assert sim.machine.motors == [240, 240]


def test_moves_and_pen_draw_strokes_in_sheet_mm(board):
    for command in ("SP,0,50", "SM,100,80,80", "SM,1,0,0", "SM,100,80,-80", "SM,1,0,0", "SP,1,50"):
        assert ask(board, command) == [b"OK\r\n"]
    sim = board.simulator
    sim.run_until_idle()
    (stroke,) = sim.strokes
    assert stroke.points.tolist() == [[0, 0], [1, 0], [1, 1]]  # motor 1 = x + y, motor 2 = x - y
    assert sim.t == pytest.approx(0.302, abs=0.002)  # moves, rests and both pen delays


def test_emergency_stop_ends_the_move_and_empties_the_fifo(board):
    sim = board.simulator
    for command in ("SP,0", "SM,1000,8000,8000", "SM,1000,8000,8000"):
        assert ask(board, command) == [b"OK\r\n"]
    sim.advance(sim.t + 0.5)
    assert ask(board, "ES", 2) == [b"1,0,0,1,0\r\n", b"OK\r\n"]
    assert not sim.planner and ask(board, "QM") == [b"QM,0,0,0,0\r\n"]
    m1, m2 = sim.machine.motors
    assert 3000 < m1 < 5000 and m1 == m2  # stopped about half way through the first move
    assert ask(board, "QP", 2)[0] == b"0\r\n"  # ES leaves the pen where it is
    assert ask(board, "SP,1") == [b"OK\r\n"]
    assert ask(board, "HM,10000") == [b"OK\r\n"]
    sim.run_until_idle()
    assert sim.machine.motors == [0, 0] and sim.strokes[0].length == pytest.approx(m1 / 80, abs=0.05)
    # the pen, still down after ES, went up where it stopped (a dot): HM draws nothing
    assert [s.length for s in sim.strokes[1:]] == [0.0]


@pytest.mark.parametrize("options, replies", [
    ("error_at=2&error_code=3", [b"OK\r\n", b"!3 Err: injected fault\r\n", b"OK\r\n"]),
    ("mute=1", [b"", b"", b""]),
])
def test_fault_options(options, replies):
    port = open_port(f"sim://axidraw-v3?time=instant&{options}", None, timeout=0.2)
    assert [ask(port, c)[0] for c in ("EM,1,1", "SP,0", "SP,1")] == replies


def test_plotink_talks_to_it():
    """Evil Mad Scientist's own host library gets the answers it expects."""
    from plotink import ebb_motion, ebb_serial

    port = open_port("sim://axidraw-v3?time=instant", None, timeout=1.0)
    assert ebb_serial.queryVersion(port).startswith("EBB")
    ebb_motion.sendEnableMotors(port, 1)
    ebb_motion.sendPenDown(port, 100)
    assert ebb_motion.QueryPenUp(port) is False
    ebb_motion.doXYMove(port, 80, 80, 100)  # SM,100,80,80
    ebb_motion.sendPenUp(port, 100)
    assert ebb_motion.QueryPenUp(port) is True
    assert ebb_motion.query_steps(port) == (80, 80)
    port.simulator.run_until_idle()
    assert port.simulator.strokes[0].points.tolist() == [[0, 0], [1, 0]]
    assert port.simulator.stats.errors == []
