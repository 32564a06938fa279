"""Writers for the files the origami world opens: FOLD, SVG, ORIPA ``.cp``, meshes."""
