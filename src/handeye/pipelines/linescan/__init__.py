"""A line-scan camera, everything but its mathematics (that is :mod:`handeye.sensors.linescan`), and its
registration (:data:`KIND`).

* :mod:`~handeye.pipelines.linescan.session`: a line-scan session's ``linescan:`` section, its scans and the robot's trajectory;
* :mod:`~handeye.pipelines.linescan.pipeline`: the target found in each scan, then the estimation core;
* :mod:`~handeye.pipelines.linescan.simulate`: pushbroom scans of a chessboard swept by the robot, rendered;
* :mod:`~handeye.pipelines.linescan.plan`: ``handeye plan --sensor line_scan``: straight scans across the board, their std.

``handeye.pipelines.linescan`` was the pipeline's module: its names still import from here, with a
DeprecationWarning, for one release.
"""

from __future__ import annotations

from ..._shared.moved import forward_names
from ..sensor_kind import KindOption, SensorKind

__all__ = ["KIND"]

#: The line-scan camera's registration (:mod:`handeye.pipelines.kinds`).
KIND = SensorKind(
    section="linescan", cli="line_scan", display="line-scan camera", package=__name__,
    calibrate="pipeline:calibrate_linescan_session", simulate="simulate:simulate_command", plan="plan:plan_command",
    simulate_help="a line-scan camera's scans of a chessboard swept by the robot (--poses of them; --arm for joint angles)",
    plan_help="a line-scan camera's straight scans across a chessboard (--line-camera, --standoff, --speed)",
    plan_takes=("--target-spec", "--standoff"),
    plan_usage="the camera (--line-camera WIDTH,FOCAL), its placement (--cam-in-flange or --camera-in-base), the "
    "target's, --target or --target-spec, --standoff (default 0.4 m; the scans at 0.75-1.25x it) and --speed",
    options=(KindOption("plan", "--line-camera", "pixels along the line and the focal length in pixels (default 2048,2400)",
                        metavar="WIDTH,FOCAL"),
             KindOption("plan", "--speed", "the scans' speed (m/s, default 0.2)", "number", 0.0, above=True)),
)

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
