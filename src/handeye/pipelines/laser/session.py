"""Laser profiler session folders read and checked (the format in docs/guide.md, "Laser line profilers").

::

    SESSION/
      session.yaml
      poses.csv        # first column `profile` (the file in profiles/), then the pose columns
      profiles/        # one profile per robot pose: .csv (x,z or x,y,z) or .npy, in the unit below
      joints.csv       # optional: joint angles per profile (a joints: block)

``session.yaml``::

    setup: eye_in_hand
    laser:
      unit: mm                      # the profiles' unit: m | mm
      range: [80, 160]              # optional: the measuring range along z, in that unit (points outside: left out)
      noise: 0.02                   # optional: the sensor's noise along z, in that unit (default 0.02 mm)
    target: {type: sphere, diameter: 0.040}   # metres; without a diameter it is estimated
    # or target: {type: plane}                # a flat plate (fixed in the cell, or on the flange)
    # or target: {type: edge}                 # a block's edge: two flat faces meeting at a line (angle fitted)
    # or target: {type: step}                 # two parallel faces at different heights
    # or target: {type: spheres, diameters: [0.04, 0.03, 0.05]}   # a fixture of balls, each profile of one
    # or target: {type: spheres, count: 3, diameter: 0.04}        # balls alike
    poses: {file: poses.csv, format: "euler:xyz", length_unit: mm, angle_unit: deg}

Nothing is fitted here (:mod:`handeye.pipelines.laser.pipeline` does that); every key is checked (an unknown
one is an error naming the nearest known key).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._shared.text import shown
from ...errors import SessionError
from ...frames.poses import RobotPoseInput
from ...frames.setups import check_setup
from ...io.session import (
    JOINTS_KEYS,
    POSES_KEYS,
    SESSION_FILE,
    check_keys,
    check_session_keys,
    files_of_views,
    joints_of_views,
    read_joints,
    read_robot_poses,
    read_session_yaml,
    read_unknowns,
    session_file,
)
from ...robot.kinematics import Chain
from ...sensors.laser.model import LASER_NOISE_M
from ...sensors.laser.profiles import PROFILE_SUFFIXES

__all__ = ["LaserSession", "load_laser_session", "rig_laser", "LASER_KEYS", "TARGET_TYPES",
           "RIG_KEYS"]

#: The keys of ``laser:``, and of session.yaml around it.
LASER_KEYS = ("unit", "range", "noise")
SESSION_KEYS = ("setup", "laser", "target", "poses", "joints", "unknowns")
#: The targets a laser session can scan.
TARGET_TYPES = ("sphere", "plane", "edge", "step", "spheres")
#: The keys of a rig's laser profiler's block under ``sensors:`` (its target: the session's when left out).
RIG_KEYS = ("laser", "profiles", "target")
#: The keys of each target.
TARGET_KEYS = {"sphere": ("type", "diameter"), "plane": ("type",), "edge": ("type",), "step": ("type",),
               "spheres": ("type", "diameters", "count", "diameter")}


@dataclass(frozen=True)
class LaserSession:
    """A laser session's inputs, read and checked (no profile read yet)."""

    folder: Path
    setup: str
    target_spec: dict[str, Any]
    names: list[str]  #: per view: the profile's file name
    profile_paths: list[Path]
    flange2base: NDArray[np.float64]
    unit: str
    working_range: tuple[float, float] | None  #: metres
    noise_m: float
    radius: float | None  #: the ball's, metres (None: estimated, or not a ball)
    notes: list[str] = field(default_factory=list)
    joints: NDArray[np.float64] | None = None
    arm: Chain | None = None
    joints_path: Path | None = None
    target: str = "sphere"  #: one of :data:`TARGET_TYPES`
    radii: tuple[float, ...] | None = None  #: a fixture's balls' radii (m), one per ball (``type: spheres``)
    pose_input: RobotPoseInput | None = None  #: the pose table's rows as written, with their declaration
    unknowns: dict[str, str] = field(default_factory=dict)  #: session.yaml's ``unknowns:`` (hold, free or auto by name)

    @property
    def input_files(self) -> list[Path]:
        """Every file the session is read from."""
        return [self.folder / SESSION_FILE] + [p for p in self.profile_paths if p.is_file()]



