"""What the pipelines of sensor models share: the options they use and those they refuse, the robot model."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import HandEyeError, InputMismatchError
from ..frames.poses import RobotPoseInput, pose_columns
from ..io.session import SESSION_FILE, load_yaml, pose_rows_inverted
from ..options import CalibrationOptions, options_from
from ..robot.models import ControllerPoses, JointAngles, RobotModel

__all__ = ["sensor_options", "robot_model", "session_robot_input", "why_skipped"]

#: The options of image and pose sessions that a sensor model's fit has no use for.
IMAGE_ONLY = ("method", "refine", "pairs", "known", "robot_noise", "compliance", "strict_images", "keyframes",
              "offset_range", "time_offset")
#: The options a sensor whose robot may be joint angles through the arm's table takes as well.
TABLE_OPTIONS = ("compliance",)


def why_skipped(exc: Exception, path: object) -> str:
    """Why a view is skipped, from the error its file gave, without the file's path in front (the
    skip names the view)."""
    text = str(exc)
    return text[len(str(path)) + 2:] if text.startswith(f"{path}: ") else text


def _given(value: Any, default: Any) -> bool:
    """Whether an option was given other than its default (an empty mapping counts as none)."""
    if value is None or (isinstance(value, dict) and not value):
        return default is not None and not (isinstance(default, dict) and not default)
    if isinstance(value, (str, bool, int, float, tuple)):
        return value != default
    return True


def sensor_options(options: CalibrationOptions | None, changes: dict, what: str, table: bool = False) -> CalibrationOptions:
    """The options of a sensor model's calibration (``robot_accuracy``, ``folds``, ``arm``; with
    ``table``, a sensor whose joint angles fit the arm's table, ``compliance`` too), refusing by name
    those that only image and pose sessions use when they are given (``what``: the session in
    words, for the message)."""
    opts = options_from(options, changes)
    default = CalibrationOptions()
    unused = [name for name in IMAGE_ONLY if _given(getattr(opts, name), getattr(default, name))
              and not (table and name in TABLE_OPTIONS)]
    unused += [] if opts.check else ["check"]
    if unused:
        flags = ", ".join(f"{name} (--{name.replace('_', '-')})" for name in unused)
        raise InputMismatchError(f"{flags}: options of image and pose sessions; {what}'s fit has no use for them (leave "
                                 "them out)")
    return opts


def robot_model(session: Any, index: list[int], options: CalibrationOptions) -> RobotModel:
    """The robot side of a sensor session's (depth, laser, rig: its ``flange2base``, ``joints``,
    ``arm``) views ``index``: joint angles through the arm's table when the session has them (each
    joint's compliance fitted too with ``options.compliance``), else the controller's poses with the
    robot's stated accuracy (``options.robot_accuracy``). Raises InputMismatchError for a compliance
    without joint angles."""
    if session.joints is not None:
        return JointAngles(session.arm, session.joints[index], compliance=options.compliance)
    if options.compliance:
        raise InputMismatchError(f"{session.folder}: compliance=True (--compliance) fits the joints' compliance from joint "
                                 "angles with the arm's table; the session has none (a joints: table in session.yaml): "
                                 "leave compliance out")
    return ControllerPoses(session.flange2base[index], options.robot_accuracy)


def session_robot_input(folder: str | Path, flange2base: NDArray[np.float64]) -> RobotPoseInput | None:
    """The flange poses a sensor's fit used (``flange2base``) as the session's pose table writes them:
    the format and units its ``poses:`` block declares. A sensor's calibration carries it as an image
    session's does, so that result.json gives X and Z in the robot's own format (``robot_format``: a
    FANUC's x, y, z, w, p, r) for every sensor. None when the session gives joint angles alone (no
    pose format declared) or its description cannot be read (the session's reader says why)."""
    try:
        poses = load_yaml(Path(folder) / SESSION_FILE).get("poses")
        if not isinstance(poses, dict) or not {"format", "length_unit"} <= set(poses):
            return None
        fmt, length_unit, angle_unit = str(poses["format"]), str(poses["length_unit"]), str(poses.get("angle_unit", "rad"))
        empty = RobotPoseInput(np.zeros((0, len(pose_columns(fmt)))), fmt, length_unit, angle_unit,
                               pose_rows_inverted(poses, str(folder)))
        return empty.rewritten(flange2base)
    except HandEyeError:
        return None

