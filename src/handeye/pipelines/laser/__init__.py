"""A laser line profiler, everything but its mathematics (that is :mod:`handeye.sensors.laser`); its
registration is in :mod:`handeye.pipelines.kinds`.

* :mod:`~handeye.pipelines.laser.session`: a laser session's ``laser:`` section and its profiles read and checked;
* :mod:`~handeye.pipelines.laser.pipeline`: every profile read, the target's sensor model, the estimation core;
* :mod:`~handeye.pipelines.laser.simulate`: profiles of a ball, a plate, an edge, a step or balls, by an arm too;
* :mod:`~handeye.pipelines.laser.plan`: ``handeye plan --sensor laser_line``: poses around the target, their std.

``handeye.pipelines.laser`` was the pipeline's module: its names still import from here, with a
DeprecationWarning, for one release.
"""

from __future__ import annotations

from ..._shared.moved import forward_names

__all__: list[str] = []  # its modules are its face; its registration is in handeye.pipelines.kinds

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
