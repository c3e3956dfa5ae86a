"""Rig session folders read and checked: several sensors, one table of robot poses (docs/guide.md, "Rigs").

::

    SESSION/
      session.yaml
      poses.csv        # first column `view` (each robot pose's name), then the pose columns
      joints.csv       # optional: first column `view`, then the joint angles (a joints: block)
      left/            # one folder per sensor: its images named by the view (v01.png, ...)
      right/

``session.yaml``::

    setup: eye_in_hand
    target: {type: chessboard, cols: 9, rows: 6, square: 0.03}
    poses: {file: poses.csv, format: quat_wxyz, length_unit: mm, angle_unit: deg}
    sensors:
      left:  {camera: {K: [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dist: [k1, k2, p1, p2, k3]}, images: left}
      right: {camera: {K: ..., dist: ...}, images: right}

A depth camera is one too: ``{depth: {unit: m, range: [0.3, 1.5]}, camera: {K: ..., dist: ...},
clouds: d435, target: ...}``, its clouds (``v01.npy``, .ply or .pcd) and, for a board, the
intensity images they are registered to (``v01.png``; ``images:``, default the clouds' folder) named
by view; its target a board (the session's, shared with the cameras: the board's pose is then one
set of unknowns) or spheres. A laser profiler is a sensor too (a camera beside a profiler on a
welding torch, two profilers on one seam): ``{laser: {unit: mm, range: [80, 160]}, profiles: laser, target: {type: sphere,
diameter: 0.04}}``, its profiles named by view (``v01.csv``), its target (any a laser session
takes) its own or, left out, the session's. Sensors that see different targets each keep their own
target's unknowns.

With ``joints: {file: joints.csv, unit: deg, arm: ur5}`` the robot's poses are its joint angles
through the arm's table (fitted with the rig, as for one sensor); ``poses:`` may then be left out.
A sensor may miss a view (no image of that name in its folder: said in a note); a sensor's name is
its key (a name given twice is an error). Nothing is measured here (:mod:`handeye.pipelines.rig.pipeline`
does that); every key is checked.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._shared.text import cut, summarize
from ...errors import SessionError
from ...frames.poses import RobotPoseInput
from ...frames.setups import check_setup
from ...io.session import (
    IMAGE_ORDER,
    JOINTS_KEYS,
    POSES_KEYS,
    SESSION_FILE,
    check_keys,
    check_session_keys,
    files_of_views,
    joints_of_views,
    read_camera,
    read_joints,
    read_robot_poses,
    read_session_yaml,
    read_unknowns,
    session_file,
)
from ...robot.kinematics import Chain
from ...sensors.camera.targets import target_from_spec
from ..kinds import member_kind, sensor_kinds

__all__ = ["RigSession", "RigSensor", "load_rig_session", "extras", "SENSOR_KEYS", "IMAGE_SUFFIXES"]

#: The keys of one camera's block (another kind's block: that kind's ``rig_member`` checks it).
SENSOR_KEYS = ("camera", "images")
#: The image files a sensor's folder may hold: an image session's (the png first).
IMAGE_SUFFIXES = IMAGE_ORDER


@dataclass(frozen=True)
class RigSensor:
    """One sensor of a rig: a camera (its intrinsics and per view its image, None where it has none)
    or a sensor of another kind (``member``: what its kind's registration reads as a rig's sensor, over
    the rig's views: a laser profiler's profiles, a depth camera's clouds; ``kind`` its section)."""

    name: str
    K: NDArray[np.float64] | None = None
    dist: NDArray[np.float64] | None = None
    images: list[Path | None] = field(default_factory=list)
    member: Any = None
    #: the target it sees (a camera's: the session's)
    target_spec: dict[str, Any] = field(default_factory=dict)
    #: its kind's section in session.yaml ("laser", "depth"), "camera" for a camera
    kind: str = "camera"

    @property
    def seen(self) -> list[bool]:
        """Per view of the rig whether the sensor has its image, profile or cloud (and intensity image)."""
        return list(self.member.seen) if self.member is not None else [p is not None for p in self.images]

    @property
    def files(self) -> list[Path]:
        """The sensor's input files."""
        return list(self.member.files) if self.member is not None else [p for p in self.images if p is not None]


@dataclass(frozen=True)
class RigSession:
    """A rig session's inputs, read and checked (no image read yet)."""

    folder: Path
    setup: str
    target_spec: dict[str, Any]
    names: list[str]  #: per robot pose: the view's name
    flange2base: NDArray[np.float64]
    sensors: list[RigSensor]
    notes: list[str] = field(default_factory=list)
    #: a ``joints:`` table: each view's joint angles (rad), the arm's nominal table, the file
    joints: NDArray[np.float64] | None = None
    arm: Chain | None = None
    joints_path: Path | None = None
    pose_input: RobotPoseInput | None = None  #: the pose table's rows as written, with their declaration
    unknowns: dict[str, str] = field(default_factory=dict)  #: session.yaml's ``unknowns:`` (hold, free or auto by name)

    @property
    def input_files(self) -> list[Path]:
        """Every file the session is read from."""
        tables = [self.joints_path] if self.joints_path is not None else []
        return [self.folder / SESSION_FILE] + tables + [p for s in self.sensors for p in s.files]

    @property
    def shared_target(self) -> bool:
        """Whether the sensors see one target: the same target spec for every sensor (cameras and
        depth cameras on the session's board, profilers on one ball). Whether its pose can be one
        set of unknowns is the sensor models' to say (:func:`handeye.pipelines.rig.pipeline.calibrate_rig_session`)."""
        return len({str(sorted(x.target_spec.items())) for x in self.sensors}) == 1



def extras(spec: dict[str, Any], folder: Path, needs: dict[str, dict[str, str]]) -> None:
    """The optional extras a rig session needs (its registration's ``extras`` hook): each sensor's,
    by its kind's ``rig_extras`` (a depth camera's clouds' readers)."""
    sensors = spec.get("sensors")
    for name, block in (sensors.items() if isinstance(sensors, dict) else ()):
        kind = member_kind(block) if isinstance(block, dict) else None
        if kind is not None and kind.rig_extras is not None:
            kind.hook("rig_extras")(block, str(name), folder, needs)


def _camera(folder: Path, name: str, block: dict, names: list[str], target: Any, at: str) -> RigSensor:
    """A rig's camera: its intrinsics and per view its image (None where it has none)."""
    if block.get("camera") is None:
        raise SessionError(f"{at}: camera (K and dist) is missing: a rig's cameras need their intrinsics (calibrate each "
                           "camera's first, e.g. with handeye calibrate on its own images)")
    K, dist = read_camera(block["camera"], at)
    if K is None:
        raise SessionError(f"{at}: camera: K is missing")
    images = session_file(folder, folder / str(block.get("images", name)), "its images' folder")
    if not images.is_dir():
        raise SessionError(f"{at}: no folder {images} (its images, named by view)")
    return RigSensor(name, K, np.zeros(5) if dist is None else dist, files_of_views(images, names, IMAGE_SUFFIXES, folder),
                     target_spec=dict(target or {}))


def load_rig_session(folder: str | Path, arm: str | None = None) -> RigSession:
    """Read and check a rig session folder (the module docstring); ``arm`` (``--arm``): the arm of
    the ``joints:`` table instead of the one session.yaml names.

    Raises :class:`SessionError` naming the file or key: no ``sensors:`` mapping or fewer than two
    sensors, a sensor without its camera's K and dist or its folder, a bad target, pose or joint table.
    """
    folder, spec, where, notes = read_session_yaml(folder)
    sensors = spec.get("sensors")
    if not isinstance(sensors, dict) or len(sensors) < 2:
        raise SessionError(f"{where}: sensors must map two sensor names or more to their camera and images folder")
    check_session_keys(spec, ("setup", "target", "poses", "joints", "sensors", "unknowns"),
                       {"poses": POSES_KEYS, "joints": JOINTS_KEYS}, where)
    setup = check_setup(str(spec.get("setup", "")))
    if any(isinstance(b, dict) and member_kind(b) is None for b in sensors.values()):  # the cameras' board
        target_from_spec(spec.get("target"), where=f"{where}: target")
    joints = read_joints(folder, spec["joints"], where, notes, arm, ("view",)) if spec.get("joints") else None
    posed = not (spec.get("poses") is None and joints is not None)
    if not posed:  # joint angles alone: the nominal table's flange poses
        names, f2b, pose_input = list(joints[0]), joints[2].forward(joints[1]), None
    else:
        f2b, names, _, pose_input = read_robot_poses(folder, spec.get("poses"), where, notes, ("view",), "view")
    out = []
    for name, block in sensors.items():
        at = f"{where}: sensors: {cut(str(name), 80)}"
        if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", str(name)):
            raise SessionError(f"{at}: a sensor's name may hold letters, digits, '_', '-' and '.' (it names the sensor's "
                               "folder of results and its ROS frame); rename it")
        if not isinstance(block, dict):
            others = [f"{k.section}: for a {k.display}" for k in sensor_kinds() if k.rig_member is not None]
            raise SessionError(f"{at}: a mapping with camera (K, dist) and images (its folder), or another kind's section "
                               f"({', '.join(others)})")
        target = block.get("target", spec.get("target"))
        kind = member_kind(block)
        if kind is not None:  # read by its kind, over the rig's views
            member = kind.hook("rig_member")(folder, setup, names, f2b, block, str(name), target, at)
            out.append(RigSensor(str(name), member=member, target_spec=dict(target or {}), kind=kind.section))
        else:
            check_keys(block, SENSOR_KEYS, at)
            out.append(_camera(folder, str(name), block, names, target, at))
        missing = [n for n, seen in zip(names, out[-1].seen) if not seen]
        if missing:
            what = out[-1].member.missing if out[-1].member is not None else "image"
            notes.append(f"sensor {name}: no {what} for {len(missing)} of {len(names)} views ({summarize(missing)}): those "
                         "views are not its")
    q = None if joints is None else joints_of_views(joints, names, f2b if posed else None, notes)
    return RigSession(folder, setup, dict(spec.get("target") or {}), list(names), f2b, out, notes, q,
                      None if joints is None else joints[2], None if joints is None else joints[3], pose_input,
                      read_unknowns(spec, where))
