"""pyserial URL handlers of foldfab (``sim://``); :mod:`foldfab.plotting.transport` registers them."""
