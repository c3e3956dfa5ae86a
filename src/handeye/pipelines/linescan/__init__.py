"""A line-scan camera, everything but its mathematics (that is :mod:`handeye.sensors.linescan`); its
registration is in :mod:`handeye.pipelines.kinds`.

* :mod:`~handeye.pipelines.linescan.session`: a line-scan session's ``linescan:`` section, its scans and the robot's trajectory;
* :mod:`~handeye.pipelines.linescan.pipeline`: the target found in each scan, then the estimation core;
* :mod:`~handeye.pipelines.linescan.simulate`: pushbroom scans of a chessboard swept by the robot, rendered;
* :mod:`~handeye.pipelines.linescan.plan`: ``handeye plan --sensor line_scan``: straight scans across the board, their std.

``handeye.pipelines.linescan`` was the pipeline's module: its names still import from here, with a
DeprecationWarning, for one release.
"""

from __future__ import annotations

from ..._shared.moved import forward_names

__all__: list[str] = []  # its modules are its face; its registration is in handeye.pipelines.kinds

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
