"""Line-scan camera session folders read and checked (the format in docs/guide.md, "Line-scan cameras").

::

    SESSION/
      session.yaml
      poses.csv        # the robot's trajectory: a time column (its clock), then the pose columns
      images.csv       # image, time: each scan's file in images/ and the time of its row 0 (the camera's clock)
      images/          # the scans: one pushbroom image each (rows in the order exposed)

``session.yaml``::

    setup: eye_in_hand
    linescan:
      width: 2048          # pixels along the line
      line_rate: 1200      # rows per second
      focal: 2470          # the focal length's nominal value (px: the lens's focal length over the pixel pitch); fitted
      noise: 0.2           # optional: the corners' noise (px)
    target: {type: chessboard, cols: 9, rows: 6, square: 0.02}
    poses: {file: poses.csv, format: quat_wxyz, length_unit: mm, angle_unit: deg}
    joints: {file: joints.csv, unit: deg, arm: ur5}   # optional: the trajectory's joint angles
    images: {file: images.csv}

A ``joints:`` table is the trajectory as joint angles: a ``time`` column (the robot's clock;
``time_unit`` as a pose table's), then one column per joint. With it the arm's table is fitted with
X (:mod:`handeye.pipelines.linescan.pipeline`), and ``poses:`` may be left out (the nominal table's poses
are the trajectory's); given too, the controller's poses are checked against the joint angles.
The robot's clock and the camera's may differ by a fraction of a second: the offset is fitted. Nothing
is measured here (:mod:`handeye.pipelines.linescan.pipeline` does that); every key is checked (an unknown one
is an error naming the nearest known key).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._shared.text import shown, summarize
from ...errors import InputMismatchError, SessionError
from ...frames.poses import RobotPoseInput
from ...frames.setups import check_setup
from ...io.session import (
    IMAGES_KEYS,
    JOINTS_KEYS,
    POSES_KEYS,
    SESSION_FILE,
    check_session_keys,
    flange_poses_of,
    pose_table_path,
    read_image_times,
    read_joint_trajectory,
    read_pose_table,
    read_session_yaml,
    read_unknowns,
    robot_pose_input,
    session_file,
    time_unit_scale,
)
from ...robot.kinematics import Chain, check_joints_against_poses, joints_at
from ...sensors.camera.targets import target_from_spec
from ...sensors.linescan.model import LINESCAN_NOISE_PX

__all__ = ["LineScanSession", "load_linescan_session", "LINESCAN_KEYS"]

#: The keys of a ``linescan:`` block.
LINESCAN_KEYS = ("width", "line_rate", "focal", "noise")
#: The keys of a line-scan session's ``joints:`` block (a trajectory: its time column's unit too).
TRAJECTORY_JOINTS_KEYS = JOINTS_KEYS + ("time_unit",)


@dataclass(frozen=True)
class LineScanSession:
    """A line-scan session's inputs, read and checked (no image read yet)."""

    folder: Path
    setup: str
    target_spec: dict[str, Any]
    names: list[str]  #: per scan: the image's file name
    image_paths: list[Path]
    starts: NDArray[np.float64]  #: per scan: its row 0's time (s, the camera's clock)
    times: NDArray[np.float64]  #: the trajectory's times (s, the robot's clock)
    flange2base: NDArray[np.float64]  #: the trajectory's poses
    width: int
    line_rate: float
    focal: float
    noise_px: float
    notes: list[str] = field(default_factory=list)
    #: with a ``joints:`` table: the trajectory's joint angles (rad) at ``times``, the arm, the table's path
    joints: NDArray[np.float64] | None = None
    arm: Chain | None = None
    joints_path: Path | None = None
    #: without joints: the pose table's rows as written, with their declaration
    pose_input: RobotPoseInput | None = None
    unknowns: dict[str, str] = field(default_factory=dict)  #: session.yaml's ``unknowns:`` (hold, free or auto by name)
    #: scans left out as the session was read, with why (a scan whose time lies outside the trajectory)
    skipped: list[tuple[str, str]] = field(default_factory=list)

    @property
    def input_files(self) -> list[Path]:
        """Every file the session is read from."""
        return [self.folder / SESSION_FILE] + [p for p in self.image_paths if p.is_file()]



def _positive(spec: dict, key: str, where: str, what: str) -> float:
    try:
        value = float(spec[key])
    except KeyError:
        raise SessionError(f"{where}: linescan: {key} is missing: {what}") from None
    except (TypeError, ValueError):
        raise SessionError(f"{where}: linescan: {key} {shown(spec[key])} is not a number: {what}") from None
    if not value > 0 or not np.isfinite(value):
        raise SessionError(f"{where}: linescan: {key} {value:g}: {what}, a positive number")
    return value


