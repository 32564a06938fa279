"""Deprecated path of the ``sim://`` handler: :mod:`foldfab.plotting.urlhandler.protocol_sim`."""

from foldfab.plotting.urlhandler.protocol_sim import Serial

__all__ = ["Serial"]
