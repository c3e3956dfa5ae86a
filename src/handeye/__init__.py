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

from ._version import __version__
from .errors import DegenerateMotionError, HandEyeError, InputMismatchError, PoseFormatError, SessionError, TargetError

# The public names load on first use (PEP 562): ``import handeye``, and any of its light modules
# (errors, vision.detect, ...), does not pay for scipy, the solvers and the report until they are
# used.
_SUBMODULES = ("depth", "kinematics", "metrics", "setups", "simulate", "solvers")
_NAMES = {
    "calibrate": "calibration", "calibrate_poses": "calibration", "certify_calibration": "calibration",
    "check_folder": "checking",
    "diagnose": "diagnostics",
    "DualQuaternion": "geometry.dualquat",
    "calibrate_joints": "joint_calibration",
    "relative_motions": "motions",
    "CalibrationOptions": "options",
    "RobotPoseInput": "poses", "format_poses": "poses", "parse_poses": "poses",
    "write_calibration": "report",
    "Calibration": "result", "Diagnostics": "result", "Unobservable": "result",
    "solve": "solvers", "solve_batch": "solvers", "solve_robot_world": "solvers", "solve_robot_world_batch": "solvers",
    "calibrate_streams": "streams",
}

if TYPE_CHECKING:  # what the names are, for type checkers and editors
    from . import depth, kinematics, metrics, setups, simulate, solvers
    from .calibration import calibrate, calibrate_poses, certify_calibration
    from .checking import check_folder
    from .diagnostics import diagnose
    from .geometry.dualquat import DualQuaternion
    from .joint_calibration import calibrate_joints
    from .motions import relative_motions
    from .options import CalibrationOptions
    from .poses import RobotPoseInput, format_poses, parse_poses
    from .report import write_calibration
    from .result import Calibration, Diagnostics, Unobservable
    from .solvers import solve, solve_batch, solve_robot_world, solve_robot_world_batch
    from .streams import calibrate_streams


def __getattr__(name: str) -> Any:
    if name in _SUBMODULES:
        value: Any = importlib.import_module(f"{__name__}.{name}")
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
    "depth",
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
