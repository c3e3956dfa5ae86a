"""Everything that differs between eye-in-hand and eye-to-hand, in one place (docs/guide.md, Conventions).

* eye-in-hand: the camera rides on the flange; ``X = cam2flange``, ``Z = target2base``;
  ``target2base = flange2base_i @ X @ target2cam_i``.
* eye-to-hand: the camera stands beside the robot and the target rides on the flange;
  ``X = cam2base``, ``Z = target2flange``; ``target2flange = inv(flange2base_i) @ X @ target2cam_i``.

Both are the robot-world form ``A_i @ X = Z @ inv(target2cam_i)`` with ``A_i = flange2base_i``
(eye-in-hand) or ``inv(flange2base_i)`` (eye-to-hand): :func:`robot_world_A` and :func:`robot_world_A_inv` give ``A_i``
and its inverse (each computed directly, never as an inverse of an inverse). Relative motions follow from it:
``A_ij = inv(A_j) @ A_i``. The names of X and Z, and the default ROS frames, are here too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import yaml
from numpy.typing import NDArray

from .._shared.text import shown
from ..errors import InputMismatchError
from ..geometry.dualquat import dq_conj
from ..geometry.se3 import invert

__all__ = ["SETUPS", "Setup", "SetupInfo", "check_setup", "setup_info", "robot_world_A", "robot_world_A_inv", "robot_world_dq",
           "robot_world_inputs", "constant_transforms", "predicted_target2cam",
           "flange_poses", "camera2base", "target2base", "pose_name"]

SETUPS = ("eye_in_hand", "eye_to_hand")


@dataclass(frozen=True)
class SetupInfo:
    """Names and roles of the transforms of one setup."""

    name: str
    camera_on_flange: bool  #: the camera moves with the flange (eye-in-hand)
    x_name: str  #: ``cam2flange`` or ``cam2base``
    z_name: str  #: ``target2base`` or ``target2flange``
    x_inverse_name: str  #: ``flange2cam`` or ``base2cam``
    x_parent: str  #: the frame X maps camera coordinates into, in words
    ros_parent_frame: str  #: ROS-Industrial's name of that frame
    ros_child_frame: str = "camera_optical_frame"  #: OpenCV's camera frame is ROS's *_optical_frame (REP 103)


_INFO = {
    "eye_in_hand": SetupInfo("eye_in_hand", True, "cam2flange", "target2base", "flange2cam", "flange", "tool0"),
    "eye_to_hand": SetupInfo("eye_to_hand", False, "cam2base", "target2flange", "base2cam", "robot base", "base_link"),
}


class Setup(str):
    """A setup name already checked (:func:`check_setup` makes one): a ``str`` everywhere a setup
    name goes (JSON, comparisons, ``setup: str`` parameters), which the functions it travels into
    do not check again, with its :class:`SetupInfo` as ``info``.

    Examples
    --------
    >>> setup = check_setup("eye_to_hand")
    >>> setup == "eye_to_hand", setup.info.x_name, check_setup(setup) is setup
    (True, 'cam2base', True)
    """

    __slots__ = ()

    @property
    def info(self) -> SetupInfo:
        """The names and roles of X and Z."""
        return _INFO[str(self)]

    def __reduce__(self):  # pickles (Dask, multiprocessing) as the plain name, checked again on arrival
        return check_setup, (str(self),)


for _dumper in (yaml.SafeDumper, getattr(yaml, "CSafeDumper", yaml.SafeDumper)):  # libyaml's too (_shared.io.dump_yaml)
    _dumper.add_representer(Setup, lambda dumper, setup: dumper.represent_str(str(setup)))  # a session.yaml's setup: eye_in_hand


def check_setup(setup: str) -> Setup:
    """``setup`` as a checked :class:`Setup` if it is a known setup name, else a clear error; a
    :class:`Setup` is returned as it is (checked where it was made)."""
    if type(setup) is Setup:
        return setup
    if not isinstance(setup, str) or setup not in _INFO:
        raise InputMismatchError(f"unknown setup {shown(setup)}; use 'eye_in_hand' (camera on the flange) "
                                 f"or 'eye_to_hand' (camera fixed, target on the flange)")
    return Setup(setup)


def setup_info(setup: str) -> SetupInfo:
    """The names and roles of X and Z for ``setup`` (raises for an unknown one)."""
    return check_setup(setup).info


def robot_world_A(flange2base: NDArray[np.float64], setup: str) -> NDArray[np.float64]:
    """``A_i`` of ``A_i X = Z inv(target2cam_i)``: eye-in-hand ``flange2base``, eye-to-hand ``base2flange``."""
    return flange2base if _INFO[setup].camera_on_flange else invert(flange2base)


def robot_world_A_inv(flange2base: NDArray[np.float64], setup: str) -> NDArray[np.float64]:
    """``inv(A_i)`` (:func:`robot_world_A`), computed directly: eye-in-hand ``base2flange``, eye-to-hand
    ``flange2base``."""
    return invert(flange2base) if _INFO[setup].camera_on_flange else flange2base


def robot_world_dq(dq_flange2base: NDArray[np.float64], setup: str) -> NDArray[np.float64]:
    """The unit dual quaternions of ``A_i`` (:func:`robot_world_A`) from those of ``flange2base``."""
    return dq_flange2base if _INFO[setup].camera_on_flange else dq_conj(dq_flange2base)


def robot_world_inputs(
    flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(A_i, B_i)`` of ``A_i X = Z B_i``: ``A_i`` as :func:`robot_world_A`, ``B_i = inv(target2cam_i)``."""
    return robot_world_A(flange2base, setup), invert(target2cam)