def load_linescan_session(folder: str | Path, arm: str | None = None) -> LineScanSession:
    """Read and check a line-scan session folder (the module docstring); nothing is measured yet.
    ``arm`` (``--arm``): the arm of the ``joints:`` table, instead of the one session.yaml names.

    Raises :class:`SessionError` naming the file or key: no ``linescan:`` mapping, a missing or bad
    width, line rate or focal length, a bad target, a trajectory without a time column, neither
    poses nor joint angles, joint angles that disagree with the poses, an image missing, a scan
    whose time lies outside the trajectory.
    """
    folder, spec, where, notes = read_session_yaml(folder)
    if not isinstance(spec.get("linescan"), dict):
        raise SessionError(f"{where}: no linescan: mapping (width, line_rate, focal)")
    check_session_keys(spec, ("setup", "target", "linescan", "poses", "joints", "images", "unknowns"),
                       {"linescan": LINESCAN_KEYS, "poses": POSES_KEYS, "joints": TRAJECTORY_JOINTS_KEYS,
                        "images": IMAGES_KEYS}, where)
    setup = check_setup(str(spec.get("setup", "")))
    target_from_spec(spec.get("target"), where=f"{where}: target")
    ls = spec["linescan"]
    width = _positive(ls, "width", where, "the pixels along the line")
    if width != int(width):
        raise SessionError(f"{where}: linescan: width {width:g}: a whole number of pixels")
    line_rate = _positive(ls, "line_rate", where, "the rows per second")
    focal = _positive(ls, "focal", where, "the focal length's nominal value in pixels (the lens's focal length over the "
                                          "pixel pitch, e.g. 16 mm / 7 um = 2286)")
    if focal < 0.05 * width:
        raise SessionError(f"{where}: linescan: focal {focal:g} px for a line of {int(width)} px: give it in pixels (the "
                           "lens's focal length over the pixel pitch), not millimetres")
    noise = float(ls.get("noise", LINESCAN_NOISE_PX))
    if not 0 < noise < 50:
        raise SessionError(f"{where}: linescan: noise {noise:g}: the corners' noise in pixels (e.g. 0.2)")
    joints = chain = joints_path = pose_input = None
    if spec.get("joints") is not None:
        times, joints, chain, joints_path = read_joint_trajectory(folder, spec["joints"], where, notes, arm)
        trajectory, f2b = joints_path, chain.forward(joints)  # the nominal table's poses: the arm's error is fitted
    elif spec.get("poses") is None:
        raise SessionError(f"{where}: neither a poses: nor a joints: block: give the robot's trajectory, as flange poses (poses:) "
                           "or joint angles (joints:), each with a time column first")
    if spec.get("poses") is not None:
        poses = spec["poses"]
        table = pose_table_path(folder, poses, where, "the robot's trajectory, a time column first")
        values, _, pose_times = read_pose_table(table, str(poses["format"]), id_columns=(), notes=notes, times=True)
        if pose_times is None:
            raise SessionError(f"{table}: no time column: a line-scan session's poses are the robot's trajectory, a time "
                               "column (the robot's clock) then the pose columns")
        pose_times = np.asarray(pose_times, float) * time_unit_scale(poses, f"{where}: poses")
        if joints is None:
            trajectory, times, f2b = table, pose_times, flange_poses_of(values, poses, table, where)
            pose_input = robot_pose_input(values, poses, where)
        else:
            notes.append(_poses_against_joints(flange_poses_of(values, poses, table, where), pose_times, times, joints,
                                               chain, joints_path))
    names, starts, _ = read_image_times(folder, spec.get("images"), where, notes)
    paths = [session_file(folder, folder / "images" / n, f"the scan {shown(n)}") for n in names]
    missing = [p.name for p in paths if not p.is_file()]
    if missing:
        raise SessionError(f"{folder / 'images'}: scan image(s) missing: {', '.join(missing[:10])}")
    starts = np.asarray(starts, float)
    inside = (starts >= times[0] - 1.0) & (starts <= times[-1] + 1.0)
    if not inside.any():  # every scan: the clocks or the files disagree, not one scan
        raise SessionError(f"{trajectory}: the trajectory runs {times[0]:.3f}-{times[-1]:.3f} s; the scans "
                           f"{summarize(names)} start outside it: give the trajectory around every scan, on a clock "
                           "within a fraction of a second of the camera's (images.csv's time)")
    span = "-".join(f"{v:.3f}".replace("-0.000", "0.000") for v in (times[0], times[-1]))
    skipped = [(n, f"starts at {t:.3f} s, outside the trajectory ({span} s): no robot pose for it")
               for n, t, ok in zip(names, starts, inside) if not ok]
    keep = np.flatnonzero(inside)
    return LineScanSession(folder, setup, dict(spec["target"]), [names[k] for k in keep], [paths[k] for k in keep],
                           starts[keep], times, f2b, int(width), line_rate, focal, noise, notes, joints, chain, joints_path,
                           skipped=skipped, pose_input=pose_input, unknowns=read_unknowns(spec, where))


def _poses_against_joints(flange2base: NDArray[np.float64], pose_times: NDArray[np.float64], times: NDArray[np.float64],
                          joints: NDArray[np.float64], chain: Chain, path: Path) -> str:
    """The controller's poses checked against the joint angles through the arm's nominal table, at
    the poses' times within the joint trajectory (the angles linear between samples): the finding,
    or a SessionError naming what makes them agree (degrees read as radians, another arm, ...)."""
    inside = (pose_times >= times[0]) & (pose_times <= times[-1])
    if not inside.any():
        raise SessionError(f"{path}: the joint angles run {times[0]:.3f}-{times[-1]:.3f} s and the poses "
                           f"{pose_times[0]:.3f}-{pose_times[-1]:.3f} s: give both on the robot's clock")
    q = joints_at(times, joints, pose_times[inside])
    try:
        return check_joints_against_poses(chain, q, flange2base[inside], f"{path.name}'s joint angles",
                                          names=[f"the pose at {s:.3f} s" for s in pose_times[inside]])
    except InputMismatchError as exc:
        raise SessionError(f"{path}: {exc}") from None
