"""Simulated plotters that behave like the real ones, faults included.

No plotter is attached to the test machines, so foldfab ships one simulator per
protocol: :class:`~foldfab.sim.hpgl.HPGLPlotter` (HP-GL plotters and cutters),
:class:`~foldfab.sim.grbl.GrblController` (GRBL 1.1), :class:`~foldfab.sim.ebb.EbbBoard`
(the EiBotBoard of AxiDraw pen plotters) and :class:`~foldfab.sim.gpgl.GPGLCutter`
(Silhouette and Graphtec cutters in GP-GL).  All are configured from a
device profile and :class:`~foldfab.sim.options.SimOptions`, run on a virtual clock
(timing model: :mod:`foldfab.sim.device`), record every stroke they draw and keep
:class:`~foldfab.sim.record.SimStats`.

Reach them as a pyserial port, ``sim://DEVICE?option=value&...``
(:mod:`foldfab.plotting.urlhandler.protocol_sim`, opened by :func:`foldfab.plotting.transport.open_port`),
or on a pseudo-terminal any program can open (:func:`foldfab.sim.pty.serve_pty`,
``foldfab sim NAME --pty``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from foldfab.sim.options import SimOptions, parse_options

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.sim.device import Simulator

__all__ = ["SimOptions", "create_simulator", "parse_options"]


def create_simulator(device: DeviceProfile, options: SimOptions | None = None) -> Simulator:
    """The simulator for ``device``'s protocol."""
    options = options or SimOptions()
    if device.protocol == "hpgl":
        from foldfab.sim.hpgl import HPGLPlotter

        return HPGLPlotter(device, options)
    if device.protocol == "ebb":
        from foldfab.sim.ebb import EbbBoard

        return EbbBoard(device, options)
    if device.protocol == "gpgl":
        from foldfab.sim.gpgl import GPGLCutter

        return GPGLCutter(device, options)
    from foldfab.sim.grbl import GrblController

    return GrblController(device, options)
