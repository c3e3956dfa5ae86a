"""A rig (several sensors on one robot, one fit), everything but its mathematics (that is
:mod:`handeye.sensors.rig`); its registration is in :mod:`handeye.pipelines.kinds`. Its sensors are cameras
or other kinds that can be a rig's (their registration names a ``rig_member``: a depth camera, a laser profiler).

* :mod:`~handeye.pipelines.rig.session`: a rig session's ``sensors:`` section, each sensor read by its kind;
* :mod:`~handeye.pipelines.rig.pipeline`: each sensor alone, then all in one fit, the sensor that disagrees named;
* :mod:`~handeye.pipelines.rig.simulate`: a stereo pair, cameras around the cell, a camera beside a depth camera or a
  laser profiler, two profilers;
* :mod:`~handeye.pipelines.rig.plan`: ``handeye plan --sensor rig`` (or ``--rig-camera``): poses every camera of a
  rig of cameras can use, each camera's predicted std.

``handeye.pipelines.rig``
was the pipeline's module: its names still import from here, with a DeprecationWarning, for one release.
"""

from __future__ import annotations

from ..._shared.moved import forward_names

__all__: list[str] = []  # its modules are its face; its registration is in handeye.pipelines.kinds

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
