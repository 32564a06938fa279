"""foldfab studio: the four-view designer in the browser (profile, trajectory, crease pattern, 3D).

:mod:`foldfab.studio.api` is the JSON API over foldfab's own core, :mod:`foldfab.studio.server`
serves it and the static page on 127.0.0.1; ``static/`` holds the page and the vendored three.js.
"""
