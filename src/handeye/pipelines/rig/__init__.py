"""A rig (several sensors on one robot, one fit), everything but its mathematics (that is
:mod:`handeye.sensors.rig`), and its registration (:data:`KIND`). Its sensors are cameras or other
kinds that can be a rig's (their registration names a ``rig_member``: a depth camera, a laser profiler).

* :mod:`~handeye.pipelines.rig.session`: a rig session's ``sensors:`` section, each sensor read by its kind;
* :mod:`~handeye.pipelines.rig.pipeline`: each sensor alone, then all in one fit, the sensor that disagrees named;
* :mod:`~handeye.pipelines.rig.simulate`: a stereo pair, cameras around the cell, a camera beside a depth camera or a
  laser profiler, two profilers.

A rig of cameras plans with ``handeye plan --rig-camera`` (:mod:`handeye.planning.rig`). ``handeye.pipelines.rig``
was the pipeline's module: its names still import from here, with a DeprecationWarning, for one release.
"""

from __future__ import annotations

from ..._shared.moved import forward_names
from ..sensor_kind import KindOption, SensorKind

__all__ = ["KIND"]

#: The rig's registration (:mod:`handeye.pipelines.kinds`).
KIND = SensorKind(
    section="sensors", cli="rig", display="rig", package=__name__,
    calibrate="pipeline:calibrate_rig_session", extras="session:extras", members="pipeline:rig_members",
    simulate="simulate:simulate_command",
    simulate_help="a stereo pair on the flange (eye_in_hand) or three fixed cameras (eye_to_hand)",
    options=(KindOption("simulate", "--cameras", "the number of cameras (default 2 on the flange, 3 fixed around the cell)",
                        "whole", 2),
             KindOption("simulate", "--laser", "a camera beside a laser profiler (a small board and a 40 mm ball) instead "
                        "of cameras", "flag"),
             KindOption("simulate", "--depth", "a camera beside a depth camera (640x480 clouds and intensity images), both "
                        "seeing the board, instead of cameras", "flag")),
)

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
