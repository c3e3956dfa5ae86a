"""Other readings of a sensor session's robot poses, tried on a cheap start before the fit.

An image session checks its poses' conventions from the camera's own poses of the board
(:func:`handeye.diagnose`). A sensor that sees no whole pose per view (a laser's profiles of a ball, a
depth camera's clouds of a ball or a shape, a line-scan camera's scans, a rig) cannot: a pose table
read with the wrong Euler sequence, quaternion order, unit or inversion, or declared for the other
setup, only shows as a fit that explains nothing, after minutes of fitting. :func:`check_readings`
fits the sensor's own closed-form start and a short robust fit on a few thousand of its measurements
(:func:`quick_rms_mm`) as declared, and when that explains nothing (beyond :data:`~handeye.estimation.core.FIT_FACTOR`
times what the sensor's noise and the robot's accuracy allow), each other reading in turn, most
likely first: the first that fits is named, with what to change, and nothing is fitted.

Examples
--------
>>> import numpy as np
>>> from handeye.frames.poses import RobotPoseInput, format_poses
>>> from handeye.robot.models import ControllerPoses
>>> from handeye.sensors.depth.model import SphereCentres
>>> from handeye.pipelines.depth.simulate_board import sphere_scene
>>> scene = sphere_scene(12, "eye_to_hand", rng=1)
>>> rows = format_poses(scene.flange2base, "quat_xyzw", "mm")
>>> declared = RobotPoseInput(rows, "quat_wxyz", "mm")       # the columns' order declared wrong
>>> model = SphereCentres("eye_to_hand", [f"v{i}" for i in range(12)], scene.target2cam[:, :3, 3], fit_depth=False)
>>> robot = ControllerPoses(parse_poses(rows, "quat_wxyz", "mm"), (0.03, 0.3))
>>> try:
...     check_readings(model, robot, declared)
... except PoseFormatError as e:
...     print("quat_xyzw" in str(e))
True
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._shared.threads import on_one_blas_thread
from ..errors import HandEyeError, InputMismatchError, PoseFormatError
from ..frames.poses import RobotPoseInput, parse_poses
from ..frames.setups import SETUPS, check_setup, setup_info
from ..geometry.se3 import invert
from ..robot.models import ControllerPoses, RobotModel
from ..sensors.base import SensorModel
from .core import FIT_FACTOR, quick_rms_mm
from .diagnostics import pose_alternatives

__all__ = ["Reading", "robot_readings", "check_readings", "BETTER"]

#: Another reading is named when it fits within what the sensor and the robot allow and this many
#: times better than the reading as declared.
BETTER = 3.0


@dataclass(frozen=True)
class Reading:
    """One reading of the robot poses: a short name (``euler:xyz``, ``invert_robot_poses``,
    ``setup:eye_to_hand``, ...), what to change to get it, the flange poses so read and the setup."""

    hint: str
    fix: str
    flange2base: NDArray[np.float64]
    setup: str


def robot_readings(pose_input: RobotPoseInput | None, flange2base: NDArray[np.float64], setup: str) -> list[Reading]:
    """The other readings of the robot poses a user may have meant, most likely first: the other
    setup, the poses inverted, then (with the table as written, ``pose_input``) the Euler sequence
    with its letters' case swapped or reversed, the quaternion order, the length and angle units,
    then every other Euler sequence (:func:`~handeye.estimation.diagnostics.pose_alternatives`)."""
    other = next(s for s in SETUPS if s != setup)
    where = "on the flange" if setup_info(other).camera_on_flange else "fixed in the cell"
    rows = "base2flange" if pose_input is None or not pose_input.inverted else "flange2base"
    out = [Reading(f"setup:{other}", f"declare setup: {other} (the sensor {where})", flange2base, other),
           Reading("invert_robot_poses", f"the rows are the poses' inverses: declare pose: {rows} in the poses: block",
                   invert(flange2base), setup)]
    if pose_input is None:
        return out
    declared = pose_input.format

    def rank(hint: str) -> int:
        if hint.startswith("euler:") and declared.startswith("euler:"):
            seq, given = hint.split(":", 1)[1], declared.split(":", 1)[1]
            return 0 if seq == given.swapcase() else 1 if seq in (given[::-1], given[::-1].swapcase()) else 3
        return 2
    for hint, change in sorted(pose_alternatives(pose_input), key=lambda item: rank(item[0])):
        kw = dict(format=pose_input.format, length_unit=pose_input.length_unit, angle_unit=pose_input.angle_unit) | change
        try:
            T = parse_poses(pose_input.values, kw["format"], kw["length_unit"], kw["angle_unit"])
        except HandEyeError:
            continue
        key, _, value = hint.partition(":")
        fix = {"length_unit": f"the positions are in {value}: declare length_unit: {value}",
               "angle_unit": f"the angles are in {value}: declare angle_unit: {value}",
               "euler": f"the angles follow the Euler sequence {value} ({'intrinsic' if value.isupper() else 'extrinsic'}): "
                        f"declare format: euler:{value}"}.get(key, f"the quaternions are in {hint} order: declare format: {hint}")
        out.append(Reading(hint, fix, invert(T) if pose_input.inverted else T, setup))
    return out


def _in_setup(sensor: SensorModel, setup: str) -> SensorModel:
    """``sensor`` read for ``setup`` (a shallow copy: its measurements are the same)."""
    if setup == sensor.setup:
        return sensor
    other: Any = copy.copy(sensor)  # its setup is read-only to the core, not to this copy
    other.setup = check_setup(setup)
    return other


@on_one_blas_thread  # narrow matrices: a second BLAS thread spins more than it works
def check_readings(sensor: SensorModel, robot: RobotModel, pose_input: RobotPoseInput | None,
                   flange2base_rows: NDArray[np.float64] | None = None, index: NDArray[np.intp] | None = None,
                   rebuild: Callable[[Reading], tuple[SensorModel, RobotModel]] | None = None
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Refuse, naming the reading that fits, a session whose robot poses fit as another reading of
    them (the module docstring); silent when they fit as declared, or when no reading fits better
    (the fit's verdict then says what it finds). Returns the sensor's start as declared (X, ``p``), for
    the fit to start from (None when it could not be made, or the robot is not the controller's poses).

    Parameters
    ----------
    sensor, robot : SensorModel, RobotModel
        The session as declared; only the controller's poses are re-read (joint angles are not poses).
    pose_input : RobotPoseInput or None
        The pose table as written (None: only the setup and the inversion are tried).
    flange2base_rows : ndarray (R, 4, 4), optional
        Every row of the pose table as declared (default: ``robot``'s poses, one per view).
    index : ndarray of int, optional
        The rows the sensor's views are (default: one row per view, in order).
    rebuild : callable, optional
        For a sensor whose measurements depend on the poses read (a line-scan camera's trajectory):
        the sensor and robot of a reading (its ``flange2base``: every row); default: the same sensor
        with the reading's setup and the poses of its views.

    Raises
    ------
    PoseFormatError
        The poses fit as another reading (its name and what to change).
    InputMismatchError
        They fit for the other setup.
    """
    if not isinstance(robot, ControllerPoses):
        return None
    accuracy = robot.accuracy
    declared, allowed, start = quick_rms_mm(sensor, ControllerPoses(robot.poses, accuracy), accuracy)
    rows = robot.poses if flange2base_rows is None else np.asarray(flange2base_rows, float)
    readings = robot_readings(pose_input, rows, sensor.setup)
    # the other setup and the inverted poses always (with small turns a wrong setup still fits within
    # what the noise and the robot allow: 0.55 mm against 0.05 mm for a profiler's 4-15 deg turns);
    # the other formats and units when the poses as declared fit nothing
    if declared <= FIT_FACTOR * max(allowed, 0.05):
        readings = readings[:2]
    fitting: list[tuple[Reading, float]] = []
    for k, reading in enumerate(readings):
        if k >= 2 and fitting:  # the setup or the inverted poses fit: no other reading is looked for
            break
        if rebuild is not None:
            s, r = rebuild(reading)
        else:
            F = reading.flange2base if index is None else reading.flange2base[np.asarray(index)]
            s, r = _in_setup(sensor, reading.setup), ControllerPoses(F, accuracy)
        # from the closed form alone: the short fit polishes it, and a reading that is not the poses' made the
        # pose refinement's noise variances crawl (0.9 s of a mesh session's 1 ms closed form)
        rms, allowed_here, _ = quick_rms_mm(s, ControllerPoses(r.flange2base(np.zeros(r.n_params)), accuracy), accuracy,
                                            refine=False)
        if rms <= FIT_FACTOR * max(allowed_here, 0.05) and rms * BETTER < declared:
            fitting.append((reading, rms))
            if k >= 2:
                break
    if not fitting:
        return start
    reading, rms = fitting[0]
    words = (f"the robot poses do not fit the {sensor.kind}'s measurements as declared ({declared:.2f} mm RMS from a start, "
             f"where the sensor's noise and the robot's accuracy allow {allowed:.2f} mm); read so, they fit ({rms:.2f} mm): "
             f"{reading.fix}")
    if len(fitting) > 1 and fitting[1][1] <= 1.1 * rms:  # the same equations: both said, the setup first
        words += f"; or {fitting[1][0].fix} ({fitting[1][1]:.2f} mm)"
    if reading.hint.startswith("setup:"):
        raise InputMismatchError(words)
    raise PoseFormatError(words)
