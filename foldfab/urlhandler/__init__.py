"""Deprecated home of foldfab's pyserial URL handlers: use ``foldfab.plotting.urlhandler``.

Kept for one release (until foldfab 0.3) so that a pyserial configuration naming
``foldfab.urlhandler`` in ``serial.protocol_handler_packages`` still opens ``sim://``.
"""
