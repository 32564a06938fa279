"""Geometry: the paper's construction, pure numpy and no file output.

Takes a profile and a trajectory (points, a template, or an SVG path read by
:mod:`~foldfab.geometry.svg_input`) and gives the reflected surface
(:mod:`~foldfab.geometry.reflection`), its crease pattern and the folded 3D model.
"""
