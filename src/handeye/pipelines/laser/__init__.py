"""A laser line profiler, everything but its mathematics (that is :mod:`handeye.sensors.laser`), and its
registration (:data:`KIND`).

* :mod:`~handeye.pipelines.laser.session`: a laser session's ``laser:`` section and its profiles read and checked;
* :mod:`~handeye.pipelines.laser.pipeline`: every profile read, the target's sensor model, the estimation core;
* :mod:`~handeye.pipelines.laser.simulate`: profiles of a ball, a plate, an edge, a step or balls, by an arm too;
* :mod:`~handeye.pipelines.laser.plan`: ``handeye plan --sensor laser_line``: poses around the target, their std.

``handeye.pipelines.laser`` was the pipeline's module: its names still import from here, with a
DeprecationWarning, for one release.
"""

from __future__ import annotations

from ..._shared.moved import forward_names
from ..sensor_kind import KindOption, SensorKind

__all__ = ["KIND"]

#: The laser line profiler's registration (:mod:`handeye.pipelines.kinds`).
KIND = SensorKind(
    section="laser", cli="laser_line", display="laser line profiler", package=__name__,
    calibrate="pipeline:calibrate_laser_session", rig_member="pipeline:rig_member",
    simulate="simulate:simulate_command", plan="plan:plan_command",
    targets=("sphere", "plane", "edge", "step", "spheres"), frame="laser_profiler_optical_frame",
    simulate_help="a laser line profiler's profiles of a ball, a plate, a block's edge, a step or a fixture of balls "
    "(--target; --poses of them; --arm for joint angles)",
    plan_help="a laser line profiler's profiles of a ball (--diameter), a plate, a block's edge, a step or a fixture of "
    "balls (--target); --target-in-base is then the ball's centre (a point of the plate, of the edge's line, the first "
    "ball's centre), its rotation by default 0,0,0: the profiler looks from above",
    plan_usage="the profiler's placement (--cam-in-flange or --camera-in-base), the target's and --target "
    "sphere|plane|edge|step|spheres",
    plan_target_rotation=(0.0, 0.0, 0.0),
    options=(KindOption("plan", "--diameter", "the ball's diameter (m, default 0.04)", "number", 0.0, 1.0, above=True),),
)

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
