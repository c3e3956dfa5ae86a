"""handeye: hand-eye calibration of a camera against a robot arm.

>>> import handeye
>>> result = handeye.calibrate_poses(flange2base, target2cam, setup="eye_in_hand")  # doctest: +SKIP
>>> result.cam2flange  # doctest: +SKIP

Conventions: a transform named ``a2b`` maps coordinates in frame ``a`` to frame ``b``; stacks
are ``(N, 4, 4)``; lengths are metres inside the library.
"""

from __future__ import annotations

from . import kinematics, metrics, setups, simulate, solvers
from ._version import __version__
from .calibration import calibrate, calibrate_poses, certify_calibration
from .checking import check_folder
from .diagnostics import diagnose
from .errors import DegenerateMotionError, HandEyeError, InputMismatchError, PoseFormatError, SessionError, TargetError
from .geometry.dualquat import DualQuaternion
from .joint_calibration import calibrate_joints
from .motions import relative_motions
from .options import CalibrationOptions
from .poses import RobotPoseInput, format_poses, parse_poses
from .report import write_calibration
from .result import Calibration, Diagnostics, Unobservable
from .solvers import solve, solve_batch, solve_robot_world, solve_robot_world_batch
from .streams import calibrate_streams

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
    "format_poses",
    "kinematics",
    "metrics",
    "parse_poses",
    "relative_motions",
    "setups",
    "simulate",
    "solve",
    "solve_batch",
    "solve_robot_world",
    "solve_robot_world_batch",
    "solvers",
    "write_calibration",
    "__version__",
]