def _laser_spec(spec: Any, where: str) -> tuple[str, tuple[float, float] | None, float]:
    if not isinstance(spec, dict):
        raise SessionError(f"{where}: laser must be a mapping (unit: m | mm, optional range and noise)")
    check_keys(spec, LASER_KEYS, f"{where}: laser")
    unit = str(spec.get("unit", ""))
    if unit not in ("m", "mm"):
        raise SessionError(f"{where}: laser: unit is m or mm (the profiles' unit), not {shown(unit)}")
    f = 1e-3 if unit == "mm" else 1.0
    rng = None
    if spec.get("range") is not None:
        try:
            lo, hi = (float(v) for v in spec["range"])
        except (TypeError, ValueError):
            raise SessionError(f"{where}: laser: range is [near, far] along z, in {unit}; got {shown(spec['range'])}") from None
        if not lo < hi:
            raise SessionError(f"{where}: laser: range [near, far] needs near < far, got {shown(spec['range'])}")
        rng = (f * lo, f * hi)
    noise = float(spec.get("noise", LASER_NOISE_M / f)) * f
    if not 0 < noise < 0.01:
        raise SessionError(f"{where}: laser: noise {noise / f:g} {unit}: give the sensor's noise along z in {unit} (a few "
                           "micrometres to a few tenths of a millimetre); if the profiles are in millimetres, write unit: "
                           "mm")
    return unit, rng, noise


def _target(target: Any, where: str) -> tuple[str, float | None, tuple[float, ...] | None]:
    """The target's type, a ball's radius (m; None: estimated, or not a ball) and a fixture's balls' radii."""
    if not isinstance(target, dict):
        raise SessionError(f"{where}: target must be a mapping, e.g. {{type: sphere, diameter: 0.04}} (metres), "
                           "{type: plane}, {type: edge}, {type: step} or {type: spheres, diameters: [0.04, 0.03]}")
    kind = str(target.get("type", ""))
    if kind not in TARGET_TYPES:
        raise SessionError(f"{where}: target: a laser session scans a {', a '.join(TARGET_TYPES[:-1])} or "
                           f"{TARGET_TYPES[-1]}, not {shown(kind)}")
    check_keys(target, TARGET_KEYS[kind], f"{where}: target ({kind})")
    if kind == "spheres":
        return kind, None, _radii(target, where)
    return kind, _radius(target, where) if kind == "sphere" else None, None


def _radii(target: dict, where: str) -> tuple[float, ...]:
    """A fixture's balls' radii (m): ``diameters: [...]`` (one per ball), or ``count`` balls alike of ``diameter``."""
    spelling = ("give diameters: [d1, d2, ...] (one per ball, metres) or, for balls alike, count: K and diameter: d "
                "(metres)")
    if target.get("diameters") is not None:
        if target.get("count") is not None or target.get("diameter") is not None:
            raise SessionError(f"{where}: target (spheres): {spelling}, not both")
        values = target["diameters"]
        if not isinstance(values, (list, tuple)) or len(values) < 2:
            raise SessionError(f"{where}: target (spheres): diameters {shown(values)}: {spelling}; one ball is type: sphere")
        if any(d is None for d in values):
            raise SessionError(f"{where}: target (spheres): diameters {shown(values)}: give every ball's diameter (metres)")
        return tuple(float(_radius({"diameter": d}, where)) for d in values)
    if target.get("count") is None or target.get("diameter") is None:
        raise SessionError(f"{where}: target (spheres): {spelling}")
    count = target["count"]
    if isinstance(count, bool) or not isinstance(count, int) or count < 2:
        raise SessionError(f"{where}: target (spheres): count {shown(count)}: the number of balls, 2 or more (one ball is "
                           "type: sphere)")
    return (float(_radius(target, where)),) * count


