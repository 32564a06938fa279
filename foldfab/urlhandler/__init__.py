"""pyserial URL handlers of foldfab (``sim://``); :mod:`foldfab.transport` registers them."""
