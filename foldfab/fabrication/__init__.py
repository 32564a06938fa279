"""Fabrication: a design and a device profile to a plot plan.

Takes a :class:`~foldfab.design.Design`, a device profile and the job's ``[fabrication]``
table (:mod:`~foldfab.fabrication.spec`) and gives a :class:`~foldfab.fabrication.plan.PlotPlan`:
scoring and cut lines placed on the sheet, in layers with their tools, ordered for little travel.
"""
