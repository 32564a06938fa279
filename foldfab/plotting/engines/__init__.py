"""The streaming engines: one sender per protocol, on one base sender.

:data:`SENDERS` maps a device profile's ``protocol`` to its sender class
(:mod:`~foldfab.plotting.engines.hpgl`, :mod:`~foldfab.plotting.engines.grbl`,
:mod:`~foldfab.plotting.engines.ebb`, :mod:`~foldfab.plotting.engines.gpgl`, all on
:class:`~foldfab.plotting.engines.base.Sender`); :func:`foldfab.plotting.stream.stream` looks it up.
"""

from __future__ import annotations

from foldfab.plotting.engines.base import Sender
from foldfab.plotting.engines.ebb import EbbSender
from foldfab.plotting.engines.gpgl import GPGLSender
from foldfab.plotting.engines.grbl import GrblSender
from foldfab.plotting.engines.hpgl import HPGLSender

SENDERS: dict[str, type[Sender]] = {"hpgl": HPGLSender, "gcode": GrblSender, "ebb": EbbSender, "gpgl": GPGLSender}
"""Sender class by :attr:`foldfab.devices.DeviceProfile.protocol`."""
