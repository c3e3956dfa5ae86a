"""``handeye live``: a capture driven from a page in the browser.

:mod:`.capture` holds the capture (devices, the session folder, calibrations, the planner) without
the web; :mod:`.server` serves its page (aiohttp, the ``live`` extra; the page's files in
``static/``, written by hand and served from the package).
"""

from .capture import LiveCapture, LiveView, PoseFileRobot, StillSimCamera, preview_frame
from .server import LiveServer, is_loopback, serve

__all__ = ["LiveCapture", "LiveView", "PoseFileRobot", "StillSimCamera", "preview_frame", "LiveServer", "serve",
           "is_loopback"]
