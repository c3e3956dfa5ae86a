"""What the pipelines of sensor models share: the options they use and those they refuse, the robot model."""

from __future__ import annotations

from typing import Any

from ..errors import InputMismatchError
from ..options import CalibrationOptions, options_from
from ..robot.models import ControllerPoses, JointAngles, RobotModel

__all__ = ["sensor_options", "robot_model"]

#: The options of image and pose sessions that a sensor model's fit has no use for.
IMAGE_ONLY = ("method", "refine", "pairs", "known", "robot_noise", "compliance", "strict_images", "keyframes",
              "offset_range", "time_offset")


def _given(value: Any, default: Any) -> bool:
    """Whether an option was given other than its default (an empty mapping counts as none)."""
    if value is None or (isinstance(value, dict) and not value):
        return default is not None and not (isinstance(default, dict) and not default)
    if isinstance(value, (str, bool, int, float, tuple)):
        return value != default
    return True


def sensor_options(options: CalibrationOptions | None, changes: dict, what: str) -> CalibrationOptions:
    """The options of a sensor model's calibration (``robot_accuracy``, ``folds``, ``arm``), refusing
    by name those that only image and pose sessions use when they are given (``what``: the session
    in words, for the message)."""
    opts = options_from(options, changes)
    default = CalibrationOptions()
    unused = [name for name in IMAGE_ONLY if _given(getattr(opts, name), getattr(default, name))]
    unused += [] if opts.check else ["check"]
    if unused:
        flags = ", ".join(f"{name} (--{name.replace('_', '-')})" for name in unused)
        raise InputMismatchError(f"{flags}: options of image and pose sessions; {what}'s fit has no use for them (leave "
                                 "them out)")
    return opts


def robot_model(session: Any, index: list[int], accuracy: tuple[float, float] | None) -> RobotModel:
    """The robot side of a sensor session's (depth, laser: its ``flange2base``, ``joints``, ``arm``)
    views ``index``: joint angles through the arm's table when the session has them, else the
    controller's poses with the robot's stated ``accuracy``."""
    if session.joints is not None:
        return JointAngles(session.arm, session.joints[index])
    return ControllerPoses(session.flange2base[index], accuracy)