def constant_transforms(
    X: NDArray[np.float64], flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str
) -> NDArray[np.float64]:
    """Per pose, the transform that must be constant given X: ``Z_i = A_i @ X @ target2cam_i``
    (target2base for eye-in-hand, target2flange for eye-to-hand)."""
    return robot_world_A(flange2base, setup) @ X @ target2cam


def predicted_target2cam(X: NDArray[np.float64], Z: NDArray[np.float64], flange2base: NDArray[np.float64],
                         setup: str) -> NDArray[np.float64]:
    """Camera-to-target poses implied by X, Z and the robot poses: ``inv(X) @ inv(A_i) @ Z``."""
    return invert(X) @ robot_world_A_inv(flange2base, setup) @ Z


def flange_poses(cam2target: NDArray[np.float64], X: NDArray[np.float64], Z: NDArray[np.float64],
                 setup: str) -> NDArray[np.float64]:
    """The robot poses that show the target from ``cam2target`` (batches broadcast): eye-in-hand
    ``Z @ cam2target @ inv(X)``, eye-to-hand ``X @ inv(cam2target) @ inv(Z)``."""
    if _INFO[setup].camera_on_flange:
        return Z @ cam2target @ invert(X)
    return X @ invert(cam2target) @ invert(Z)


def camera2base(X: NDArray[np.float64], flange2base: NDArray[np.float64], setup: str) -> NDArray[np.float64]:
    """The camera pose per robot pose in the base frame."""
    if _INFO[setup].camera_on_flange:
        return flange2base @ X
    return np.broadcast_to(X, flange2base.shape)


def target2base(Z: NDArray[np.float64], flange2base: NDArray[np.float64], setup: str) -> NDArray[np.float64]:
    """The target pose per robot pose in the base frame."""
    if _INFO[setup].camera_on_flange:
        return np.broadcast_to(Z, flange2base.shape)
    return flange2base @ Z


def pose_name(child: str, parent: str) -> str:
    """The name of the transform mapping coordinates in frame ``child`` into frame ``parent`` where a
    frame is named by the user (a rig's sensors): ``cam1_to_cam0``, ``cam1_to_flange``. The frames
    handeye names itself keep ``a2b`` (``cam2flange``, ``target2base``); a user's name may end in a
    digit, and ``cam12cam0`` reads as nothing.

    Examples
    --------
    >>> pose_name("cam1", "cam0"), pose_name("left", "flange")
    ('cam1_to_cam0', 'left_to_flange')
    """
    return f"{child}_to_{parent}"
