"""handeye: hand-eye calibration of a camera against a robot arm.

>>> import handeye
>>> result = handeye.calibrate_poses(flange2base, target2cam, setup="eye_in_hand")  # doctest: +SKIP
>>> result.cam2flange  # doctest: +SKIP

Conventions: a transform named ``a2b`` maps coordinates in frame ``a`` to frame ``b``; stacks
are ``(N, 4, 4)``; lengths are metres inside the library.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._shared.moved import install as install_moved
from ._version import __version__
from .errors import DegenerateMotionError, HandEyeError, InputMismatchError, PoseFormatError, SessionError, TargetError

# The public names load on first use (PEP 562): ``import handeye``, and any of its light modules
# (errors, vision.detect, ...), does not pay for scipy, the solvers and the report until they are
# used.
_SUBMODULES = ("estimation", "frames", "io", "pipelines", "planning", "report", "robot", "sensors", "simulate",
               "solvers", "workflows")
_NAMES = {
    "calibrate": "pipelines.calibration", "calibrate_poses": "pipelines.calibration",
    "certify_calibration": "pipelines.calibration",
    "check_folder": "pipelines.folders",
    "diagnose": "estimation.diagnostics",
    "DualQuaternion": "geometry.dualquat",
    "calibrate_joints": "pipelines.joints",
    "relative_motions": "frames.motions",
    "CalibrationOptions": "options",
    "RobotPoseInput": "frames.poses", "format_poses": "frames.poses", "parse_poses": "frames.poses",
    "write_calibration": "report",
    "Calibration": "result", "Diagnostics": "result", "Unobservable": "result",
    "solve": "solvers", "solve_batch": "solvers", "solve_robot_world": "solvers", "solve_robot_world_batch": "solvers",
    "calibrate_streams": "pipelines.streams",
    "load_result": "io.results",
}

#: Modules that moved when the package was cut into folders by domain: the old path still imports,
#: with a DeprecationWarning, for one release (old name -> the modules that now hold its names).
MOVED = {f"handeye.{old}": tuple(f"handeye.{n}" for n in new) for old, new in {
    "setups": ("frames.setups",), "poses": ("frames.poses",), "motions": ("frames.motions",),
    "metrics": ("frames.metrics",), "kinematics": ("robot.kinematics",), "urdf": ("robot.urdf",),
    "vision": ("sensors.camera",), "vision.detect": ("sensors.camera.detect",), "vision.pnp": ("sensors.camera.pnp",),
    "vision.render": ("sensors.camera.render",), "vision.preview": ("sensors.camera.preview",),
    "vision.targets": ("sensors.camera.targets",),
    **{f"vision.targets.{m}": (f"sensors.camera.targets.{m}",) for m in
       ("base", "chessboard", "charuco", "circles", "modified_circles", "apriltag", "aruco_grid")},
    "printing": ("sensors.camera.printing",),
    "depth": ("sensors.depth", "pipelines.depth.pipeline", "pipelines.depth.session"),
    "depth.clouds": ("sensors.depth.clouds",), "depth.spheres": ("sensors.depth.spheres",),
    "depth.fit": ("pipelines.depth.pipeline",), "depth.session": ("pipelines.depth.pipeline", "pipelines.depth.session"),
    "diagnostics": ("estimation.diagnostics",), "validation": ("estimation.validation",),
    "estimators": ("estimation.estimators",), "partial": ("estimation.partial",), "verdict": ("estimation.verdict",),
    "sync": ("estimation.sync",), "session": ("io.session",), "importers": ("io.importers",),
    "calibration": ("pipelines.calibration",), "joint_calibration": ("pipelines.joints",),
    "streams": ("pipelines.streams",), "checking": ("pipelines.folders",), "verification": ("pipelines.verify",),
    "joint_planning": ("planning.joints",), "acquire": ("workflows.acquire",), "fleet": ("workflows.fleet",),
    "study": ("workflows.study",),
    # refine_kinematic is gone: joint angles are the estimation core's robot model (robot.models.JointAngles)
    "solvers.kinematic": ("robot.models", "estimation.core"),
    # a sensor kind is two folders (sensors/<kind>/ and pipelines/<kind>/): its session reader, simulator
    # and planner left io/, simulate/ and planning/
    **{f"io.{kind}_session": (f"pipelines.{kind}.session",) for kind in ("depth", "laser", "linescan", "rig", "silhouette")},
    **{f"simulate.{kind}": (f"pipelines.{kind}.simulate",) for kind in ("laser", "linescan", "rig", "silhouette")},
    "simulate.depth": ("pipelines.depth.simulate_board",), "simulate.mesh": ("pipelines.depth.simulate_mesh",),
    "simulate.arm_depth": ("pipelines.depth.simulate_arm",),
    "simulate.scene": ("pipelines.depth.simulate_scene",),
    "pipelines.mesh": ("pipelines.depth.mesh",), "pipelines.arm_depth": ("pipelines.depth.arm",),
    "pipelines.scene": ("pipelines.depth.scene",),
    "planning.laser": ("pipelines.laser.plan",), "planning.linescan": ("pipelines.linescan.plan",),
    "planning.rig": ("pipelines.rig.plan",),
}.items()}
#: Names that left a package that stays (package -> {name: the module that holds it now}); a kind's
#: folder that was its pipeline's module (``handeye.pipelines.laser``) forwards every name of it ("*").
MOVED_NAMES = {
    "handeye.simulate": {
        **dict.fromkeys(("DepthScene", "SphereScene", "depth_scene", "sphere_scene", "write_depth_session"),
                        "handeye.pipelines.depth.simulate_board"),
        **dict.fromkeys(("MeshScene", "flange_mesh", "mesh_scene", "write_mesh_session"), "handeye.pipelines.depth.simulate_mesh"),
        **dict.fromkeys(("LaserScene", "laser_scene", "write_laser_session"), "handeye.pipelines.laser.simulate")},
    "handeye.planning": {**dict.fromkeys(("LaserPlan", "plan_laser"), "handeye.pipelines.laser.plan"),
                         **dict.fromkeys(("LineScanPlan", "plan_linescan"), "handeye.pipelines.linescan.plan"),
                         **dict.fromkeys(("RigPlan", "RigPlanCamera", "plan_rig"), "handeye.pipelines.rig.plan")},
    "handeye.solvers.refine": dict.fromkeys(("refine_pose", "refine_reprojection"), "handeye.estimation.refinement"),
    "handeye.io.extras": dict.fromkeys(("session_extras", "missing_extras", "check_extras"), "handeye.pipelines.folders"),
    "handeye.io.importers": {"import_robcalibrator": "handeye.pipelines.laser.importers",
                             "import_easyhec": "handeye.pipelines.silhouette.importers"},
    **{f"handeye.pipelines.{kind}": {"*": f"handeye.pipelines.{kind}.pipeline"}
       for kind in ("depth", "laser", "linescan", "rig", "silhouette")},
}
install_moved(MOVED, MOVED_NAMES)

if TYPE_CHECKING:  # what the names are, for type checkers and editors
    from . import estimation, frames, io, pipelines, planning, report, robot, sensors, simulate, solvers, workflows
    from .estimation.diagnostics import diagnose
    from .frames.motions import relative_motions
    from .frames.poses import RobotPoseInput, format_poses, parse_poses
    from .geometry.dualquat import DualQuaternion
    from .io.results import load_result
    from .options import CalibrationOptions
    from .pipelines.calibration import calibrate, calibrate_poses, certify_calibration
    from .pipelines.folders import check_folder
    from .pipelines.joints import calibrate_joints
    from .pipelines.streams import calibrate_streams
    from .report import write_calibration
    from .result import Calibration, Diagnostics, Unobservable
    from .solvers import solve, solve_batch, solve_robot_world, solve_robot_world_batch


def __getattr__(name: str) -> Any:
    if name in _SUBMODULES:
        value: Any = importlib.import_module(f"{__name__}.{name}")
    elif f"{__name__}.{name}" in MOVED:  # an old module's name: its stand-in, with the warning
        value = importlib.import_module(f"{__name__}.{name}")
    elif name in _NAMES:
        value = getattr(importlib.import_module(f"{__name__}.{_NAMES[name]}"), name)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value  # once loaded, a plain attribute
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


__all__ = [
    "Calibration",
    "CalibrationOptions",
    "DegenerateMotionError",
    "Diagnostics",
    "DualQuaternion",
    "HandEyeError",
    "InputMismatchError",
    "PoseFormatError",
    "RobotPoseInput",
    "SessionError",
    "TargetError",
    "Unobservable",
    "calibrate",
    "calibrate_joints",
    "calibrate_poses",
    "calibrate_streams",
    "certify_calibration",
    "check_folder",
    "diagnose",
    "estimation",
    "format_poses",
    "frames",
    "io",
    "load_result",
    "parse_poses",
    "pipelines",
    "planning",
    "relative_motions",
    "report",
    "robot",
    "sensors",
    "simulate",
    "solve",
    "solve_batch",
    "solve_robot_world",
    "solve_robot_world_batch",
    "solvers",
    "workflows",
    "write_calibration",
    "__version__",
]
