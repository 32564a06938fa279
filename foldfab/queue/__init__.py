"""The job queue: programs waiting for plotters, and the workers that plot them.

Takes fabricated jobs (program, device, sheet) and gives them to workers one plotter at a
time (:mod:`~foldfab.queue.store`, SQLite), which stream them with leases and heartbeats
(:mod:`~foldfab.queue.worker`) so that a killed process loses nothing.
"""
