"""foldfab: mirror-reflection column origami, from two polylines to a plotter program."""

__version__ = "0.1.0"