def _radius(target: dict, where: str) -> float | None:
    if target.get("diameter") is None:
        return None
    try:
        d = float(target["diameter"])
    except (TypeError, ValueError):
        raise SessionError(f"{where}: target: diameter {shown(target['diameter'])}: give metres, e.g. 0.04") from None
    if not 0 < d <= 1.0:
        raise SessionError(f"{where}: target: diameter {d:g} m: give it in metres (e.g. 0.04 for 40 mm)")
    return d / 2


def load_laser_session(folder: str | Path, arm: str | None = None) -> LaserSession:
    """Read and check a laser session folder (the module's docstring); no profile is read yet.

    Raises :class:`SessionError` naming the file and the key: no ``laser:`` mapping, an unknown key,
    a bad unit, range, noise or target, a diameter in millimetres given as metres, a missing pose
    table or profile file, a pose table whose first column is not ``profile``.
    """
    folder, spec, where, notes = read_session_yaml(folder)
    check_session_keys(spec, SESSION_KEYS, {"poses": POSES_KEYS, "joints": JOINTS_KEYS}, where)
    if spec.get("laser") is None:
        raise SessionError(f"{where}: no laser: mapping; a laser session says its profiles' unit there")
    setup = check_setup(str(spec.get("setup", "")))
    unit, working, noise = _laser_spec(spec["laser"], where)
    target, radius, radii = _target(spec.get("target"), where)
    joints = read_joints(folder, spec["joints"], where, notes, arm, ("profile",)) if spec.get("joints") else None
    posed = not (spec.get("poses") is None and joints is not None)
    if not posed:  # joint angles alone: the nominal table's flange poses
        names, f2b, pose_input = list(joints[0]), joints[2].forward(joints[1]), None
    else:
        f2b, names, _, pose_input = read_robot_poses(folder, spec.get("poses"), where, notes, ("profile",),
                                         "'profile', naming each pose's profile file in profiles/")
    q = None if joints is None else joints_of_views(joints, names, f2b if posed else None, notes)
    paths = _profiles_of(folder, folder / "profiles", names)
    return LaserSession(folder, setup, dict(spec["target"]), list(names), paths, f2b, unit, working, noise, radius, notes,
                        q, None if joints is None else joints[2], None if joints is None else joints[3], target, radii,
                        pose_input, read_unknowns(spec, where))


def rig_laser(folder: Path, setup: str, names: list[str], flange2base: NDArray[np.float64], laser: Any, profiles: Path,
              target: Any, where: str) -> LaserSession:
    """A rig's laser profiler (:mod:`handeye.pipelines.rig.session`) as a laser session over the rig's views
    ``names``: its ``laser:`` block, its folder of ``profiles`` named by view (``v01.csv``; a view
    with no file is one it did not see) and its ``target``, checked as a laser session's are."""
    unit, working, noise = _laser_spec(laser, where)
    kind, radius, radii = _target(target, where)
    session_file(folder, profiles, "its profiles' folder")
    if not profiles.is_dir():
        raise SessionError(f"{where}: no folder {profiles} (its profiles, named by view: v01.csv, ...)")
    paths = _profiles_of(folder, profiles, names)
    return LaserSession(folder, setup, dict(target), list(names), paths, flange2base, unit, working, noise, radius, [],
                        target=kind, radii=radii)


def _profiles_of(root: Path, folder: Path, names: list[str]) -> list[Path]:
    """Per view its profile in ``folder`` (:func:`~handeye.io.session.files_of_views`, inside the
    session folder ``root``); a path that does not exist for a view without one (the reader names it)."""
    return [found or folder / name for found, name in zip(files_of_views(folder, names, PROFILE_SUFFIXES, root), names)]
