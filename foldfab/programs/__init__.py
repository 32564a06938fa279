"""Programs: a plot plan to a device's program text, and any program read back.

Takes a :class:`~foldfab.fabrication.plan.PlotPlan` and gives a
:class:`~foldfab.programs.program.Program` in the device's language (HP-GL, G-code, GP-GL); reads
programs back into strokes (:mod:`~foldfab.programs.interpret`, one reader per language:
:mod:`~foldfab.programs.read_hpgl`, :mod:`~foldfab.programs.read_gcode`, :mod:`~foldfab.programs.read_gpgl`)
for time estimates and previews.
"""
