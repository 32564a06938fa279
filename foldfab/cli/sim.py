"""``foldfab sim``: a simulated plotter served on a pseudo-terminal, for any program that opens
a real port; its recordings and statistics once it is stopped."""

from __future__ import annotations

import argparse
from pathlib import Path

from foldfab.cli.common import _check_output


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


def add_commands(sub) -> None:
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
