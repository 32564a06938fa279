"""Plotting: a program sent to a machine, and what the machine drew.

Takes a :class:`~foldfab.programs.program.Program` and a port chosen by URL
(:mod:`~foldfab.plotting.transport`) and gives progress events and a result confirmed by the
machine; a stopped plot leaves a resume state (:mod:`~foldfab.plotting.resume`).
"""
