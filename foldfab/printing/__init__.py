"""Printable templates: a design's crease pattern at true size, tiled across pages of a
printer's paper in origami's line conventions, with the folded model and folding notes.

The page layout (:mod:`~foldfab.printing.tiles`, :mod:`~foldfab.printing.template`) is a
list of :class:`~foldfab.printing.page.Page` drawings in page millimetres, which
:mod:`~foldfab.printing.pdf` and :mod:`~foldfab.printing.svg` render alike;
:func:`foldfab.printing.output.write_template` is the entry point.
"""
