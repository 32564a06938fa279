"""The job queue: programs waiting for plotters, and the workers that plot them.

Takes fabricated jobs (program, device, sheet) as snapshots (:mod:`~foldfab.queue.snapshot`) and
gives them to workers one plotter at a time (:mod:`~foldfab.queue.limits`: states and limits;
:mod:`~foldfab.queue.records`: records;
:mod:`~foldfab.queue.store`: the store interface; :mod:`~foldfab.queue.sqlite`: SQLite;
:mod:`~foldfab.queue.postgres`: a PostgreSQL server; :func:`open_queue` chooses), which stream
them with leases and heartbeats (:mod:`~foldfab.queue.worker`) so that a killed process loses nothing.

Import from the modules: this package imports nothing, so that the command line's parser can read
the queue's limits (:mod:`~foldfab.queue.limits`) without loading its records or a store.
"""
